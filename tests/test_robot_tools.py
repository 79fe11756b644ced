"""Robot files from models: URDF import, ``robot check`` (one test per diagnosis), ``robot init``, and one test per
validation branch of a robot file (one line naming the file and the key, exit 2)."""

import importlib.util
import json
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from nextage_qp.cli import main
from nextage_qp.errors import ConfigError
from nextage_qp.robots import urdf
from nextage_qp.robots.arms import left_by_name
from nextage_qp.robots.check_report import check_robot
from nextage_qp.robots.model import Robot
from nextage_qp.robots.modelfile import self_contacts
from nextage_qp.robots.poses import find_home
from nextage_qp.sensing.sensors import WrenchSensor, unsensed

DATA = Path(__file__).parent / "data" / "robots"
TWO_ARMS = DATA / "two_arms.xml"
BROKEN = DATA / "broken.urdf"
HAS_ROBOSUITE = importlib.util.find_spec("robosuite_models") is not None
needs_robosuite = pytest.mark.skipif(not HAS_ROBOSUITE, reason="robosuite_models is not installed")
ALOHA = "package://robosuite_models/assets/robots/aloha/robot.xml"

# A valid robot file for two_arms.xml ({model} is filled in); each validation test changes one thing.
BASE = """name: two_arms
model: {model}
arms:
  - {{name: left, joints: [l_shoulder_pitch, l_shoulder_roll, l_elbow, l_wrist], wrist: l_grip}}
  - {{name: right, joints: [r_shoulder_pitch, r_shoulder_roll, r_elbow, r_wrist], wrist: r_grip}}
joint_groups: {{torso: [waist], head: [head_pan]}}
frames: {{l_tip: {{body: l_hand, pos: [0.1, 0, 0]}}}}
exclude: [[base, l_fore]]
keyframes:
  home: {{l_shoulder_pitch: -0.5, l_shoulder_roll: 0.5, l_elbow: 0.65, r_shoulder_pitch: -0.5, r_shoulder_roll: -0.5,
          r_elbow: -0.65}}
torque_limits: 10.0
"""


def robot_file(tmp_path: Path, old: str = "", new: str = "", model: Path | str = TWO_ARMS, name: str = "r.yaml") -> Path:
    text = BASE.format(model=model)
    assert old in text, old
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1) if old else text)
    return path


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def topics(report) -> dict[str, list[str]]:
    found: dict[str, list[str]] = {}
    for f in report.findings:
        found.setdefault(f.topic, []).append(f"{f.level}: {f.message}")
    return found


# URDF import.


def urdf_copy(tmp_path: Path, drop: tuple[str, ...] = ("no_such_package", "tetra.ply")) -> Path:
    """The fixture URDF and its meshes in tmp_path, the lines naming ``drop`` removed."""
    shutil.copytree(DATA / "meshes", tmp_path / "meshes")
    lines = [ln for ln in BROKEN.read_text().splitlines() if not any(d in ln for d in drop)]
    path = tmp_path / "arm.urdf"
    path.write_text("\n".join(lines))
    return path


def test_urdf_import_keeps_fixed_frames_and_effort_limits(tmp_path):
    path = urdf_copy(tmp_path, drop=("no_such_package", "tetra.ply", "tetra.dae"))
    model = urdf.urdf_spec(path, (), "t").compile()
    assert model.body("tool0").id > 0 and model.body("base_link").id > 0  # fusestatic would merge both
    assert model.nu == 0 and model.njnt == 4
    np.testing.assert_allclose(model.jnt_actfrcrange[:, 1], [40, 40, 20, 10])  # <limit effort> -> actuatorfrcrange
    assert model.jnt_actfrclimited.all()


def test_urdf_package_mesh_found_through_package_paths(tmp_path):
    (tmp_path / "pkgs" / "mypkg" / "meshes").mkdir(parents=True)
    shutil.copy(DATA / "meshes" / "tetra.stl", tmp_path / "pkgs" / "mypkg" / "meshes")
    text = BROKEN.read_text().replace("package://no_such_package/meshes/link1.stl", "package://mypkg/meshes/tetra.stl")
    lines = [ln for ln in text.splitlines() if "tetra.ply" not in ln and "tetra.dae" not in ln]
    (tmp_path / "arm.urdf").write_text("\n".join(lines))
    shutil.copytree(DATA / "meshes", tmp_path / "meshes")
    model = urdf.urdf_spec(tmp_path / "arm.urdf", (tmp_path / "pkgs",), "t").compile()
    assert model.nmesh == 2


