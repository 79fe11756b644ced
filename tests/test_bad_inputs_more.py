"""More bad inputs, each with the exit code and the words its one-line message must hold.

Cases are ``(id, argv, files, code, expected)``: ``{tmp}`` in argv is the case's temporary folder, ``{root}`` the
project's, and ``files`` maps a file name in the temporary folder to its content. Every case is refused before
anything moves.
"""

import json
import re
from pathlib import Path

import pytest

from nextage_qp.cli import main

ROOT = Path(__file__).resolve().parents[1]
PUSH = str(ROOT / "configs" / "push_cube.yaml")
PICK = str(ROOT / "configs" / "pick_place_box.yaml")
STACK = str(ROOT / "configs" / "stack_boxes.yaml")
SWEEP = str(ROOT / "configs" / "sweeps" / "push_cube.yaml")
STUDY = str(ROOT / "configs" / "studies" / "pd_gains.yaml")

NEXTAGE = ((ROOT / "robots" / "nextage.yaml").read_text()
           .replace("model: nextage/", f"model: {ROOT}/robots/nextage/")
           .replace("../configs/gains", f"{ROOT}/configs/gains"))


def robot(old: str, new: str) -> dict[str, str]:
    """The Nextage's robot file with one exact piece of text replaced, as the case's file r.yaml."""
    assert old in NEXTAGE, old
    return {"r.yaml": NEXTAGE.replace(old, new, 1)}


