import json

import numpy as np
import pytest

from nextage_qp.cli import main


def run_json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_info_lists_joints_sites_objects(capsys):
    info = run_json(capsys, ["info", "dock_dumbbell", "--json"])
    assert [j["name"] for j in info["joints"]][:3] == ["CHEST_JOINT0", "HEAD_JOINT0", "HEAD_JOINT1"]
    assert len(info["actuators"]) == 15
    assert "left_tool" in info["sites"]
    assert info["objects"]["dumbbell"]["mass_kg"] == pytest.approx(0.3)
    assert info["robot_total_mass_kg"] == pytest.approx(65.678269, abs=1e-6)
    assert info["collision_groups"]["obstacle"] == 1


def test_info_table_output(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    assert main(["info"]) == 0
    out = capsys.readouterr().out
    assert "LARM_JOINT3" in out and "sites:" in out
    assert "lower [rad]" in out and "torque [N m]" in out  # unit brackets are not read as rich markup


def test_fk_json_at_home(capsys):
    out = run_json(capsys, ["fk", "LARM_JOINT5_Link", "--keyframe", "home", "--json"])
    np.testing.assert_allclose(out["position_m"], (0.504975, 0.23, 1.032149), atol=1e-6)
    assert len(out["q"]) == 15
    assert np.linalg.norm(out["quaternion_wxyz"]) == pytest.approx(1.0)


def test_fk_with_joint_assignments(capsys):
    out = run_json(capsys, ["fk", "RARM_JOINT5_Link", "--q", "RARM_JOINT1=-0.4", "--json"])
    np.testing.assert_allclose(out["position_m"], (0.504975, -0.23, 1.032149), atol=1e-6)


def test_fk_human_output(capsys):
    assert main(["fk", "left_wrist"]) == 0
    assert "position [m]" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv,message",
    [
        (["fk", "LARM_HAND"], "unknown frame 'LARM_HAND'; valid: left_wrist"),
        (["fk", "left_wrist", "--q", "LARM_JOINT9=1"], "unknown joint 'LARM_JOINT9'; valid: CHEST_JOINT0"),
        (["fk", "left_wrist", "--q", "LARM_JOINT1"], "expected NAME=RAD"),
        (["fk", "left_wrist", "--keyframe", "rest"], "unknown keyframe 'rest'; valid: home, zero"),
        (["info", "no_scene"], "bundled scenes:"),
    ],
)
def test_cli_errors_are_one_line_exit_2(capsys, argv, message):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_docs_synopsis_names_every_option_of_every_command():
    import argparse
    from pathlib import Path

    from nextage_qp.cli import build_parser

    readme = (Path(__file__).resolve().parents[1] / "docs" / "getting-started.md").read_text()
    block = readme[readme.index("## The command line"):]
    block = block[block.index("```") + 3:]
    block = block[: block.index("```")]
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    missing: list[str] = []
    for name, parser in sub.choices.items():
        line = block[block.index(f"nextage-qp {name} "):]  # the command's lines, up to the next command
        nxt = line.find("\nnextage-qp ", 1)
        text = line if nxt < 0 else line[:nxt]
        missing += [f"{name} {o}" for a in parser._actions for o in a.option_strings
                    if o.startswith("--") and o != "--help" and o not in text]
    assert not missing, f"the synopsis in docs/getting-started.md lacks: {missing}"


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("nextage-qp ")


def test_library_notices_stay_off_stderr(capsys):
    assert main(["ik", "--frame", "left_wrist", "--pos", "0.4", "0.2", "1.0", "--solver", "osqp", "--json"]) == 0
    assert capsys.readouterr().err == ""


def test_step_response_says_never_and_log_names_its_columns(tmp_path, capsys):
    code = main(["step-response", "--joint", "LARM_JOINT1", "--target-deg", "-10", "--duration", "0.05",
                 "--log", str(tmp_path / "sr")])
    assert code == 0
    assert "settling_time_s    never" in capsys.readouterr().out
    with np.load(tmp_path / "sr.npz") as z:  # the suffix is added, and the arrays say what their columns are
        assert list(z["joint_names"])[:2] == ["CHEST_JOINT0", "HEAD_JOINT0"] and z["q"].shape[1] == 15


@pytest.mark.parametrize("command", [[], ["info"], ["fk"], ["ik"], ["step-response"], ["reach"], ["run"], ["sweep"]])
def test_help_is_plain_text(command, capsys):
    assert main([*command, "--help"]) == 0
    out = capsys.readouterr().out
    assert "``" not in out and ":mod:" not in out and ":class:" not in out, out