def test_urdf_unresolved_package_is_one_line(tmp_path):
    with pytest.raises(ConfigError) as exc:
        urdf.urdf_spec(BROKEN, (), "robot.yaml")
    message = str(exc.value)
    assert "\n" not in message and "robot.yaml" in message and "link1" in message
    assert "package://no_such_package/meshes/link1.stl" in message and "package_paths" in message


def test_dae_refused_without_trimesh(tmp_path, monkeypatch):
    monkeypatch.setattr(urdf, "_trimesh", lambda: None)
    path = urdf_copy(tmp_path)
    with pytest.raises(ConfigError, match=r"tetra\.dae.*COLLADA.*nextage-qp\[mesh\]") as exc:
        urdf.urdf_spec(path, (), "t")
    assert "\n" not in str(exc.value)


def test_dae_and_ascii_stl_converted_with_trimesh(tmp_path, monkeypatch):
    pytest.importorskip("trimesh")
    pytest.importorskip("collada")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    ascii_stl = tmp_path / "a.stl"
    ascii_stl.write_text("solid t\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n"
                         "   vertex 0 1 0\n  endloop\n endfacet\nendsolid t\n")
    assert "ASCII" in urdf.unreadable_reason(ascii_stl)
    assert urdf.unreadable_reason(DATA / "meshes" / "tetra.stl") is None
    for mesh in (DATA / "meshes" / "tetra.dae", ascii_stl):
        out = urdf.convert_mesh(mesh)
        assert out.parent == tmp_path / "cache" / "nextage_qp" / "meshes" and urdf.unreadable_reason(out) is None
    model = urdf.urdf_spec(urdf_copy(tmp_path), (), "t").compile()
    assert model.nmesh == 2


# robot check.


def test_check_broken_urdf_reports_each_problem(capsys, monkeypatch):
    monkeypatch.setattr(urdf, "_trimesh", lambda: None)
    code, out, _ = cli(capsys, "robot", "check", str(BROKEN))
    assert code == 1
    lines = out.splitlines()
    assert any("problem package" in ln and "no_such_package" in ln and "fix:" in ln for ln in lines)
    assert any("problem mesh format" in ln and "tetra.dae" in ln and "nextage-qp[mesh]" in ln for ln in lines)
    assert any("problem mesh format" in ln and "tetra.ply" in ln for ln in lines)
    assert any("fixed frame" in ln and "tool0" in ln for ln in lines)
    assert "3 problems" in out


def test_check_json_and_tables(capsys):
    code, out, _ = cli(capsys, "robot", "check", str(TWO_ARMS), "--json")
    import json

    doc = json.loads(out)
    assert code == 1 and doc["problems"] >= 1  # the bare model: hands touch at qpos0, no torque limits
    assert {a["name"] for a in doc["arms"]} == {"left", "right"} and len(doc["joints"]) == 10
    assert doc["total_mass_kg"] > doc["moving_mass_kg"] > 0


@needs_robosuite
def test_check_aloha_angle_trap(tmp_path, capsys):
    code, out, _ = cli(capsys, "robot", "check", str(Path(importlib.util.find_spec("robosuite_models")
                                                            .submodule_search_locations[0]) / ALOHA.split("/", 3)[3]))
    assert code == 1 and "problem angle" in out and "[-0.055, 0.055] rad" in out
    arms = "\n".join(f"  - {{name: {s}, joints: [{', '.join(f'{s}/{j}' for j in ('waist', 'shoulder', 'elbow', 'forearm_roll', 'wrist_angle', 'wrist_rotate'))}], wrist: {s}/gripper}}" for s in ("left", "right"))
    text = (f"name: aloha\nmodel: {ALOHA}\narms:\n{arms}\n"
            "keyframes:\n  home: {left/wrist_angle: 1.5, right/wrist_angle: 1.5}  # gripper down: within 1 N m\n")
    (tmp_path / "aloha.yaml").write_text(text)
    code, out, _ = cli(capsys, "robot", "check", str(tmp_path / "aloha.yaml"))
    assert code == 1 and "problem angle" in out
    (tmp_path / "aloha.yaml").write_text(text + "angle: radian\n")
    code, out, _ = cli(capsys, "robot", "check", str(tmp_path / "aloha.yaml"))
    assert code == 0 and "no problems" in out, out


