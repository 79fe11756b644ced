"""The sweep instrument: validation, seeding, backends, failures kept, resume, replay, summary."""

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from nextage_qp.cli import main
from nextage_qp.errors import ConfigError
from nextage_qp.sweep.episode import Episode
from nextage_qp.sweep.keys import yaml_scalar
from nextage_qp.sweep.run import plan, replay_commands, run_sweep
from nextage_qp.sweep.spec import SweepSpec
from nextage_qp.sweep.store import SweepStore
from nextage_qp.sweep.summary import by_target_clearance, estimation, summarize, wilson, write_summary

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "tests" / "data" / "quick_push.yaml"
PUSH_BASE = ROOT / "configs" / "push_cube.yaml"


def write_sweep(tmp_path, randomize, **top):
    doc = {"base": str(PUSH_BASE), "randomize": randomize, **top}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


# --- sweep files -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["push_cube", "dock_dumbbell"])
def test_bundled_sweeps_cover_the_envelope(name):
    spec = SweepSpec(ROOT / "configs" / "sweeps" / f"{name}.yaml")
    obj, tgt = ("cube", "cube_target") if name == "push_cube" else ("dumbbell", "dumbbell_target")
    d = spec.distributions
    for body in (obj, tgt):
        lo, hi = (np.asarray(b) for b in d[f"scene.poses.{body}.pos"].offset)
        assert np.allclose(lo[:2], -0.05) and np.allclose(hi[:2], 0.05) and lo[2] == hi[2] == 0.0
    assert d[f"scene.poses.{obj}.yaw"].offset == pytest.approx((-math.pi / 6, math.pi / 6), abs=1e-6)
    assert d[f"scene.friction_scale.{obj}"].uniform == (0.5, 2.0)
    assert d[f"scene.masses.{obj}"].uniform == ((0.05, 0.30) if name == "push_cube" else (0.15, 0.90))
    if name == "dock_dumbbell":
        assert d[f"scene.poses.{tgt}.yaw"].offset == pytest.approx((-math.pi / 6, math.pi / 6), abs=1e-6)
        assert spec.base_values[f"scene.poses.{tgt}.yaw"] == pytest.approx(math.pi / 4, abs=1e-6)


def test_draws_depend_on_seed_and_index_only():
    spec = SweepSpec(QUICK)
    a = [spec.draw(7, i) for i in range(5)]
    b = [spec.draw(7, i) for i in reversed(range(5))][::-1]
    assert a == b
    assert spec.draw(7, 0) != spec.draw(8, 0)
    assert len({json.dumps(p) for p, _ in a}) == 5
    params, _ = a[0]
    base = spec.base_values["scene.poses.cube.pos"]
    assert all(abs(params["scene.poses.cube.pos"][k] - base[k]) <= 0.02 for k in range(2))
    assert params["scene.poses.cube.pos"][2] == base[2]
    assert 0.8 <= params["scene.friction_scale.cube"] <= 1.25
    assert params["phases.0.attempts"] in (1, 2)


@pytest.mark.parametrize("value", [0.1, 1e-05, -3.2e-07, 1e20, 0.33333333333333331, 12.0, -0.0])
def test_yaml_scalar_reads_back_bit_exact(value):
    assert yaml.safe_load(yaml_scalar(value)) == value
    assert yaml.safe_load(yaml_scalar([value, 1.0])) == [value, 1.0]


@pytest.mark.parametrize("value", [0.1, 1e-05, 1e20, "default", "1e5", "yes", "on", "a,b", [1.0, "no"]])
def test_yaml_scalar_reads_back_through_the_override_loader(value):
    from nextage_qp.io.yaml_file import load_yaml

    assert load_yaml(yaml_scalar(value)) == value  # what --set and the sweep's overrides are parsed with


