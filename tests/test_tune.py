"""nextage-qp tune: study files validated, a small study end to end on 2 workers, kill and --resume, the YAML runs."""

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from nextage_qp.cli import main
from nextage_qp.errors import ConfigError
from nextage_qp.loop.pd import load_gains
from nextage_qp.manipulation.config import load_config
from nextage_qp.tune.study import Study

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ROOT / "configs" / "sweeps" / "push_cube.yaml"

optuna = pytest.importorskip("optuna")


def write_study(tmp_path, doc, name="study.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def steps_study(**over):
    doc = {
        "steps": {"gains": "default", "amplitude_deg": 30, "joints": ["LARM_JOINT3", "LARM_JOINT4"], "duration_s": 0.6},
        "held_out": {"amplitude_deg": 20},
        "startup_trials": 2,
        "trials": 4,
        "space": {
            "joints.LARM_JOINT3.kp": {"log": [40, 200], "also": ["joints.RARM_JOINT3.kp"]},
            "joints.LARM_JOINT3.kd": {"float": [2, 8]},
        },
    }
    doc.update(over)
    return doc


def complete_trials(db, name):
    """Numbers of the study's complete trials, read from the SQLite file directly (read-only, no schema work)."""
    if not Path(db).exists():
        return []
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=30)
    try:
        rows = con.execute("SELECT t.number FROM trials t JOIN studies s ON t.study_id = s.study_id "
                           "WHERE s.study_name = ? AND t.state = 'COMPLETE' ORDER BY t.number", (name,)).fetchall()
    except sqlite3.OperationalError:  # the tables are not there yet
        return []
    finally:
        con.close()
    return [r[0] for r in rows]