@pytest.mark.parametrize("content", ["<mujoco><worldbody><body", "not xml at all", b"\x00\x01"])
def test_check_unreadable_model_exits_2(tmp_path, capsys, content):
    path = tmp_path / "bad.xml"
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    code, out, err = cli(capsys, "robot", "check", str(path))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "bad.xml" in err and not out


def test_check_missing_file_exits_2(tmp_path, capsys):
    code, _, err = cli(capsys, "robot", "check", str(tmp_path / "none.yaml"))
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_check_clean_robot_file(tmp_path):
    report = check_robot(robot_file(tmp_path))
    assert not report.problems, report.findings


def test_check_self_contact_at_home(tmp_path):
    found = topics(check_robot(robot_file(tmp_path, "  home: {l_shoulder_pitch", "  home: {}\n  x: {l_shoulder_pitch")))
    assert "contact" in found and "[l_fore, r_fore]" in found["contact"][0] and "base, r_fore" in found["contact"][0]


def test_check_frames_no_arm_moves(tmp_path):
    path = robot_file(tmp_path, "wrist: l_grip}", "wrist: l_grip, tool: chest}")
    path.write_text(path.read_text().replace("body: l_hand", "body: base"))
    found = topics(check_robot(path))["reach"]
    assert any("arms[0].tool: 'chest'" in f for f in found) and any("frames.l_tip" in f for f in found)


def test_check_names_the_model_lacks(tmp_path):
    found = topics(check_robot(robot_file(tmp_path, "wrist: r_grip", "wrist: r_gripper")))
    assert any("arms[1].wrist: 'r_gripper'" in f for f in found["frame"])


def test_check_left_out_joints_are_info(tmp_path):
    report = check_robot(robot_file(tmp_path, ", head: [head_pan]", ""))
    assert not report.problems and "head_pan" in topics(report)["joints"][0]


def test_check_torque_limits(tmp_path):
    found = topics(check_robot(robot_file(tmp_path, "torque_limits: 10.0", "torque_limits: {waist: 10.0}")))
    assert any("'l_elbow' has no actuator" in f for f in found["torque"])
    found = topics(check_robot(robot_file(tmp_path, "torque_limits: 10.0", "torque_limits: 0.05")))
    assert any("gravity torque" in f and "l_shoulder_pitch" in f for f in found["torque"])


def test_check_names_joints_whose_damping_outruns_their_motors(tmp_path):
    """A joint damped at 100 N m s/rad behind a 10 N m motor moves at 0.1 rad/s at most (less its gravity load): the
    check says so and gives the velocity limit to write; the other joints are not named."""
    model = model_variant(tmp_path, '<joint name="l_elbow"', '<joint name="l_elbow" damping="100"')
    said = [f for f in check_robot(robot_file(tmp_path, model=model)).findings if "damping" in f.message]
    assert len(said) == 1 and said[0].level == "info" and "l_elbow (100 N m s/rad, 10 N m: 0.0" in said[0].message
    assert said[0].fix.startswith("velocity_limits: {l_elbow: 0.0") and "r_elbow" not in said[0].message
    assert not [f for f in topics(check_robot(robot_file(tmp_path))).get("torque", []) if "damping" in f]


def test_check_angle_given_where_the_model_states_it(tmp_path):
    found = topics(check_robot(robot_file(tmp_path, "torque_limits", "angle: radian\ntorque_limits")))
    assert found["angle"][0].startswith("info") and "repeats" in found["angle"][0]
    found = topics(check_robot(robot_file(tmp_path, "torque_limits", "angle: degree\ntorque_limits")))
    assert found["angle"][0].startswith("problem") and "overrides" in found["angle"][0]


def model_variant(tmp_path: Path, old: str, new: str) -> Path:
    text = TWO_ARMS.read_text()
    assert old in text
    path = tmp_path / "variant.xml"
    path.write_text(text.replace(old, new, 1))
    return path


def test_check_actuator_not_a_gear_1_motor(tmp_path):
    model = model_variant(tmp_path, "</worldbody>", "</worldbody><actuator><motor joint='l_elbow' gear='2' "
                          "ctrlrange='-1 1'/><position joint='r_elbow' kp='10'/></actuator>")
    found = topics(check_robot(robot_file(tmp_path, model=model)))["actuator"]
    assert len(found) == 2 and all(f.startswith("problem") for f in found) and "gear 2" in found[0]


