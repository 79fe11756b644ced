"""The phases that work a clamped object against a scripted view: carry, place, release, the clamp itself."""


import numpy as np
import pytest
from phase_support import DT, ScriptedView, grasp_view, held_grip, make, pose, run_until_done

from nextage_qp.errors import PhaseError
from nextage_qp.geometry import Pose, rot_z, yaw_of
from nextage_qp.ik import RelativeTarget
from nextage_qp.manipulation.clamp import MAX_ROLL, Clamp
from nextage_qp.manipulation.context import Grip


def test_carry_needs_a_grip_and_drives_both_pads_with_the_relative_target():
    view = grasp_view()
    view.bodies["dumbbell_target"] = pose(0.35, 0.38, 1.0, yaw=0.785398)
    phase = make("carry", object="dumbbell", speed=0.1, relative_cost=7.0,
                 waypoints=[{"relative_to": "dumbbell", "offset": [0, 0, 0.1]}])
    with pytest.raises(PhaseError, match=r"\(carry\): needs 'dumbbell' clamped"):
        phase.start(view)
    view.grip = held_grip()
    phase.start(view)
    cmd = phase.update(view)
    assert cmd.relative[0].cost == 7.0 and cmd.relative[0].frame == "left_pad"
    left, right = (t.pos for t in cmd.targets)
    assert left - right == pytest.approx([0.0, 0.144, 0.0])
    assert left[2] == pytest.approx(1.015 + 0.105 + 1.0 * DT**2)
    done = run_until_done(phase, view)
    assert done.targets[0].pos[2] == pytest.approx(1.015 + 0.105 + 0.1)


def place_view():
    view = grasp_view()
    view.grip, view.rest, view.obstacle = held_grip(), 1.015, 1.0
    view.bodies["dumbbell_target"] = pose(0.35, 0.38, 1.0, yaw=0.785398 + np.pi)  # equivalent to 45 deg (pi-symmetric)
    return view


def carried_by_the_clamp(view, phase, heights):
    """A kinematic object: it follows the place setpoint and stands on the table at its resting height."""

    def follow(_cmd):
        pos = np.array([*phase.sp.pos[:2], max(phase.sp.pos[2], view.rest)])
        view.bodies["dumbbell"] = Pose(pos, rot_z(phase.yaw))
        heights.append(pos[2])

    return follow


def test_place_lifts_over_the_obstacles_turns_to_the_nearest_equivalent_yaw_and_sets_down():
    view = place_view()
    phase = make("place", object="dumbbell", target="dumbbell_target", clearance=0.03)
    with pytest.raises(PhaseError, match=r"\(place\): needs 'dumbbell' clamped"):
        phase.start(ScriptedView(bodies=view.bodies))
    phase.start(view)
    carry = 1.0 + 0.03 + (1.015 - 0.875)  # obstacle top + clearance + the object's depth below its origin
    assert phase.info["carry_height_m"] == pytest.approx(carry)
    assert phase.info["place_yaw_rad"] == pytest.approx(0.785398, abs=1e-4)  # not 225 deg: the nearer equivalent yaw
    heights = []
    cmd = run_until_done(phase, view, each=carried_by_the_clamp(view, phase, heights))
    assert cmd.done and max(heights) == pytest.approx(carry)
    obj = view.bodies["dumbbell"]
    assert obj.pos[:2] == pytest.approx([0.35, 0.38]) and yaw_of(obj.rot) == pytest.approx(0.785398, abs=1e-4)
    assert obj.pos[2] <= 1.015 + 0.001  # set down: within 1 mm of its resting height
    left, right = (t.pos for t in cmd.targets)
    assert np.linalg.norm(left - right) == pytest.approx(0.144)  # the pads keep the grip's spread


def test_place_takes_a_lower_or_sideways_route_where_the_one_over_the_obstacles_is_blocked():
    view = place_view()
    carry = 1.0 + 0.03 + (1.015 - 0.875)
    ceiling = carry - 0.01  # something hangs over the route: any pad above this height touches it
    view.blocked = lambda plans: next((f"left_pad into ceiling at {t.pos[2]:.3f}" for targets in plans
                                       for t in targets if t.pos[2] > ceiling), None)
    phase = make("place", object="dumbbell", target="dumbbell_target", clearance=0.03)
    phase.start(view)
    assert phase.info["carry"] == "routed" and "ceiling" in phase.info["carry_blocked"]
    assert phase.info["carry_height_m"] < carry and phase.info["carry_routes_checked"] > 1
    heights = []
    cmd = run_until_done(phase, view, each=carried_by_the_clamp(view, phase, heights))
    assert cmd.done and max(heights) < ceiling  # the object went under it and was set down
    assert view.bodies["dumbbell"].pos[:2] == pytest.approx([0.35, 0.38])


