"""Every phase kind against a scripted view: no simulation, only the contract start(view) -> update(view) -> Command."""

from dataclasses import dataclass, field

import numpy as np
import pytest

from nextage_qp.errors import PhaseError
from nextage_qp.geometry import Pose, rot_z
from nextage_qp.ik import RelativeTarget
from nextage_qp.manipulation.context import Grip
from nextage_qp.manipulation.phases import REGISTRY, build

DT = 0.004


@dataclass
class ScriptedView:
    """A View whose every answer the test sets."""

    t: float = 0.0
    dt: float = DT
    grip: Grip | None = None
    bodies: dict = field(default_factory=dict)
    frames: dict = field(default_factory=dict)
    commanded: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    is_settled: bool = True
    tracking: float = 0.0
    half: float = 0.035

    def body_pose(self, name):
        return self.bodies[name]

    def frame_pose(self, name):
        return self.frames[name]

    def commanded_pose(self, name):
        return self.commanded[name]

    def joint_positions(self, names):
        return np.array([self.joints[n] for n in names])

    def settled(self):
        return self.is_settled

    def tracking_error(self):
        return self.tracking

    def extent(self, obj, direction):
        return self.half


def pose(x, y, z, yaw=0.0):
    return Pose(np.array([x, y, z], dtype=float), rot_z(yaw))


def make(kind, **fields):
    spec_type, _ = REGISTRY[kind]
    return build(spec_type.model_validate({"kind": kind, **fields}), kind)


def run_until_done(phase, view, ticks=20000, each=None):
    for _ in range(ticks):
        cmd = phase.update(view)
        view.t += DT
        if each:
            each(cmd)
        if cmd.done:
            return cmd
    raise AssertionError("phase never finished")


def test_registry_lists_every_kind():
    assert list(REGISTRY) == ["move", "push", "grasp", "carry", "release", "joints", "wait"]


def test_move_walks_at_its_speed_and_waits_for_the_real_frame():
    view = ScriptedView(commanded={"left_tool": pose(0.4, 0.2, 1.0)}, frames={"left_tool": pose(0.4, 0.2, 1.0)})
    phase = make("move", targets=[{"frame": "left_tool", "offset": [0.5, 0.2, 1.0]}], speed=0.1, tolerance=0.002)
    phase.start(view)
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


def test_push_lifts_goes_behind_lowers_and_pushes_to_the_finish_point():
    view = ScriptedView(bodies={"cube": pose(0.33, 0.0, 0.91), "cube_target": pose(0.70, 0.0, 0.91)},
                        commanded={"left_tool": pose(0.5, 0.23, 0.98)})
    phase = make("push", frame="left_tool", object="cube", target="cube_target", approach=0.04, clearance=0.07,
                 height=0.015, attempts=2, tolerance=0.002)
    phase.start(view)
    points = []
    for _ in range(5000):
        cmd = phase.update(view)
        view.t += DT
        points.append(cmd.targets[0].pos.copy())
        if phase.wait_from is not None:
            break
    points = np.array(points)
    top = 0.91 + 0.035 + 0.07
    assert points[:, 2].max() == pytest.approx(top)
    assert np.allclose(points[-1], [0.70 - 0.035, 0.0, 0.925])  # the face puts the cube centre on the target
    low = points[:, 2] < top - 1e-9
    assert np.all(points[low & (np.arange(len(points)) > 10), 0] >= 0.33 - 0.035 - 0.04 - 1e-9)
    assert np.allclose(cmd.targets[0].rot, np.eye(3))  # facing +x, the push direction
    # the cube did not move: after the check a second attempt is planned, then the phase gives up
    with pytest.raises(PhaseError, match=r"still 370\.0 mm from cube_target after 2 attempts"):
        run_until_done(phase, view)
    assert phase.info["attempts"] == 2


def test_push_ends_when_the_object_is_on_target():
    view = ScriptedView(bodies={"cube": pose(0.33, 0.0, 0.91), "cube_target": pose(0.70, 0.0, 0.91)},
                        commanded={"left_tool": pose(0.5, 0.23, 1.03)})
    phase = make("push", frame="left_tool", object="cube", target="cube_target", tolerance=0.002)
    phase.start(view)

    def follow(cmd):  # the cube sits in front of the tool face once the push leg starts
        if phase.leg == 3:
            view.bodies["cube"] = pose(cmd.targets[0].pos[0] + 0.035, 0.0, 0.91)

    cmd = run_until_done(phase, view, each=follow)
    assert phase.info["attempts"] == 1 and phase.info["object_error_xy_m"] < 0.002 and cmd.done


def grasp_view():
    return ScriptedView(bodies={"dumbbell": pose(0.5, 0.0, 1.015)},
                        commanded={"left_pad": pose(0.5, 0.25, 1.05), "right_pad": pose(0.5, -0.25, 1.05, yaw=0.0)})


def test_grasp_closes_past_the_surface_holds_and_leaves_a_grip():
    view = grasp_view()
    phase = make("grasp", object="dumbbell", half_width=0.084, height=0.105, gap=0.04, squeeze=0.012, hold=0.3)
    phase.start(view)
    assert phase.grip(None) is None
    first = phase.update(view)
    assert not first.done and len(first.targets) == 2
    last = run_until_done(phase, view)
    left, right = (t.pos for t in last.targets)
    assert left == pytest.approx([0.5, 0.084 - 0.012, 1.12]) and right == pytest.approx([0.5, -0.072, 1.12])
    grip = phase.grip(None)
    assert grip.object == "dumbbell" and grip.frames == ("left_pad", "right_pad")
    assert grip.offsets["left_pad"] == pytest.approx([0.0, 0.072, 0.105])
    assert grip.relative.frame == "left_pad" and grip.relative.root == "right_pad"


def held_grip():
    rel = RelativeTarget("left_pad", "right_pad", np.array([0.0, 0.144, 0.0]), np.eye(3), 1.0)
    return Grip("dumbbell", ("left_pad", "right_pad"),
                {"left_pad": np.array([0.0, 0.072, 0.105]), "right_pad": np.array([0.0, -0.072, 0.105])},
                {"left_pad": np.eye(3), "right_pad": np.eye(3)}, rel)


def test_carry_needs_a_grip_and_drives_both_pads_with_the_relative_target():
    view = grasp_view()
    view.bodies["dumbbell_target"] = pose(0.35, 0.38, 1.0, yaw=0.785398)
    phase = make("carry", object="dumbbell", speed=0.1, relative_cost=7.0,
                 waypoints=[{"relative_to": "dumbbell", "offset": [0, 0, 0.1]}])
    with pytest.raises(PhaseError, match="carry needs 'dumbbell' clamped"):
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


def test_release_opens_lifts_and_ends_the_grip():
    view = grasp_view()
    view.grip = held_grip()
    view.commanded = {"left_pad": pose(0.5, 0.072, 1.12), "right_pad": pose(0.5, -0.072, 1.12)}
    phase = make("release", object="dumbbell", gap=0.05, lift=0.08)
    phase.start(view)
    assert phase.grip(view.grip) is None
    last = run_until_done(phase, view)
    assert last.targets[0].pos == pytest.approx([0.5, 0.122, 1.20])
    assert last.targets[1].pos == pytest.approx([0.5, -0.122, 1.20])


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
