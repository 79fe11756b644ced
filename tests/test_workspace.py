"""One task config, any robot: positions in the robot file's workspace, what the config leaves to the robot."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from nextage_qp.cli import main
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner, build_robot, for_robot
from nextage_qp.robots.description import load_robot
from nextage_qp.robots.gains import config_gains, rule_gains

ROOT = Path(__file__).resolve().parents[1]
ACROSS = ROOT / "configs" / "push_across.yaml"
needs_robosuite = pytest.mark.skipif(importlib.util.find_spec("robosuite_models") is None,
                                     reason="robosuite_models is not installed (the robots extra)")


@needs_robosuite
@pytest.mark.parametrize("robot", ["nextage", "yumi", "aloha"])
def test_a_workspace_config_puts_the_scene_where_each_robot_works(robot):
    cfg = load_config(ACROSS, [f"robot={robot}"])
    built = build_robot(cfg, str(ACROSS))
    ws = load_robot(robot).workspace
    assert ws is not None
    cube = built.model.body("cube").pos
    assert np.allclose(cube, [ws.centre[0], ws.centre[1] + 0.10, ws.top + 0.035])
    target = built.model.body("cube_target").pos
    assert np.allclose(target[:2], [ws.centre[0], ws.centre[1] - 0.10])
    table = built.model.body("table")
    top = table.pos[2] + built.model.geom("table_top").pos[2] + built.model.geom("table_top").size[2]
    assert top == pytest.approx(ws.top)  # the robot file's table top is where the table is
    if ws.table is not None:
        assert np.allclose(table.pos, ws.table)


@needs_robosuite
@pytest.mark.parametrize("robot", ["nextage", "aloha"])
def test_a_task_config_written_once_runs_on_two_robots(robot):
    cfg = load_config(ACROSS, [f"robot={robot}"])
    result = Runner(cfg, str(ACROSS)).run()
    assert result["success"], result.get("error")
    assert result["object_error_xy_m"] < 0.005


def test_a_workspace_config_on_a_robot_without_one_is_refused_in_one_line(tmp_path, capsys):
    text = (ROOT / "robots" / "nextage.yaml").read_text()
    block = text[text.index("workspace:"):text.index("keyframes:")]
    robot = _nextage_copy(tmp_path, block, "")
    assert main(["run", str(ACROSS), "--robot", str(robot)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "declares no workspace" in err and "scene.frame: world" in err


@needs_robosuite
def test_orient_auto_holds_the_whole_rotation_only_with_seven_joints_to_the_tool():
    for robot, expected in (("nextage", "full"), ("yumi", "full"), ("aloha", "normal")):
        cfg = load_config(ACROSS, [f"robot={robot}"])
        assert cfg.phases[0].orient == "auto"
        resolved = for_robot(cfg, build_robot(cfg, str(ACROSS)))
        assert resolved.phases[0].orient == expected, robot


@needs_robosuite
def test_a_gains_profile_serves_a_robot_whose_gains_come_from_the_rule():
    cfg = load_config(ACROSS, ["robot=yumi"])
    robot = build_robot(cfg, str(ACROSS))
    base = rule_gains(robot, robot.description.gains)
    stiff = config_gains("stiff_wrist", robot)
    wrists = {robot.joint_index(j) for arm in robot.arms for j in arm.joints[-3:]}
    for j in range(robot.nq):
        factor = 4.0 if j in wrists else 1.0  # twice the bandwidth: kp x 4
        assert stiff.kp[j] == pytest.approx(factor * base.kp[j])
    nextage = build_robot(load_config(ACROSS), str(ACROSS))
    assert config_gains("stiff_wrist", nextage).source.endswith("stiff_wrist.yaml")  # its own file wins
    plain = config_gains("default", robot)  # the clamp tasks' gains: the rule's own
    assert np.allclose(plain.kp, base.kp) and np.allclose(plain.kd, base.kd)
    assert config_gains("default", nextage).source.endswith("default.yaml")


def _nextage_copy(tmp_path, old="", new=""):
    """The bundled Nextage's robot file, with its paths made absolute and ``old`` replaced by ``new``."""
    text = (ROOT / "robots" / "nextage.yaml").read_text()
    out = []
    for line in text.splitlines():
        if line.startswith(("model:", "gains:", "gains_dir:")):
            key, value = line.split(":", 1)
            line = f"{key}: {(ROOT / 'robots' / value.split('#')[0].strip()).resolve()}"
        out.append(line)
    path = tmp_path / "mine.yaml"
    path.write_text("\n".join(out).replace(old, new) + "\n")
    return path


