"""Runs under a ``faults:`` block: reproducible noise, estimation report, shoves, failing sensors, bad input."""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from nextage_qp.cli import main
from nextage_qp.errors import ConfigError
from nextage_qp.estimation.report import SHOVE_SETTLE_S
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner

ROOT = Path(__file__).resolve().parents[1]
PUSH = ROOT / "configs" / "push_cube.yaml"
CAMERA = {"rate_hz": 30, "latency_s": 0.02, "noise_pos_m": 0.002, "noise_rot_rad": 0.0175, "dropout": 0.1}
JOINTS = {"noise_rad": 0.0005, "noise_rad_s": 0.01}


def short_config(tmp_path: Path, faults: dict, seconds: float = 1.0, name: str = "faults.yaml") -> Path:
    """The push scene with one wait phase and the given faults."""
    doc = yaml.safe_load((ROOT / "configs" / "push_cube.yaml").read_text())
    doc["phases"] = [{"kind": "wait", "name": "wait", "duration": seconds}]
    doc["timing"] = {"settle": 0.0}
    doc["faults"] = faults
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc))
    return path


def run(path: Path, overrides=()) -> tuple[dict, Runner]:
    runner = Runner(load_config(path, list(overrides)), str(path))
    return runner.run(), runner


def test_a_run_with_faults_is_bit_identical_when_repeated(tmp_path):
    path = short_config(tmp_path, {"object_pose": CAMERA, "joint_sensors": JOINTS})
    (a, ra), (b, rb) = run(path), run(path)
    for key in ("estimation", "final_object_position", "object_error_m"):
        assert a[key] == b[key]
    for k, arr in ra.sim.recorder.arrays().items():
        np.testing.assert_array_equal(arr, rb.sim.recorder.arrays()[k], err_msg=k)
    c, _ = run(path, ["seed=7"])  # another seed, other noise
    assert c["estimation"] != a["estimation"]


def test_estimation_report_and_log(tmp_path):
    path = short_config(tmp_path, {"object_pose": CAMERA}, seconds=2.0)
    result, runner = run(path)
    cube = result["estimation"]["objects"]["cube"]
    assert result["estimation"]["object_filter"] == "kalman"
    assert cube["measurements"] == pytest.approx(2.0 * 30, abs=2) and 0 < cube["dropouts"] < cube["measurements"]
    assert cube["estimate_rms_m"] < 0.6 * cube["raw_rms_m"]  # a resting cube, convergence included
    arrays = runner.sim.recorder.arrays()
    assert arrays["extra_estimate_cube"].shape[1] == 6 and len(arrays["extra_measurement_cube"]) > 40
    raw, _ = run(path, ["estimation.object_filter=none"])
    assert raw["estimation"]["objects"]["cube"]["estimate_rms_m"] > cube["estimate_rms_m"]


def test_no_faults_block_changes_nothing(tmp_path):
    path = short_config(tmp_path, None)
    result, runner = run(path)
    assert result["estimation"] is None and result["shoves"] == []
    assert runner.sensors is None


def test_noisy_encoders_put_the_robot_frames_where_the_measured_joints_say(tmp_path):
    for faults, exact in (({"object_pose": CAMERA, "joint_sensors": JOINTS}, False), ({"object_pose": CAMERA}, True)):
        runner = Runner(load_config(short_config(tmp_path, faults, seconds=0.1), []), "faults.yaml")
        runner.run()
        d, site = runner.sim.data, runner.robot.model.site("left_tool").id
        gap = float(np.linalg.norm(runner.view.frame_pose("left_tool").pos - d.site_xpos[site]))
        assert runner.sensors.joints_exact is exact
        assert gap == 0.0 if exact else 0.0 < gap < 0.002  # 0.5 mrad per joint: a fraction of a millimetre


def test_a_shove_moves_the_object_and_is_reported(tmp_path):
    shove = {"body": "cube", "at_s": 0.2, "impulse_ns": [0.0, 0.15, 0.0]}
    path = short_config(tmp_path, {"object_pose": CAMERA, "shoves": [shove]})
    result, shoved = run(path)
    assert result["shoves"] == [{"body": "cube", "t_s": 0.2, "impulse_ns": [0.0, 0.15, 0.0], "phase": "wait"}]
    assert result["final_object_position"][1] > 0.005  # pushed along +y
    quiet, _ = run(short_config(tmp_path, {"object_pose": CAMERA}, name="quiet.yaml"))
    assert abs(quiet["final_object_position"][1]) < 1e-3
    # the estimate's error is also reported without the shove's force window and the SHOVE_SETTLE_S after it
    cube, calm = result["estimation"]["objects"]["cube"], quiet["estimation"]["objects"]["cube"]
    assert abs(cube["shove_ticks"] - (0.05 + SHOVE_SETTLE_S) / shoved.sim.ctrl_dt) <= 1 and calm["shove_ticks"] == 0
    assert cube["estimate_outside_shoves_rms_m"] < 0.5 * cube["estimate_rms_m"]  # the flung cube is the error
    assert calm["estimate_outside_shoves_rms_m"] == calm["estimate_rms_m"]


