r"""``push``: closed-loop pushing of an object onto a target with one tool frame.

A small state machine, every step driven by the live object pose:

* **transit**: lift to ``clearance`` over the object, then through planned joints to ``approach`` behind its
  face, for the reachable direction nearest the line to the target (:mod:`~nextage_qp.manipulation.push_approach`).
* **push**: the tool closes the gap slowly, then advances at a speed that falls from ``push_speed`` to
  ``creep_speed`` over the last ``slow_down``, never more than ``preload`` into the face, at a fixed height. Once
  in contact the direction :math:`\hat d` turns (at most ``turn_rate``) towards the object's bearing to the
  target plus an integral bias that makes the object's own motion point at the target; inside ``freeze`` it is
  kept. A tilting object gets no push until it is flat. The first push stops ``standoff`` short.
* **hold**: the object comes to rest and the error is judged: within ``tolerance`` the tool retreats and the phase
  is done; short on the same line, the push resumes (up to ``nudges``); otherwise the tool retreats and approaches
  again along the error (within ``correction_fan``), up to ``attempts`` approaches. When nothing is left to try,
  an error within ``accept`` ends the phase, a larger one fails it.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from nextage_qp.errors import PhaseError
from nextage_qp.geometry import rot_z, rotate2, turn2, unit2, yaw_of
from nextage_qp.ik import FrameTarget
from nextage_qp.manipulation.contact import PushContact
from nextage_qp.manipulation.context import Setpoint, View
from nextage_qp.manipulation.phases.base import MAX_SECONDS, Phase, Spec, name_field
from nextage_qp.manipulation.push_approach import plan_approach
from nextage_qp.servo import Command

PUSH_ACCEL = 0.1
"""Acceleration of the push speed [m/s²]."""
STEER_GAIN = 0.5
"""Integral gain of the push's heading bias per radian of object-motion error [1/s]."""
MAX_BIAS = 0.35
"""Largest heading bias between the push and the object's bearing to the target [rad]."""
MIN_STEER_SPEED = 0.005
"""Object speed above which its motion direction is trusted for steering [m/s]."""
VELOCITY_WINDOW = 0.2
"""Time constant of the object's velocity estimate [s]."""
HEIGHT_GAIN = 5.0
"""Integral gain of the tool-height hold while pushing [1/s]."""
MAX_HEIGHT_BIAS = 0.01
"""Largest correction of the commanded tool height while pushing [m]."""
GAP_TIME = 0.5
"""Before contact the tool closes the gap to the object in about this time [s] (slowly at the touch)."""


