"""The grasp phase against a scripted view: approach, close to a force, off-centre grips, refusals."""


import numpy as np
import pytest
from phase_support import ScriptedView, grasp_view, make_grasp, pose, run_until_done, squeezed_by_the_pads

from nextage_qp.errors import InfeasibleError, PhaseError
from nextage_qp.geometry import Pose
from nextage_qp.ik import FrameTarget
from nextage_qp.manipulation.route import PlannedRoute


def test_grasp_goes_down_beside_the_object_closes_to_the_force_and_leaves_a_grip():
    view = grasp_view()
    view.half = 0.1  # the object's top is 0.1 m over its origin
    phase = make_grasp()
    phase.start(view)
    assert phase.grip(None) is None and phase.info["approach_gap_m"] == 0.04
    rise, high, above = (view.plans[i][0] for i in range(3))  # rolls left to the planner over the faces
    assert above.pos == pytest.approx([0.5, 0.124, 1.015 + 0.1 + 0.04]) and above.axis is not None
    assert high.pos == pytest.approx(above.pos + np.array([0.0, 0.0, 0.08]))
    assert rise.pos == pytest.approx([0.5, 0.25, high.pos[2]])  # first straight up from where the pad is
    assert view.plans[4][0].pos == pytest.approx([0.5, 0.124, 1.12])  # then straight down
    last = run_until_done(phase, view, each=squeezed_by_the_pads(view))
    left, right = (t.pos for t in last.targets)
    assert left[1] == pytest.approx(0.084 - 0.01, abs=2e-4) and right[1] == pytest.approx(-0.074, abs=2e-4)
    assert phase.info["squeeze_n"] == pytest.approx([10.0, 10.0], abs=0.3)
    grip = phase.grip(None)
    assert grip.object == "dumbbell" and grip.frames == ("left_pad", "right_pad") and grip.force == 10.0
    assert grip.offsets["left_pad"] == pytest.approx([0.0, 0.074, 0.105], abs=2e-4)
    assert grip.relative.frame == "left_pad" and grip.relative.root == "right_pad"


@pytest.mark.parametrize(("kg", "expected"), [(0.3, 10.0), (0.8, 2.5 * 9.81 * 0.8)])
def test_grasp_squeezes_at_least_force_per_weight_times_the_objects_weight(kg, expected):
    view = grasp_view()
    view.half, view.kg = 0.1, kg
    phase = make_grasp(force_per_weight=2.5)  # 0.3 kg: 7.4 N, below the 10 N floor; 0.8 kg: 19.6 N
    phase.start(view)
    assert phase.info["force_n"] == pytest.approx(expected, abs=0.01)
    run_until_done(phase, view, each=squeezed_by_the_pads(view))
    assert phase.info["squeeze_n"] == pytest.approx([expected, expected], abs=0.3)
    assert phase.grip(None).force == pytest.approx(expected)  # the clamp keeps squeezing at it, and judges a loss by it


def test_grasp_comes_in_closer_when_the_arms_cannot_spread_and_refuses_when_they_cannot_reach():
    view = grasp_view()
    view.reach = lambda targets: all(abs(t.pos[1]) < 0.084 + 0.6 * 0.04 - 1e-6 for t in targets)
    phase = make_grasp()
    phase.start(view)
    assert phase.info["approach_gap_m"] == pytest.approx(0.35 * 0.04)
    view.reach = lambda targets: False
    with pytest.raises(InfeasibleError, match=r"cannot reach both sides of dumbbell \(168 mm wide at the pads\) at any of its headings \(0, -180 deg\)"):
        make_grasp().start(view)  # before anything moved: a refusal (exit 2)
    view.t = 1.0
    with pytest.raises(PhaseError, match="cannot reach both sides"):
        make_grasp().start(view)  # after an earlier phase: the phase fails


def test_grasp_clamps_off_the_centre_of_the_faces_when_the_centre_is_out_of_reach():
    view = grasp_view()
    view.reach = lambda targets: all(t.pos[0] <= 0.49 for t in targets if t.pos[2] < 1.2)  # nothing past x = 0.49
    with pytest.raises(InfeasibleError, match="cannot reach both sides"):
        make_grasp().start(view)  # the centre only
    phase = make_grasp(off_centre=0.035)
    phase.start(view)
    assert phase.info["off_centre_m"] == pytest.approx(-0.0175)  # half way, towards the robot
    run_until_done(phase, view, each=squeezed_by_the_pads(view))
    assert phase.grip(None).offsets["left_pad"][0] == pytest.approx(-0.0175, abs=2e-4)


