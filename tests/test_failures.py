"""Failures that say why: a stall names the contact that holds it, a limit violation the joint, a timeout its phase."""

from pathlib import Path

import numpy as np
import pytest

from nextage_qp.loop.diagnosis import at_limits, limit_violation, saturated, what_holds
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.metrics import judge, unmet_criteria
from nextage_qp.manipulation.runner import Runner

ROOT = Path(__file__).resolve().parents[1]
PUSH = ROOT / "configs" / "push_cube.yaml"

PRESS = """
task: press_on_table
scene: {file: push_cube}
object: cube
target: cube_target
start: home
phases:
  - kind: move
    name: press the hand into the table
    targets: [{frame: left_tool, offset: [0.40, 0.15, 0.80]}]
    speed: 0.2
    timeout: 2.0
"""


def test_a_stall_against_a_contact_names_the_bodies_in_touch_and_the_force(tmp_path):
    path = tmp_path / "press.yaml"
    path.write_text(PRESS)  # the tool 11 cm below the table top: no IK pair keeps the hand off it
    result = Runner(load_config(path), str(path)).run()
    assert not result.success and result.failed_phase == "press the hand into the table"
    assert "timed out after 2 s" in result.error
    clause = result.error.split("in contact: ")[1]
    first = clause.split(",")[0]  # the strongest contact: a link of the left arm pressing on the table
    assert first.startswith("LARM_") and "-table " in first and first.endswith(" N"), result.error
    assert float(first.rsplit(" ", 2)[1]) > 10.0


def test_a_timeout_names_its_phase_and_the_phase_s_last_state():
    result = Runner(load_config(PUSH, ["phases[0].timeout=1"]), str(PUSH)).run()
    assert result.failed_phase == "push cube to target" and not result.success
    assert result.error.startswith("phase 'push cube to target' (push) timed out after 1 s of simulated time")
    assert "last state: " in result.error and "attempts=1" in result.error
    assert result.failed_criteria == ["completed", "object_error"]
    assert "object_error " in result.unmet_criteria() and " > 0.005" in result.unmet_criteria()


def test_a_limit_violation_names_the_joint_by_how_much_and_when():
    names = ("J0", "J1", "J2")
    lower, upper = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    t = np.arange(5) * 0.02
    q = np.zeros((5, 3))
    q[2:4, 1] = [1.004, 1.0123]  # J1 past its upper limit at t=0.04 s and, worse, at 0.06 s
    q[3, 2] = -1.002
    text = limit_violation(names, t, q, lower, upper, tolerance=1e-3)
    assert text == "J1 12.3 mrad past its upper limit (worst at t=0.060 s, first past at t=0.040 s, 2 ticks)"
    assert limit_violation(names, t, np.zeros((5, 3)), lower, upper, tolerance=1e-3) is None
    record = {"failed_criteria": ["joint_limits"],
              "criteria": {"joint_limits": {"value": 2, "limit": 0, "ok": False, "detail": text}}}
    assert unmet_criteria(record) == f"criteria not met: joint_limits 2 > 0 ({text})"


def test_judge_carries_the_limit_detail_only_when_a_limit_was_violated():
    from nextage_qp.manipulation.config import SuccessCriteria
    from nextage_qp.manipulation.metrics import ObjectState

    state = ObjectState(np.zeros(3), np.zeros(3), 0.001, 0.001, 0.0, 0.0, True)
    ok = judge(SuccessCriteria(planar_error=0.005), state, completed=True, dropped=False, limit_violations=0,
               obstacle_contacts=0)
    assert "detail" not in ok["joint_limits"]
    bad = judge(SuccessCriteria(planar_error=0.005), state, completed=True, dropped=False, limit_violations=3,
                obstacle_contacts=0, limit_detail="J1 2.0 mrad past its upper limit")
    assert bad["joint_limits"]["detail"].startswith("J1")


def test_saturated_joints_and_joints_at_a_limit_are_named():
    assert saturated(("A", "B", "C"), np.array([90, 5, 30]), 100) == [("A", 0.9), ("C", 0.3)]
    assert saturated(("A",), np.array([0]), 0) == []
    limits = at_limits(("A", "B", "C"), np.array([0.995, 0.0, -1.0]), -np.ones(3), np.ones(3))
    assert limits == [("A", "upper"), ("C", "lower")]
    text = what_holds([("L5", "table", 173.0), ("L4", "cube", 0.2)], [("A", 0.9)], [("C", "lower")])
    assert text == "in contact: L5-table 173 N; torque saturated: A 90 % of the phase; at a limit: C (lower)"
    assert what_holds([], [], []) == ""


def test_a_phase_without_a_timeout_times_out_after_its_budget_and_says_so(tmp_path):
    """The stalled move has no timeout: it gets twice its budget (the line at its speed, then a rest), and the
    message says where the figure came from and which key sets it."""
    path = tmp_path / "press.yaml"
    path.write_text(PRESS.replace("    timeout: 2.0\n", "").replace("speed: 0.2", "speed: 0.02"))
    result = Runner(load_config(path), str(path)).run()
    record = result.phases[0]
    budget = record["budget_s"]
    assert 16.0 < budget < 19.0  # the hand's line of 0.33 m at 0.02 m/s, then 1 s to come to rest
    assert record["timeout_s"] == pytest.approx(2 * budget, abs=0.1)
    assert f"timed out after {record['timeout_s']:.1f} s of simulated time (unset: 2 x its budget of {budget:.1f} s, " \
           "at least 10 s; phases[0].timeout sets it)" in result.error
