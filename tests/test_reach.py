import json

import numpy as np
import pytest

pytest.importorskip("nextage_qp.ik")

from nextage_qp.cli import main
from nextage_qp.experiments.reach import run_reach
from nextage_qp.loop.pd import load_gains
from nextage_qp.loop.reference import TrajectoryLimits

TARGETS = [(0.45, 0.25, 1.05), (0.40, 0.15, 1.00), (0.50, 0.30, 1.10), (0.35, 0.20, 0.98), (0.55, 0.10, 1.05)]
LIMITS = TrajectoryLimits(max_velocity=0.8, max_acceleration=3.0, max_jerk=30.0)


@pytest.mark.slow
@pytest.mark.parametrize("pos", TARGETS)
def test_reach_within_2mm_with_limited_references(robot, pos):
    res, sim = run_reach(robot, "left_wrist", np.array(pos), gains=load_gains("default"), limits=LIMITS, duration=2.5)
    assert res.final_error_m < 2e-3
    assert res.time_to_1mm_s is not None
    a = sim.recorder.arrays()
    v, acc, jerk = LIMITS.arrays(robot.joint_names)
    dt = sim.ctrl_dt  # one log row per control tick
    np.testing.assert_allclose(np.diff(a["t"]), dt)
    qdd = np.diff(a["qd_ref"], axis=0) / dt  # mean acceleration over each tick
    jrk = np.diff(a["qd_ref"], n=2, axis=0) / dt**2  # mean jerk over each two-tick window
    assert np.all(np.abs(a["qd_ref"]) <= v + 1e-9)
    assert np.all(np.abs(qdd) <= acc + 1e-6)
    assert np.all(np.abs(jrk) <= jerk * (1 + 1e-6) + 1e-6)
    assert np.all(np.abs(a["tau"]) <= robot.torque_limit + 1e-9)
    assert np.all(a["q_ref"] >= robot.lower - 1e-9) and np.all(a["q_ref"] <= robot.upper + 1e-9)


def test_reach_cli_json_and_plot(tmp_path, capsys):
    png = tmp_path / "reach.png"
    code = main(["reach", "--frame", "left_wrist", "--pos", "0.45", "0.25", "1.05", "--duration", "1.5",
                 "--json", "--plot", str(png)])
    assert code == 0 and png.stat().st_size > 10_000
    out = json.loads(capsys.readouterr().out)
    assert out["final_error_m"] < 2e-3 and out["time_to_1mm_s"] is not None and out["max_abs_torque_nm"] > 0


def test_reach_cli_rejects_axis_without_direction(capsys):
    assert main(["reach", "--pos", "0.4", "0.2", "1.0", "--axis", "0", "0", "1"]) == 2
    assert "--axis and --direction go together" in capsys.readouterr().err


def test_reach_cli_unknown_frame(capsys):
    assert main(["reach", "--frame", "left_hnd", "--pos", "0.4", "0.2", "1.0"]) == 2
    assert "unknown frame 'left_hnd'" in capsys.readouterr().err
