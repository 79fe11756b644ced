import json

import numpy as np
import pytest

from nextage_qp.cli import main
from nextage_qp.experiments.step_response import run_step, step_metrics
from nextage_qp.loop.pd import load_gains

JOINTS = ["CHEST_JOINT0", *(f"LARM_JOINT{i}" for i in range(6))]


@pytest.mark.parametrize("joint", JOINTS)
def test_default_gains_45_degree_step(robot, joint):
    """Acceptance: a 45-degree step ends within 0.005 rad with at most 5 % overshoot."""
    gains = load_gains("default")
    target = float(robot.keyframe_q()[robot.joint_index(joint)] + np.deg2rad(45.0))
    m, _ = run_step(robot, joint, target, gains, duration=1.5)
    assert m.final_error_rad < 0.005
    assert m.overshoot_pct <= 5.0
    assert m.settling_time_s is not None and m.settling_time_s < 1.0
    assert m.max_abs_torque_nm <= robot.torque_limit[robot.joint_index(joint)]


def test_report_gains_pass_the_report_criterion_on_the_chest(robot):
    m, _ = run_step(robot, "CHEST_JOINT0", np.deg2rad(45.0), load_gains("report"), duration=3.0)
    assert m.final_error_rad < 0.035


def test_step_metrics_on_a_known_curve():
    t = np.linspace(0.0, 2.0, 2001)
    q = 1.0 - np.exp(-t / 0.1)  # first-order step: rise 0.1 * ln(9), 2 % settling 0.1 * ln(50)
    m = step_metrics(t, q, np.zeros_like(t), 0.0, 1.0, 10.0)
    assert m.overshoot_pct == 0.0
    assert m.rise_time_s == pytest.approx(0.1 * np.log(9), abs=2e-3)
    assert m.settling_time_s == pytest.approx(0.1 * np.log(50), abs=2e-3)


def test_cli_json_and_plot(tmp_path, capsys):
    png = tmp_path / "step.png"
    code = main(["step-response", "--joint", "LARM_JOINT3", "--target-deg", "30", "--duration", "0.6",
                 "--json", "--plot", str(png)])
    assert code == 0 and png.stat().st_size > 10_000
    out = json.loads(capsys.readouterr().out)
    for key in ("final_error_rad", "overshoot_pct", "rise_time_s", "settling_time_s", "max_abs_torque_nm"):
        assert key in out
    assert out["final_error_rad"] < 0.005


def test_cli_rejects_out_of_range_target(capsys):
    assert main(["step-response", "--joint", "LARM_JOINT2", "--target-deg", "120"]) == 2
    err = capsys.readouterr().err
    assert "outside LARM_JOINT2's range" in err and len(err.strip().splitlines()) == 1


def test_step_into_the_pedestal_names_the_contact(capsys):
    import json

    from nextage_qp.cli import main

    assert main(["step-response", "--joint", "LARM_JOINT1", "--target-deg", "45", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["settling_time_s"] is None and "pedestal" in out["blocked_by_contact"]
    assert main(["step-response", "--joint", "LARM_JOINT2", "--target-deg", "45", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["blocked_by_contact"] is None