def test_robot_check_judges_the_workspace_reach_and_table():
    from nextage_qp.experiments.table_ready import check_at_table

    report = check_at_table(ROOT / "robots" / "nextage.yaml")
    found = [f for f in report.findings if f.topic == "workspace"]
    assert len(found) == 1 and found[0].level == "info", found  # the table and the tools' reach are right
    # the work region's far corners cannot be pushed back towards the robot; its centre and near corners every way
    message = found[0].message
    assert "corner (+1, -1) towards -x" in message and "corner (+1, +1) towards -x" in message, message
    assert "centre" not in message and "corner (-1" not in message, message


@pytest.mark.parametrize("old, new, says", [
    ("centre: [0.45, 0.0]", "centre: [1.6, 0.0]", "falls short of the work region's centre"),
    ("top: 0.875", "top: 0.95", "workspace.top: 0.95 m, but the table's top stands at 0.875 m"),
])
def test_robot_check_names_a_workspace_the_robot_cannot_work_in(tmp_path, old, new, says):
    from nextage_qp.experiments.table_ready import check_at_table

    report = check_at_table(_nextage_copy(tmp_path, old, new))
    problems = [f for f in report.problems if f.topic == "workspace"]
    assert problems and says in problems[0].message, report.findings


@needs_robosuite
def test_robot_init_drafts_a_robot_ready_for_the_shared_push(tmp_path, capsys):
    """The YuMi's model, never seen by a robot file: tools, a workspace where a tool reaches behind an object from
    every side, a ready home, and the push runs on it."""
    import mujoco

    from nextage_qp.ik import QPIK, FrameTarget
    from nextage_qp.ik.config import IKConfig
    from nextage_qp.robots.model import Robot
    from nextage_qp.robots.modelfile import self_contacts

    model = Path(importlib.util.find_spec("robosuite_models").origin).parent / "assets" / "robots" / "yumi" / "robot.xml"
    out = tmp_path / "yumi.yaml"
    assert main(["robot", "init", str(model), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "robot check finds no problems" in printed and "ready home" in printed
    desc = load_robot(out)
    assert desc.workspace is not None and {a.tool for a in desc.arms} == {"left_tool", "right_tool"}
    robot = Robot.from_scene("push_cube", None, desc)
    d = mujoco.MjData(robot.model)
    qpos = d.qpos.copy()
    qpos[robot.qpos_idx] = robot.keyframe_q("home")
    assert not [p for p in self_contacts(robot.model, d, qpos) if "table" not in p and "cube" not in p]
    note = next(line for line in out.read_text().splitlines() if "manipulability" in line)
    values = [float(v) for v in out.read_text().split("each tool)")[1].split("\nkeyframes")[0].replace("#", "").split(",")]
    assert note and min(values) > 1e-3  # away from singularities
    ik, home, ws = QPIK(robot, IKConfig()), robot.keyframe_q("home"), desc.workspace
    for sx, sy in ((-1, -1), (-1, 1), (1, -1), (1, 1)):  # at each corner, a push's approach from every side
        corner = np.array([ws.centre[0] + sx * ws.size[0], ws.centre[1] + sy * ws.size[1], ws.top + 0.035])
        for facing in np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]]):
            behind = corner - facing * (0.035 + 0.04)  # behind a 7 cm cube, the push's approach gap back
            assert any(ik.solve([FrameTarget(tool, pos=behind, axis=np.array([1.0, 0, 0]), direction=facing)],
                                home).pos_err_m <= 0.005 for tool in ("left_tool", "right_tool")), (corner, facing)
    result = Runner(load_config(ACROSS, [f"robot={out}"]), str(ACROSS)).run()
    assert result["success"], result.get("error")
    assert result["object_error_xy_m"] <= 0.005