def test_check_inertias(tmp_path):
    model = model_variant(tmp_path, '<joint name="l_wrist" axis="1 0 0" range="-2 2"/>',
                          '<joint name="l_wrist" axis="1 0 0" range="-2 2"/><inertial pos="0 0 0" mass="1e-8" '
                          'diaginertia="1e-9 1e-9 1e-9"/>')
    model.write_text(model.read_text().replace('<geom type="box" size="0.03 0.02 0.04" pos="0.03 0 0"/>',
                                               '<geom type="box" size="0.03 0.02 0.04" pos="0.03 0 0" mass="0"/>', 1))
    model.write_text(model.read_text().replace('<geom type="sphere" size="0.06"/>',
                                               '<geom type="sphere" size="0.06"/><inertial pos="0 0 0" mass="1" '
                                               'diaginertia="0.01 0.01 0.05"/>'))
    found = topics(check_robot(robot_file(tmp_path, model=model)))["inertia"]
    assert any("l_hand" in f and "mass 1e-08" in f for f in found)
    assert any("'head'" in f and "triangle" in f for f in found)
    assert any("MuJoCo refuses" in f for f in found)


def test_check_fused_mjcf_bodies(tmp_path):
    model = model_variant(tmp_path, 'autolimits="true"', 'autolimits="true" fusestatic="true"')
    model.write_text(model.read_text().replace('<site name="l_grip"', '<body name="l_tool"/><site name="l_grip"'))
    found = topics(check_robot(robot_file(tmp_path, model=model)))
    assert any("l_tool" in f for f in found["fused frame"])


# robot init.


def test_init_two_arms(tmp_path, capsys):
    out = tmp_path / "two.yaml"
    code, text, _ = cli(capsys, "robot", "init", str(TWO_ARMS), "--out", str(out))
    assert code == 0 and "robot check finds no problems" in text
    robot = Robot.from_scene("scene", robot=out)
    left, right = robot.arms
    assert (left.name, right.name) == ("left", "right") and left.joints[0] == "l_shoulder_pitch"
    assert (left.wrist, right.wrist) == ("l_grip", "r_grip")
    assert robot.description.joint_groups["torso"] == ("waist",) and "head_pan" in robot.description.joints
    m = mujoco.MjModel.from_xml_path(str(TWO_ARMS))
    qpos = m.qpos0.copy()
    for name, value in robot.q_to_names(robot.keyframe_q("home")).items():
        qpos[m.joint(name).qposadr[0]] = value
    assert not self_contacts(m, mujoco.MjData(m), qpos)  # the hands touch at qpos0; home is free
    assert self_contacts(m, mujoco.MjData(m), m.qpos0)
    assert "mount:" not in out.read_text() and "torque_limits:" in out.read_text()
    pads = [arm.pad for arm in robot.arms]  # the tools' faces clamp, with the force/torque sensors the file adds
    assert pads == ["left_pad", "right_pad"] and not unsensed(robot, pads)
    assert cli(capsys, "robot", "check", str(out))[0] == 0
    # it runs: a reach from home (motors added in model order) and a step with the rule's gains
    d = mujoco.MjData(robot.model)
    robot.set_q(d, robot.keyframe_q("home"))
    mujoco.mj_kinematics(robot.model, d)
    target = d.site("l_grip").xpos + np.array([0.03, 0.0, 0.03])
    assert cli(capsys, "reach", "--robot", str(out), "--frame", "l_grip", "--duration", "2",
               "--pos", *map(str, target))[0] == 0
    assert cli(capsys, "step-response", "--robot", str(out), "--joint", "l_elbow", "--target-deg", "45",
               "--duration", "0.5")[0] == 0


