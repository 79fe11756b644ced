r"""``push``: closed-loop pushing of an object onto a target with one tool frame.

A small state machine, every step driven by the live object pose:

* **transit**: lift to ``clearance`` over the object, then through planned joints to ``approach`` behind its
  face, for the reachable direction nearest the line to the target (:mod:`~nextage_qp.manipulation.push_approach`).
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
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from nextage_qp.geometry import Pose, angle2, clamp, rot_of, rot_z, rotate2, turn2, unit2, yaw_of
from nextage_qp.ik import FrameTarget
from nextage_qp.manipulation.contact import PushContact
from nextage_qp.manipulation.context import Setpoint, View
from nextage_qp.manipulation.phases.base import Phase
from nextage_qp.manipulation.phases.push_judge import hold, look, no_approach, retreat, start_retreat
from nextage_qp.manipulation.phases.push_spec import (
    BLIND_S,
    GAP_TIME,
    HEIGHT_GAIN,
    HIDDEN_S,
    LOST_GAP,
    MAX_BIAS,
    MAX_HEIGHT_BIAS,
    MIN_STEER_SPEED,
    PRESS_M,
    PUSH_ACCEL,
    STEER_GAIN,
    TIPPING_SHARE,
    VELOCITY_WINDOW,
    PushSpec,
)
from nextage_qp.manipulation.push_approach import plan_approach, plan_handover
from nextage_qp.servo import Command

_X = np.array([1.0, 0.0, 0.0])


class Push(Phase):
    """See the module docstring."""

    spec: PushSpec
    route: list[np.ndarray]  # the retreat (push_judge): its waypoints, the next one's index, whether it ends the phase
    leg: int
    final: bool
    back_at: float  # when the retreat reached its last waypoint [s]
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
        obj, tgt, _ = self._planar(view)
        self._approach(view, unit2((tgt - obj)[:2]))
        if self.plan_failed:
            raise no_approach(self, view)

    def stalled(self, view: View) -> str | None:  # noqa: D102
        tilted_s = self.info.get("tilt_pauses", 0) * view.dt  # ticks the push paused for a tipping object
        if tilted_s < TIPPING_SHARE * self.spec.timeout:
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
        if not (pushing and view.unseen_s(c.object) > HIDDEN_S) or self.stage not in ("push", "hold"):
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
        plan = plan_approach(view, c, self.sp.pos, d_goal, fan, self._target, higher=higher)
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
        self.info["direction"] = self.d.round(4).tolist()
        self.stage, self.lifting = "transit", True

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
        return rot_of(np.array([0.0, self.spec.pitch, 0.0]))  # about the tool's y axis

    def _turn_tool(self, view: View) -> None:  # towards the goal at the turn rate
        step = self.spec.turn_rate * view.dt
        self.tool_yaw += clamp(float(np.angle(np.exp(1j * (self.goal_yaw - self.tool_yaw)))), -step, step)

    def update(self, view: View) -> Command:  # noqa: D102
        if self.stage in ("hold", "retreat"):  # what follows a push: nextage_qp.manipulation.phases.push_judge
            return hold(self, view) if self.stage == "hold" else retreat(self, view)
        return self._transit(view) if self.stage == "transit" else self._push(view)

    def carrier(self, view: View) -> tuple[str, Callable[[], Pose]] | None:
        """While the push is felt (or pressed), the object and the tool's advance along it, which its estimate takes."""
        felt = self.contact.in_contact or self.pressed if self.contact.available else self.touched  # else geometry
        carrier = self.contact.carrier(view, self.d if self.stage in ("push", "hold") and felt else None)
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
            return self._command(allow=False) if not self.plan_failed else look(self, view)
        if self.lifting:
            self.lifting = not self.sp.advance(self.lift, c.speed, view.dt)
            return self._command(allow=False)
        command = self.planned.step(view)
        if self.planned.done:
            self._on_tool(view)
            self.z_bias = 0.0
            self._begin_push(touched=False)
        return command

    def _on_tool(self, view: View) -> None:
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
        self.stage, self.v, self.touched, self.bias, self.pressed = "push", 0.0, touched, 0.0, False
        self.blind_m, self.blind_stop = 0.0, False  # how far the tool pushed unseen [m]; whether it stopped to look
        self.contact.restart()  # the last push's contact is stale: _felt reads it before this push's first reading
        self.last_obj: np.ndarray | None = None
        self.obj_v = np.zeros(2)

    def _track(self, view: View, obj: np.ndarray) -> None:
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
        stop = remaining <= (c.standoff if self.approaches == 1 and self.nudges == 0 else 0.2 * c.tolerance)
        blind = self.blind_m > c.blind or unseen > BLIND_S  # pushed unseen too far or long
        self.blind_stop = not stop and self.touched and blind  # stop and look
        if stop or self.blind_stop:
            self.sp.jump(np.array([*view.frame_pose(self.frame).pos[:2], self.sp.pos[2]]))  # stop pushing, no shove
            self.stage, self.hold_from, self.v = "hold", view.t, 0.0
            return self._command(allow=True)
        half = view.extent(c.object, np.array([-d[0], -d[1], 0.0]))  # the face pushed: behind the object (any shape)
        rel = self.sp.pos[:2] - obj[:2]
        along, lateral = float(rel @ d), float(rel @ n)
        gap = max(-half - along, 0.0)  # the setpoint's distance to the object's face before contact
        if gap > c.approach + LOST_GAP or abs(lateral) > half + LOST_GAP:  # knocked away from the tool's line
            self._knocked_away()
            self.next_d, self.full = unit2((tgt - obj)[:2]), True
            return start_retreat(self, final=False) if self.approaches < c.attempts else look(self, view)  # the last
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