@needs_robosuite
def test_the_aloha_draft_pushes_unedited(tmp_path, capsys):
    """The ALOHA's model drives its wrists with +-1 N m motors, less than their gravity torque: the draft raises them
    (and says so), and the shared push runs on the draft as written."""
    model = Path(importlib.util.find_spec("robosuite_models").origin).parent / "assets" / "robots" / "aloha" / "robot.xml"
    out = tmp_path / "aloha.yaml"
    assert main(["robot", "init", str(model), "--out", str(out)]) == 0
    assert "robot check finds no problems" in capsys.readouterr().out
    desc = load_robot(out)
    assert isinstance(desc.torque_limits, dict) and all(desc.torque_limits[f"{s}/wrist_angle"] >= 5.0
                                                       for s in ("left", "right"))
    result = Runner(load_config(ACROSS, [f"robot={out}"]), str(ACROSS)).run()
    assert result["success"], result.get("error")
    assert result["object_error_xy_m"] <= 0.005


def test_robot_init_says_why_a_model_gets_no_workspace(tmp_path, capsys):
    out = tmp_path / "two_arms.yaml"
    assert main(["robot", "init", str(ROOT / "tests" / "data" / "robots" / "two_arms.xml"), "--out", str(out)]) == 0
    assert "no table height found" in capsys.readouterr().out
    assert load_robot(out).workspace is None  # the draft loads without one: world-frame tasks still run on it


PICK = ROOT / "configs" / "pick_place_box.yaml"


