"""A corpus of bad inputs: every case exits 2 (bad input) or 1 (a valid input that fails at run time), prints
exactly one line on stderr naming what is wrong, never a traceback, and any JSON it prints is strict JSON.

Cases are ``(id, argv, files)``: ``{tmp}`` in argv is the case's temporary folder and ``files`` maps a file name
in it to its content (str or bytes). ``{push}`` / ``{dock}`` are the bundled configs' paths.
"""

import json
import re
from pathlib import Path

import pytest

from nextage_qp.cli import main

ROOT = Path(__file__).resolve().parents[1]
PUSH = (ROOT / "configs" / "push_cube.yaml").read_text()
GAINS = (ROOT / "configs" / "gains" / "default.yaml").read_text()


def push(old: str, new: str) -> str:
    """The push config with one exact piece of text replaced (the piece must be there)."""
    assert old in PUSH, old
    return PUSH.replace(old, new, 1)


def run_cfg(text: str | bytes, *extra: str) -> tuple[list[str], dict[str, str | bytes]]:
    return ["run", "{tmp}/c.yaml", *extra], {"c.yaml": text}


CONFIG_CASES = {
    "not utf-8": b"task: push_cube\nscene: \xff\xfe\n",
    "binary": b"\x00\x01\x02\x03garbage\x00",
    "empty": "",
    "top-level list": "- a\n- b\n",
    "top-level scalar": "42\n",
    "bad yaml syntax": "task: [push\n",
    "tab indentation": "task: push_cube\nscene:\n\tfile: push_cube\n",
    "duplicate top key": push("task: push_cube\n", "task: push_cube\ntask: push_cube\n"),
    "duplicate nested key": push("  settle: 0.5 ", "  settle: 0.5\n  settle: 0.6 "),
    "unknown top key": push("task: push_cube\n", "task: push_cube\ntaks: x\n"),
    "unknown nested key": push("  settle: 0.5 ", "  setle: 0.5 "),
    "yaml 1.1 boolean as number": push("  settle: 0.5 ", "  settle: yes "),
    "settle inf": push("  settle: 0.5 ", "  settle: .inf "),
    "settle nan": push("  settle: 0.5 ", "  settle: .nan "),
    "settle negative": push("  settle: 0.5 ", "  settle: -1 "),
    "settle huge": push("  settle: 0.5 ", "  settle: 1e9 "),
    "settle string": push("  settle: 0.5 ", "  settle: soon "),
    "timeout inf": push("    timeout: 90.0 ", "    timeout: .inf "),
    "timeout huge": push("    timeout: 90.0 ", "    timeout: 1.0e12 "),
    "timeout zero": push("    timeout: 90.0 ", "    timeout: 0 "),
    "sim_dt zero": push("  sim_dt: 0.001 ", "  sim_dt: 0 "),
    "sim_dt nan": push("  sim_dt: 0.001 ", "  sim_dt: .nan "),
    "ctrl_dt not a multiple": push("  ctrl_dt: 0.02 ", "  ctrl_dt: 0.0205 "),
    "max_velocity inf": push("  max_velocity: 1.0 ", "  max_velocity: .inf "),
    "max_velocity zero": push("  max_velocity: 1.0 ", "  max_velocity: 0 "),
    "max_jerk nan": push("  max_jerk: 40.0 ", "  max_jerk: .nan "),
    "ik velocity_limit inf": push("  velocity_limit: 1.0 ", "  velocity_limit: .inf "),
    "ik position_cost negative": push("  position_cost: 1.0 ", "  position_cost: -1 "),
    "ik lm_damping nan": push("  lm_damping: 0.1\n", "  lm_damping: .nan\n"),
    "collision group unknown": push("{a: left_hand, b: table,", "{a: left_hnd, b: table,"),
    "collision min_distance inf": push("{a: left_hand, b: table, min_distance: 0.002",
                                       "{a: left_hand, b: table, min_distance: .inf"),
    "pose pos nan": push("cube: {pos: [0.33, 0.0, 0.91]", "cube: {pos: [.nan, 0.0, 0.91]"),
    "pose pos two values": push("cube: {pos: [0.33, 0.0, 0.91]", "cube: {pos: [0.33, 0.0]"),
    "pose pos string": push("cube: {pos: [0.33, 0.0, 0.91]", "cube: {pos: here"),
    "pose yaw inf": push("cube: {pos: [0.33, 0.0, 0.91], yaw: 0.0}", "cube: {pos: [0.33, 0.0, 0.91], yaw: .inf}"),
    "pose unknown body": push("    cube: {pos:", "    cubee: {pos:"),
    "pose on a robot link": push("    cube: {pos:", "    CHEST_JOINT0_Link: {pos:"),
    "mass inf": PUSH.replace("  poses:\n", "  masses: {cube: .inf}\n  poses:\n", 1),
    "mass negative": PUSH.replace("  poses:\n", "  masses: {cube: -1}\n  poses:\n", 1),
    "mass on unknown body": PUSH.replace("  poses:\n", "  masses: {cub: 0.5}\n  poses:\n", 1),
    "friction nan": PUSH.replace("  poses:\n", "  friction_scale: {cube: .nan}\n  poses:\n", 1),
    "object unknown": push("object: cube\n", "object: cub\n"),
    "target unknown": push("target: cube_target\n", "target: cube_tgt\n"),
    "start unknown keyframe": push("start: home\n", "start: homme\n"),
    "gains missing file": push("gains: stiff_wrist", "gains: no_such_gains"),
    "scene missing file": push("  file: push_cube\n", "  file: no_such_scene\n"),
    "phase kind unknown": push("  - kind: push\n", "  - kind: shove\n"),
    "phase kind missing": push("  - kind: push\n    name:", "  - name:"),
    "phase frame unknown": push("    frame: left_tool\n", "    frame: left_toool\n"),
    "phase object unknown": push("    object: cube\n    target", "    object: cub\n    target"),
    "phase speed zero": push("    speed: 0.15 ", "    speed: 0 "),
    "phase speed inf": push("    speed: 0.15 ", "    speed: .inf "),
    "phase attempts float": push("    attempts: 4 ", "    attempts: 2.5 "),
    "phase attempts negative": push("    attempts: 4 ", "    attempts: -1 "),
    "phase height nan": push("    height: 0.002 ", "    height: .nan "),
    "phases empty": PUSH[: PUSH.index("phases:")] + "phases: []\n",
    "phases not a list": PUSH[: PUSH.index("phases:")] + "phases: push\n",
    "success criterion inf": push("  planar_error: 0.005 ", "  planar_error: .inf "),
    "success unknown criterion": push("  planar_error: 0.005 ", "  planar_eror: 0.005 "),
    "success criterion negative": push("  planar_error: 0.005 ", "  planar_error: -0.005 "),
    "push tolerance negative": push("    tolerance: 0.002 ", "    tolerance: -0.002 "),
    "push accept nan": push("    accept: 0.005 ", "    accept: .nan "),
    "scene not a mapping": PUSH[: PUSH.index("scene:")] + "scene: 3\n" + PUSH[PUSH.index("object: cube"):],
    "poses not a mapping": push("  poses:\n", "  poses: 3\n  unused:\n"),
    "phase item not a mapping": PUSH[: PUSH.index("phases:")] + "phases: [1]\n",
    "ik solver unknown": push("  lm_damping: 0.1\n", "  lm_damping: 0.1\n  solver: nope\n"),
    "collision pair without b": push("{a: left_hand, b: table, ", "{a: left_hand, "),
    "trajectory per-joint list too short": push("  max_velocity: 1.0 ", "  max_velocity: [1.0, 1.0] "),
    "ctrl_dt too long": push("  ctrl_dt: 0.02 ", "  ctrl_dt: 5 "),
    "gains a number": push("gains: stiff_wrist", "gains: 3"),
    "object a list": push("object: cube\n", "object: [cube]\n"),
    "start a number": push("start: home\n", "start: 7\n"),
}