def test_place_fails_naming_what_blocks_every_route():
    view = place_view()
    view.blocked = lambda plans: "right_forearm 4 mm into clutter_3" if len(plans) > 1 else None
    phase = make("place", object="dumbbell", target="dumbbell_target")
    with pytest.raises(PhaseError, match=r"no collision-free route to carry dumbbell to dumbbell_target: over the "
                                         r"obstacles, right_forearm 4 mm into clutter_3; \d+ lower and sideways"):
        phase.start(view)


def test_place_never_checks_its_route_with_plan_never():
    view = place_view()
    view.blocked = lambda plans: "anything"
    phase = make("place", object="dumbbell", target="dumbbell_target", plan="never")
    phase.start(view)
    assert "carry" not in phase.info


def test_clamp_ties_the_pads_by_their_relative_pose_at_the_close_drawn_in_by_the_squeeze():
    grip = held_grip()  # the pads held 144 mm apart when the clamp closed, though their targets were 144 mm too
    grip = Grip(grip.object, grip.frames, grip.offsets, grip.rotations,
                RelativeTarget("left_pad", "right_pad", np.array([0.0, 0.140, 0.001]), np.eye(3), 1.0))
    clamp = Clamp(grip, relative_cost=10.0)
    clamp.depth = [0.002, 0.001]
    targets, tie = clamp.pads(np.array([0.5, 0.0, 1.1]), 0.0)
    assert tie.pos == pytest.approx([0.0, 0.137, 0.001]) and tie.cost == 10.0  # what the arms held, not the targets
    assert targets[0].pos - targets[1].pos == pytest.approx([0.0, 0.141, 0.0])


def test_place_unchecked_slides_the_posture_from_the_default_to_the_hover_joints():
    view = place_view()
    phase = make("place", object="dumbbell", target="dumbbell_target", plan="never")
    phase.start(view)
    first = phase.update(view)
    assert first.posture == pytest.approx(view.default_posture(), abs=1e-6)  # no jump at the start of the lift
    view.t += 2.0
    assert phase.update(view).posture == pytest.approx(phase.posture)


