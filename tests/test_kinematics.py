import importlib.util

import numpy as np
import pytest
from tests_support import NEXTAGE_JOINTS as JOINT_NAMES

from nextage_qp.errors import UnknownFrameError
from nextage_qp.kinematics.frames import Kinematics, chain_fk
from nextage_qp.kinematics.nextage_chain import TOPOLOGY as NEXTAGE_TOPOLOGY

# Spec section 1.4: world positions of the link frames.
REF_ZERO = {
    "CHEST_JOINT0": (0, 0, 1.117),
    "HEAD_JOINT0": (0, 0, 1.419),
    "HEAD_JOINT1": (0, 0, 1.499),
    "ARM_JOINT0": (0.04, 0.135, 1.2185),
    "ARM_JOINT1": (0.04, 0.135, 1.2845),
    "ARM_JOINT2": (0.04, 0.23, 1.0345),
    "ARM_JOINT3": (0.2205, 0.23, 1.0045),
    "ARM_JOINT4": (0.37, 0.23, 1.0045),
    "ARM_JOINT5": (0.37, 0.23, 0.871),
}


def expanded(ref):
    out = {}
    for name, (x, y, z) in ref.items():
        if name.startswith("ARM"):
            out["L" + name] = (x, y, z)
            out["R" + name] = (x, -y, z)
        else:
            out[name] = (x, y, z)
    return out


@pytest.mark.parametrize("link,expected", sorted(expanded(REF_ZERO).items()))
def test_fk_matches_spec_at_zero(robot, link, expected):
    pose = Kinematics(robot).fk(f"{link}_Link", robot.keyframe_q("zero"))
    np.testing.assert_allclose(pose.pos, expected, atol=1e-6)
    np.testing.assert_allclose(pose.rot, np.eye(3), atol=1e-12)  # every URDF rpy is zero


@pytest.mark.parametrize("side,sign", [("L", 1.0), ("R", -1.0)])
def test_fk_matches_spec_at_home(robot, side, sign):
    kin = Kinematics(robot)
    q = robot.keyframe_q("home")
    np.testing.assert_allclose(kin.fk(f"{side}ARM_JOINT5_Link", q).pos, (0.504975, sign * 0.23, 1.032149), atol=1e-6)
    np.testing.assert_allclose(kin.fk(f"{side}ARM_JOINT1_Link", q).pos, (0.04, sign * 0.135, 1.2845), atol=1e-6)


def test_home_links_above_shoulder_unchanged(robot):
    kin = Kinematics(robot)
    for name in ("CHEST_JOINT0", "HEAD_JOINT0", "HEAD_JOINT1"):
        np.testing.assert_allclose(kin.fk(f"{name}_Link", robot.keyframe_q("home")).pos, REF_ZERO[name], atol=1e-6)


def test_mujoco_fk_equals_transform_chain_on_1000_random_configurations(robot):
    kin = Kinematics(robot)
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(1000):
        q = rng.uniform(robot.lower, robot.upper)
        for joint in JOINT_NAMES:
            pose = kin.fk(f"{joint}_Link", q)
            t = chain_fk(joint, dict(zip(JOINT_NAMES, q, strict=True)), NEXTAGE_TOPOLOGY)
            worst = max(worst, np.abs(pose.pos - t[:3, 3]).max(), np.abs(pose.rot - t[:3, :3]).max())
    assert worst < 1e-9


def test_transform_chain_topology_covers_every_joint():
    assert set(NEXTAGE_TOPOLOGY) == set(JOINT_NAMES)


def test_chain_fk_takes_a_link_or_its_joint_and_zero_for_joints_left_out(robot):
    q = robot.keyframe_q("home")
    by_name = chain_fk("LARM_JOINT5_Link", robot.q_to_names(q), NEXTAGE_TOPOLOGY)
    np.testing.assert_allclose(by_name, chain_fk("LARM_JOINT5", {"LARM_JOINT1": -0.4}, NEXTAGE_TOPOLOGY))


@pytest.mark.parametrize("frame", ["left_wrist", "right_tool", "LARM_JOINT3_Link", "CHEST_JOINT0_Link"])
def test_jacobian_matches_finite_differences(robot, frame):
    kin = Kinematics(robot)
    rng = np.random.default_rng(1)
    eps = 1e-6
    for _ in range(5):
        q = rng.uniform(robot.lower + 0.01, robot.upper - 0.01)
        jac = kin.jacobian(frame, q)
        base = kin.fk(frame, q)
        num = np.zeros((6, robot.nq))
        for i in range(robot.nq):
            dq = np.zeros(robot.nq)
            dq[i] = eps
            plus, minus = kin.fk(frame, q + dq), kin.fk(frame, q - dq)
            num[:3, i] = (plus.pos - minus.pos) / (2 * eps)
            # angular velocity from dR R^T (world frame)
            w = (plus.rot - minus.rot) / (2 * eps) @ base.rot.T
            num[3:, i] = (w[2, 1], w[0, 2], w[1, 0])
        np.testing.assert_allclose(jac, num, atol=1e-6)


def test_fk_does_not_disturb_a_running_simulation(push_robot):
    import mujoco

    data = mujoco.MjData(push_robot.model)
    mujoco.mj_resetDataKeyframe(push_robot.model, data, 0)
    mujoco.mj_forward(push_robot.model, data)
    before = (data.qpos.copy(), data.xpos.copy())
    Kinematics(push_robot).fk("left_wrist", push_robot.keyframe_q("zero"))
    np.testing.assert_array_equal(data.qpos, before[0])
    np.testing.assert_array_equal(data.xpos, before[1])


def test_unknown_frame_lists_valid_names(robot):
    with pytest.raises(UnknownFrameError, match="valid: left_wrist"):
        Kinematics(robot).fk("LARM_HAND", robot.keyframe_q())
    with pytest.raises(UnknownFrameError, match="LARM_JOINT5_Link"):
        chain_fk("LARM_HAND", {}, NEXTAGE_TOPOLOGY)


def test_pose_quaternion_is_unit_and_matches_rotation(robot):
    import mujoco

    pose = Kinematics(robot).fk("left_wrist", robot.keyframe_q("home"))
    assert np.isclose(np.linalg.norm(pose.quat), 1.0)
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, pose.quat)
    np.testing.assert_allclose(mat.reshape(3, 3), pose.rot, atol=1e-12)


@pytest.mark.parametrize(("scene", "robot_name"), [
    ("push_cube", None),
    pytest.param("push_cube", "yumi", marks=pytest.mark.skipif(importlib.util.find_spec("robosuite_models") is None,
                                                               reason="robosuite_models is not installed")),
])
def test_reach_sphere_holds_every_configuration(scene, robot_name) -> None:
    """No configuration takes a frame's origin out of its reach sphere, and the sphere is not loose by much."""
    from nextage_qp.robots.model import Robot

    robot = Robot.from_scene(scene, robot=robot_name)
    kin, rng = Kinematics(robot), np.random.default_rng(2)
    for frame in (robot.arms[0].wrist, robot.arms[1].tool):
        centre, radius, joint = kin.reach(frame, robot.keyframe_q("home"))
        assert joint is not None and np.isfinite(radius)
        far = max(float(np.linalg.norm(kin.fk(frame, rng.uniform(robot.lower, robot.upper)).pos - centre))
                  for _ in range(500))
        assert 0.7 * radius < far <= radius + 1e-9, (frame, far, radius)