@pytest.mark.parametrize(
    "over,message",
    [
        ({"steps": None}, "give exactly one of 'sweep'"),
        ({"sweep": {"file": str(SWEEP), "episodes": 2}}, "give exactly one of 'sweep'"),
        ({"space": {}}, "space: Dictionary should have at least 1 item"),
        ({"space": {"joints.LARM_JOINT3.kp": {"log": [0, 10]}}}, "log needs lo > 0"),
        ({"space": {"joints.LARM_JOINT3.kp": {"float": [10, 1]}}}, "lo > hi"),
        ({"space": {"joints.LARM_JOINT3.kp": {"float": [1, 10], "log": [1, 10]}}}, "exactly one of float, log"),
        ({"space": {"joints.LARM_JOINT3.kp": {"flaot": [1, 10]}}}, "unknown key"),
        ({"space": {"joints.LARM_JOINT3.kp": {"float": [1, float("nan")]}}}, "space.joints.LARM_JOINT3.kp"),
        ({"space": {"joints.LARM_JOINT3.kp": {"float": [-5, 10]}}}, "value -5"),
        ({"space": {"joints.LARM_JOINT3.kpp": {"float": [1, 10]}}}, "'joints.LARM_JOINT3.kpp' is not a key"),
        ({"space": {"joints.LARM_JOINT3.kp": {"float": [1, 10], "also": ["joints.NOPE.kp"]}}}, "joints.NOPE.kp: not in the base gains file"),
        ({"space": {"joints.LARM_JOINT3.kp": {"float": [1, 10], "also": ["joints.LARM_JOINT3.kp"]}}}, "tied once"),
        ({"objective": "failures_then_p95_error"}, "does not apply to a steps study"),
        ({"held_out": {"episodes": 10}}, "held_out of a steps study"),
        ({"sampler": "random"}, "sampler"),
        ({"trials": 0}, "trials"),
        ({"steps": {"gains": "nope", "amplitude_deg": 30}}, "gains file 'nope' not found"),
        ({"steps": {"gains": "default", "amplitude_deg": 30, "relative": ["ARM"]}}, "unknown joint 'ARM'"),
        ({"spaec": {}}, "spaec: unknown key"),
    ],
)
def test_bad_study_files_give_one_line_and_exit_2(tmp_path, capsys, over, message):
    doc = steps_study(**over)
    doc = {k: v for k, v in doc.items() if v is not None}  # None: the key left out
    path = write_study(tmp_path, doc)
    with pytest.raises(ConfigError) as info:
        Study(path)
    assert message in str(info.value) and str(path) in str(info.value)
    assert main(["tune", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


@pytest.mark.parametrize(
    "space,message",
    [
        ({"scene.masses.cube": {"float": [0.1, 0.2]}}, "the sweep randomises this key"),
        ({"ik.posture_costt": {"log": [0.001, 0.1]}}, "'ik.posture_costt' is not a key of the base config"),
        ({"ik.posture_cost": {"choice": [[1, 2]]}}, "choices must be numbers"),
    ],
)
def test_bad_sweep_study_keys(tmp_path, capsys, space, message):
    path = write_study(tmp_path, {"sweep": {"file": str(SWEEP), "episodes": 2}, "space": space})
    assert main(["tune", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


@pytest.mark.parametrize(
    "held,message",
    [
        ({"episodes": 10, "seed": 0}, "held_out.seed 0 is the objective's sweep.seed"),
        ({"episodes": 10}, "held_out of a sweep study: give episodes and seed"),
    ],
)
def test_held_out_episodes_must_be_other_scenes(tmp_path, capsys, held, message):
    path = write_study(tmp_path, {"sweep": {"file": str(SWEEP), "episodes": 2, "seed": 0}, "held_out": held,
                                  "space": {"ik.posture_cost": {"log": [0.005, 0.05]}}})
    assert main(["tune", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


@pytest.mark.parametrize("text,message", [("[1, 2]", "expected a mapping"), ("space: [", "not valid YAML")])
def test_study_file_that_is_not_a_mapping(tmp_path, capsys, text, message):
    path = tmp_path / "s.yaml"
    path.write_text(text)
    assert main(["tune", str(path)]) == 2
    assert message in capsys.readouterr().err


def test_bad_tune_arguments(tmp_path, capsys):
    path = write_study(tmp_path, steps_study())
    for args, message in ((["--trials", "0"], "--trials must be between 1"),
                          (["--workers", "0"], "--workers must be between 1"),
                          (["--ray-address", "1.2.3.4:6379"], "--ray-address needs --backend ray"),
                          (["--out", str(ROOT / "pyproject.toml")], "cannot create the directory")):
        assert main(["tune", str(path), *args]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, err


def test_bundled_studies_validate():
    for name in ("pd_gains", "dock_dumbbell"):
        study = Study(ROOT / "configs" / "studies" / f"{name}.yaml")
        assert study.base_params is not None  # the base config is trial 0


@pytest.mark.slow
def test_four_trial_study_on_two_workers_writes_a_gains_file_that_loads(tmp_path, capsys):
    path = write_study(tmp_path, steps_study())
    out = tmp_path / "out"
    assert main(["tune", str(path), "--workers", "2", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials"]["complete"] == 4 and summary["base"]["number"] == 0
    assert summary["best"]["value"] <= summary["base"]["value"]
    assert set(summary["held_out"]) == {"base", "best"} and summary["held_out"]["best"]["details"]["steps"] == 4
    assert (out / "history.png").stat().st_size > 0
    gains = load_gains(out / "best.yaml")
    best = summary["best"]["params"]
    j3 = list(gains.as_dict())
    assert gains.as_dict()["LARM_JOINT3"]["kp"] == pytest.approx(best["joints.LARM_JOINT3.kp"])
    assert gains.as_dict()["RARM_JOINT3"]["kp"] == pytest.approx(best["joints.LARM_JOINT3.kp"])  # also: tied
    assert len(j3) == 15
    # a second run without --resume refuses to mix into the stored study
    assert main(["tune", str(path), "--workers", "2", "--out", str(out)]) == 2
    assert "--resume" in capsys.readouterr().err


@pytest.mark.slow
def test_killed_study_resumes_its_trial_count(tmp_path):
    doc = steps_study(trials=8)
    doc["steps"]["duration_s"] = 2.0  # slower trials, so the kill lands mid-study
    path = write_study(tmp_path, doc)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "nextage_qp.cli", "tune", str(path), "--workers", "2", "--out", str(out)]
    log = (tmp_path / "first.err").open("w")
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=log, start_new_session=True,
                            env={**os.environ, "MUJOCO_GL": "egl"})
    db = out / "study.db"
    deadline = time.monotonic() + 240
    try:
        while time.monotonic() < deadline:
            if len(complete_trials(db, "study")) >= 2 or proc.poll() is not None:
                break
            time.sleep(0.5)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    log.close()
    before = complete_trials(db, "study")
    assert 2 <= len(before) < 8, (tmp_path / "first.err").read_text()[-2000:]
    assert main(["tune", str(path), "--workers", "2", "--out", str(out), "--resume"]) == 0
    after = complete_trials(db, "study")
    assert len(after) == 8 and after[: len(before)] == before  # the finished trials are kept, the count continues
    assert json.loads((out / "summary.json").read_text())["trials"]["complete"] == 8


@pytest.mark.slow
def test_sweep_study_writes_a_task_config_that_loads_and_runs(tmp_path):
    path = write_study(tmp_path, {"sweep": {"file": str(SWEEP), "episodes": 1, "seed": 3},
                                  "trials": 2, "startup_trials": 1,
                                  "space": {"ik.posture_cost": {"log": [0.005, 0.05]}}})
    out = tmp_path / "out"
    assert main(["tune", str(path), "--workers", "2", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials"]["complete"] == 2 and summary["held_out"] is None
    cfg = load_config(out / "best.yaml")
    assert cfg.ik.posture_cost == pytest.approx(summary["best"]["params"]["ik.posture_cost"])
    from nextage_qp.manipulation.runner import Runner

    result = Runner(cfg, str(out / "best.yaml")).run()
    assert result["success"], result.get("error") or result.get("failed_criteria")


@pytest.mark.slow
def test_ray_backend_gives_the_same_trials_as_the_local_pool(tmp_path):
    pytest.importorskip("ray")
    path = write_study(tmp_path, steps_study(trials=2, held_out=None))
    values = {}
    for backend in ("local", "ray"):
        out = tmp_path / backend
        assert main(["tune", str(path), "--workers", "2", "--backend", backend, "--out", str(out)]) == 0
        summary = json.loads((out / "summary.json").read_text())
        values[backend] = [(h["number"], h["value"], h["params"]) for h in summary["history"]]
    assert values["ray"] == values["local"] and len(values["local"]) == 2


@pytest.mark.slow
def test_shipped_tuned_gains_meet_the_step_criteria_and_settle_sooner_than_the_defaults():
    import dataclasses

    from nextage_qp.tune.steps import run_step_task

    ev = Study(ROOT / "configs" / "studies" / "pd_gains.yaml").evaluator
    scores = {}
    for name in ("default", "tuned"):
        tasks = [dataclasses.replace(t, gains=load_gains(name)) for t in ev.tasks({})]
        scores[name] = ev.score([run_step_task(t) for t in tasks])
    default, tuned = scores["default"].details, scores["tuned"].details
    assert tuned["met"] == tuned["steps"] == 29  # every joint, both directions (HEAD_JOINT1 -45 deg out of range)
    assert all(r["final_error_rad"] <= 0.005 and r["overshoot_pct"] <= 5.0 for r in tuned["per_step"])
    assert tuned["mean_settling_time_s"] < 0.8 * default["mean_settling_time_s"]


@pytest.mark.slow
def test_cmaes_sampler_starts_from_the_base_and_stays_in_bounds(tmp_path):
    path = write_study(tmp_path, steps_study(sampler="cmaes", trials=5, startup_trials=1, held_out=None))
    out = tmp_path / "out"
    assert main(["tune", str(path), "--workers", "2", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["sampler"] == "cmaes" and summary["trials"]["complete"] == 5
    assert summary["history"][0]["params"] == {"joints.LARM_JOINT3.kp": 77.0, "joints.LARM_JOINT3.kd": 3.9}
    for h in summary["history"]:
        assert 40 <= h["params"]["joints.LARM_JOINT3.kp"] <= 200 and 2 <= h["params"]["joints.LARM_JOINT3.kd"] <= 8
