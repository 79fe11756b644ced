r"""``push``: closed-loop pushing of an object onto a target with one tool frame.

A small state machine, every step driven by the live object pose:

* **transit**: lift to ``clearance`` over the object, then through planned joints to ``approach`` behind its
  face, for the reachable direction nearest the line to the target (:mod:`.approach`).
* **push**: the tool closes the gap slowly, then advances at a speed that falls from ``push_speed`` to ``creep_speed``
  over the last ``slow_down``, never more than ``preload`` into the face, at a fixed height. Once in contact the
  direction :math:`\hat d` turns (at most ``turn_rate``) towards the object's bearing to the target plus an integral
  bias that makes the object's own motion point at the target; inside ``freeze`` it is kept. A tilting object gets
  no push until it is flat. The first push stops ``standoff`` short.
* **hold**: the object comes to rest and the error is judged: within ``tolerance`` the tool retreats and the phase
  is done; short on the same line, the push resumes (up to ``nudges``); otherwise the tool retreats and approaches
  again along the error (within ``correction_fan``), up to ``attempts`` approaches. When nothing is left to try,
  an error within ``accept`` ends the phase, a larger one fails it.

While the wrist feels the push (or the tool is ``PRESS_M`` past the object's estimated face), the object's estimate
moves with the tool (:meth:`Push.carrier`). A camera's view may be hidden by the hand (``View.unseen_s``): with no
measurement younger than ``HIDDEN_S``, the object is where the contact puts it (its face on the tool), and a hold the
camera cannot see, or a knock on the last approach, backs off and judges once the object is in sight (``LOOK_S``).

After the push stops, the object comes to rest against the tool and the push is judged: within ``tolerance`` the
tool retreats and the phase is done; short on the same line it pushes again (``nudges``); otherwise it retreats and
approaches again along the error, up to ``attempts`` approaches, and with nothing left to try an error within
``accept`` ends the phase, a larger one fails it. A push the camera could not see (the hand hid the object) is judged
after backing off, once the object is in sight again (the tool first moves towards the robot's side, ``ASIDE``, which
folds the arm out of the camera's line of sight, through a planned joint leg, or to where the default posture holds
it when clutter stands there; still hidden after ``LOOK_S``, it moves on as far again, up to ``LOOK_AGAIN`` times,
and then judges on the estimate it has). A stop to look uses no attempt when the camera then sees the object; one
that never sees it does. With ``look_to_judge`` every push is judged so, never
with the hand beside the object (a push judged short is then approached again rather than nudged).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from enum import Enum

import numpy as np

from nextage_qp.errors import NextageQPError, PhaseError
from nextage_qp.geometry import Pose, angle2, clamp, rot_of, rot_z, rotate2, turn2, unit2, yaw_of
from nextage_qp.ik import FrameTarget
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import Poses, RunState, Setpoint, View
from nextage_qp.manipulation.phases.base import SETTLE_S, Phase
from nextage_qp.manipulation.phases.push.approach import plan_approach, plan_handover
from nextage_qp.manipulation.phases.push.contact import PushContact
from nextage_qp.manipulation.phases.push.spec import (
    ASIDE,
    BLIND_S,
    GAP_TIME,
    HEIGHT_GAIN,
    HIDDEN_S,
    LOOK_AGAIN,
    LOOK_S,
    LOST_GAP,
    MAX_BIAS,
    MAX_HEIGHT_BIAS,
    MIN_STEER_SPEED,
    PRESS_M,
    PUSH_ACCEL,
    SEEN_S,
    STEER_GAIN,
    STUCK_M,
    STUCK_S,
    TIPPING_SHARE,
    VELOCITY_WINDOW,
    PushSpec,
)
from nextage_qp.manipulation.route import PlanMode, PlannedRoute

_X = np.array([1.0, 0.0, 0.0])


class Stage(str, Enum):
    """The push's stages (a ``str`` enum: each compares equal to its name)."""

    TRANSIT = "transit"
    """Lift over the object, then planned joints to the approach behind its face."""
    PUSH = "push"
    """Close the gap, then advance along the steered direction."""
    HOLD = "hold"
    """The object comes to rest against the tool; then the push is judged."""
    RETREAT = "retreat"
    """Back off (and aside, to look); then end, judge what was seen, or approach again."""


class Verdict(Enum):
    """What a judged push leads to (:func:`judge`)."""

    DONE = "done"
    """Within ``tolerance``: retreat and end the phase."""
    NUDGE = "nudge"
    """Short on the same line: push again from where the tool is."""
    CORRECT = "correct"
    """Retreat and approach again along the error."""
    GIVE_UP = "give_up"
    """Nothing left to try: accept the error within ``accept``, else fail."""