def test_a_floating_robot_with_its_motors_in_another_order_stands_fixed_and_reaches(tmp_path, capsys):
    """A humanoid's model: a free joint at its root (fixed at the mount: it would fall) and motors listed in an order
    of their own (the G1's legs, torso, right arm, left arm), driven each by its own joint's control."""
    joints = ["waist", "head_pan", "l_shoulder_pitch", "l_shoulder_roll", "l_elbow", "l_wrist", "r_shoulder_pitch",
              "r_shoulder_roll", "r_elbow", "r_wrist"]
    motors = "".join(f"<motor joint='{j}' ctrlrange='-50 50'/>" for j in reversed(joints))
    model = model_variant(tmp_path, '<body name="base">', '<body name="base"><freejoint/>')
    model.write_text(model.read_text().replace("</worldbody>", f"</worldbody><actuator>{motors}</actuator>"))
    out = tmp_path / "float.yaml"
    assert cli(capsys, "robot", "init", str(model), "--out", str(out))[0] == 0
    robot = Robot.from_scene("scene", robot=out)
    assert robot.actuator_ids.tolist() != sorted(robot.actuator_ids.tolist())  # not in joint order
    m = robot.model
    assert not (m.jnt_type == mujoco.mjtJoint.mjJNT_FREE).any()  # fixed at its mount
    base, chest = m.body("base").id, m.body("chest").id  # welded to the world now, its child still does not collide
    assert ((base << 16) + chest) in m.exclude_signature.tolist() or ((chest << 16) + base) in m.exclude_signature
    d = mujoco.MjData(robot.model)
    robot.set_q(d, robot.keyframe_q("home"))
    mujoco.mj_kinematics(robot.model, d)
    target = d.site("l_grip").xpos + np.array([0.03, 0.0, 0.03])
    code, text, _ = cli(capsys, "reach", "--robot", str(out), "--frame", "l_grip", "--duration", "2",
                        "--pos", *map(str, target), "--json")
    assert code == 0 and json.loads(text)["reached"]


def test_wrench_sensors_give_a_site_a_force_and_a_torque_sensor(tmp_path):
    """A model without force/torque sensors: the robot file adds them at a frame; a name that is no site is one
    line naming the sites there are."""
    path = robot_file(tmp_path, "torque_limits: 10.0", "torque_limits: 10.0\nwrench_sensors: [l_tip]")
    robot = Robot.from_scene("scene", robot=path)
    assert [robot.model.body(s.body).name for s in WrenchSensor.of_model(robot.model)] == ["l_hand"]
    assert not unsensed(robot, ["l_tip"]) and unsensed(robot, ["r_grip"])
    bad = robot_file(tmp_path, "torque_limits: 10.0", "torque_limits: 10.0\nwrench_sensors: [l_nope]", name="b.yaml")
    with pytest.raises(ConfigError, match=r"wrench_sensors\[0\]: 'l_nope' is not a site of the model or a frame of "
                                          r"the file; sites: .*l_tip"):
        Robot.from_scene("scene", robot=bad)


def test_a_model_with_an_unnamed_texture_composes(tmp_path):
    """A skybox without a name in the robot's model, as the scene has one: neither is renamed, no geom loses its mesh."""
    sky = '<asset><texture type="skybox" builtin="flat" rgb1="1 1 1" width="8" height="8"/></asset><worldbody>'
    model = model_variant(tmp_path, "<worldbody>", sky)
    robot = Robot.from_scene("scene", robot=robot_file(tmp_path, model=model))
    assert robot.model.ntex == 3  # the scene's skybox and ground, the robot's skybox


def test_init_raises_motor_limits_that_cannot_hold_the_arm_up(tmp_path, capsys):
    """Motors weaker than the arm's gravity torque: the draft takes the joint's actuator-force range where the model
    gives one, else the default rule, and says so; motors strong enough keep the model's limits."""
    joints = ["waist", "head_pan", "l_shoulder_pitch", "l_shoulder_roll", "l_elbow", "l_wrist", "r_shoulder_pitch",
              "r_shoulder_roll", "r_elbow", "r_wrist"]
    weak = {"l_shoulder_pitch", "r_shoulder_pitch"}
    motors = "".join(f"<motor joint='{j}' ctrlrange='{'-0.01 0.01' if j in weak else '-50 50'}'/>" for j in joints)
    model = model_variant(tmp_path, "</worldbody>", f"</worldbody><actuator>{motors}</actuator>")
    text = model.read_text()
    at = text.index('name="l_shoulder_pitch"')
    model.write_text(text[:at] + 'actuatorfrcrange="-33 33" ' + text[at:])
    out = tmp_path / "weak.yaml"
    assert cli(capsys, "robot", "init", str(model), "--out", str(out))[0] == 0
    assert "cannot hold the arm up" in out.read_text()
    robot = Robot.from_scene("scene", robot=out)
    limit = dict(zip(robot.joint_names, robot.torque_limit, strict=True))
    assert limit["l_shoulder_pitch"] == 33.0  # the joint's own range
    assert limit["r_shoulder_pitch"] >= 5.0  # the default rule: 3 x its gravity torque, at least 5 N m
    assert limit["l_elbow"] == 50.0  # strong enough: the model's
    assert "gravity torque" not in "".join(topics(check_robot(out)).get("torque", []))