GAINS_CASES = {
    "gains not utf-8": b"joints: \xff\n",
    "gains binary": b"\x00\x00\x00",
    "gains kp nan": GAINS.replace("kp: ", "kp: .nan  #", 1),
    "gains kp negative": GAINS.replace("kp: ", "kp: -1  #", 1),
    "gains kp yes": GAINS.replace("kp: ", "kp: yes  #", 1),
    "gains duplicate joint": GAINS + "\n  CHEST_JOINT0: {kp: 1.0, kd: 1.0}\n",
    "gains unknown key": GAINS + "\nextra: 1\n",
    "gains top-level list": "- 1\n",
}

CASES: list[tuple[str, list[str], dict[str, str | bytes]]] = []
for name, text in CONFIG_CASES.items():
    CASES.append((f"config: {name}", *run_cfg(text)))
for name, text in GAINS_CASES.items():
    CASES.append((f"gains: {name}", *run_cfg(push("gains: stiff_wrist", "gains: g.yaml"), "--json")))
    CASES[-1][2]["g.yaml"] = text  # relative paths inside a config resolve against the working folder (tmp)

SET_CASES = [
    "timing.settle=[1,", "timing.settle", "=1", "timing.settle=.inf", "timing.settle=yes", "timing.settle=1e12",
    "phases.5.timeout=1", "phases.x.timeout=1", "scene.poses.cube.pos=[1,2]", "scene.poses.cube.pos=[nan,0,0.9]",
    "scene.masses.cube=-2", "scene.masses.cube=.inf", "object=nope", "phases.0.kind=shove", "phases.0.speed=0",
    "ik.velocity_limit=.nan", "trajectory.max_velocity=-1", "task={a: 1}", "timing={x: 1}", "scene.file=nope",
    "phases.0=3", "scene.poses=3", "ik.solver=nope", "timing.settle.x=1", "scene.masses.table=2",
    "phases[0]={name: x}", "phases[0].kind=joints", "phases[9].timeout=1", "phases[0].timeout=.nan",
]
for item in SET_CASES:
    CASES.append((f"--set {item}", ["run", "{push}", "--set", item], {}))