def judge(error: np.ndarray, d: np.ndarray, spec: PushSpec, nudges: int, approaches: int) -> Verdict:
    """Judge a push that came to rest.

    ``error`` is the object's planar error [m] (target minus object) after pushing along the unit direction ``d``,
    with ``nudges`` made on this approach and ``approaches`` made in all. Within ``tolerance``: done. Short along
    ``d`` and within ``tolerance`` across it: a nudge, while ``nudges`` last. Otherwise another approach along the
    error while ``attempts`` last, and nothing left to try after that.
    """
    if float(np.linalg.norm(error)) <= spec.tolerance:
        return Verdict.DONE
    short = float(error @ d) > 0 and abs(float(error @ np.array([-d[1], d[0]]))) <= spec.tolerance
    if short and nudges < spec.nudges:
        return Verdict.NUDGE
    return Verdict.CORRECT if approaches < spec.attempts else Verdict.GIVE_UP


def worth_correcting(error: np.ndarray, d: np.ndarray, tolerance: float, accept: float) -> bool:
    """Whether a correction along the unit direction ``d`` may be pushed, for the planar error ``error`` [m].

    It may when the error is beyond ``accept`` (nothing to lose), or when a push along ``d``, even a perfect one, could
    bring it within ``tolerance``: a perfect push removes the error's component along ``d`` and leaves the rest,
    ``err * sin`` of the angle between ``d`` and where the object should go (all of it when ``d`` points away). Where
    the reachable side deviates so far that this rest exceeds the tolerance, the push could only trade an accepted
    error for a gamble: a push across the object's face at an angle shoves it sideways too.
    """
    err = float(np.linalg.norm(error))
    if err > accept or err <= tolerance:
        return True
    e = error / err
    rest = err * abs(float(e[0] * d[1] - e[1] * d[0])) if float(e @ d) > 0 else err
    return rest <= tolerance


def push_time(distance: float, spec: PushSpec) -> float:
    """Time [s] to push ``distance`` [m] at the push's speeds: ``push_speed`` (reached at ``PUSH_ACCEL``), falling in
    proportion to the distance left over the last ``slow_down`` to ``creep_speed``, which covers the rest.
    """  # noqa: D205
    c = spec
    creep_from = c.slow_down * c.creep_speed / c.push_speed  # where the falling speed meets creep_speed
    near = min(distance, c.slow_down)
    slowing = (c.slow_down / c.push_speed) * np.log(near / creep_from) if near > creep_from else 0.0
    return (max(0.0, distance - c.slow_down) / c.push_speed + c.push_speed / PUSH_ACCEL + slowing
            + min(near, creep_from) / c.creep_speed)