@pytest.mark.parametrize(
    "randomize,top,message",
    [
        ({"ik.position_costt": {"uniform": [0, 1]}}, {}, "randomize.ik.position_costt: 'ik.position_costt' is not a key"),
        ({"scene.masses.cube": {"uniform": [0.3, 0.1]}}, {}, "randomize.scene.masses.cube: lo > hi"),
        ({"scene.masses.cube": {"uniform": [0.1, float("nan")]}}, {}, "randomize.scene.masses.cube"),
        ({"scene.masses.cube": {"uniform": [0.1, float("inf")]}}, {}, "finite number"),
        ({"scene.masses.cube": {"uniform": [0.1, 0.2], "scale": [1, 2]}}, {}, "exactly one of uniform, offset"),
        ({"scene.masses.cube": {"unifrom": [0.1, 0.2]}}, {}, "unknown key; valid: choice, offset, scale, uniform"),
        ({"scene.masses.cube": {"uniform": [-0.1, 0.2]}}, {}, "value -0.1"),
        ({"scene.poses.cube.pos": {"offset": [[-0.05, 0], [0.05, 0]]}}, {}, "bounds have 2 component(s)"),
        ({"scene.poses.cube.pos": {"offset": [[-0.05, 0, 0], [0.05, 0]]}}, {}, "same length"),
        ({"phases.0.name": {"offset": [0, 1]}}, {}, "offset needs a numeric base value"),
        ({"phases.3.speed": {"uniform": [0.1, 0.2]}}, {}, "list has 1 item(s)"),
        ({"scene.poses.cubee.pos": {"uniform": [[0, 0, 1], [0, 0, 1]]}}, {}, "unknown scene body (object, target or obstacle) 'cubee'"),
        ({"seed": {"uniform": [0, 1]}}, {}, "randomize.seed: the sweep sets each episode's run seed"),
        ({"gains": {"choice": ["default", "nope"]}}, {}, "gains"),
        ({}, {}, "randomize: Dictionary should have at least 1 item"),
        ({"scene.masses.cube": {"uniform": [0.1, 0.2]}}, {"randomise": {}}, "randomise: unknown key; valid: base"),
        ({"scene.masses.cube": {"uniform": [0.1, 0.2]}}, {"wall_limit": float("inf")}, "wall_limit"),
        ({"scene.masses.cube": {"uniform": [0.1, 0.2]}}, {"base": "missing.yaml"}, "base: 'missing.yaml' is not a file"),
    ],
)
def test_bad_sweep_files_give_one_line_and_exit_2(tmp_path, capsys, randomize, top, message):
    path = write_sweep(tmp_path, randomize, **top)
    with pytest.raises(ConfigError, match=None) as info:
        SweepSpec(path)
    assert message in str(info.value) and str(path) in str(info.value)
    assert main(["sweep", str(path), "--n", "1", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


@pytest.mark.parametrize("text,message", [("[1, 2]", "expected a mapping"), ("base: [", "not valid YAML")])
def test_sweep_file_that_is_not_a_mapping(tmp_path, capsys, text, message):
    path = tmp_path / "s.yaml"
    path.write_text(text)
    assert main(["sweep", str(path), "--n", "1"]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize(
    "args,message",
    [
        (["--n", "0"], "--n must be between 1"),
        ([], "--n is required"),
        (["--n", "2", "--seed", "-1"], "--seed: expected an integer in [0, 4294967295], got '-1'"),
        (["--only", "x,1"], "--only 'x,1': expected episode indices"),
        (["--n", "2", "--workers", "0"], "--workers must be between 1"),
        (["--n", "2", "--ray-address", "1.2.3.4:6379"], "--ray-address needs --backend ray"),
        (["--n", "2", "--plot", "pyproject.toml/p.png"], "is a file, not a folder"),
        (["--n", "2", "--plot", "p.txt"], "expected a file ending in .png or .pdf or .svg"),
        (["--n", "2", "--set", "timing.ctrl_dtt=0.01"], "--set: "),
        (["--n", "2", "--set", "timing.ctrl_dt=0.0015"], "--set: "),
        (["--n", "2", "--set", "timing.settle=0.1"], "the sweep randomises timing.settle"),
    ],
)
def test_bad_sweep_arguments(capsys, args, message):
    assert main(["sweep", str(QUICK), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


def test_out_dir_with_episodes_needs_resume(tmp_path, capsys):
    spec = SweepSpec(QUICK)
    store = SweepStore(tmp_path, spec, 0, resume=False)
    store.add(Episode(0, 1, {}, [], "failed"))
    store.close()
    assert main(["sweep", str(QUICK), "--n", "2", "--out", str(tmp_path)]) == 2
    assert "pass --resume" in capsys.readouterr().err
    assert main(["sweep", str(QUICK), "--n", "2", "--seed", "5", "--out", str(tmp_path), "--resume"]) == 2
    assert "another seed" in capsys.readouterr().err


def test_set_applies_to_every_episode_its_replays_and_its_resume(tmp_path, capsys):
    spec = SweepSpec(QUICK, ["timing.ctrl_dt=0.008"])
    assert spec.base.timing.ctrl_dt == 0.008
    tasks = plan(spec, 0, [0, 1])
    assert all("timing.ctrl_dt=0.008" in t.overrides for t in tasks)
    episode = Episode(1, tasks[1].seed, dict(tasks[1].params), list(tasks[1].overrides), "failed")
    replay = replay_commands(spec, 0, episode)
    assert "--only 1 --set timing.ctrl_dt=0.008" in replay["sweep"] and "timing.ctrl_dt=0.008" in replay["run"]
    store = SweepStore(tmp_path, spec, 0, resume=False)
    store.add(episode)
    store.close()
    assert main(["sweep", str(QUICK), "--n", "2", "--out", str(tmp_path), "--resume"]) == 2  # without the --set
    assert "another fingerprint" in capsys.readouterr().err


# --- statistics --------------------------------------------------------------------------------------------------


def test_success_is_split_by_target_clearance():
    def ep(i, status, clearance):
        result = None if status == "refused" else {"target_clearance_m": clearance}
        return Episode(i, i, {}, [], status, result=result)

    eps = [ep(0, "success", 0.03), ep(1, "failed", 0.012), ep(2, "success", 0.004), ep(3, "failed", 0.002),
           ep(4, "failed", 0.001), ep(5, "refused", None)]
    clear, tight = by_target_clearance(eps)
    assert (clear["episodes"], clear["successes"], tight["episodes"], tight["successes"]) == (2, 1, 3, 1)
    assert tight["success_rate_ci95"] == pytest.approx(list(wilson(1, 3)))
    assert by_target_clearance([ep(0, "success", None)]) == []  # no obstacle in the scene: no split


def test_estimation_errors_pool_over_episodes_with_and_without_the_shoves():
    def ep(i, est, outside, raw, ticks):
        cube = {"estimate_rms_m": est, "estimate_outside_shoves_rms_m": outside, "raw_rms_m": raw,
                "held_rms_m": 2 * raw, "dropouts": 1, "measurements": 10, "shove_ticks": ticks}
        return Episode(i, i, {}, [], "success", result={"estimation": {"objects": {"cube": cube}},
                                                         "shoves": [{"body": "cube"}] if ticks else []})

    est = estimation([ep(0, 0.003, 0.001, 0.004, 5), ep(1, 0.001, 0.001, 0.002, 0)])
    assert est["estimate_rms_m"] == pytest.approx(np.sqrt((0.003**2 + 0.001**2) / 2))
    assert est["estimate_outside_shoves_rms_m"] == pytest.approx(0.001)
    assert est["estimate_outside_shoves_over_raw"] == pytest.approx(0.001 / np.sqrt((0.004**2 + 0.002**2) / 2))
    assert est["estimate_over_held"] == pytest.approx(est["estimate_over_raw"] / 2)
    assert (est["shove_ticks"], est["shoves"], est["episodes"]) == (5, 1, 2)
    assert estimation([Episode(0, 0, {}, [], "success", result={"estimation": None})]) is None


def test_a_robot_cameras_detections_pool_over_the_episodes_unoccluded_frames():
    def ep(i, clear, ok, rms):
        cube = {"estimate_rms_m": 0.004, "estimate_unoccluded_rms_m": rms, "raw_rms_m": 0.002, "held_rms_m": 0.003,
                "dropouts": 1, "measurements": 10}
        camera = {"objects": {"cube": {"unoccluded": clear, "unoccluded_ok": ok}}}
        return Episode(i, i, {}, [], "success", result={"estimation": {"objects": {"cube": cube}, "camera": camera}})

    refused = Episode(2, 2, {}, [], "refused", result={"error": "out of reach"})  # ran nothing: no estimation
    est = estimation([ep(0, 100, 90, 0.002), refused, ep(1, 300, 294, 0.001)])
    assert est["episodes"] == 2 and (est["camera_unoccluded"], est["camera_unoccluded_ok"]) == (400, 384)
    assert est["camera_detected_of_unoccluded"] == pytest.approx(0.96)
    assert est["estimate_unoccluded_rms_m"] == pytest.approx(np.sqrt((0.002**2 + 0.001**2) / 2))
    simulated = {"estimate_rms_m": 0.001, "raw_rms_m": 0.001, "held_rms_m": 0.001, "dropouts": 0, "measurements": 1}
    plain = estimation([Episode(0, 0, {}, [], "success", result={"estimation": {"objects": {"cube": simulated}}})])
    assert "camera_unoccluded" not in plain and plain["estimate_unoccluded_rms_m"] is None  # no robot camera


def test_wilson_interval_known_values():
    lo, hi = wilson(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.2775, abs=1e-4)
    lo, hi = wilson(198, 200)
    assert lo == pytest.approx(0.9643, abs=1e-4) and hi == pytest.approx(0.9973, abs=1e-4)
    lo, hi = wilson(50, 100)
    assert (lo, hi) == pytest.approx((0.4038, 0.5962), abs=1e-4)


def test_summary_groups_failures_and_bins_parameters():
    spec = SweepSpec(QUICK)
    episodes = []
    for i, (params, seed) in enumerate(spec.draw(0, i) for i in range(8)):
        ok = i % 2 == 0
        result = {"object_error_m": 0.001 * (i + 1), "object_error_xy_m": 0.001 * (i + 1),
                  "criteria": {"object_error": {"value": 0.001 * (i + 1), "limit": 0.01, "ok": ok}}}
        status = ["success", "failed", "success", "error", "success", "failed", "success", "refused"][i]
        episodes.append(Episode(i, seed, params, spec.overrides(params, seed), status, failed_phase="push" if status == "failed" else None,
                                failed_criteria=[] if ok else ["object_error"], result=None if i == 3 else result))
    s = summarize(spec, 0, episodes, session_episodes=8, session_wall_s=60.0)
    assert s["counts"] == {"success": 4, "failed": 2, "refused": 1, "error": 1, "lost": 0}
    assert s["ran"] == 7 and s["success_rate"] == pytest.approx(4 / 7)
    assert s["failures_by_phase"] == {"push": 2, "(episode error)": 1}
    assert s["failures_by_criterion"]["object_error"] == 3
    assert s["object_error_m"]["max"] == pytest.approx(0.007)
    assert s["episodes_per_minute"] == pytest.approx(8.0)
    friction = [r for r in s["by_parameter"] if r["parameter"] == "scene.friction_scale.cube"]
    assert len(friction) == 4 and sum(r["episodes"] for r in friction) == 7
    assert {r["index"] for r in s["failed"]} == {1, 3, 5, 7}
    replay = s["failed"][0]["replay"]
    assert "--only 1" in replay["sweep"] and "--set seed=" in replay["run"]


# --- running -----------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def six_local(tmp_path_factory):
    """The quick sweep's six episodes with one worker (the reference for the other backends)."""
    spec = SweepSpec(QUICK)
    return spec, run_sweep(plan(spec, 3, range(6)), store=None, workers=1)


@pytest.mark.slow
def test_two_workers_give_bit_identical_episodes(six_local):
    spec, ref = six_local
    two = run_sweep(plan(spec, 3, range(6)), store=None, workers=2)
    assert [e.comparable() for e in two] == [e.comparable() for e in ref]
    assert len({e.worker for e in two}) == 2
    assert all(e.status in ("success", "failed") for e in ref)


@pytest.mark.slow
def test_ray_backend_gives_bit_identical_episodes(six_local):
    pytest.importorskip("ray")
    spec, ref = six_local
    ray_eps = run_sweep(plan(spec, 3, range(6)), store=None, workers=2, backend="ray")
    assert [e.comparable() for e in ray_eps] == [e.comparable() for e in ref]


@pytest.mark.slow
def test_replay_command_reproduces_the_episode(six_local, capsys):
    spec, ref = six_local
    episode = ref[4]
    cmd = replay_commands(spec, 3, episode)["run"]
    import shlex

    argv = shlex.split(cmd)[1:]
    code = main([*argv, "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == (0 if episode.status == "success" else 1)
    assert abs(out["object_error_m"] - episode.result["object_error_m"]) <= 1e-9


@pytest.mark.slow
def test_failures_are_recorded_and_the_sweep_goes_on(tmp_path):
    from sweep_helpers import faulty_episode

    spec = SweepSpec(QUICK)
    store = SweepStore(tmp_path, spec, 0, resume=False)
    tasks = plan(spec, 0, range(5))
    tasks[2] = dataclasses.replace(tasks[2], wall_limit=1.0)  # the hanging one: killed 1 + 2 s after it starts
    episodes = run_sweep(tasks, store=store, workers=2, episode_fn=faulty_episode, grace=2.0)
    store.close()
    by = {e.index: e for e in episodes}
    assert sorted(by) == [0, 1, 2, 3, 4]
    assert by[1].status == "error" and "RuntimeError: boom in episode 1" in by[1].reason
    assert by[2].status == "error" and "killed" in by[2].reason and "wall-time limit" in by[2].reason
    assert by[3].status == "lost" and "worker process died (exit code 3)" in by[3].reason
    assert by[3].attempts == 2  # a dead worker is the machine's failure: run once more, here dead again
    assert by[0].result is not None and by[4].result is not None
    lines = (tmp_path / "episodes.jsonl").read_text().splitlines()
    assert sorted({json.loads(ln)["index"] for ln in lines}) == [0, 1, 2, 3, 4]
    summary = summarize(spec, 0, episodes, session_episodes=5, session_wall_s=1.0)
    assert summary["counts"]["lost"] == 1 and summary["ran"] == 4 and summary["retried"] == 1


@pytest.mark.slow
def test_a_worker_killed_mid_episode_is_run_again_and_the_sweep_ends_with_every_episode_run(tmp_path, monkeypatch):
    from sweep_helpers import killed_once_episode

    monkeypatch.setenv("NQ_KILL_MARKS", str(tmp_path))
    spec = SweepSpec(QUICK)
    store = SweepStore(tmp_path / "out", spec, 0, resume=False)
    episodes = run_sweep(plan(spec, 0, range(3)), store=store, workers=2, episode_fn=killed_once_episode)
    store.close()
    assert (tmp_path / "1.killed").exists()  # its first attempt was killed
    assert [e.index for e in episodes] == [0, 1, 2]
    assert all(e.status in ("success", "failed") for e in episodes), [(e.status, e.reason) for e in episodes]
    assert episodes[1].attempts == 2 and episodes[0].attempts == 1


def test_resume_runs_a_lost_episode_again(tmp_path):
    from sweep_helpers import instant_success

    from nextage_qp.sweep.episode import failed_episode

    spec = SweepSpec(QUICK)
    tasks = plan(spec, 0, range(2))
    store = SweepStore(tmp_path, spec, 0, resume=False)
    store.add(failed_episode(tasks[0], "worker process died (exit code -9)", 0.0, lost=True))
    store.close()
    store = SweepStore(tmp_path, spec, 0, resume=True)
    assert 0 not in store.done and 0 in store.lost
    episodes = run_sweep(tasks, store=store, workers=1, episode_fn=instant_success)
    store.close()
    assert [(e.index, e.status) for e in episodes] == [(0, "success"), (1, "success")]
    assert episodes[0].attempts == 2 and episodes[1].attempts == 1


@pytest.mark.slow
def test_episode_past_its_wall_limit_fails_with_its_reason(tmp_path):
    path = tmp_path / "slow.yaml"
    doc = yaml.safe_load(QUICK.read_text())
    doc["base"] = str(PUSH_BASE)
    doc["wall_limit"] = 0.3
    path.write_text(yaml.safe_dump(doc))
    spec = SweepSpec(path)
    (episode,) = run_sweep(plan(spec, 0, [0]), store=None, workers=1)
    assert episode.status == "error"
    assert "wall-time limit of 0.3 s" in episode.reason
    assert episode.failed_phase == "push cube to target" and episode.result is not None


def test_resume_keeps_the_records_and_reruns_lines_that_are_not_records(tmp_path):
    """A damaged episodes.jsonl (bytes that are not UTF-8, a cut multi-byte character at the end, JSON that is not an
    episode) is no traceback: its good records are kept, the rest run again."""
    spec = SweepSpec(QUICK)
    store = SweepStore(tmp_path, spec, 0, resume=False)
    store.add(Episode(0, 1, {}, [], "failed"))
    store.add(Episode(2, 1, {}, [], "success"))
    store.close()
    with (tmp_path / "episodes.jsonl").open("ab") as f:
        f.write(b"\xff\xfe not text\n[1, 2]\n{\"index\": 5}\n{\"index\": 3, \"note\": \"\xc3")
    resumed = SweepStore(tmp_path, spec, 0, resume=True)
    resumed.close()
    assert sorted(resumed.done) == [0, 2]
    assert (tmp_path / "episodes.jsonl").read_bytes().endswith(b"{\"index\": 5}\n")  # the cut line is gone


@pytest.mark.slow
def test_resume_runs_only_the_missing_episodes(tmp_path, six_local):
    spec, ref = six_local
    store = SweepStore(tmp_path, spec, 3, resume=False)
    for e in ref[:3]:
        store.add(e)
    store.close()
    with (tmp_path / "episodes.jsonl").open("a") as f:  # an interrupted write of episode 3
        f.write(json.dumps(ref[3].to_json())[:40])
    ran = []
    resumed = SweepStore(tmp_path, spec, 3, resume=True)
    assert sorted(resumed.done) == [0, 1, 2]
    episodes = run_sweep(plan(spec, 3, range(6)), store=resumed, workers=2, on_episode=lambda e: ran.append(e.index))
    resumed.close()
    assert sorted(ran) == [3, 4, 5]
    assert [e.comparable() for e in episodes] == [e.comparable() for e in ref]
    assert len((tmp_path / "episodes.jsonl").read_text().splitlines()) == 6


@pytest.mark.slow
def test_sweep_cli_writes_summary_plot_and_replays(tmp_path, capsys):
    out, png = tmp_path / "out", tmp_path / "s.png"
    assert main(["sweep", str(QUICK), "--n", "3", "--seed", "1", "--workers", "2", "--out", str(out),
                 "--json", "--plot", str(png)]) == 0
    summary = json.loads(capsys.readouterr().out)  # --json: the summary on standard output, as run --json prints
    assert summary["episodes"] == 3 and summary == json.loads((out / "summary.json").read_text())
    assert main(["sweep", str(QUICK), "--n", "3", "--seed", "1", "--out", str(out), "--resume"]) == 0
    assert "95 % CI" in capsys.readouterr().out  # without --json: the table
    assert summary["success_rate_ci95"][0] <= (summary["success_rate"] or 0) <= summary["success_rate_ci95"][1]
    assert png.stat().st_size > 20_000
    assert (out / "summary.json").is_file()
    assert main(["sweep", str(QUICK), "--seed", "1", "--only", "2"]) == 0
    assert "episode 2:" in capsys.readouterr().out


def test_a_drawn_choice_is_named_by_what_is_not_drawn():
    from nextage_qp.sweep.nested import choice_label

    assert choice_label({"shape": "prism", "sides": 6, "size": [0.031, 0.035]}) == "shape=prism sides=6"
    assert choice_label({"shape": "box", "size": [0.02, 0.04, 0.035]}) == "shape=box"
    assert choice_label("kalman") == "kalman" and choice_label(0.5) == "0.5"
    assert choice_label([0.1, 0.2]) == "[...]"


def test_summary_is_written_beside_the_records(tmp_path):
    """The CLI and the Python API keep the same summary.json in the records' folder."""
    spec = SweepSpec(QUICK)
    episodes = [Episode(t.index, t.seed, t.params, list(t.overrides), "error", reason="boom")
                for t in plan(spec, 0, range(3))]
    summary = write_summary(tmp_path, spec, 0, episodes, session_episodes=3, session_wall_s=1.0)
    assert summary["out"] == str(tmp_path) and summary["counts"]["error"] == 3
    assert json.loads((tmp_path / "summary.json").read_text()) == json.loads(json.dumps(summary))