CLI_CASES = [
    ["run"], ["run", "{tmp}/missing.yaml"], ["run", "{tmp}"], ["run", "{push}", "--seed", "-1"],
    ["run", "{push}", "--seed", "x"], ["run", "{push}", "--log", "{tmp}"], ["run", "{push}", "--log", "{tmp}/"],
    ["run", "{push}", "--plot", "{tmp}/p.txt"], ["run", "{push}", "--video", "{tmp}/v.avi"],
    ["run", "{push}", "--plot", "{push}/p.png"], ["run", "{push}", "--bogus"],
    ["fk"], ["fk", "no_such_frame"], ["fk", "left_wrist", "--q", "LARM_JOINT1=nan"],
    ["fk", "left_wrist", "--q", "LARM_JOINT1=inf"], ["fk", "left_wrist", "--q", "LARM_JOINT1=9"],
    ["fk", "left_wrist", "--q", "LARM_JOINT1"], ["fk", "left_wrist", "--q", "NO_JOINT=0.1"],
    ["fk", "left_wrist", "--keyframe", "homme"], ["fk", "left_wrist", "--scene", "no_scene"],
    ["ik", "--frame", "left_wrist"], ["ik", "--frame", "left_wrist", "--pos", "0.4", "0.2", "nan"],
    ["ik", "--frame", "left_wrist", "--pos", "0.4", "0.2", "inf"], ["ik", "--frame", "left_wrist", "--pos", "1e9", "0", "1"],
    ["ik", "--frame", "left_wrist", "--pos", "0.4", "0.2", "1.0", "--quat", "0", "0", "0", "0"],
    ["ik", "--frame", "nope", "--pos", "0.4", "0.2", "1.0"], ["ik", "--frame", "left_wrist", "--pos", "0.4", "0.2", "1.0",
                                                             "--method", "magic"],
    ["ik", "--frame", "left_wrist", "--pos", "0.4", "0.2", "1.0", "--dir", "0", "0", "1"],
    ["info", "no_such_scene"], ["info", "{tmp}/bin.xml"], ["info", "{tmp}/bad.xml"], ["info", "{tmp}"],
    ["reach", "--pos", "0.4", "0.2"], ["reach", "--pos", "0.4", "0.2", "1.0", "--max-velocity", "0"],
    ["reach", "--pos", "0.4", "0.2", "1.0", "--max-velocity", "-1"],
    ["reach", "--pos", "0.4", "0.2", "1.0", "--max-velocity", "nan"],
    ["reach", "--pos", "0.4", "0.2", "1.0", "--duration", "inf"],
    ["reach", "--pos", "0.4", "0.2", "1.0", "--duration", "1e9"], ["reach", "--pos", "0.4", "0.2", "1.0", "--duration", "0"],
    ["reach", "--pos", "0.4", "0.2", "1.0", "--frame", "nope"],
    ["reach", "--pos", "0.4", "0.2", "1.0", "--gains", "{tmp}/g.yaml"],
    ["reach", "--pos", "3.0", "0.2", "1.0", "--duration", "0.3", "--json"],  # valid but out of reach: exit 1
    ["step-response"], ["step-response", "--joint", "LARM_JOINT1", "--target-deg", "nan"],
    ["step-response", "--joint", "LARM_JOINT1", "--target-deg", "1e9"],
    ["step-response", "--joint", "LARM_JOINT1", "--target-deg", "10", "--duration", "1e9"],
    ["step-response", "--joint", "NOPE", "--target-deg", "10"],
    ["step-response", "--joint", "LARM_JOINT1", "--target-deg", "10", "--log", "{tmp}"],
    ["sweep"], ["sweep", "{tmp}/missing.yaml", "--n", "2"], ["sweep", "{push}", "--n", "2"],
    ["sweep", "{tmp}/c.yaml", "--n", "-3"], ["sweep", "{tmp}/c.yaml", "--n", "2", "--seed", "-1"],
    ["sweep", "{tmp}/c.yaml", "--n", "2", "--workers", "0"], ["sweep", "{tmp}/c.yaml", "--n", "2", "--json", "{tmp}"],
    ["nope"], [], ["--bogus"],
]
CLI_FILES: dict[str, str | bytes] = {
    "bin.xml": b"\x00\x01binary\xff", "bad.xml": "<mujoco><worldbody><body></mujoco>", "g.yaml": "joints: [1, 2]\n",
    "c.yaml": "base: ../no_such.yaml\nrandomize: {}\n",
}
for argv in CLI_CASES:
    CASES.append((f"cli: {' '.join(argv) or '(none)'}", argv, CLI_FILES))


