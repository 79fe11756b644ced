import itertools

import mujoco
import numpy as np
import pytest
from tests_support import NEXTAGE_JOINTS as JOINT_NAMES

from nextage_qp.errors import ConfigError, UnknownJointError, UnknownNameError
from nextage_qp.robots.model import Robot
from nextage_qp.scene.files import BodyPose, SceneOverrides, scene_path

# Spec section 1.2: link masses [kg].
MASSES = {
    "nextage_base": 40.0,
    "WAIST": 5.0,
    "CHEST_JOINT0_Link": 10.0,
    "HEAD_JOINT0_Link": 0.317929,
    "HEAD_JOINT1_Link": 0.4,
    **{f"{s}ARM_JOINT{i}_Link": m for s in "LR" for i, m in
       enumerate((1.32626, 1.14898, 0.577518, 0.457418, 0.418434, 1.05156))},
}
SCENES = ["scene", "push_cube", "dock_dumbbell"]


def test_joint_names_order_and_indices(robot):
    assert robot.nq == 15
    assert [robot.model.joint(int(j)).name for j in robot.joint_ids] == list(JOINT_NAMES)
    assert [robot.model.actuator(int(a)).name for a in robot.actuator_ids] == list(JOINT_NAMES)
    assert robot.joint_index("RARM_JOINT5") == 14
    with pytest.raises(UnknownJointError, match="valid: CHEST_JOINT0"):
        robot.joint_index("LARM_JOINT6")


def test_index_arrays_are_read_only(robot):
    with pytest.raises(ValueError):
        robot.qpos_idx[0] = 3


def test_link_masses_and_total(robot):
    m = robot.model
    for name, mass in MASSES.items():
        assert m.body(name).mass[0] == pytest.approx(mass, abs=1e-9), name
    assert sum(MASSES.values()) == pytest.approx(65.678269, abs=1e-6)
    moving = [b for b in range(m.nbody) if m.body_weldid[b] != 0]
    assert np.sum(m.body_mass[moving]) == pytest.approx(65.678269 - 45.0, abs=1e-6)


def test_inertials_follow_urdf(robot):
    m = robot.model
    b = m.body("LARM_JOINT1_Link").id
    np.testing.assert_allclose(m.body_ipos[b], (-0.04, 0.1, -0.12))
    # principal moments of the URDF's full inertia tensor are preserved
    full = np.array([[0.0154168, 9.95417e-07, 3.38147e-06], [9.95417e-07, 0.0147117, 0.00213719],
                     [3.38147e-06, 0.00213719, 0.0012658]])
    np.testing.assert_allclose(np.sort(m.body_inertia[b]), np.sort(np.linalg.eigvalsh(full)), rtol=1e-6)


def test_joint_axes_ranges_damping_and_torque_limits(robot):
    m = robot.model
    axes = {"CHEST_JOINT0": (0, 0, 1), "HEAD_JOINT1": (0, 1, 0), "LARM_JOINT3": (1, 0, 0), "RARM_JOINT5": (0, 0, 1)}
    for name, axis in axes.items():
        np.testing.assert_allclose(m.jnt_axis[m.joint(name).id], axis)
    i = robot.joint_index("RARM_JOINT3")
    assert (robot.lower[i], robot.upper[i]) == pytest.approx((-1.74532, 3.141592))
    assert m.dof_damping[robot.dof_idx[robot.joint_index("LARM_JOINT2")]] == 0.5
    assert m.dof_damping[robot.dof_idx[0]] == 0.2
    assert robot.torque_limit[0] == 100 and robot.torque_limit[3] == 150


def test_keyframes(robot):
    home = robot.keyframe_q("home")
    assert home[robot.joint_index("LARM_JOINT1")] == -0.4 and home[robot.joint_index("RARM_JOINT1")] == -0.4
    assert np.count_nonzero(home) == 2
    assert not np.any(robot.keyframe_q("zero"))
    with pytest.raises(UnknownNameError, match="home, zero"):
        robot.keyframe_q("rest")


def test_sites_and_groups(robot):
    assert set(robot.site_names) >= {"left_wrist", "right_wrist", "left_tool", "right_tool", "left_pad", "right_pad"}
    assert list(robot.group("left_arm")) == list(range(3, 9))
    assert robot.frame("left_tool")[0] == "site" and robot.frame("LARM_JOINT5_Link")[0] == "body"


def test_visual_geoms_never_collide(robot):
    m = robot.model
    visual = [g for g in range(m.ngeom) if m.geom_group[g] == 2]
    assert visual and all(m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0 for g in visual)
    collision = [g for g in range(m.ngeom) if m.geom_group[g] == 3]
    assert len(collision) == 45  # spec section 1.3: 5 base + 1 waist + 7 chest + 2 head + 2 x 15 arm primitives


def test_table_top_height(push_robot):
    m, d = push_robot.model, mujoco.MjData(push_robot.model)
    mujoco.mj_forward(m, d)
    g = m.geom("table_top").id
    assert d.geom_xpos[g][2] + m.geom_size[g][2] == pytest.approx(0.875, abs=1e-12)