@pytest.mark.parametrize("old, new, says", [
    ("    pad: left_palm", "    pad:", "arms left, right declare no pad"),  # an undeclared pad is the wrist
    ("    pad: left_palm", "    pad: left_tool", "arm right declares no pad"),
])
def test_a_clamp_the_robot_cannot_make_is_refused_in_one_line(tmp_path, capsys, old, new, says):
    robot = _nextage_copy(tmp_path, old, new).read_text().replace("    pad: right_palm\n", "")
    path = tmp_path / "nopad.yaml"
    path.write_text("\n".join(line for line in robot.splitlines() if line.strip() != "pad:") + "\n")
    assert main(["run", str(PICK), "--robot", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "phases[0] (clamp): robot" in err and "cannot clamp" in err and says in err and "arms[].pad" in err


def test_a_pad_on_a_body_without_a_force_sensor_is_refused_naming_the_bodies_with_one(tmp_path, capsys):
    robot = _nextage_copy(tmp_path, "    pad: left_palm", "    pad: left_elbow_pad")
    robot.write_text(robot.read_text() + "frames:\n  left_elbow_pad: {body: LARM_JOINT2_Link, pos: [0.0, 0.0, 0.0]}\n")
    assert main(["run", str(PICK), "--robot", str(robot)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "pad 'left_elbow_pad' is on body 'LARM_JOINT2_Link', which has no force/torque sensor" in err
    assert "LARM_JOINT5_Link (left_pad)" in err  # where one is


@needs_robosuite
@pytest.mark.parametrize("config, robot", [("pick_place_box", "yumi"), ("pick_place_box", "aloha"),
                                           ("stack_boxes", "aloha")])
def test_the_shared_clamp_tasks_refuse_a_robot_they_are_out_of_reach_of_before_anything_moves(capsys, config, robot):
    """The YuMi's and the ALOHA's flanges clamp (their files' pads, with force/torque sensors the files add), but the
    targets these tasks put 30-38 cm to the side of the work region are out of their arms' reach."""
    assert main(["run", str(ROOT / "configs" / f"{config}.yaml"), "--set", f"robot={robot}"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "phase 'clamp' (grasp): the clamp cannot reach" in err
    assert "out of the arms' reach" in err


@needs_robosuite
def test_the_yumi_stacks_with_its_flanges_as_pads(capsys):
    """The shared stacking task on the YuMi: its flanges clamp the box, the force/torque sensors its file adds at
    the pads feel the squeeze, and the box stands on the other."""
    assert main(["run", str(ROOT / "configs" / "stack_boxes.yaml"), "--set", "robot=yumi", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["success"] and result["object_error_xy_m"] < 0.005


@pytest.mark.parametrize("config", ["pick_place_box", "stack_boxes"])
def test_the_shared_clamp_tasks_stand_in_the_workspace(config):
    path = ROOT / "configs" / f"{config}.yaml"
    cfg = load_config(path)
    assert cfg.scene.frame == "workspace" and all(s.frames is None for s in cfg.phases if s.kind == "grasp")
    built = build_robot(cfg, str(path))
    ws = load_robot("nextage").workspace
    assert ws is not None
    for name, decl in cfg.scene.objects.items():
        assert decl.pos is not None
        assert np.allclose(built.model.body(name).pos[:2], np.add(ws.centre, decl.pos[:2]))


@needs_robosuite
def test_a_tool_the_last_joint_does_not_move_does_not_read_as_a_singularity():
    """The ALOHA's tools sit on the link before wrist_rotate: five joints move each, so the 6 x 6 Jacobian over the
    arm's joints is singular everywhere; the measure over the joints that move the tool is not, at its home."""
    from nextage_qp.experiments.table_ready import _manipulability
    from nextage_qp.kinematics.frames import Kinematics
    from nextage_qp.robots.model import Robot

    robot = Robot.from_scene("push_cube", None, load_robot("aloha"))
    q = robot.keyframe_q("home")
    for arm in robot.arms:
        assert len(robot.chain_joints(arm.tool)) == 5
        jac = Kinematics(robot).jacobian(arm.tool, q)[:, [robot.joint_index(j) for j in arm.joints]]
        assert abs(np.linalg.det(jac)) < 1e-9  # the whole arm's: a zero column
    assert min(_manipulability(robot, q, [arm.tool for arm in robot.arms])) > 1e-2


@needs_robosuite
@pytest.mark.slow
def test_robot_init_tips_a_tool_down_that_cannot_come_low_enough_level(tmp_path, capsys):
    """The PR2's long grippers: level, its arms meet the table before the tips come within a quarter of a 7 cm cube
    over its centre; pitched down they do, and the draft says so."""
    model = Path(importlib.util.find_spec("robosuite_models").origin).parent / "assets" / "robots" / "pr2" / "robot.xml"
    out = tmp_path / "pr2.yaml"
    assert main(["robot", "init", str(model), "--out", str(out)]) == 0
    capsys.readouterr()
    face = load_robot(out).push_face
    assert face.pitch > 0 and face.height < 0.07 / 4
    assert "tipped down" in out.read_text()


def test_robot_check_says_whether_the_robot_can_clamp(tmp_path):
    from nextage_qp.experiments.table_ready import check_at_table

    assert not [f for f in check_at_table(ROOT / "robots" / "nextage.yaml").findings if f.topic == "clamp"]
    bare = _nextage_copy(tmp_path, "    pad: left_palm", "")
    bare.write_text(bare.read_text().replace("    pad: right_palm\n", ""))
    said = [f for f in check_at_table(bare).findings if f.topic == "clamp"]
    assert len(said) == 1 and said[0].level == "info" and "declare no pad" in said[0].message
    numb = _nextage_copy(tmp_path, "    pad: left_palm", "    pad: left_elbow_pad")
    numb.write_text(numb.read_text() + "frames:\n  left_elbow_pad: {body: LARM_JOINT2_Link, pos: [0.0, 0.0, 0.0]}\n")
    said = [f for f in check_at_table(numb).problems if f.topic == "clamp"]
    assert len(said) == 1 and "'LARM_JOINT2_Link', which has no force/torque sensor" in said[0].message


def test_a_hand_tipped_down_leads_into_an_object_with_its_upper_rim():
    """A box hand pitched 0.3 rad about y (its +x face's normal tipped down): along +x its upper front edge leads, at
    the height of that edge; level, the face's centre."""
    from types import SimpleNamespace

    import mujoco

    from nextage_qp.experiments.table_ready import _leading_height

    def lead(pitch: float) -> float:
        m = mujoco.MjModel.from_xml_string(f"""<mujoco><compiler angle="radian"/><worldbody><body name="hand" pos="0 0 1">
            <geom type="box" size="0.01 0.03 0.03" euler="0 {pitch} 0"/></body></worldbody></mujoco>""")
        robot = SimpleNamespace(model=m, qpos_idx=np.zeros(0, dtype=int), frame_body=lambda _: m.body("hand").id)
        return _leading_height(robot, np.zeros(0), "tool", np.array([1.0, 0.0, 0.0]))

    assert lead(0.0) == pytest.approx(1.0, abs=1e-9)
    assert lead(0.3) == pytest.approx(1.0 - 0.01 * np.sin(0.3) + 0.03 * np.cos(0.3), abs=1e-9)


def test_the_work_region_is_centred_between_the_arms():
    """Of the blocks a tool reaches, the work region is the best one centred on the middle column (the midline
    between the arms, where a clamp or a hand-over meets): a larger block to one side loses; none there gives None."""
    from nextage_qp.experiments.table_ready import _largest_rectangle

    ok = np.zeros((5, 9), dtype=bool)
    ok[:5, :4] = True  # 5 x 4 cells left of the middle column 4
    ok[:3, 3:6] = True  # 3 x 3 around it
    assert _largest_rectangle(ok) == (0, 4, 0, 4 - 1)  # the larger block, off the middle
    assert _largest_rectangle(ok, middle=4) == (0, 2, 3, 5)
    ok[1, 4] = False  # a hole on the midline: a strip of one row on either side of it
    assert _largest_rectangle(ok, middle=4) == (0, 0, 3, 5)
    ok[:, 4] = False
    assert _largest_rectangle(ok, middle=4) is None


def test_the_shoulder_is_the_first_joint_turning_about_a_level_axis():
    """A pan joint at the foot of a tall link (a Baxter's) stands below the shoulder: the table tops are sought under
    the pitch joint above it; an arm of upright joints only has its first joint as the shoulder."""
    import mujoco

    from nextage_qp.experiments.table_ready import _shoulder

    m = mujoco.MjModel.from_xml_string("""<mujoco><worldbody><body name="a" pos="0 0 0.2"><joint name="pan"/>
        <geom size="0.05"/><body name="b" pos="0 0 0.3" euler="90 0 0"><joint name="pitch"/><geom size="0.05"/>
        <body name="c" pos="0 0 0.3"><joint name="wrist" axis="1 0 0"/><geom size="0.05"/></body></body></body>
        </worldbody></mujoco>""")
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    assert _shoulder(m, d, ["pan", "pitch", "wrist"])[2] == pytest.approx(0.5)
    assert _shoulder(m, d, ["pan"])[2] == pytest.approx(0.2)


@pytest.mark.parametrize("axis", ["1 0 0", "0 1 0"])
def test_a_hand_faces_where_it_points_whether_its_last_joint_rolls_or_flexes_it(axis):
    """The tool's face normal (its x) points out of the hand: along the last joint's axis where that joint rolls the
    hand (a spherical wrist's), square to it where it flexes the hand (a TIAGo's); on the hand's outermost point."""
    from types import SimpleNamespace

    import mujoco

    from nextage_qp.experiments.table_ready import tool_frames

    m = mujoco.MjModel.from_xml_string(f"""<mujoco><worldbody><body name="fore"><joint name="elbow" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/><body name="hand" pos="0.3 0 0">
        <joint name="wrist" axis="{axis}"/><geom type="box" size="0.05 0.02 0.02" pos="0.05 0 0"/></body></body>
        </worldbody></mujoco>""")
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    ready = tool_frames(m, d, SimpleNamespace(arms=[SimpleNamespace(name="left", joints=("elbow", "wrist"))]))
    frame = ready.frames["left_tool"]
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, np.array(frame.quat))
    assert frame.body == "hand" and frame.pos == pytest.approx((0.1, 0.0, 0.0))
    assert rot.reshape(3, 3)[:, 0] == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)


def test_a_hand_without_geometry_pushes_with_the_first_link_up_the_arm_that_has_some():
    """A model whose hand links carry no collision geometry (a GR1's without its hands): the tool is on the forearm's
    end face, facing along it, not the empty wrist."""
    from types import SimpleNamespace

    import mujoco

    from nextage_qp.experiments.table_ready import tool_frames

    m = mujoco.MjModel.from_xml_string("""<mujoco><worldbody><body name="fore"><joint name="roll" axis="1 0 0"/>
        <geom type="box" size="0.1 0.03 0.03" pos="0.1 0 0"/><body name="wrist" pos="0.25 0 0">
        <joint name="yaw" axis="0 0 1"/><inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/>
        <body name="hand"><joint name="pitch" axis="0 1 0"/>
        <geom type="box" size="0.05 0.02 0.02" pos="0.05 0 0" contype="0" conaffinity="0"/></body></body></body>
        </worldbody></mujoco>""")
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    arm = SimpleNamespace(name="left", joints=("roll", "yaw", "pitch"))
    frame = tool_frames(m, d, SimpleNamespace(arms=[arm])).frames["left_tool"]
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, np.array(frame.quat))
    assert frame.body == "fore" and frame.pos == pytest.approx((0.2, 0.0, 0.0))
    assert rot.reshape(3, 3)[:, 0] == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)