CASES: list[tuple[str, list[str], dict[str, str], int, str]] = [
    ("object thinner than 1 mm", ["run", PUSH, "--set", "scene.objects.cube.size=[1e-9,0.03,0.03]"], {}, 2,
     "scene.objects.cube.size[0]: Input should be greater than or equal to 0.001"),
    ("run --plot into /proc", ["run", PUSH, "--json", "--plot", "/proc/x.png"], {}, 2,
     "--plot: '/proc/x.png': folder /proc is not writable"),
    ("run --log under a missing folder of /proc", ["run", PUSH, "--log", "/proc/x/y.npz"], {}, 2,
     "folder /proc is not writable"),
    ("run --log summary onto the config", ["run", "{tmp}/c.json", "--log", "{tmp}/c.npz"],
     {"c.json": open(PUSH).read()}, 2, "--log summary {tmp}/c.json: that is the config, which this would overwrite"),
    ("sweep --only beyond the episode cap", ["sweep", SWEEP, "--only", "3,1000000"], {}, 2,
     "--only '3,1000000': expected episode indices from 0 to 999999"),
    ("tune --out a sweep's folder", ["tune", STUDY, "--out", "{tmp}/o"], {"o/sweep.json": "{}"}, 2,
     "--out {tmp}/o: holds a sweep's records (sweep.json, episodes.jsonl)"),
    ("tune --out another study's folder", ["tune", STUDY, "--out", "{tmp}/o"],
     {"o/summary.json": '{"study": "other"}'}, 2, "--out {tmp}/o: holds study 'other''s outputs"),
    ("run --plot name over the file system's limit", ["run", PUSH, "--plot", "{tmp}/" + "a" * 300 + ".png"], {}, 2,
     "File name too long (at most "),
    ("YAML true for a number", ["run", PUSH, "--set", "phases.0.attempts=true"], {}, 2,
     "phases[0]: attempts: expected a number, got a boolean"),
    ("YAML false in a list of numbers", ["run", PUSH, "--set", "scene.poses.cube.pos=[0.3,false,0.91]"], {}, 2,
     "scene.poses.cube: pos[1]: expected a number, got a boolean"),
    ("YAML true for a mass in scene.masses", ["run", PUSH, "--set", "scene.masses.cube=true"], {}, 2,
     "scene: masses.cube: expected a number, got a boolean"),
    ("YAML true in a robot file's number", ["run", PUSH, "--robot", "{tmp}/r.yaml"],
     robot("gains_dir:", "torque_limits: {LARM_JOINT0: true}\ngains_dir:"), 2,
     "torque_limits.LARM_JOINT0: expected a number, got a boolean"),
    ("collision pair of a group with itself", ["run", PUSH, "--set", "ik.collision_pairs.0.b=left_hand"], {}, 2,
     "ik.collision_pairs[0]: 'left_hand' with itself keeps nothing apart: no two of its geoms on different bodies"),
    ("two phases of one name", ["run", str(ROOT / "configs" / "dock_dumbbell.yaml"), "--set", "phases.1.name=clamp"],
     {}, 2, "phases[1].name: 'clamp' is also phases[0]'s name"),
    ("scene.masses of 1e300 kg", ["run", PUSH, "--set", "scene.masses.cube=1e300"], {}, 2,
     "scene.masses.cube: Input should be less than or equal to 50"),
    ("scene.friction_scale of 1e6", ["run", PUSH, "--set", "scene.friction_scale.cube=1e6"], {}, 2,
     "scene.friction_scale.cube: Input should be less than or equal to 20"),
    ("sweep --plot into /proc", ["sweep", SWEEP, "--n", "1", "--plot", "/proc/x.png"], {}, 2,
     "--plot: '/proc/x.png': folder /proc is not writable"),
    ("perception.dump into /proc", ["run", PUSH, "--set", "perception.source=camera", "--set",
                                    "perception.dump=/proc/x"], {}, 2,
     "perception.dump: '/proc/x': folder /proc is not writable"),
    ("perception.dump under a file", ["run", PUSH, "--set", "perception.source=camera", "--set",
                                      "perception.dump={root}/pyproject.toml/x"], {}, 2,
     "pyproject.toml is a file, not a folder"),
    ("perception.dump without a camera", ["run", PUSH, "--set", "perception.dump={tmp}/frame"], {}, 2,
     "perception.dump: '{tmp}/frame' writes a frame of the robot's camera, but the poses come from truth"),
    # a value that fits no member of a union: the member meant, without pydantic's names of the members
    ("start joint nan", ["run", PUSH, "--set", "start={LARM_JOINT1: .nan}"], {}, 2,
     "push_cube.yaml: start.LARM_JOINT1: Input should be a finite number (got nan)"),
    ("start a number", ["run", PUSH, "--set", "start=7"], {}, 2,
     "start: Input should be a valid string; or Input should be a valid dictionary (got 7)"),
    ("posture target unknown", ["run", PUSH, "--set", "ik.posture_target=nope"], {}, 2,
     "ik.posture_target: Input should be 'home' or 'zero'; or Input should be a valid dictionary (got 'nope')"),
    ("object pos nan", ["run", PUSH, "--set", "scene.objects.puck={shape: sphere, size: [0.02], pos: [.nan, 0]}"],
     {}, 2, "scene.objects.puck.pos[0]: Input should be a finite number (got nan)"),
    ("sweep bound inf", ["sweep", "{tmp}/s.yaml", "--n", "1"],
     {"s.yaml": f"base: {PUSH}\nrandomize: {{scene.masses.cube: {{uniform: [0.05, .inf]}}}}\n"}, 2,
     "randomize.scene.masses.cube.uniform[1]: Input should be a finite number; or Input should be a valid list"),
    # joint angles outside the robot's joints or their ranges: refused before anything moves, not a failed task
    ("start angle out of range", ["run", PUSH, "--set", "start={LARM_JOINT1: 9}"], {}, 2,
     "push_cube.yaml: start.LARM_JOINT1: 9 is outside the joint's range [-2.443, 1.047] rad"),
    ("start joint unknown", ["run", PUSH, "--set", "start={NOPE: 0.1}"], {}, 2,
     "push_cube.yaml: start: unknown joint 'NOPE'; valid: CHEST_JOINT0, "),
    ("joints phase angle out of range", ["run", PUSH, "--set", "phases[0]={kind: joints, positions: {LARM_JOINT1: 9}}"],
     {}, 2, "phases[0].positions.LARM_JOINT1: 9 is outside the joint's range"),
    ("posture target out of range", ["run", PUSH, "--set", "ik.posture_target={LARM_JOINT1: -5}"], {}, 2,
     "ik.posture_target.LARM_JOINT1: -5 is outside the joint's range"),
    # phases that cannot do what they say: refused before anything moves
    ("move offset huge", ["run", PUSH, "--set", "phases[0]={kind: move, targets: [{frame: left_tool, offset: [1e9, 0, 0]}]}"],
     {}, 2, "phases[0].targets[0].offset[0]: Input should be less than or equal to 10 (got 1000000000.0)"),
    ("move speed huge", ["run", PUSH, "--set", "phases[0]={kind: move, targets: [{frame: left_tool}], speed: 1e12}"], {},
     2, "phases[0].speed: Input should be less than or equal to 1"),
    ("move yaw huge", ["run", PUSH, "--set", "phases[0]={kind: move, targets: [{frame: left_tool, yaw: 1e9}]}"], {}, 2,
     "phases[0].targets[0].yaw: Input should be less than or equal to 7"),
    ("wait timeout under its duration", ["run", PUSH, "--set", "phases[0]={kind: wait, duration: 3, timeout: 2}"], {}, 2,
     "phases[0]: timeout (2 s) must exceed duration (3 s)"),
    ("run --log whose summary is a folder", ["run", PUSH, "--log", "{tmp}/d.npz"], {"d.json/x": ""}, 2,
     "its summary {tmp}/d.json is a directory; give --log another name"),
    ("run --robot unknown", ["run", PUSH, "--robot", "nope"], {}, 2,
     "push_cube.yaml: robot: robot 'nope' not found; bundled robots: aloha, "),
    ("object named after the world", ["run", PUSH, "--set", "scene.objects.world={shape: box, size: [0.03, 0.03, 0.03], "
                                                            "pos: [0.5, 0.3]}"], {}, 2,
     "scene.objects.world: 'world' is taken in the scene push_cube (Error: repeated name 'world' in body); choose "),
    ("object named after a robot link", ["run", PUSH, "--set", "scene.objects.LARM_JOINT0_Link={shape: box, size: "
                                                               "[0.03, 0.03, 0.03], pos: [0.5, 0.3]}"], {}, 2,
     "scene.objects.LARM_JOINT0_Link: 'LARM_JOINT0_Link' is taken in the scene push_cube"),
    ("sweep given a task config", ["sweep", PUSH, "--n", "1"], {}, 2,
     "push_cube.yaml: this is a task config (it has phases), not a sweep file: give a sweep file"),
    ("robot check given a task config", ["robot", "check", PUSH], {}, 2,
     "push_cube.yaml: this is a task config (it has phases), not a robot file"),
    ("robot check given a sweep file", ["robot", "check", SWEEP], {}, 2,
     "push_cube.yaml: this is a sweep file (it has randomize), not a robot file"),
    ("trajectory velocity too small for Ruckig", ["run", PUSH, "--set", "trajectory.max_velocity=1e-6"], {}, 2,
     "trajectory.max_velocity: every limit must be finite and >= 0.01, got 1e-06"),
    ("reach max-velocity too small", ["reach", "--pos", "0.3", "0.1", "1.0", "--max-velocity", "1e-7"], {}, 2,
     "argument --max-velocity: expected a finite number in [0.01, 100], got '1e-7'"),
    ("step-response shorter than a tick", ["step-response", "--joint", "LARM_JOINT0", "--target-deg", "10",
                                           "--duration", "0.0005"], {}, 2,
     "argument --duration: expected a finite number in [0.01, 3600], got '0.0005'"),
    ("place without a grasp", ["run", PUSH, "--set", "phases=[{kind: place, object: cube, target: cube_target}]"], {},
     2, "push_cube.yaml: phases[0]: place needs 'cube' clamped by an earlier grasp phase"),
    ("release after the clamp let go", ["run", PICK, "--set", "phases[1]={kind: release, object: box}"], {}, 2,
     "pick_place_box.yaml: phases[2]: release needs 'box' clamped by an earlier grasp phase"),
    ("ik one frame twice", ["ik", "--frame", "left_tool", "--pos", "0.3", "0", "1", "--frame2", "left_tool", "--pos2",
                            "0.3", "0.1", "1"], {}, 2, "--frame2 'left_tool' is --frame itself; give two different"),
    ("fk one joint twice", ["fk", "left_tool", "--q", "LARM_JOINT0=0.1", "--q", "LARM_JOINT0=0.2"], {}, 2,
     "--q 'LARM_JOINT0=0.2': LARM_JOINT0 is given twice; give each joint once"),
    ("robot file keyframe with an unknown joint", ["run", PUSH, "--robot", "{tmp}/r.yaml"],
     robot("  home: model", "  home: {FOO: 0.1}"), 2, "{tmp}/r.yaml: keyframes.home: unknown joint 'FOO'; valid: "),
    ("frame unknown, the arm's tool a body", ["run", PUSH, "--robot", "{tmp}/r.yaml", "--set", "phases.0.frame=nope"],
     robot("    tool: right_tool", "    tool: RARM_JOINT5_Link"), 2,
     "phases[0].frame: 'nope' is not valid; valid: left_wrist, left_tool, left_pad, left_palm, right_wrist, right_tool, "
     "right_pad, right_palm, RARM_JOINT5_Link"),
    ("robot model a folder", ["robot", "check", "{tmp}/r.yaml"],
     robot("nextage/nextage.xml", "nextage"), 2, "model: '" + str(ROOT) + "/robots/nextage' is a folder; name the "
                                                  "model file in it (nextage.xml)"),
    ("robot file collision group with an unknown body", ["run", PUSH, "--robot", "{tmp}/r.yaml"],
     robot("head: {bodies: [HEAD_JOINT0_Link, HEAD_JOINT1_Link]}", "head: {bodies: [HEAD_JOINT0_Link, HEAD_LINK]}"), 2,
     "{tmp}/r.yaml: collision_groups: unknown body (collision group 'head') 'HEAD_LINK'; valid: "),
    ("move target beyond the arm's reach", ["run", PUSH, "--set", "phases=[{kind: move, targets: [{frame: left_tool, "
                                                              "relative_to: world, offset: [5, 0, 1]}]}]"], {}, 2,
     "phase 'move[0]' (move): left_tool: out of reach: 5.001 m from CHEST_JOINT0 at (0.000, 0.000, 1.117), and "
     "left_tool reaches at most 1.061 m from there"),
    ("move one frame twice", ["run", PUSH, "--set", "phases[0]={kind: move, targets: [{frame: left_tool}, "
                                                    "{frame: left_tool, offset: [0, 0, 0.2]}]}"], {}, 2,
     "phases[0]: targets: two targets for frame 'left_tool'"),
    ("move zero axis", ["run", PUSH, "--set", "phases[0]={kind: move, targets: [{frame: left_tool, axis: [0, 0, 0], "
                                              "direction: [0, 0, -1]}]}"], {}, 2,
     "phases[0].targets[0]: axis must be a non-zero vector"),
    ("push to the object itself", ["run", PUSH, "--set", "phases[0].target=cube"], {}, 2,
     "phases[0]: target: 'cube' is the phase's object itself"),
    ("place on the object itself", ["run", STACK, "--set", "phases[1].target=box_b"], {}, 2,
     "phases[1]: target: 'box_b' is the phase's object itself"),
    ("grasp placing at the object itself", ["run", PICK, "--set", "phases[0].place_at=box"], {}, 2,
     "phases[0]: place_at: 'box' is the phase's object itself"),
    ("grasp with one pad twice", ["run", PICK, "--set", "phases[0].frames=[left_palm, left_palm]"], {}, 2,
     "phases[0]: frames: 'left_palm' twice"),
    ("config target is the object", ["run", PUSH, "--set", "target=cube"], {}, 2,
     "push_cube.yaml: target: 'cube' is the object itself"),
    ("object start off the table", ["run", PUSH, "--set", "scene.poses.cube.pos=[30, 0, 0.91]"], {}, 2,
     "scene.poses.cube: cube starts at (30.000, 0.000), not over the table"),
    ("object colour above 1", ["run", PUSH, "--set", "scene.objects.cube={shape: box, size: [0.03, 0.03, 0.03], "
                                                     "rgba: [2, 0, 0, 1]}"], {}, 2,
     "scene.objects.cube.rgba[0]: Input should be less than or equal to 1 (got 2)"),
    ("part colour negative", ["run", PUSH, "--set", "scene.objects.cube={shape: compound, parts: [{shape: sphere, "
                                                    "size: [0.03], rgba: [0.5, -1, 0, 1]}]}"], {}, 2,
     "scene.objects.cube.parts[0].rgba[1]: Input should be greater than or equal to 0 (got -1)"),
    ("robot gains rule nan", ["robot", "check", "{tmp}/r.yaml"],
     robot("gains: " + f"{ROOT}/configs/gains/default.yaml", "gains: {bandwidth: .nan}"), 2,
     "r.yaml: gains.bandwidth: Input should be a finite number (got nan)"),
    ("robot home nan", ["robot", "check", "{tmp}/r.yaml"], robot("  home: model", "  home: {LARM_JOINT1: .nan}"), 2,
     "r.yaml: keyframes.home.LARM_JOINT1: Input should be a finite number (got nan)"),
    ("robot home outside a joint's range", ["run", PUSH, "--set", "robot={tmp}/r.yaml"],
     robot("  home: model", "  home: {LARM_JOINT1: 100}"), 2,
     "keyframes.home: joint LARM_JOINT1 at 100 rad is outside its range [-2.443, 1.047]"),
    ("ik target out of reach", ["ik", "--frame", "left_tool", "--pos", "5", "5", "5"], {}, 2,
     "--pos for left_tool: out of reach: 8.067 m from CHEST_JOINT0 at (0.000, 0.000, 1.117)"),
    ("ik frame no joint moves", ["ik", "--frame", "table", "--pos", "0.4", "0.2", "1.0", "--scene", "push_cube"], {}, 2,
     "--pos for table: table is moved by no joint of the robot"),
    ("reach target out of reach", ["reach", "--pos", "3", "3", "3"], {}, 2,
     "--pos for left_wrist: out of reach: 4.642 m from CHEST_JOINT0"),
    ("push target out of every hand's reach", ["run", PUSH, "--set", "scene.poses.cube_target.pos=[1.45,1.0,0.91]"],
     {}, 2, "target: cube at the target (1.450, 1.000) is out of every hand's reach (left_tool, the nearest, reaches "
     "at most 1.061 m from CHEST_JOINT0; the target is 0.712 m beyond)"),
    ("object under the table", ["run", PUSH, "--set", "scene.poses.cube.pos=[0.33,0,0.5]"], {}, 2,
     "scene.poses.cube: cube starts at height 0.500 m, below the table top at 0.875 m"),
    ("robot frame named as a model site", ["info", "--robot", "{tmp}/r.yaml"],
     robot("gains_dir:", "frames: {left_tool: {body: LARM_JOINT5_Link}}\ngains_dir:"), 2,
     "r.yaml: frames.left_tool: the model has a site 'left_tool' already"),
    ("robot frame with a zero quat", ["robot", "check", "{tmp}/r.yaml"],
     robot("gains_dir:", "frames: {extra: {body: LARM_JOINT5_Link, quat: [0, 0, 0, 0]}}\ngains_dir:"), 2,
     "r.yaml: frames.extra: quat must be a non-zero quaternion"),
    # where an object goes: a scene body, never one of the robot's links (nor listed among the valid ones)
    ("target a robot link", ["run", PUSH, "--set", "target=WAIST"], {}, 2,
     "push_cube.yaml: target: 'WAIST' is not valid; valid: table, cube, cube_target"),
    ("push handover to an unknown frame", ["run", PUSH, "--set", "phases.0.other_frames=[nose]"], {}, 2,
     "phases[0].other_frames[0]: 'nose' is not valid; valid: left_wrist, left_tool,"),
    ("place_at a robot link", ["run", PICK, "--set", "phases[0].place_at=LARM_JOINT5_Link"], {}, 2,
     "phases[0].place_at: 'LARM_JOINT5_Link' is not valid; valid: table, obstacle, box, box_target"),
    # a sweep's base config that is itself wrong is named as the base, a key of its set: as set
    ("sweep base with an unknown key", ["sweep", "{tmp}/s.yaml", "--n", "1"],
     {"s.yaml": "base: b.yaml\nrandomize: {scene.masses.cube: {uniform: [0.05, 0.3]}}\n",
      "b.yaml": Path(PUSH).read_text().replace("  ctrl_dt:", "  ctrl_dtt:").replace("../", f"{ROOT}/")}, 2,
     "s.yaml: base: {tmp}/b.yaml: timing.ctrl_dtt: unknown key; valid: ctrl_dt, settle, sim_dt"),
    ("sweep set with an unknown key", ["sweep", "{tmp}/s.yaml", "--n", "1"],
     {"s.yaml": f"base: {PUSH}\nset: {{timing.ctrl_dtt: 0.01}}\n"
                "randomize: {scene.masses.cube: {uniform: [0.05, 0.3]}}\n"}, 2,
     "s.yaml: set: " + PUSH + ": timing.ctrl_dtt: unknown key"),
    ("sweep bounds of two lengths", ["sweep", "{tmp}/s.yaml", "--n", "1"],
     {"s.yaml": f"base: {PUSH}\nrandomize: {{scene.poses.cube.pos: {{offset: [[-0.05, -0.05], [0.05, 0.05, 0]]}}}}\n"},
     2, "randomize.scene.poses.cube.pos: lo and hi must have the same length, got [-0.05, -0.05] and [0.05, 0.05, 0.0]"),
]