class Push(Phase):
    """See the module docstring. Its state is declared here; only its own methods write it."""

    spec: PushSpec
    stage: Stage
    frame: str  # the tool pushing now: a correction may hand over to one of spec.other_frames
    sp: Setpoint  # the pushing tool's position setpoint [m]
    tool_yaw: float  # the tool's commanded yaw [rad]
    goal_yaw: float  # the yaw the tool turns to, at spec.turn_rate [rad]
    contact: PushContact  # the wrist's force/torque sensor's view of the contact
    # approaches
    approaches: int  # approaches made (a knock within spec.recoveries and a look do not count)
    recoveries: int  # knocks recovered from
    nudges: int  # nudges on this approach
    full: bool  # the next approach may use the whole fan, not only spec.correction_fan
    plan_failed: bool  # the last approach found no reachable direction
    blocked: str | None  # why the last route the arm reached had no collision-free leg, when no approach was found
    planned_at: np.ndarray  # the object's planar position the approach was planned for [m]
    raised: float  # the first approach's raise over the push height, which later ones keep [m]
    d: np.ndarray  # the planar unit push direction
    lift: np.ndarray  # the transit's first waypoint, straight over the tool [m]
    planned: PlannedRoute  # the transit's planned route
    push_z: float  # the push height [m]
    lifting: bool  # the transit still lifts
    next_d: np.ndarray  # the direction the next approach aims at
    # pushing
    v: float  # the tool's speed along d [m/s]
    touched: bool  # the tool has touched the object (geometry or the wrist)
    pressed: bool  # the tool is PRESS_M past the object's estimated face
    bias: float  # the integral steering bias [rad]
    z_bias: float  # the push height's integral correction [m]
    blind_m: float  # how far the tool pushed unseen [m]
    blind_stop: bool  # the push stopped to look, not to be judged
    slanted: bool  # the first push's approach deviates more than correction_fan from its line: it stops `square` out
    square_stop: bool  # the push stopped to approach again square behind the object, not to be judged
    last_obj: np.ndarray | None  # the object's last planar position [m]
    obj_v: np.ndarray  # low-pass planar velocity of the object [m/s]
    hold_from: float  # when the hold began [s]
    nearest: float  # the object's least distance to the target in this push [m]
    nearest_at: float | None  # when it last came STUCK_M nearer [s]
    # retreat
    route: list[np.ndarray | PlannedRoute]  # the retreat's legs: the tool's waypoints [m] and planned joint legs
    aside_from: np.ndarray  # where the next move aside starts [m]
    leg: int  # the next waypoint's index
    final: bool  # the retreat ends the phase
    back_at: float  # when the retreat reached its last waypoint [s]
    looking: bool  # backing off to judge from a look
    seen_from: float | None  # since when the camera has seen the object, looking after a hidden push [s]
    asides: int  # moves aside made to look again, the object still hidden

    def start(self, view: View) -> None:  # noqa: D102
        self.frame = self.spec.frame  # the tool pushing now: a correction may hand over to one of other_frames
        pos, rot = view.commanded_pose(self.frame)
        self.sp = Setpoint(pos)
        self.tool_yaw = yaw_of(rot)
        self.approaches, self.recoveries, self.full, self.contact = 0, 0, False, PushContact(self.frame)
        self.info.update(attempts=0, nudges=0, contact_onsets=0, contact_losses=0)
        self.raised, self.looking, self.pressed = 0.0, False, False
        self.blind_stop = self.square_stop = False  # (a knock seen on the first approach looks before any push)
        obj, tgt, _ = self._planar(view)
        self._approach(view, unit2((tgt - obj)[:2]))
        if self.plan_failed:
            raise self._no_approach(view)

    def budget(self, view: View) -> float:
        """The first approach's transit and push, every further approach (``attempts``) as a retreat over the object,
        an approach behind it and a push of ``accept``, and a stop to look every ``blind`` of the way (a camera the
        hand hides), each at the spec's speeds. Nudges and recoveries from a knock are left to the margin.
        """  # noqa: D205
        c = self.spec
        obj, _, travel = self._planar(view)
        tool = view.commanded_pose(self.frame).pos
        along = 2 * view.extent(c.object, np.array([*self.d, 0.0]))  # the object's depth along the push
        tall = view.extent(c.object, np.array([0.0, 0.0, 1.0])) - (self.push_z - obj[2])  # its top over the tool
        touch = c.approach / c.push_speed + 4 * GAP_TIME  # closing the gap slowly
        rest = c.settle + SETTLE_S
        first = (float(np.linalg.norm(self.lift - tool)) + self.planned.length(self.lift)) / c.speed \
            + touch + push_time(travel, c) + rest
        again = (2 * (max(0.0, tall) + c.clearance) + along + 2 * c.approach) / c.speed + touch \
            + push_time(c.accept, c) + rest
        looks = np.ceil(travel / c.blind) * (LOOK_S + SEEN_S + 2 * ASIDE / c.speed)
        return first + (c.attempts - 1) * again + looks

    def stalled(self, view: View) -> str | None:  # noqa: D102
        tilted_s = self.info.get("tilt_pauses", 0) * view.dt  # ticks the push paused for a tipping object
        if tilted_s < TIPPING_SHARE * self.timeout:
            return None
        tilt = np.degrees(self.spec.max_tilt)
        return (f"{self.spec.object} tipped under the tool for {tilted_s:.0f} s of it (tilted over {tilt:.0f} deg, the "
                "push paused): the tool meets it too high to slide it on this table")

    def _planar(self, view: View) -> tuple[np.ndarray, np.ndarray, float]:
        obj, tgt = self._felt(view, view.body_pose(self.spec.object).pos), view.body_pose(self.spec.target).pos
        return obj, tgt, float(np.linalg.norm((tgt - obj)[:2]))

    def _felt(self, view: View, obj: np.ndarray) -> np.ndarray:
        """The object's position: ``obj`` as estimated, or where the contact puts it.

        While the wrist feels the push (or the tool is ``PRESS_M`` past the estimated face) and no camera has measured
        it for ``HIDDEN_S``, its face is on the tool along the push.
        """
        c = self.spec
        pushing = self.contact.in_contact or self.pressed
        if not (pushing and view.unseen_s(c.object) > HIDDEN_S) or self.stage not in (Stage.PUSH, Stage.HOLD):
            return obj  # (no contact yet when start() asks, before there is a stage)
        d = np.array([*self.d, 0.0])
        tool = view.frame_pose(self.frame).pos
        return obj + (float((tool - obj) @ d) + view.extent(c.object, -d)) * d  # the face the tool is on

    def _approach(self, view: View, d_goal: np.ndarray, full: bool = False) -> None:
        """Plan the next approach: the direction closest to ``d_goal`` with a route the arm can reach.

        The first approach (and ``full``) may deviate by the whole ``fan``, a correction by ``correction_fan``.
        """
        c = self.spec
        self.approaches += 1
        self.nudges = 0
        fan = c.fan if self.approaches == 1 or full else tuple(a for a in c.fan if a <= c.correction_fan)
        higher: bool | float = True if self.approaches == 1 else self.raised  # later ones at the first one's height
        blocked: list[str] = []
        plan = plan_approach(view, c, self.sp.pos, d_goal, fan, self._target, higher=higher, blocked=blocked)
        self.blocked = blocked[-1] if blocked and plan is None else None
        if self.approaches > 1 and c.other_frames:  # a correction: the tool that reaches nearest the error pushes
            handover = plan_handover(view, c, self.frame, d_goal, fan, self._target, higher, plan)
            if handover is not None:
                self.frame, plan = handover
                self.contact.retarget(self.frame)
                self._on_tool(view)
                self.info["handovers"] = self.info.get("handovers", 0) + 1
        self.planned_at = view.body_pose(c.object).pos[:2].copy()
        tried = plan.tried if plan else sum(1 + (a != 0) for a in fan)
        self.info.update(attempts=self.approaches, directions_tried=tried)
        self.plan_failed = plan is None
        if plan is None:
            return
        self.d, self.lift, self.goal_yaw, self.planned, self.push_z = plan[:5]
        if self.approaches == 1:
            self.raised = plan.raised
            far = self._planar(view)[2] > 2 * c.square  # nearer, a slanted push would stop almost where it starts
            square = c.square > 0 and far and not self.info.get("squared")  # once: the square approach is not slanted
            self.slanted = square and abs(angle2(self.d, d_goal)) > c.correction_fan + 1e-6
        self.info["direction"] = self.d.round(4).tolist()
        self.stage, self.lifting = Stage.TRANSIT, True

    def _square_reachable(self, view: View, obj: np.ndarray, tgt: np.ndarray) -> bool:
        """Whether a tool reaches an approach within ``correction_fan`` of the object's line to the target from here.

        Asked once, where a slanted first push would stop ``square`` short: stopped where no square approach is in
        reach, the object would be left short with only slanted sides to push it from.
        """
        c = self.spec
        wanted = unit2((tgt - obj)[:2])
        fan = tuple(a for a in c.fan if a <= c.correction_fan)
        for frame in (self.frame, *c.other_frames):
            target = functools.partial(self._target, frame=frame)
            tool = view.commanded_pose(frame).pos
            if plan_approach(view, c, tool, wanted, fan, target, higher=self.raised) is not None:
                return True
        self.info["square_unreachable"] = 1
        return False

    def _command(self, allow: bool, done: bool = False) -> Command:
        target = self._target(self.sp.pos.copy(), self.tool_yaw)
        return Command((target,), allow=frozenset({self.spec.object}) if allow else frozenset(), done=done)

    def _target(self, pos: np.ndarray, yaw: float, frame: str | None = None) -> FrameTarget:
        """A tool (default: the one pushing) at ``pos`` pushing at ``yaw``: its rotation or face normal (``orient``)."""
        rot, frame = rot_z(yaw) @ self._pitch, frame or self.frame
        if self.spec.orient == "normal":  # only the face's normal (the frame's x axis) is held; roll about it free
            return FrameTarget(frame, pos=pos, axis=_X, direction=rot[:, 0].copy())
        return FrameTarget(frame, pos=pos, rot=rot)

    @functools.cached_property
    def _pitch(self) -> np.ndarray:
        return rot_of(np.array([0.0, self.spec.pitch or 0.0, 0.0]))  # about the tool's y axis

    def _turn_tool(self, view: RunState) -> None:  # towards the goal at the turn rate
        step = self.spec.turn_rate * view.dt
        self.tool_yaw += clamp(float(np.angle(np.exp(1j * (self.goal_yaw - self.tool_yaw)))), -step, step)

    def update(self, view: View) -> Command:  # noqa: D102
        step = {Stage.TRANSIT: self._transit, Stage.PUSH: self._push, Stage.HOLD: self._hold,
                Stage.RETREAT: self._retreat}[self.stage]
        return step(view)

    def carrier(self, view: View) -> tuple[str, Callable[[], Pose]] | None:
        """While the push is felt (or pressed), the object and the tool's advance along it, which its estimate takes."""
        felt = self.contact.in_contact or self.pressed if self.contact.available else self.touched  # else geometry
        carrier = self.contact.carrier(view, self.d if self.stage in (Stage.PUSH, Stage.HOLD) and felt else None)
        return (self.spec.object, carrier) if carrier is not None else None

    def _transit(self, view: View) -> Command:
        """Lift straight up, then move through the planned joints of the route (the wrist turns once lifted)."""
        c = self.spec
        obj, tgt, _ = self._planar(view)
        moved = float(np.linalg.norm(obj[:2] - self.planned_at)) > LOST_GAP
        if moved and self.recoveries < c.recoveries:  # knocked away during the transit: plan for where it is now
            self._knocked_away()
            self._on_tool(view)
            self.next_d = unit2((tgt - obj)[:2])  # what a look's next approach aims at
            self._approach(view, self.next_d, full=True)  # none reachable: judge from a look (a smeared view?)
            return self._command(allow=False) if not self.plan_failed else self._look(view)
        if self.lifting:
            self.lifting = not self.sp.advance(self.lift, c.speed, view.dt)
            return self._command(allow=False)
        command = self.planned.step(view)
        if self.planned.done:
            self._on_tool(view)
            self.z_bias = 0.0
            self._begin_push(touched=False)
        return command

    def _on_tool(self, view: Poses) -> None:
        """Put the setpoint and the tool's yaw where the pushing tool is commanded now."""
        pos, rot = view.commanded_pose(self.frame)
        self.sp.jump(pos)
        self.tool_yaw = yaw_of(rot)

    def _knocked_away(self) -> None:
        """Count a knock; while the recovery budget lasts, the next approach does not use up a precision attempt."""
        self.info["knocked_away"] = self.info.get("knocked_away", 0) + 1
        if self.recoveries < self.spec.recoveries:
            self.recoveries, self.approaches = self.recoveries + 1, self.approaches - 1

    def _begin_push(self, touched: bool) -> None:
        self.stage, self.v, self.touched, self.bias, self.pressed = Stage.PUSH, 0.0, touched, 0.0, False
        self.blind_m, self.blind_stop = 0.0, False  # how far the tool pushed unseen [m]; whether it stopped to look
        self.square_stop = False  # whether it stopped to approach again square behind the object
        self.contact.restart()  # the last push's contact is stale: _felt reads it before this push's first reading
        self.last_obj: np.ndarray | None = None
        self.obj_v = np.zeros(2)
        self.nearest, self.nearest_at = np.inf, None

    def _track(self, view: RunState, obj: np.ndarray) -> None:
        """Low-pass estimate of the object's planar velocity [m/s]."""
        if self.last_obj is not None:
            alpha = view.dt / VELOCITY_WINDOW
            self.obj_v = (1.0 - alpha) * self.obj_v + alpha * (obj - self.last_obj) / view.dt
        self.last_obj = obj.copy()

    def _push(self, view: View) -> Command:
        c = self.spec
        obj_pose = view.body_pose(c.object)
        obj, tgt = self._felt(view, obj_pose.pos), view.body_pose(c.target).pos
        dist = float(np.linalg.norm((tgt - obj)[:2]))
        moved = float(np.linalg.norm(obj[:2] - self.last_obj)) if self.last_obj is not None else 0.0
        unseen = view.unseen_s(c.object)
        self.blind_m = self.blind_m + moved if unseen > HIDDEN_S else 0.0  # pushed unseen [m]
        self._track(view, obj[:2])
        if dist > c.freeze and self.touched:  # turn only once in contact: the approach side was chosen to reach
            bearing = unit2((tgt - obj)[:2])
            speed = float(np.linalg.norm(self.obj_v))
            if speed > MIN_STEER_SPEED:  # integral steering: aim the push so the object moves at the target
                moving = self.obj_v / speed
                error = angle2(moving, bearing)
                self.bias = clamp(self.bias + STEER_GAIN * error * view.dt, -MAX_BIAS, MAX_BIAS)
            self.d = turn2(self.d, rotate2(bearing, self.bias), c.turn_rate * view.dt)
            self.goal_yaw = float(np.arctan2(self.d[1], self.d[0])) + c.yaw
        self._turn_tool(view)
        d, n = self.d, np.array([-self.d[1], self.d[0]])
        remaining = float((tgt - obj)[:2] @ d)
        first = self.approaches == 1 and self.nudges == 0
        if first and self.slanted and self.touched and dist <= c.square:  # stop here only if the arm reaches behind
            self.square_stop = self._square_reachable(view, obj, tgt)
            self.slanted = self.square_stop  # else the slanted push goes all the way
        stop = self.square_stop or remaining <= (c.standoff if first else 0.2 * c.tolerance)
        blind = self.blind_m > c.blind or unseen > BLIND_S  # pushed unseen too far or long
        self.blind_stop = not stop and self.touched and blind  # stop and look
        if stop or self.blind_stop:
            self.sp.jump(np.array([*view.frame_pose(self.frame).pos[:2], self.sp.pos[2]]))  # stop pushing, no shove
            self.stage, self.hold_from, self.v = Stage.HOLD, view.t, 0.0
            return self._command(allow=True)
        half = view.extent(c.object, np.array([-d[0], -d[1], 0.0]))  # the face pushed: behind the object (any shape)
        rel = self.sp.pos[:2] - obj[:2]
        along, lateral = float(rel @ d), float(rel @ n)
        gap = max(-half - along, 0.0)  # the setpoint's distance to the object's face before contact
        if gap > c.approach + LOST_GAP or abs(lateral) > half + LOST_GAP:  # knocked away from the tool's line
            self._knocked_away()
            self.next_d, self.full = unit2((tgt - obj)[:2]), True
            return self._start_retreat(final=False) if self.approaches < c.attempts else self._look(view)  # the last
        wanted = clamp(c.push_speed * (remaining + gap) / c.slow_down, c.creep_speed, c.push_speed)
        felt, k = self.contact.update(view, d), self.contact  # read every tick: _felt needs the contact's state
        self.touched = self.touched or gap < 1e-3 or felt  # geometry or the wrist's sensor
        past = float((view.frame_pose(self.frame).pos[:2] - obj[:2]) @ d) + half  # the tool past the face: it moved it
        self.pressed = self.pressed or (self.touched and past > PRESS_M)
        self.info.update(contact_onsets=k.onsets, contact_losses=k.losses, wrist_sensor=k.available)  # else geometry
        if not self.touched:
            wanted = min(wanted, max(c.creep_speed, gap / GAP_TIME))  # touch the object slowly
        self.v = min(wanted, self.v + PUSH_ACCEL * view.dt)
        # tipping: no face of the box is down (a box that rolled onto another face is flat again)
        tilted = float(np.arccos(clamp(float(np.abs(obj_pose.rot[2]).max()), -1.0, 1.0))) > c.max_tilt
        lead = 0.0 if tilted else c.preload  # a tipping object gets no push until it is flat again
        self.info["tilt_pauses"] = self.info.get("tilt_pauses", 0) + int(tilted)
        if dist < self.nearest - STUCK_M or self.nearest_at is None or tilted or not self.touched:
            self.nearest, self.nearest_at = min(dist, self.nearest), view.t
        elif view.t - self.nearest_at > STUCK_S:  # in contact and going nowhere: back off and approach again
            self.info["stuck"] = self.info.get("stuck", 0) + 1
            self.next_d, self.full = unit2((tgt - obj)[:2]), True
            if self.approaches < c.attempts:
                return self._start_retreat(final=False)
            return self._finish(dist, f": the push stuck for {STUCK_S:g} s, the object going no nearer its target")
        along = min(along + self.v * view.dt, -half + lead)
        if self.touched:  # in contact, recentre only near the face's edge (sliding along it drags the object)
            excess = lateral - clamp(lateral, -c.centre_band, c.centre_band)
            lateral -= clamp(excess, -c.creep_speed * view.dt, c.creep_speed * view.dt)
        else:
            lateral -= clamp(lateral, -c.push_speed * view.dt, c.push_speed * view.dt)
        # Hold the real tool at the push height: contact forces lift a compliant arm, and a hand sliding up the
        # object's face drags it onto the table (more friction, more force, more lift).
        rise = view.frame_pose(self.frame).pos[2] - self.push_z
        self.z_bias = clamp(self.z_bias - HEIGHT_GAIN * rise * view.dt, -MAX_HEIGHT_BIAS, MAX_HEIGHT_BIAS)
        self.sp.pos = np.array([*(obj[:2] + along * d + lateral * n), self.push_z + self.z_bias])
        return self._command(allow=True)

    def _hold(self, view: View) -> Command:
        """Let the object come to rest against the tool, then judge the push (see the module doc)."""
        c = self.spec
        if view.t - self.hold_from < c.settle:
            return self._command(allow=True)
        hidden = view.unseen_s(c.object) > HIDDEN_S
        if hidden or (c.look_to_judge and not self.blind_stop):  # hidden (or told to look): back off, look, judge
            return self._look(view)
        if self.blind_stop:  # stopped to look, and the camera sees it: push on, steering from what it sees
            self._begin_push(touched=True)
            return self._command(allow=True)
        obj, tgt, err = self._planar(view)
        if self.square_stop:  # the slanted push's end: approach again from behind the object's line, no new attempt
            self.next_d = unit2((tgt - obj)[:2])
            return self._start_retreat(final=False)
        self.info["object_error_xy_m"] = err
        e = (tgt - obj)[:2]
        verdict = judge(e, self.d, c, self.nudges, self.approaches)
        if verdict is Verdict.DONE:
            return self._start_retreat(final=True)
        if verdict is Verdict.NUDGE:
            self.nudges += 1
            self.info["nudges"] += 1
            self._begin_push(touched=True)
            return self._command(allow=True)
        if verdict is Verdict.CORRECT:
            self.next_d = unit2(e)
            return self._start_retreat(final=False)
        return self._finish(err)

    def _look(self, view: View) -> Command:
        """Back off, move aside and judge the push once the object is in sight.

        For a push the camera could not see, and for a knock seen when no approach is left or none reaches the object's
        new place: the view that saw the knock may be one that the hand beside the object smeared.
        """
        self.looking = True
        return self._start_retreat(final=False, view=view)

    def _no_approach(self, view: View) -> NextageQPError:
        """The error of a push that finds no reachable approach at its start, with the object's height.

        A refusal (exit 2) when nothing has moved yet: the robot cannot do this push.
        """
        c = self.spec
        tall = sum(view.extent(c.object, np.array([0.0, 0.0, z])) for z in (1.0, -1.0)) * 1e3
        return self.refusal(view, f"no approach to {c.object} ({tall:.0f} mm tall) within "
                          f"{np.degrees(max(c.fan)):.0f} deg of its line to {c.target} is reachable by {self.frame}: "
                          "out of the arm's reach at the push height, lower than the hand reaches down, or a tool "
                          "point inside the hand, which then collides with the object (docs/robots.md)"
                          + (f"; the last route the arm reached is blocked: {self.blocked}" if self.blocked else ""))

    def _finish(self, err: float, cause: str = "") -> Command:
        """Nothing left to try: accept the error within ``accept`` (retreat and end) or fail (saying why: ``cause``)."""
        c = self.spec
        if err <= c.accept:
            return self._start_retreat(final=True)
        raise self.failure(f"{c.object} is still {err * 1e3:.1f} mm from {c.target} "
                         f"after {self.approaches} approaches (tolerance {c.tolerance * 1e3:g} mm, accepted "
                         f"{c.accept * 1e3:g} mm){cause or f': all {c.attempts} attempts used'}")

    def _start_retreat(self, final: bool, view: View | None = None) -> Command:
        """Back the tool off along the push, then up; ``final``: the phase ends there.

        ``view`` given: the retreat is to look at the object, and the tool then moves on, level, towards the robot's
        side (:func:`_aside`).
        """
        c = self.spec
        back = self.sp.pos - np.array([*self.d, 0.0]) * c.approach
        up = back + np.array([0.0, 0.0, c.clearance])
        self.route = [back, up]
        self.stage, self.leg, self.final, self.seen_from, self.asides = Stage.RETREAT, 0, final, None, 0
        self.aside_from = up
        if view is not None:
            self._move_aside(view)
        return self._command(allow=True)

    def _move_aside(self, view: View) -> None:
        """Add a leg to the retreat: the tool level by ``ASIDE`` towards the robot's side (:func:`_aside`).

        A joint-space leg, planned around the obstacles with the planner's clearance (a straight line of the tool may
        sweep the arm through clutter; a straight joint move that only misses it grazes it once the arm lags its
        reference). Where the point is out of reach (clutter stands there), the tool goes to where the robot's default
        posture holds it; with no path there either, no leg: the push is judged on what is seen.
        """
        home = view.pose_at(self.frame, view.default_posture()).pos
        aside_plan: PlanMode = "never" if self.spec.plan == "never" else "always"  # kept clear, not only out of contact
        for point in (_aside(self.aside_from, self.frame, view), home):  # the tool's home: clear of the clutter
            route = PlannedRoute([(self._target(point, self.tool_yaw),)], plan=aside_plan)
            if route.plan(view, restarts=False) or route.plan(view):
                self.route.append(route)
                self.aside_from = point
                return
        self.asides = LOOK_AGAIN

    def _retreat(self, view: View) -> Command:
        """Follow the retreat; then judge a push the camera could not see, end the phase, or approach again."""
        c = self.spec
        if self.leg < len(self.route):
            leg = self.route[self.leg]
            if isinstance(leg, PlannedRoute):
                try:
                    command = leg.step(view)
                except PhaseError:  # no path from where the arm is: look from here
                    self.route, self.asides = self.route[: self.leg], LOOK_AGAIN
                    return self._command(allow=False)
                if not leg.done:
                    return command
                self._on_tool(view)
                self.leg, self.back_at = self.leg + 1, view.t
            elif self.sp.advance(leg, c.speed, view.dt):
                self.leg, self.back_at = self.leg + 1, view.t
        if self.leg < len(self.route):
            return self._command(allow=self.leg == 0)
        if self.looking:  # backed off from a push the camera could not see: judge it once the object is in sight
            waited = view.t - self.back_at
            if view.unseen_s(c.object) > HIDDEN_S:
                self.seen_from = None
                if waited < LOOK_S:
                    return self._command(allow=False)
                if self.asides < LOOK_AGAIN:  # the arm still hides it: fold further to the robot's side, look again
                    self.asides += 1
                    self._move_aside(view)
                    return self._command(allow=False)
            else:
                self.seen_from = view.t if self.seen_from is None else self.seen_from
                if view.t - self.seen_from < SEEN_S and waited < LOOK_S + SEEN_S:
                    return self._command(allow=False)
            self.looking = False
            seen = self.seen_from is not None  # a look that never saw the object: the next approach is a new one
            obj, tgt, err = self._planar(view)
            self.info["object_error_xy_m"] = err
            if err <= c.tolerance:
                self.final = True
            elif self.approaches >= c.attempts and not (self.blind_stop and seen):
                return self._finish(err, "" if seen else f": the camera has not seen {c.object} for "
                                    f"{view.unseen_s(c.object):.1f} s, looking from aside")
            else:
                self.next_d = unit2((tgt - obj)[:2])
                if self.blind_stop and seen:  # it stopped to look, not to be judged: the next approach is no new one
                    self.approaches -= 1
                    self.info["looks"] = self.info.get("looks", 0) + 1
            self.blind_stop = False
        if self.final:
            return self._command(allow=False, done=view.settled())
        if self.square_stop:  # (a look after it may have judged it instead: then it is an attempt)
            self.square_stop, self.approaches, self.full = False, self.approaches - 1, True
            self.info["squared"] = 1
        self._approach(view, self.next_d, full=self.full)
        if self.plan_failed and not self.full:  # no reachable side within the correction fan: try the whole fan
            self.approaches -= 1
            self._approach(view, self.next_d, full=True)
        self.full = False
        if self.plan_failed:  # no reachable side to correct from
            self.info["unreachable_corrections"] = self.info.get("unreachable_corrections", 0) + 1
            obj, _, err = self._planar(view)
            e, fan = self.next_d, np.degrees(max(c.fan))
            why = f"; the last route the arm reached is blocked: {self.blocked}" if self.blocked else ""
            return self._finish(err, f": no side to push it from towards {c.target} is within the robot's reach (at "
                                     f"({obj[0]:.3f}, {obj[1]:.3f}) m it would have to go towards ({e[0]:+.2f}, "
                                     f"{e[1]:+.2f}); no tool reaches it within {fan:.0f} deg of that{why})")
        if not self._worth_it(view):  # an accepted error, and a correction that could not reach the tolerance: keep it
            self.info["declined_corrections"] = self.info.get("declined_corrections", 0) + 1
            self.stage, self.final, self.approaches = Stage.RETREAT, True, self.approaches - 1
            self.info["attempts"] = self.approaches  # the declined one was planned, not made
            return self._command(allow=False, done=view.settled())
        return self._command(allow=False)

    def _worth_it(self, view: View) -> bool:
        """Whether the correction just planned may be pushed (:func:`worth_correcting`)."""
        obj, tgt, _ = self._planar(view)
        return worth_correcting((tgt - obj)[:2], self.d, self.spec.tolerance, self.spec.accept)


def _aside(point: np.ndarray, frame: str, view: View) -> np.ndarray:
    """``point`` moved level by ``ASIDE`` towards where the robot's default posture holds the tool ``frame``.

    The arm folds out of the camera's line of sight: backing off along the push leaves the hand over an object pushed
    away from the robot.
    """
    home = view.pose_at(frame, view.default_posture()).pos
    away = home[:2] - point[:2]
    dist = float(np.linalg.norm(away))
    step = away * min(ASIDE, dist) / dist if dist > 1e-9 else np.zeros(2)
    return np.array([*(point[:2] + step), point[2]])