def test_init_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "two.yaml"
    out.write_text("keep me\n")
    code, _, err = cli(capsys, "robot", "init", str(TWO_ARMS), "--out", str(out))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--force" in err and out.read_text() == "keep me\n"
    assert cli(capsys, "robot", "init", str(TWO_ARMS), "--out", str(out), "--force")[0] == 0


def test_init_unwritable_path(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    code, _, err = cli(capsys, "robot", "init", str(TWO_ARMS), "--out", str(tmp_path / "file" / "r.yaml"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "cannot write" in err


def test_init_out_folder_or_yaml_only(tmp_path, capsys):
    """--out a folder: NAME.yaml in it; a path that is not .yaml: one line, nothing written."""
    (tmp_path / "d").mkdir()
    assert cli(capsys, "robot", "init", str(TWO_ARMS), "--out", str(tmp_path / "d"))[0] == 0
    assert [p.suffix for p in (tmp_path / "d").iterdir()] == [".yaml"]
    code, _, err = cli(capsys, "robot", "init", str(TWO_ARMS), "--out", str(tmp_path / "r.txt"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and ".yaml" in err and not (tmp_path / "r.txt").exists()


def test_init_model_keyframe_and_urdf(tmp_path, capsys):
    model = model_variant(tmp_path, "</worldbody>", '</worldbody><keyframe><key name="home" qpos="0 0 -0.5 0.5 0.65 '
                          '0 -0.5 -0.5 -0.65 0"/></keyframe>')
    assert cli(capsys, "robot", "init", str(model), "--out", str(tmp_path / "k.yaml"))[0] == 0
    assert "home: model" in (tmp_path / "k.yaml").read_text()
    path = urdf_copy(tmp_path / "u", drop=("no_such_package", "tetra.ply", "tetra.dae"))
    assert cli(capsys, "robot", "init", str(path), "--out", str(tmp_path / "u.yaml"))[0] == 0
    robot = Robot.from_scene("scene", robot=tmp_path / "u.yaml")
    assert robot.arms[0].name == "arm" and robot.arms[0].wrist == "tool0"
    np.testing.assert_allclose(robot.torque_limit, [40, 40, 20, 10])  # from the URDF's efforts


def test_init_unreadable_model_exits_2(tmp_path, capsys):
    code, _, err = cli(capsys, "robot", "init", str(BROKEN), "--out", str(tmp_path / "b.yaml"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "no_such_package" in err
    code, _, err = cli(capsys, "robot", "init", str(tmp_path / "m.obj"))
    assert code == 2 and ".urdf" in err


@needs_robosuite
def test_init_aloha_writes_angle_and_pairs_arms(tmp_path, capsys):
    root = Path(importlib.util.find_spec("robosuite_models").submodule_search_locations[0])
    out = tmp_path / "aloha.yaml"
    assert cli(capsys, "robot", "init", str(root / "assets/robots/aloha/robot.xml"), "--out", str(out))[0] == 0
    text = out.read_text()
    assert "angle: radian" in text and ALOHA in text
    robot = Robot.from_scene("scene", robot=out)
    assert [a.name for a in robot.arms] == ["left", "right"] and robot.arms[0].joints[0] == "left/waist"
    assert robot.upper[0] == pytest.approx(3.14158)


@needs_robosuite
@pytest.mark.parametrize(("name", "target"), [("g1", (0.3, 0.2, 0.95)), ("h1", (0.4, 0.25, 1.1)),
                                              ("pr2", (0.55, 0.3, 0.85))])
def test_init_humanoids_and_the_pr2_find_arms_not_legs_and_reach(tmp_path, capsys, name, target):
    """The G1 and H1 float at the pelvis, list their motors legs first and have four chains of joints: the two that
    end at the feet are legs; the PR2's qpos0 stretches its arms straight at their elbow limits."""
    root = Path(importlib.util.find_spec("robosuite_models").submodule_search_locations[0])
    out = tmp_path / f"{name}.yaml"
    assert cli(capsys, "robot", "init", str(root / f"assets/robots/{name}/robot.xml"), "--out", str(out))[0] == 0
    robot = Robot.from_scene("scene", robot=out)
    assert [a.name for a in robot.arms] == ["left", "right"]
    legs = robot.description.joint_groups.get("legs", ())
    assert (len(legs) >= 10) == (name != "pr2") and not any("leg" in j for a in robot.arms for j in a.joints)
    code, text, _ = cli(capsys, "reach", "--robot", str(out), "--pos", *map(str, target), "--json")
    assert code == 0 and json.loads(text)["reached"]


def test_arm_pairing_by_name_and_home_search_deterministic():
    assert left_by_name(["LARM_JOINT0"], ["RARM_JOINT0"]) == 0
    assert left_by_name(["yumi_joint_1_r"], ["yumi_joint_1_l"]) == 1
    assert left_by_name(["left/waist"], ["right/waist"]) == 0
    assert left_by_name(["a1"], ["b1"]) is None
    m = mujoco.MjModel.from_xml_path(str(TWO_ARMS))
    joints = list(range(m.njnt))
    a, b = find_home(m, joints), find_home(m, joints)
    assert not a.contacts and np.array_equal(a.qpos, b.qpos)


def test_a_drafted_home_keeps_its_joints_off_their_limits():
    """An elbow whose qpos0 is its limit (a straight arm, singular) is bent 10 % of its range into it."""
    m = mujoco.MjModel.from_xml_string("""<mujoco><compiler angle="radian"/><worldbody><body name="upper"><joint name="shoulder" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/><body name="fore" pos="0.3 0 0">
      <joint name="elbow" range="-2 0"/><geom type="capsule" fromto="0.02 0 0 0.3 0 0" size="0.02"/></body></body>
      </worldbody></mujoco>""")
    home = find_home(m, [0, 1])
    assert home.qpos[1] == pytest.approx(-0.2) and home.qpos[0] == 0.0  # the shoulder was inside already
    assert "off their limits" in home.how


# Robot-file validation: every branch is one line naming the file and the key, exit 2.

VALIDATION = {
    "unknown key": ("torque_limits: 10.0", "torque_limits: 10.0\ncolour: red", "colour: unknown key"),
    "missing home": ("  home: {", "  rest: {", "keyframes needs 'home'"),
    "joint twice": ("head: [head_pan]", "head: [head_pan, l_elbow]", "'l_elbow' is listed twice"),
    "unknown joint": ("head: [head_pan]", "head: [head_tilt]", "joint 'head_tilt' is not in the model"),
    "unknown frame body": ("body: l_hand", "body: l_palm", "frames.l_tip.body: 'l_palm'"),
    "unknown exclude body": ("[[base, l_fore]]", "[[base, l_forearm]]", "exclude[0]: 'l_forearm'"),
    "missing torque limit": ("torque_limits: 10.0", "torque_limits: {waist: 5.0}", "has no actuator and no torque "
                             "limit; give torque_limits"),
    "NaN": ("torque_limits: 10.0", "torque_limits: .nan", "torque_limits"),
    "bad number": ("pos: [0.1, 0, 0]", "pos: [0.1, 0, abc]", "frames.l_tip.pos"),
    "missing model": ("two_arms.xml", "nope.xml", "model: '"),
    "wrong model suffix": ("two_arms.xml", "meshes/tetra.stl", "must be an MJCF (.xml) or URDF (.urdf)"),
}


@pytest.mark.parametrize("case", list(VALIDATION))
def test_robot_file_validation(tmp_path, capsys, case):
    old, new, expected = VALIDATION[case]
    path = robot_file(tmp_path, old, new, name="robot.yaml")
    code, _, err = cli(capsys, "info", "--robot", str(path))
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert str(path) in err and expected in err, err


def test_robot_file_unresolved_package(tmp_path, capsys):
    path = robot_file(tmp_path, model="package://no_such_package/two_arms.xml")
    code, _, err = cli(capsys, "info", "--robot", str(path))
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert str(path) in err and "model: 'package://no_such_package/two_arms.xml'" in err and "package_paths" in err


@pytest.mark.parametrize("command", [["robot"], ["robot", "init"], ["robot", "check"]])
def test_robot_help_is_plain_text(command, capsys):
    assert main([*command, "--help"]) == 0
    out = capsys.readouterr().out
    assert "``" not in out and ":mod:" not in out and ":func:" not in out, out