def _strict_json(text: str) -> None:
    def refuse(value: str) -> None:
        raise ValueError(f"non-strict JSON constant {value}")

    json.loads(text, parse_constant=refuse)


@pytest.mark.parametrize(("argv", "files"), [(a, f) for _, a, f in CASES], ids=[c[0] for c in CASES])
def test_bad_input_gives_one_line_and_a_failure_code(tmp_path, monkeypatch, capsys, argv, files):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COLUMNS", "400")
    for name, content in files.items():
        path = tmp_path / name
        path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
    subs = {"{tmp}": str(tmp_path), "{push}": str(ROOT / "configs" / "push_cube.yaml")}
    args = [re.sub(r"\{tmp\}|\{push\}", lambda m: subs[m.group(0)], a) for a in argv]
    code = main(args)
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code in (1, 2), f"exit {code}; stderr: {err!r}"
    assert "Traceback" not in err and len(lines) == 1, err
    assert "error" in lines[0] or code == 1, lines[0]
    if "--json" in args and out.strip():
        _strict_json(out)


def test_corpus_is_large():
    assert len(CASES) >= 150


@pytest.mark.parametrize(("item", "expected"), [
    ("phases[0]={name: x}", "phases[0].kind: missing; valid: move, push"),
    ("phases[0].kind=joints", "phases[0].positions: required, but missing"),
    ("phases[0].timeout=.nan", "phases[0].timeout: Input should be a finite number"),
])
def test_messages_name_the_key_without_pydantic_internals(item, expected, capsys):
    assert main(["run", str(ROOT / "configs" / "push_cube.yaml"), "--set", item]) == 2
    err = capsys.readouterr().err
    assert expected in err and "discriminator" not in err and "[+" not in err, err
