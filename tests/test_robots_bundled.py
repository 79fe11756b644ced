"""Robots other than the Nextage: one scene file composed around several robots, the bundled YuMi and ALOHA files,
the bimanual move, and the robot-file settings the simulation reads (velocity and torque limits, keyframes)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from nextage_qp.cli import main
from nextage_qp.experiments.bimanual import run_bimanual
from nextage_qp.loop.simulation import Simulation
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner
from nextage_qp.robots.description import load_robot
from nextage_qp.robots.gains import robot_gains
from nextage_qp.robots.model import Robot
from nextage_qp.sweep.spec import SweepSpec

ROOT = Path(__file__).resolve().parents[1]
TWO_ARMS = ROOT / "tests" / "data" / "robots" / "two_arms.xml"
needs_robosuite = pytest.mark.skipif(importlib.util.find_spec("robosuite_models") is None,
                                     reason="robosuite_models is not installed (the robots extra)")
TWO_ARMS_FILE = """name: two_arms
model: {model}
mount: {{pos: [0.0, 0.0, 0.2]}}
arms:
  - {{name: left, joints: [l_shoulder_pitch, l_shoulder_roll, l_elbow, l_wrist], wrist: l_grip}}
  - {{name: right, joints: [r_shoulder_pitch, r_shoulder_roll, r_elbow, r_wrist], wrist: r_grip}}
joint_groups: {{torso: [waist], head: [head_pan]}}
collision_groups: {{left_arm: {{subtrees: [l_upper]}}, right_arm: {{subtrees: [r_upper]}}}}
keyframes:
  home: {{l_shoulder_pitch: -0.5, l_shoulder_roll: 0.5, l_elbow: 0.65, r_shoulder_pitch: -0.5, r_shoulder_roll: -0.5,
          r_elbow: -0.65}}