def test_grasp_takes_the_off_centre_grip_that_also_reaches_the_placement():
    view = grasp_view()
    view.bodies["target"] = pose(0.35, 0.38, 1.0)
    view.reach = lambda targets: all(t.pos[0] >= 0.38 for t in targets if t.pos[1] > 0.2)  # near the target: far x
    phase = make_grasp(off_centre=0.035, place_at="target")
    phase.start(view)
    assert phase.info["rolls_fit_placement"] and abs(phase.info["off_centre_m"]) == pytest.approx(0.035)
    assert phase.place_q is not None
    view.reach = lambda targets: all(t.pos[1] < 0.2 for t in targets)  # nothing near the target
    with pytest.raises(InfeasibleError, match=r"cannot reach target's pose .* out of the arms' reach"):
        make_grasp(off_centre=0.035, place_at="target").start(view)


def test_grasp_plans_no_approach_at_a_height_where_no_grip_reaches_the_placement():
    # Such an approach would be given up anyway: only the placement is asked, and the refusal names it.
    view = grasp_view()
    view.bodies["target"] = pose(0.35, 0.38, 1.0)
    asked = []
    view.reach = lambda targets: asked.append(targets) or all(t.pos[1] < 0.2 for t in targets)
    with pytest.raises(InfeasibleError, match=r"cannot reach target's pose .* out of the arms' reach"):
        make_grasp(off_centre=0.035, place_at="target").start(view)
    assert asked and all(t.pos[1] > 0.2 for targets in asked for t in targets)


def test_a_continuous_route_restarts_the_planner_for_its_first_waypoint_only():
    asked = []

    class Recording(ScriptedView):
        def plan(self, targets, start=None, allow=frozenset(), pos_tol=None, restarts=True):
            asked.append(restarts)
            return super().plan(targets, start, allow, pos_tol, restarts)

    legs = [(FrameTarget("left_pad", pos=np.array([0.5, 0.2, z])),) for z in (1.2, 1.1, 1.0)]
    assert PlannedRoute(legs, continuous=True).plan(Recording())
    assert asked == [True, False, False]
    asked.clear()
    assert PlannedRoute(legs).plan(Recording()) and asked == [True, True, True]
    asked.clear()
    assert PlannedRoute(legs, continuous=True).plan(Recording(), restarts=False) and asked == [False] * 3


def test_grasp_fails_when_the_pads_close_on_nothing():
    view = grasp_view()
    phase = make_grasp()
    phase.start(view)
    with pytest.raises(PhaseError, match=r"closed 20 mm inside dumbbell's surface without feeling 10 N"):
        run_until_done(phase, view)  # no force ever: the object is not there


def test_a_route_leg_is_reached_where_the_planned_joints_put_the_frame():
    """Near the edge of reach the planner stops a few millimetres short; the leg is done there, not never."""
    short = np.array([0.0, 0.0, -0.004])

    class Short(ScriptedView):
        def pose_at(self, frame, q):
            p = super().pose_at(frame, q)
            return Pose(p.pos + short, p.rot)

    view = Short(frames={"left_pad": pose(0.4, 0.2, 1.0)}, commanded={"left_pad": pose(0.4, 0.2, 1.0)})
    route = PlannedRoute([(FrameTarget("left_pad", pos=np.array([0.5, 0.2, 1.1])),)], pos_tol=0.006)
    assert route.plan(view)
    route.step(view)
    view.frames["left_pad"] = Pose(np.array([0.5, 0.2, 1.1]) + short, np.eye(3))  # the arm got where it was planned
    route.step(view)
    assert route.done


def test_grasp_fails_when_the_object_is_knocked_over_on_the_way_in():
    view = grasp_view()
    phase = make_grasp()
    phase.start(view)
    phase.update(view)
    view.bodies["dumbbell"] = Pose(view.bodies["dumbbell"].pos, np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]))
    with pytest.raises(PhaseError, match="knocked dumbbell over on the way in \\(tilted 90 deg"):
        phase.update(view)