def hold_home(robot: Robot, seconds: float = 2.0) -> mujoco.MjData:
    """Simple PD with bias compensation holding `home`; fails on any MuJoCo warning or NaN."""
    m = robot.model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    q_ref = robot.keyframe_q("home")
    for _ in range(int(seconds / m.opt.timestep)):
        q, qd = robot.get_q(d), robot.get_qd(d)
        d.ctrl[robot.actuator_ids] = 300.0 * (q_ref - q) - 20.0 * qd + d.qfrc_bias[robot.dof_idx]
        mujoco.mj_step(m, d)
    assert np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))
    assert all(w.number == 0 for w in d.warning), [(i, w.number) for i, w in enumerate(d.warning) if w.number]
    np.testing.assert_allclose(robot.get_q(d), q_ref, atol=1e-3)
    return d


@pytest.mark.parametrize("scene", SCENES)
def test_every_scene_holds_home_for_two_seconds(scene):
    hold_home(Robot.from_scene(scene))


def test_cube_settles_at_start(push_robot):
    d = hold_home(push_robot)
    np.testing.assert_allclose(d.qpos[push_robot.object_qpos_slice("cube")][:3], (0.33, 0, 0.91), atol=1e-3)


def test_dumbbell_settles_at_start(dock_robot):
    d = hold_home(dock_robot)
    np.testing.assert_allclose(d.qpos[dock_robot.object_qpos_slice("dumbbell")][:3], (0.5, 0, 1.015), atol=1e-3)
    assert dock_robot.model.body("dumbbell").mass[0] == pytest.approx(0.3)


def test_scene_overrides_move_objects_targets_and_mass():
    over = SceneOverrides(
        poses={
            "dumbbell": BodyPose(pos=(0.52, 0.02, 1.015), yaw=0.2),
            "dumbbell_target": BodyPose(pos=(0.3, 0.4, 1.0)),
        },
        masses={"dumbbell": 0.03},
    )
    robot = Robot.from_scene("dock_dumbbell", over)
    m = robot.model
    np.testing.assert_allclose(m.qpos0[robot.object_qpos_slice("dumbbell")][:3], (0.52, 0.02, 1.015))
    np.testing.assert_allclose(m.body("dumbbell_target").pos, (0.3, 0.4, 1.0))
    assert m.body("dumbbell").mass[0] == pytest.approx(0.03)
    np.testing.assert_allclose(m.body("dumbbell").inertia, np.array([0.01084329, 0.01084329, 0.00371606]) / 10)
    hold_home(robot, 0.5)


def test_scene_override_errors():
    with pytest.raises(UnknownNameError, match="cube"):
        Robot.from_scene("push_cube", SceneOverrides(poses={"cubee": BodyPose(pos=(0, 0, 1))}))
    with pytest.raises(ConfigError, match="must be a finite mass > 0"):
        Robot.from_scene("dock_dumbbell", SceneOverrides(masses={"dumbbell": -1.0}))
    with pytest.raises(UnknownNameError, match="unknown object 'wall'; valid: dumbbell"):
        Robot.from_scene("dock_dumbbell", SceneOverrides(masses={"wall": 1.0}))
    with pytest.raises(UnknownNameError, match=r"scene body .* 'LARM_JOINT0_Link'"):
        Robot.from_scene("dock_dumbbell", SceneOverrides(poses={"LARM_JOINT0_Link": BodyPose(pos=(0, 0, 1))}))
    with pytest.raises(ConfigError, match="bundled scenes: dock_dumbbell"):
        scene_path("no_such_scene")


def test_no_contacts_at_home_or_zero_in_robot_model(robot):
    m, d = robot.model, mujoco.MjData(robot.model)
    for key in ("home", "zero"):
        mujoco.mj_resetDataKeyframe(m, d, m.key(key).id)
        mujoco.mj_forward(m, d)
        assert d.ncon == 0, key


def test_trimmed_excludes_keep_the_contact_set():
    """The adjacent-link excludes the MJCF leaves out (MuJoCo's parent filter covers them) change no contact."""
    import mujoco

    from nextage_qp.robots.compose import robot_spec
    from nextage_qp.robots.description import load_robot

    description = load_robot("nextage")
    spec = robot_spec(description)
    arms = [[f"{prefix}_JOINT{i}_Link" for i in range(6)] for prefix in ("LARM", "RARM")]
    heads = ("HEAD_JOINT0_Link", "HEAD_JOINT1_Link")
    adjacent = [("CHEST_JOINT0_Link", heads[0]), heads]
    for links in arms:
        adjacent += [("CHEST_JOINT0_Link", links[0]), *itertools.pairwise(links)]
    assert len(adjacent) == 14
    for a, b in adjacent:
        spec.add_exclude(bodyname1=a, bodyname2=b)
    full, trimmed = spec.compile(), robot_spec(description).compile()
    assert trimmed.nexclude == 3 and full.nexclude == 17
    robot = Robot(trimmed, description)
    rng = np.random.default_rng(0)
    datas = [mujoco.MjData(full), mujoco.MjData(trimmed)]
    touched = 0
    for _ in range(3000):
        q = rng.uniform(robot.lower, robot.upper)
        sets = []
        for model, data in zip((full, trimmed), datas, strict=True):
            data.qpos[robot.qpos_idx] = q
            mujoco.mj_forward(model, data)
            sets.append({tuple(sorted((int(c.geom1), int(c.geom2)))) for c in data.contact[: data.ncon]})
        assert sets[0] == sets[1]
        touched += bool(sets[0])
    assert touched > 100  # the configurations do produce contacts to compare