class PushSpec(Spec):
    """Push an object onto a target with one tool frame, steering from the object's live pose."""

    kind: Literal["push"]
    frame: str = name_field("frame", description="Tool frame that pushes, e.g. left_tool.")
    object: str = name_field("object", description="Free body to push, e.g. cube.")
    target: str = name_field("body", description="Body marking where the object should end, e.g. cube_target.")
    height: float = Field(default=0.0, ge=-0.2, le=0.2, description="Tool height over the object centre [m].")
    approach: float = Field(default=0.04, gt=0, le=0.3, description="Gap behind the object before a push [m].")
    clearance: float = Field(default=0.07, gt=0, le=0.5, description="Height over the object's top in transit [m].")
    tolerance: float = Field(default=0.002, gt=0, le=0.1, description="Planar error that ends the phase [m].")
    accept: float = Field(default=0.005, gt=0, le=0.2, description="Error accepted when no try is left [m].")
    attempts: int = Field(default=4, ge=1, le=20, description="Approaches (the first push and re-approaches).")
    nudges: int = Field(default=3, ge=0, le=20, description="Resumed pushes on the same line per approach.")
    speed: float = Field(default=0.15, gt=0, le=1.0, description="Transit speed [m/s].")
    push_speed: float = Field(default=0.05, gt=0, le=0.5, description="Top speed in contact [m/s].")
    creep_speed: float = Field(default=0.005, gt=0, le=0.1, description="Speed at the target [m/s].")
    slow_down: float = Field(default=0.04, gt=0, le=0.5, description="Distance over which the push slows [m].")
    preload: float = Field(default=0.012, gt=0, le=0.05, description="Lead of the tool into the object [m].")
    turn_rate: float = Field(default=0.5, gt=0, le=5.0, description="Turn rate of the push direction [rad/s].")
    freeze: float = Field(default=0.04, ge=0, le=0.2, description="Distance inside which the direction is kept [m].")
    centre_band: float = Field(default=0.01, ge=0, le=0.1,
                               description="Offset of the object along the tool face left alone [m].")
    max_tilt: float = Field(default=0.07, gt=0, le=1.0,
                            description="Object tilt above which the push pauses until it is flat again [rad].")
    settle: float = Field(default=0.3, ge=0, le=MAX_SECONDS, description="Rest before the error is judged [s].")
    yaw: float = Field(default=0.0, ge=-np.pi, le=np.pi, description="Tool yaw relative to the push [rad].")
    pitch: float = Field(default=0.0, ge=-0.8, le=0.8,
                         description="Tool pitch [rad]; > 0 tilts the push face's normal down.")
    standoff: float = Field(default=0.004, ge=0, le=0.05,
                            description="The first push stops this short of the target; a short push aimed from "
                                        "the side the error then points to finishes the job [m].")
    correction_fan: float = Field(default=0.53, ge=0, le=1.6,
                                  description="Largest deviation from the error's direction for a correction [rad].")
    fan: tuple[float, ...] = Field(
        default=(0.0, 0.2618, 0.5236, 0.7854, 1.0472), min_length=1,
        description="Deviations from the line to the target tried, each way, when its approach is out of reach [rad].",
    )

    @model_validator(mode="after")
    def _accept_covers_tolerance(self) -> PushSpec:
        if self.accept < self.tolerance:
            raise ValueError(f"accept ({self.accept} m) must be >= tolerance ({self.tolerance} m)")
        if self.creep_speed > self.push_speed:
            raise ValueError(f"creep_speed ({self.creep_speed}) must be <= push_speed ({self.push_speed})")
        return self