@pytest.mark.parametrize(("argv", "files", "code", "expected"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_refused_with_one_line_naming_it(tmp_path, monkeypatch, capsys, argv, files, code, expected):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COLUMNS", "400")
    for name, content in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(content)
    subs = {"{tmp}": str(tmp_path), "{root}": str(ROOT)}

    def fill(text: str) -> str:
        return re.sub(r"\{tmp\}|\{root\}", lambda m: subs[m.group(0)], text)

    assert main([fill(a) for a in argv]) == code
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "error" in lines[0] and fill(expected) in lines[0], lines[0]
    assert not out.strip()


FINDINGS = {  # robot check finds these (exit 1: the file reads, but the commands refuse it)
    "frame named as a model site": (("gains_dir:", "frames: {left_tool: {body: LARM_JOINT5_Link}}\ngains_dir:"),
                                    "frames.left_tool: the model has a site 'left_tool' already"),
    "collision group body unknown": (("head: {bodies: [HEAD_JOINT0_Link, HEAD_JOINT1_Link]}",
                                      "head: {bodies: [HEAD_JOINT0_Link, HEAD_LINK]}"),
                                     "collision_groups.head.bodies: 'HEAD_LINK' is not a body of the model"),
    "camera body unknown": (("{body: HEAD_JOINT1_Link, pos: [0.088, 0.0, 0.105]", "{body: HEAD_LINK, pos: [0.088, 0.0, 0.105]"),
                            "cameras.head_rgbd.body: 'HEAD_LINK' is not a body of the model"),
}


@pytest.mark.parametrize("case", list(FINDINGS))
def test_robot_check_finds_what_the_commands_refuse(tmp_path, capsys, case):
    (old, new), message = FINDINGS[case]
    path = tmp_path / "r.yaml"
    path.write_text(robot(old, new)["r.yaml"])
    assert main(["robot", "check", str(path), "--json"]) == 1
    found = json.loads(capsys.readouterr().out)["findings"]
    assert [f["message"] for f in found if f["level"] == "problem"] == [message]


def test_robot_check_loads_the_file_as_the_commands_do(tmp_path, capsys):
    """A torque limit of a joint the robot lacks: the commands refuse it, so robot check names it."""
    path = tmp_path / "r.yaml"
    path.write_text(robot("gains_dir:", "torque_limits: {NOSUCH_JOINT: 5}\ngains_dir:")["r.yaml"])
    assert main(["robot", "check", str(path), "--json"]) == 1
    found = [f["message"] for f in json.loads(capsys.readouterr().out)["findings"] if f["level"] == "problem"]
    assert len(found) == 1 and "torque_limits: ['NOSUCH_JOINT'] are not robot joints" in found[0], found


@pytest.mark.slow
def test_a_run_whose_phases_complete_but_a_criterion_fails_says_which(capsys):
    """Exit 1 with one line naming the unmet criterion, its value and its limit (the phases all completed)."""
    code = main(["run", PUSH, "--set", "success.planar_error=0.0001", "--set", "timing.settle=0.1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and err[-1].startswith("nextage-qp run: failed: criteria not met: object_error")
    assert "> 0.0001" in err[-1]


def test_an_invalid_mujoco_gl_is_one_line_and_exit_2():
    """MuJoCo reads MUJOCO_GL when it is imported: the command line says so on one line, with the valid values."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "MUJOCO_GL": "bogus"}
    out = subprocess.run([sys.executable, "-m", "nextage_qp.cli", "info"], env=env, capture_output=True, text=True,
                         cwd=ROOT, timeout=120)
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 2 and len(lines) == 1 and "MUJOCO_GL='bogus'" in lines[0] and "valid: egl" in lines[0]


def test_a_wait_longer_than_the_default_timeout_runs_its_course():
    from nextage_qp.manipulation.config import load_config

    cfg = load_config(PUSH, ["phases=[{kind: wait, duration: 12}]"])
    assert cfg.phases[0].timeout >= 12.0 + 1.0 - 1e-9  # the default 10 s stretched to cover it
    assert load_config(PUSH, ["phases=[{kind: wait, duration: 2}]"]).phases[0].timeout == 10.0


def test_a_phase_that_times_out_names_the_collision_pairs_that_held_the_ik():
    """A move into the table: the hand stops at its pair's minimum distance, and the timeout says which pair held."""
    from nextage_qp.manipulation.config import load_config
    from nextage_qp.manipulation.runner import Runner

    cfg = load_config(PUSH, ["phases=[{kind: move, targets: [{frame: left_tool, relative_to: cube, "
                             "offset: [0, 0, -0.08]}], timeout: 3}]"])
    result = Runner(cfg, PUSH).run()
    assert not result["success"] and "timed out after 3 s" in result["error"]
    assert re.search(r"; held by ik\.collision_pairs: \S+ at -?[0-9.]+ mm \(min [0-9.]+\)", result["error"])


def test_run_log_summary_into_the_file_stdout_goes_to_is_refused(tmp_path):
    """``run --json --log run.npz > run.json`` would write the summary and the result into one file: refused."""
    import subprocess
    import sys

    out = tmp_path / "run.json"
    with out.open("w") as stdout:
        done = subprocess.run([sys.executable, "-m", "nextage_qp.cli", "run", PUSH, "--json", "--log",
                               str(tmp_path / "run.npz")], stdout=stdout, stderr=subprocess.PIPE, text=True,
                              timeout=120, check=False)
    assert done.returncode == 2 and "is the file standard output goes to" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not (tmp_path / "run.npz").exists()


def test_run_robot_is_the_same_as_set_robot():
    from nextage_qp.cli import build_parser

    args = build_parser().parse_args(["run", PUSH, "--robot", "nextage"])
    assert args.robot == "nextage"


def test_the_python_api_refuses_bad_arguments_in_one_line():
    """The API's own arguments: a lone override string, a non-string override, episodes and seeds out of range."""
    import nextage_qp as nq
    from nextage_qp.errors import ConfigError

    task = nq.load_task("push_cube", overrides="scene.poses.cube.yaw=0.3")  # one override, not its characters
    assert abs(task.config.scene.poses["cube"].yaw - 0.3) < 1e-12
    with pytest.raises(ConfigError, match=r"overrides: None is not a 'KEY=VALUE' string"):
        nq.load_task("push_cube", overrides=[None])  # type: ignore[list-item]
    for episodes in (0, -3, 1.5, True, 10**9):
        with pytest.raises(ConfigError, match=r"episodes: .* must be a whole number from 1 to 1000000"):
            nq.run_sweep(SWEEP, episodes)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"seed: -1 must be a whole number"):
        nq.run_sweep(SWEEP, 1, seed=-1)
    for workers in (0, 2.0, True):
        with pytest.raises(ConfigError, match=r"workers: .* must be a whole number >= 1, or None"):
            nq.run_sweep(SWEEP, 1, workers=workers)  # type: ignore[arg-type]
    for call in (lambda: nq.load_task(5), lambda: nq.run_sweep(None, 1), lambda: nq.load_robot(3.0)):
        with pytest.raises(ConfigError, match=r"is not a file path or bundled name"):
            call()  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"on_tick: 5 is not callable"):
        nq.run_task("push_cube", on_tick=5)  # type: ignore[arg-type]


def test_phase_kinds_are_checked_when_registered_and_removed():
    """register_phase refuses what is no Spec/Phase pair, a kind that is no one-string Literal and a built-in kind;
    unregister_phase refuses a built-in or unknown kind, naming the kinds that may be removed."""
    from typing import Literal

    import nextage_qp as nq
    from nextage_qp.manipulation.phases import REGISTRY, Phase, Spec
    from nextage_qp.manipulation.phases.push.phase import Push, PushSpec

    class NoLiteral(Spec):
        kind: str = "x"

    class Mine(Spec):
        kind: Literal["mine_for_a_test"]

    with pytest.raises(TypeError, match=r"give a Spec subclass and a Phase subclass"):
        nq.register_phase(dict, Phase)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"NoLiteral.kind must be a Literal of one string"):
        nq.register_phase(NoLiteral, Phase)
    with pytest.raises(TypeError, match=r"'push' is a built-in phase kind"):
        nq.register_phase(type("Other", (PushSpec,), {}), Push)
    with pytest.raises(KeyError, match=r"'push' is a built-in phase kind; kinds added that may be removed: none"):
        nq.unregister_phase("push")
    with pytest.raises(KeyError, match=r"'nope' is not registered"):
        nq.unregister_phase("nope")
    nq.register_phase(Mine, Phase)
    try:
        assert REGISTRY["mine_for_a_test"] == (Mine, Phase)
    finally:
        nq.unregister_phase("mine_for_a_test")
    assert "mine_for_a_test" not in REGISTRY and REGISTRY["push"] == (PushSpec, Push)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_json_result_that_cannot_be_written_is_one_line_and_exit_2():
    import subprocess
    import sys

    with open("/dev/full", "w") as full:
        done = subprocess.run([sys.executable, "-m", "nextage_qp.cli", "fk", "left_tool", "--json"], stdout=full,
                              stderr=subprocess.PIPE, text=True, timeout=120, check=False)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip() == ("nextage-qp fk: error: standard output: cannot write the JSON result "
                                   "(No space left on device)")


def test_a_sweep_record_that_cannot_be_written_is_one_line(tmp_path, monkeypatch):
    """A full disk under a sweep's --out: a ConfigError naming the folder and --resume, not a traceback."""
    from nextage_qp.errors import ConfigError
    from nextage_qp.sweep import store as store_module

    class Full:
        def write(self, text):
            raise OSError(28, "No space left on device")

    s = object.__new__(store_module.SweepStore)
    s.out, s.done, s._file = tmp_path, {}, Full()
    episode = type("E", (), {"index": 7, "to_json": lambda self: {}})()
    with pytest.raises(ConfigError, match=r"cannot write episode 7's record \(No space left on device\); free space "
                                          r"and run again with --resume"):
        s.add(episode)


def test_a_sweep_in_which_no_episode_ran_exits_1_saying_so(tmp_path, capsys, monkeypatch):
    """Every episode refused (objects placed 4-5 m off the table): the summary is written, and the exit code and one
    line say that nothing was measured (a script would read 0 as a measured sweep)."""
    monkeypatch.setenv("COLUMNS", "200")
    sweep = tmp_path / "s.yaml"
    sweep.write_text(f"base: {PUSH}\nrandomize: {{scene.poses.cube.pos: {{offset: [[4, 4, 0], [5, 5, 0]]}}}}\n")
    assert main(["sweep", str(sweep), "--n", "2", "--workers", "1", "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert "nextage-qp sweep: error: no episode ran to its end (2 refused, 0 errors" in err
    assert (tmp_path / "out" / "summary.json").is_file()


def test_robot_check_flags_a_joint_range_written_upper_bound_first(tmp_path):
    """MuJoCo leaves a joint whose range reads "2 -2" (limited="auto") unlimited without a word: robot check says so."""
    import shutil

    from nextage_qp.robots.check_report import check_robot

    shutil.copytree(ROOT / "robots" / "nextage", tmp_path / "nextage")
    xml = tmp_path / "nextage" / "nextage.xml"
    old = '<joint name="LARM_JOINT0" class="arm" axis="0 0 1" range="-1.5708 1.5708"/>'
    assert old in xml.read_text()
    xml.write_text(xml.read_text().replace(old, old.replace('range="-1.5708 1.5708"',
                                                            'range="1.5708 -1.5708" limited="auto"')))
    (tmp_path / "r.yaml").write_text(NEXTAGE.replace(f"model: {ROOT}/robots/nextage/", f"model: {tmp_path}/nextage/"))
    found = [f for f in check_robot(tmp_path / "r.yaml").findings if f.topic == "range"]
    assert len(found) == 1 and found[0].level == "problem"
    assert "joint 'LARM_JOINT0' range [1.5708, -1.5708] has its lower bound above its upper" in found[0].message


@pytest.mark.parametrize(("argv", "expected"), [
    (["run", "a" * 300 + ".yaml"], "file name too long"),
    (["reach", "--pos", "0.3", "0.1", "1.0", "--duration", "0.2", "--max-acceleration", "0.001"], "[0.01, 10000]"),
    (["reach", "--pos", "0.3", "0.1", "1.0", "--duration", "0.2", "--max-jerk", "1e-12"], "[0.01, 1e+06]"),
    (["run", "configs/push_cube.yaml", "--set", "timing.sim_dt=1e-9"], "timing.sim_dt"),
    (["run", "configs/push_cube.yaml", "--set",
      "scene.objects.cube={shape: box, size: [0.03,0.03,0.03], mass: 1e-12}"], "scene.objects.cube.mass"),
])
def test_limits_that_used_to_crash_or_hang_are_refused_in_one_line(capsys, argv, expected):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expected in err and "Traceback" not in err
