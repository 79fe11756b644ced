from pathlib import Path

import pytest
import yaml

from nextage_qp.cli import main
from nextage_qp.errors import ConfigError
from nextage_qp.manipulation.config import apply_override, load_config
from nextage_qp.manipulation.runner import build_robot

ROOT = Path(__file__).resolve().parents[1]
PUSH = ROOT / "configs" / "push_cube.yaml"
DOCK = ROOT / "configs" / "dock_dumbbell.yaml"


def write_variant(tmp_path, base: Path, edit) -> Path:
    doc = yaml.safe_load(base.read_text())
    edit(doc)
    path = tmp_path / "variant.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize("path", [PUSH, DOCK])
def test_bundled_configs_validate_and_resolve_names(path):
    cfg = load_config(path)
    robot = build_robot(cfg, str(path))
    assert cfg.object in robot.object_names


def test_overrides_reach_the_scene():
    cfg = load_config(PUSH, ["scene.poses.cube.pos=[0.35,0.02,0.91]", "scene.poses.cube_target.yaw=3.0"])
    robot = build_robot(cfg, "x")
    assert list(robot.model.body("cube").pos) == pytest.approx([0.35, 0.02, 0.91])
    assert cfg.scene.poses["cube_target"].yaw == 3.0


def test_override_into_phase_list():
    cfg = load_config(DOCK, ["phases.1.speed=0.05"])
    assert cfg.phases[1].speed == 0.05


@pytest.mark.parametrize(
    "edit,message",
    [
        (lambda d: d.update(taks="x"), "taks: unknown key; valid: estimation, faults, gains, ik, mount, object"),
        (lambda d: d["phases"][0].update(tolerence=0.1), "phases[0].tolerence: unknown key; valid: accept, approach"),
        (lambda d: d["phases"][0].update(tolerance=-0.01), "phases[0].tolerance: Input should be greater than 0"),
        (lambda d: d["phases"][0].update(kind="jump"), "phases[0]: unknown kind; valid: move, push"),
        (lambda d: d["ik"].update(solver="cplex"), "ik.solver: solver 'cplex' is not installed; available: daqp"),
        (lambda d: d["timing"].update(ctrl_dt=0.0045), "must be a whole multiple of sim_dt"),
        (lambda d: d["phases"][0].update(frame="left_hnd"), "phases[0].frame: 'left_hnd' is not valid; valid: left_wrist"),
        (lambda d: d["phases"][0].update(object="ball"), "phases[0].object: 'ball' is not valid; valid: cube"),
        (lambda d: d.update(target="goal"), "target: 'goal' is not valid; valid:"),
        (lambda d: d["scene"]["poses"].update(cub={"pos": [0, 0, 1]}), "unknown scene body (object, target or obstacle) 'cub'; valid: table, cube, cube_target"),
        (lambda d: d["ik"]["collision_pairs"].append({"a": "left_arm", "b": "wall"}), "unknown geom group"),
    ],
)
def test_bad_configs_give_one_line_errors_and_exit_2(tmp_path, capsys, edit, message):
    path = write_variant(tmp_path, PUSH, edit)
    assert main(["run", str(path), "--json"]) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert err.count("\n") == 1 and str(path) in err


def test_unreachable_target_fails_the_phase_with_its_name(tmp_path, capsys):
    def edit(d):
        d["phases"] = [{"kind": "move", "name": "reach far", "timeout": 1.0,
                        "targets": [{"frame": "left_tool", "relative_to": "world", "offset": [1.0, 0.0, 1.0]}]}]
    path = write_variant(tmp_path, PUSH, edit)
    log = tmp_path / "log.npz"
    assert main(["run", str(path), "--json", "--log", str(log)]) == 1
    captured = capsys.readouterr()
    assert "phase 'reach far' (move) timed out after 1 s" in captured.err
    assert log.is_file() and log.with_suffix(".json").is_file()  # the partial run is still written
    assert '"status": "failed"' in captured.out


def test_text_summary_keeps_unit_brackets(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")

    def edit(d):
        d["phases"] = [{"kind": "move", "name": "reach far", "timeout": 0.2,
                        "targets": [{"frame": "left_tool", "relative_to": "world", "offset": [1.0, 0.0, 1.0]}]}]
    assert main(["run", str(write_variant(tmp_path, PUSH, edit))]) == 1
    out = capsys.readouterr().out
    for text in ("start [s]", "duration [s]", "final object position [m]", "obstacle contacts [steps]"):
        assert text in out


@pytest.mark.parametrize("assignment", ["noequals", "phases.9.speed=1", "task.sub=1"])
def test_bad_set_overrides(assignment):
    with pytest.raises(ConfigError):
        apply_override({"task": "x", "phases": [{}]}, assignment)


def test_missing_config_file(capsys):
    assert main(["run", "configs/nope.yaml"]) == 2
    assert "no such config file" in capsys.readouterr().err