def test_place_follows_the_joints_its_route_was_checked_with_from_where_the_arms_are():
    view = place_view()
    phase = make("place", object="dumbbell", target="dumbbell_target")
    phase.start(view)
    assert phase.info["carry"] == "over" and len(phase.postures) == len(phase.legs) > 3
    start = view.joint_positions(view.joint_names())
    postures = []
    carry = carried_by_the_clamp(view, phase, [])

    def each(cmd):
        carry(cmd)
        postures.append(cmd.posture)

    run_until_done(phase, view, each=each)
    steps = np.abs(np.diff(np.array([start, *postures])[:, 0]))
    assert steps.max() <= 0.3 * DT + 1e-9  # the joints turn no faster than POSTURE_RATE: no jump anywhere
    assert postures[len(phase.legs) // 2] is not None


def test_place_refuses_a_target_pose_the_clamp_cannot_reach():
    view = place_view()
    view.reach = lambda targets: False
    with pytest.raises(PhaseError, match="cannot reach dumbbell_target's pose with dumbbell at any of its 2"):
        make("place", object="dumbbell", target="dumbbell_target").start(view)


def test_release_opens_lifts_and_ends_the_grip():
    view = grasp_view()
    view.grip = held_grip()
    view.commanded = {"left_pad": pose(0.5, 0.072, 1.12), "right_pad": pose(0.5, -0.072, 1.12)}
    view.joints = {"plan": 3.0}  # the joints the release starts from
    phase = make("release", object="dumbbell", gap=0.05, lift=0.08)
    phase.start(view)
    assert phase.grip(view.grip) is None
    view.joints = {"plan": 4.0}  # the arms move on; the posture target stays where the release began
    postures = []
    last = run_until_done(phase, view, each=lambda cmd: postures.append(cmd.posture))
    assert last.targets[0].pos == pytest.approx([0.5, 0.122, 1.20])
    assert last.targets[1].pos == pytest.approx([0.5, -0.122, 1.20])
    assert postures and all(p is not None and list(p) == [3.0] for p in postures)


def test_release_opens_less_where_opening_fully_would_touch_clutter_beside_the_object():
    view = grasp_view()
    view.grip = held_grip()
    view.commanded = {"left_pad": pose(0.5, 0.072, 1.12), "right_pad": pose(0.5, -0.072, 1.12)}
    view.joints = {"plan": -1.0}
    wall = 0.072 + 0.04  # clutter 40 mm beside the left pad: a pad further out touches it
    view.blocked = lambda plans: next((f"left_pad into clutter_0 at y={t.pos[1]:.3f}" for targets in plans
                                       for t in targets if t.pos[1] > wall), None)
    phase = make("release", object="dumbbell", gap=0.05, lift=0.08)
    phase.start(view)
    last = run_until_done(phase, view)
    assert phase.info["opened_m"] == pytest.approx(0.03)  # 60 % of the gap: the widest that touches nothing
    assert last.targets[0].pos == pytest.approx([0.5, 0.102, 1.20])


def test_release_first_hands_the_weight_to_the_table():
    view = grasp_view()
    view.grip = held_grip()
    view.joints = {"plan": 0.0}
    view.commanded = {"left_pad": pose(0.5, 0.072, 1.12), "right_pad": pose(0.5, -0.072, 1.12)}
    view.forces = {"left_pad": [0.0, 0.0, -2.0], "right_pad": [0.0, 0.0, -2.0]}  # the pads hold it up
    phase = make("release", object="dumbbell", gap=0.05, lift=0.08, unload=0.006)
    phase.start(view)
    for _ in range(200):  # 0.8 s at 5 mm/s: down 4 mm, still carrying the weight
        cmd = phase.update(view)
    assert cmd.targets[0].pos[2] == pytest.approx(1.116, abs=2e-4) and cmd.targets[0].pos[1] == pytest.approx(0.072)
    view.forces = {}  # the table carries it now: open from here
    last = run_until_done(phase, view)
    assert last.targets[0].pos == pytest.approx([0.5, 0.122, 1.116 + 0.08], abs=2e-4)
    assert phase.info["unloaded_m"] == pytest.approx(0.004, abs=2e-4)


def test_place_fails_when_the_object_does_not_come_down():
    view = place_view()
    phase = make("place", object="dumbbell", target="dumbbell_target")
    phase.start(view)
    heights = []
    follow = carried_by_the_clamp(view, phase, heights)

    def stuck(cmd):  # something under the object holds it 40 mm up
        follow(cmd)
        obj = view.bodies["dumbbell"]
        view.bodies["dumbbell"] = Pose(np.array([*obj.pos[:2], max(obj.pos[2], 1.055)]), obj.rot)

    with pytest.raises(PhaseError, match=r"set-down stalled: dumbbell is still 40 mm over its resting height"):
        run_until_done(phase, view, each=stuck)


def test_levelling_rolls_both_pads_against_the_tilt_about_the_clamp_axis():
    class TiltedView:
        dt = 0.004

        def __init__(self, tilt):
            c, s = np.cos(tilt), np.sin(tilt)
            self.rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # about +y, the clamp axis

        def body_pose(self, name):
            return Pose(np.zeros(3), self.rot)

    clamp = Clamp(held_grip(), 1.0)
    clamp.level_gain = 2.0
    assert clamp.level(TiltedView(0.05), yaw=0.0) == pytest.approx(0.05)
    assert clamp.roll == pytest.approx(-2.0 * 0.05 * 0.004)  # rolls the other way
    clamp.roll = 0.0
    before, rel_before = clamp.pads(np.array([0.5, 0.0, 1.0]), 0.0)
    clamp.roll = -0.1
    after, rel_after = clamp.pads(np.array([0.5, 0.0, 1.0]), 0.0)
    for b, a in zip(before, after, strict=True):
        np.testing.assert_allclose(a.pos, b.pos)  # the pads stay where they are, on the roll's axis
        turned = b.rot.T @ a.rot
        assert np.degrees(np.arccos((np.trace(turned) - 1) / 2)) == pytest.approx(np.degrees(0.1))
        np.testing.assert_allclose(turned @ np.array([0, 1.0, 0]), [0, 1.0, 0], atol=1e-12)  # about the axis
    np.testing.assert_allclose(rel_after.pos, rel_before.pos)
    for _ in range(10_000):  # bounded, but far enough to follow a dumbbell creeping all through a long place phase
        clamp.level(TiltedView(0.5), yaw=0.0)
    assert clamp.roll == pytest.approx(-MAX_ROLL) and MAX_ROLL >= 0.6