torque_limits: 10.0
{extra}"""


def two_arms(tmp_path: Path, extra: str = "") -> Path:
    path = tmp_path / "two_arms.yaml"
    path.write_text(TWO_ARMS_FILE.format(model=TWO_ARMS, extra=extra))
    return path


def test_one_scene_file_serves_every_robot(tmp_path):
    robots = ["nextage", two_arms(tmp_path)]
    if importlib.util.find_spec("robosuite_models") is not None:
        robots += ["yumi", "aloha"]
    for ref in robots:
        robot = Robot.from_scene("push_cube", robot=ref)
        assert robot.object_names == ("cube",)
        assert {"table", "cube_target"} <= set(robot.body_names)
        desc = load_robot(ref)
        assert set(robot.joint_names) == set(desc.joints)
        groups = robot.collision_geoms()
        assert groups["table"] and groups["cube"]
        # the robot sits where its file mounts it: its top body at the mount
        top = int(robot.model.body_rootid[robot.model.jnt_bodyid[robot.joint_ids[0]]])
        np.testing.assert_allclose(robot.model.body_pos[top][:2], np.asarray(desc.mount.pos)[:2], atol=0.5)


def test_composed_robot_keeps_its_names_and_scene_keeps_its_options(tmp_path):
    robot = Robot.from_scene("push_cube", robot=two_arms(tmp_path))
    assert robot.frame("l_grip")[0] == "site"
    assert robot.model.opt.timestep == pytest.approx(0.001)
    assert robot.keyframe_q("home")[robot.joint_index("l_elbow")] == pytest.approx(0.65)


def test_zero_keyframe_is_built_in(tmp_path):
    robot = Robot.from_scene("scene", robot=two_arms(tmp_path))
    q = robot.keyframe_q("zero")
    assert np.all(q >= robot.lower) and np.all(q <= robot.upper)
    with pytest.raises(Exception, match="keyframe"):
        robot.keyframe_q("nope")


def test_robot_file_velocity_limits_cap_the_references(tmp_path):
    robot = Robot.from_scene("scene", robot=two_arms(tmp_path, "velocity_limits: {l_elbow: 0.25}\n"))
    sim = Simulation(robot, robot_gains(robot))
    v = sim.limits.arrays(robot.joint_names)[0]
    assert v[robot.joint_index("l_elbow")] == pytest.approx(0.25)
    assert v[robot.joint_index("r_elbow")] == pytest.approx(1.0)  # the trajectory default, uncapped


def test_robot_file_torque_limits_win_over_the_model(tmp_path):
    text = (ROOT / "robots" / "nextage.yaml").read_text()
    text = text.replace("model: nextage/nextage.xml", f"model: {ROOT / 'robots' / 'nextage' / 'nextage.xml'}")
    text = text.replace("gains: ../configs/gains/default.yaml", f"gains: {ROOT / 'configs' / 'gains' / 'default.yaml'}")
    text = text.replace("gains_dir: ../configs/gains", f"gains_dir: {ROOT / 'configs' / 'gains'}")
    (tmp_path / "n.yaml").write_text(text + "torque_limits: {LARM_JOINT0: 40.0}\n")
    robot = Robot.from_scene("scene", robot=tmp_path / "n.yaml")
    assert robot.torque_limit[robot.joint_index("LARM_JOINT0")] == pytest.approx(40.0)  # the model's motor: 150
    assert robot.torque_limit[robot.joint_index("LARM_JOINT1")] == pytest.approx(150.0)
    (tmp_path / "bad.yaml").write_text(text + "torque_limits: {NOT_A_JOINT: 40.0}\n")
    with pytest.raises(Exception, match="NOT_A_JOINT"):
        Robot.from_scene("scene", robot=tmp_path / "bad.yaml")


def test_bimanual_move_holds_the_relative_pose():
    robot = Robot.from_scene("scene")
    res, _ = run_bimanual(robot, np.array([0.03, 0.0, 0.02]), gains=robot_gains(robot), speed=0.1)
    assert res.max_relative_error_m < 0.002
    assert res.final_lead_error_m < 0.002
    assert res.frames == (robot.arms[0].wrist, robot.arms[1].wrist)


def test_bimanual_bad_input_is_one_line(capsys):
    assert main(["bimanual", "--frames", "left_wrist", "left_wrist"]) == 2
    err = capsys.readouterr().err
    assert "two different frames" in err and err.count("\n") == 1


def test_config_start_as_joint_angles():
    cfg = load_config(ROOT / "configs" / "push_cube.yaml", ["start={LARM_JOINT0: 0.1}"])
    runner = Runner(cfg, "push_cube")
    assert runner.servo.q_cmd[runner.robot.joint_index("LARM_JOINT0")] == pytest.approx(0.1)


@needs_robosuite
def test_aloha_angle_unit_fixed_by_its_robot_file():
    robot = Robot.from_scene("scene", robot="aloha")
    j = robot.joint_index("left/waist")
    assert robot.upper[j] == pytest.approx(3.14158, abs=1e-4)  # read as degrees it would be 0.0548 rad


@needs_robosuite
def test_the_same_base_goes_under_another_robot_and_parks_it():
    cfg = load_config(ROOT / "configs" / "aloha" / "park.yaml")
    runner = Runner(cfg, "configs/aloha/park.yaml")
    assert runner.robot.base is not None and runner.robot.base.type == "diff_drive"
    result = runner.run()
    assert result["success"], result.get("error")
    assert result["object_error_xy_m"] < 0.05 and result["base"]["max_lateral_speed_m_s"] < 0.01


@needs_robosuite
def test_sweep_of_another_robot_is_named_after_it():
    spec = SweepSpec(ROOT / "configs" / "sweeps" / "push_across.yaml", ["robot=yumi"])
    assert spec.name == "yumi-push_across"
    assert SweepSpec(ROOT / "configs" / "sweeps" / "push_cube.yaml").name == "push_cube"


@pytest.mark.parametrize("old, new, message", [
    ("wrist: l_grip}", "wrist: l_nowhere}", "arms[0].wrist: 'l_nowhere' is neither a site nor a body"),
    ("torque_limits: 10.0", "torque_limits: {l_elbow: -3}", "torque_limits: -3 for joint 'l_elbow' is not a limit"),
    ("torque_limits: 10.0", "torque_limits: .nan", "is not a limit"),
    ("joint_groups: {torso: [waist]", "joint_groups: {torso: [waist_x]", "joint_groups.torso: joint 'waist_x'"),
])
def test_robot_file_frames_limits_and_joint_keys_are_one_line(tmp_path, capsys, old, new, message):
    path = two_arms(tmp_path)
    path.write_text(path.read_text().replace(old, new, 1))
    assert main(["info", "--robot", str(path)]) == 2
    err = capsys.readouterr().err
    assert message in err and str(path) in err and err.count("\n") == 1, err


def test_bundled_robot_by_file_name_from_anywhere(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert load_robot("nextage.yaml").name == "nextage"
    (tmp_path / "nextage.yaml").write_text("name: mine\n")  # a file here wins over the bundled one
    with pytest.raises(Exception, match=r"nextage.yaml: .*model"):
        load_robot("nextage.yaml")