@pytest.mark.parametrize("mode, words", [("freeze", "the sensor froze"), ("nan", "not finite")])
def test_a_failed_force_sensor_fails_the_run_with_outputs_written(tmp_path, capsys, mode, words):
    path = short_config(tmp_path, {"wrench": {"noise_n": 0.05, "fail": {"site": "left_pad", "at_s": 0.3,
                                                                         "mode": mode}}})
    log = tmp_path / "out.npz"
    code = main(["run", str(path), "--json", "--log", str(log)])
    out = json.loads(capsys.readouterr().out)
    assert code == 1 and not out["success"]
    assert "force/torque sensor left_pad" in out["error"] and words in out["error"]
    assert log.exists() and json.loads(log.with_suffix(".json").read_text())["samples"] > 0


def test_perfect_sensors_never_look_frozen(tmp_path):
    result, _ = run(short_config(tmp_path, None, seconds=2.0))
    assert result["error"] is None


@pytest.mark.parametrize("faults, message", [
    ({"object_pose": {"rate": 30}}, "faults.object_pose.rate"),
    ({"object_pose": {"dropout": 1.5}}, "faults.object_pose.dropout"),
    ({"object_pose": {"noise_pos_m": float("nan")}}, "faults.object_pose.noise_pos_m"),
    ({"shoves": [{"body": "cube", "impulse_ns": [0, 0.1, 0]}]}, "exactly one of at_s"),
    ({"shoves": [{"body": "cube", "at_s": 1, "impulse_ns": [0, 100, 0]}]}, "over 10 N s"),
    ({"shoves": [{"body": "table", "at_s": 1, "impulse_ns": [0, 0.1, 0]}]}, "faults.shoves[0].body: 'table'"),
    ({"shoves": [{"body": "cube", "phase": "carry", "impulse_ns": [0, 0.1, 0]}]}, "'carry' is not a phase"),
    ({"wrench": {"fail": {"site": "left_tool", "at_s": 1}}}, "not a force/torque sensor; valid: left_pad, right_pad"),
])
def test_bad_faults_are_one_line_errors(tmp_path, faults, message):
    path = short_config(tmp_path, faults)
    with pytest.raises(ConfigError) as exc:
        Runner(load_config(path), str(path))
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_fault_sweep_files_apply_their_fixed_keys():
    from nextage_qp.sweep.spec import SweepSpec

    for name in ("push_cube_faults", "dock_dumbbell_faults"):
        spec = SweepSpec(ROOT / "configs" / "sweeps" / f"{name}.yaml")
        params, seed = spec.draw(0, 3)
        cfg = load_config(spec.base_path, spec.overrides(params, seed))
        assert cfg.faults is not None and cfg.faults.object_pose.rate_hz == 30
        assert cfg.faults.shoves[0].after_s == params["faults.shoves.0.after_s"]


class FakeView:
    """Just enough of a View for the force-sensing helpers: time, period and one wrench."""

    def __init__(self, force):
        from nextage_qp.sensing.sensors import Wrench

        self.t, self.dt, self._wrench = 0.0, 0.004, Wrench(np.asarray(force, float), np.zeros(3))

    def wrench(self, site):
        return self._wrench


def test_push_contact_onset_and_loss_from_the_wrist_force():
    from nextage_qp.manipulation.phases.push.contact import PushContact

    contact, view = PushContact("left_tool"), FakeView([-2.0, 0.0, 0.0])  # the cube pushes back along -x
    d = np.array([1.0, 0.0])
    felt = []
    for k in range(200):
        view.t = k * view.dt
        if k == 100:
            view._wrench = view._wrench._replace(force=np.zeros(3))  # the cube slipped off the tool
        felt.append(contact.update(view, d))
    assert not felt[0] and felt[60] and not felt[-1]
    assert contact.onsets == 1 and contact.losses == 1


def test_a_clamp_whose_pads_no_longer_feel_the_object_fails_the_phase():
    from nextage_qp.errors import PhaseError
    from nextage_qp.ik import RelativeTarget
    from nextage_qp.manipulation.clamp import Clamp
    from nextage_qp.manipulation.context import Grip

    tie = RelativeTarget("left_pad", "right_pad", np.zeros(3), np.eye(3))
    grip = Grip("dumbbell", ("left_pad", "right_pad"), {}, {}, tie, force=20.0)
    clamp = Clamp(grip, relative_cost=1.0)
    clamp.check_hold()  # felt starts at the grip force
    clamp.felt = [3.0, 1.0]
    with pytest.raises(PhaseError, match=r"the clamp lost dumbbell: the pads feel 3\.0 N and 1\.0 N of the 20 N"):
        clamp.check_hold()


def test_a_failed_run_from_estimated_poses_says_where_the_object_truly_ends():
    """The phases judge the poses the robot estimates: a failure from them also names the true planar error."""
    cfg = load_config(PUSH, [f"faults.object_pose={json.dumps(CAMERA)}", "phases[0].timeout=1"])
    result = Runner(cfg, str(PUSH)).run()
    assert not result["success"] and "timed out" in result["error"]
    true = f"it truly ends {result['object_error_xy_m'] * 1e3:.1f} mm from cube_target in the plane]"
    assert result["error"].endswith(f"[cube's pose as estimated (simulated perception); {true}")
    truth = Runner(load_config(PUSH, ["phases[0].timeout=1"]), str(PUSH)).run()
    assert "timed out" in truth["error"] and "truly" not in truth["error"]  # the truth needs no such note