class Push(Phase):
    """See the module docstring."""

    spec: PushSpec

    def start(self, view: View) -> None:  # noqa: D102
        pos, rot = view.commanded_pose(self.spec.frame)
        self.sp = Setpoint(pos)
        self.tool_yaw = yaw_of(rot)
        self.approaches, self.contact = 0, PushContact(self.spec.frame)
        self.info.update(attempts=0, nudges=0, contact_onsets=0, contact_losses=0)
        obj, tgt, _ = self._planar(view)
        self._approach(view, unit2((tgt - obj)[:2]))
        if self.plan_failed:
            raise PhaseError(f"phase {self.name!r} (push): no approach to {self.spec.object} within "
                             f"{np.degrees(max(self.spec.fan)):.0f} deg of its line to {self.spec.target} is reachable")

    def _planar(self, view: View) -> tuple[np.ndarray, np.ndarray, float]:
        obj, tgt = view.body_pose(self.spec.object).pos, view.body_pose(self.spec.target).pos
        return obj, tgt, float(np.linalg.norm((tgt - obj)[:2]))

    def _approach(self, view: View, d_goal: np.ndarray) -> None:
        """Plan the next approach: the direction closest to ``d_goal`` with a route the arm can reach."""
        c = self.spec
        self.approaches += 1
        self.nudges = 0
        fan = c.fan if self.approaches == 1 else tuple(a for a in c.fan if a <= c.correction_fan)
        plan = plan_approach(view, c, self.sp.pos, d_goal, fan, self._rot)
        tried = plan.tried if plan else sum(1 + (a != 0) for a in fan)
        self.info.update(attempts=self.approaches, directions_tried=tried)
        self.plan_failed = plan is None
        if plan is None:
            return
        self.d, self.lift, self.goal_yaw, self.planned, self.push_z = plan[:5]
        self.info["direction"] = self.d.round(4).tolist()
        self.stage, self.lifting = "transit", True

    def _command(self, allow: bool, done: bool = False) -> Command:
        target = FrameTarget(self.spec.frame, pos=self.sp.pos.copy(), rot=self._rot(self.tool_yaw))
        return Command((target,), allow=frozenset({self.spec.object}) if allow else frozenset(), done=done)

    def _rot(self, yaw: float) -> np.ndarray:
        c, s = np.cos(self.spec.pitch), np.sin(self.spec.pitch)
        return rot_z(yaw) @ np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])

    def _turn_tool(self, view: View) -> None:  # towards the goal at the turn rate
        step = self.spec.turn_rate * view.dt
        self.tool_yaw += float(np.clip(np.angle(np.exp(1j * (self.goal_yaw - self.tool_yaw))), -step, step))

    def update(self, view: View) -> Command:  # noqa: D102
        return getattr(self, f"_{self.stage}")(view)  # _transit, _push, _hold or _retreat

    def _transit(self, view: View) -> Command:
        """Lift straight up, then move through the planned joints of the route (the wrist turns once lifted)."""
        c = self.spec
        if self.lifting:
            self.lifting = not self.sp.advance(self.lift, c.speed, view.dt)
            return self._command(allow=False)
        command = self.planned.step(view)
        if self.planned.done:
            pos, rot = view.commanded_pose(c.frame)
            self.sp.jump(pos)
            self.tool_yaw = yaw_of(rot)
            self.z_bias = 0.0
            self._begin_push(touched=False)
        return command

    def _begin_push(self, touched: bool) -> None:
        self.stage, self.v, self.touched, self.bias = "push", 0.0, touched, 0.0
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
        obj, tgt = obj_pose.pos, view.body_pose(c.target).pos
        dist = float(np.linalg.norm((tgt - obj)[:2]))
        self._track(view, obj[:2])
        if dist > c.freeze and self.touched:  # turn only once in contact: the approach side was chosen to reach
            bearing = unit2((tgt - obj)[:2])
            speed = float(np.linalg.norm(self.obj_v))
            if speed > MIN_STEER_SPEED:  # integral steering: aim the push so the object moves at the target
                moving = self.obj_v / speed
                error = float(np.arctan2(moving[0] * bearing[1] - moving[1] * bearing[0], moving @ bearing))
                self.bias = float(np.clip(self.bias + STEER_GAIN * error * view.dt, -MAX_BIAS, MAX_BIAS))
            self.d = turn2(self.d, rotate2(bearing, self.bias), c.turn_rate * view.dt)
            self.goal_yaw = float(np.arctan2(self.d[1], self.d[0])) + c.yaw
        self._turn_tool(view)
        d, n = self.d, np.array([-self.d[1], self.d[0]])
        remaining = float((tgt - obj)[:2] @ d)
        if remaining <= (c.standoff if self.approaches == 1 and self.nudges == 0 else 0.2 * c.tolerance):
            self.sp.jump(np.array([*view.frame_pose(c.frame).pos[:2], self.sp.pos[2]]))  # stop pushing, no shove
            self.stage, self.hold_from, self.v = "hold", view.t, 0.0
            return self._command(allow=True)
        half = view.extent(c.object, np.array([*d, 0.0]))
        rel = self.sp.pos[:2] - obj[:2]
        along, lateral = float(rel @ d), float(rel @ n)
        gap = max(-half - along, 0.0)  # the setpoint's distance to the object's face before contact
        wanted = float(np.clip(c.push_speed * (remaining + gap) / c.slow_down, c.creep_speed, c.push_speed))
        self.touched = self.touched or gap < 1e-3 or self.contact.update(view, d)  # geometry or the wrist's sensor
        self.info.update(contact_onsets=self.contact.onsets, contact_losses=self.contact.losses)
        if not self.touched:
            wanted = min(wanted, max(c.creep_speed, gap / GAP_TIME))  # touch the object slowly
        self.v = min(wanted, self.v + PUSH_ACCEL * view.dt)
        tilted = float(np.arccos(np.clip(obj_pose.rot[2, 2], -1.0, 1.0))) > c.max_tilt
        lead = 0.0 if tilted else c.preload  # a tipping object gets no push until it is flat again
        self.info["tilt_pauses"] = self.info.get("tilt_pauses", 0) + int(tilted)
        along = min(along + self.v * view.dt, -half + lead)
        if self.touched:  # in contact, recentre only near the face's edge (sliding along it drags the object)
            excess = lateral - float(np.clip(lateral, -c.centre_band, c.centre_band))
            lateral -= float(np.clip(excess, -c.creep_speed * view.dt, c.creep_speed * view.dt))
        else:
            lateral -= float(np.clip(lateral, -c.push_speed * view.dt, c.push_speed * view.dt))
        # Hold the real tool at the push height: contact forces lift a compliant arm, and a hand sliding up the
        # object's face drags it onto the table (more friction, more force, more lift).
        rise = view.frame_pose(c.frame).pos[2] - self.push_z
        self.z_bias = float(np.clip(self.z_bias - HEIGHT_GAIN * rise * view.dt, -MAX_HEIGHT_BIAS, MAX_HEIGHT_BIAS))
        self.sp.pos = np.array([*(obj[:2] + along * d + lateral * n), self.push_z + self.z_bias])
        return self._command(allow=True)

    def _hold(self, view: View) -> Command:
        c = self.spec
        if view.t - self.hold_from < c.settle:
            return self._command(allow=True)
        obj, tgt, err = self._planar(view)
        self.info["object_error_xy_m"] = err
        e = (tgt - obj)[:2]
        if err <= c.tolerance:
            return self._start_retreat(final=True)
        short = float(e @ self.d) > 0 and abs(float(e @ np.array([-self.d[1], self.d[0]]))) <= c.tolerance
        if short and self.nudges < c.nudges:
            self.nudges += 1
            self.info["nudges"] += 1
            self._begin_push(touched=True)
            return self._command(allow=True)
        if self.approaches < c.attempts:
            self.next_d = unit2(e)
            return self._start_retreat(final=False)
        return self._finish(err)

    def _finish(self, err: float) -> Command:
        """Nothing left to try: accept the error within ``accept`` (retreat and end) or fail."""
        c = self.spec
        if err <= c.accept:
            return self._start_retreat(final=True)
        raise PhaseError(f"phase {self.name!r} (push): {c.object} is still {err * 1e3:.1f} mm from {c.target} "
                         f"after {self.approaches} approaches (tolerance {c.tolerance * 1e3:g} mm, accepted "
                         f"{c.accept * 1e3:g} mm)")

    def _start_retreat(self, final: bool) -> Command:
        c = self.spec
        back = self.sp.pos - np.array([*self.d, 0.0]) * c.approach
        self.route = [back, back + np.array([0.0, 0.0, c.clearance])]
        self.stage, self.leg, self.final = "retreat", 0, final
        return self._command(allow=True)

    def _retreat(self, view: View) -> Command:
        if self.leg < len(self.route) and self.sp.advance(self.route[self.leg], self.spec.speed, view.dt):
            self.leg += 1
        if self.leg < len(self.route):
            return self._command(allow=self.leg == 0)
        if self.final:
            return self._command(allow=False, done=view.settled())
        self._approach(view, self.next_d)
        if self.plan_failed:  # no reachable side to correct from
            self.info["unreachable_corrections"] = self.info.get("unreachable_corrections", 0) + 1
            _, _, err = self._planar(view)
            return self._finish(err)
        return self._command(allow=False)
