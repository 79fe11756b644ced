"""The registry and the simple phases against a scripted view: move, joints, wait, setpoints."""


import numpy as np
import pytest
from phase_support import DT, ScriptedView, make, pose

from nextage_qp.manipulation.phases import REGISTRY


def test_registry_lists_every_kind():
    assert list(REGISTRY) == ["move", "push", "grasp", "carry", "place", "release", "joints", "wait", "drive"]


def test_move_walks_at_its_speed_and_waits_for_the_real_frame():
    view = ScriptedView(commanded={"left_tool": pose(0.4, 0.2, 1.0)}, frames={"left_tool": pose(0.4, 0.2, 1.0)})
    phase = make("move", targets=[{"frame": "left_tool", "offset": [0.5, 0.2, 1.0]}], speed=0.1, tolerance=0.002)
    phase.start(view)
    assert view.reach_checked == [("left_tool", (0.5, 0.2, 1.0))]  # its goal checked against the arm's reach first
    cmd = phase.update(view)
    (target,) = cmd.targets
    assert np.linalg.norm(target.pos - [0.4, 0.2, 1.0]) == pytest.approx(1.0 * DT**2)  # from rest at 1 m/s^2
    assert not cmd.done
    for _ in range(300):
        cmd = phase.update(view)
    assert np.allclose(cmd.targets[0].pos, [0.5, 0.2, 1.0]) and not cmd.done  # the real frame is still behind
    view.frames["left_tool"] = pose(0.4995, 0.2, 1.0)
    view.is_settled = False
    assert not phase.update(view).done
    view.is_settled = True
    assert phase.update(view).done


def test_joints_sends_its_goal_until_reached_and_settled():
    view = ScriptedView(joints={"LARM_JOINT0": 0.0})
    phase = make("joints", positions={"LARM_JOINT0": 0.5}, tolerance=0.01)
    phase.start(view)
    cmd = phase.update(view)
    assert dict(cmd.joints) == {"LARM_JOINT0": 0.5} and not cmd.targets and not cmd.done
    view.joints["LARM_JOINT0"] = 0.495
    view.is_settled = False
    assert not phase.update(view).done
    view.is_settled, view.tracking = True, 0.02  # another joint still lags its command
    assert not phase.update(view).done
    view.tracking = 0.005
    assert phase.update(view).done


def test_wait_holds_for_its_duration():
    view = ScriptedView(t=1.0)
    phase = make("wait", duration=0.1)
    phase.start(view)
    cmd = phase.update(view)
    assert cmd.holds and not cmd.done
    view.t = 1.1
    assert phase.update(view).done


def test_setpoint_ramps_up_cruises_and_stops_on_the_goal():
    from nextage_qp.manipulation.context import Setpoint

    sp, goal, speeds = Setpoint(np.zeros(3), accel=1.0), np.array([0.1, 0.0, 0.0]), []
    while not sp.advance(goal, 0.1, DT):
        speeds.append(sp.speed)
    assert np.array_equal(sp.pos, goal) and sp.speed == 0.0
    steps = np.diff([0.0, *speeds])
    assert max(speeds) == pytest.approx(0.1) and np.all(np.abs(steps) <= 1.0 * DT + 1e-12)
    assert len(speeds) * DT == pytest.approx(0.1 / 0.1 + 0.1 / 1.0, abs=0.02)  # cruise time + one ramp
