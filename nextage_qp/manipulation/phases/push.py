r"""``push``: push an object to a target with one tool frame, re-planning every attempt from the live poses."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.errors import PhaseError
from nextage_qp.ik import FrameTarget
from nextage_qp.manipulation.context import Setpoint, View, rot_z
from nextage_qp.manipulation.phases.base import Phase, Spec, name_field
from nextage_qp.servo import Command


class PushSpec(Spec):
    """Push an object to a target with one tool frame, re-planning from the object's live pose."""

    kind: Literal["push"]
    frame: str = name_field("frame", description="Tool frame that pushes, e.g. left_tool.")
    object: str = name_field("object", description="Free body to push, e.g. cube.")
    target: str = name_field("body", description="Body marking where the object should end, e.g. cube_target.")
    height: float = Field(default=0.0, description="Tool height relative to the object centre while pushing [m].")
    approach: float = Field(default=0.05, gt=0, description="Gap behind the object before a push [m].")
    clearance: float = Field(default=0.08, gt=0, description="Height above the object when moving around it [m].")
    tolerance: float = Field(default=0.002, gt=0, description="Planar object error that ends the phase [m].")
    attempts: int = Field(default=6, ge=1, description="Pushes before the phase gives up.")
    speed: float = Field(default=0.12, gt=0, description="Speed of approach moves [m/s].")
    push_speed: float = Field(default=0.05, gt=0, description="Speed while in contact [m/s].")
    yaw: float = Field(default=0.0, description="Tool yaw relative to the push direction [rad].")


class Push(Phase):
    r"""Approach behind the object on its line to the target, push, re-check; up to ``attempts`` times.

    Each attempt re-plans from the live poses: direction :math:`\hat d = (p_t - p_o)_{xy} / \|\cdot\|`,
    approach point :math:`p_o - \hat d (h + a)`, and the push ends where the tool face puts the object's
    centre on the target, :math:`p_t - \hat d h` (:math:`h` = the object's half-extent along
    :math:`\hat d`, :math:`a` = approach gap [m]).
    """

    spec: PushSpec

    def start(self, view: View) -> None:  # noqa: D102
        self.attempt = 0
        self.sp = Setpoint(view.commanded_pose(self.spec.frame).pos)
        self._plan(view)

    def _plan(self, view: View) -> None:
        c = self.spec
        obj = view.body_pose(c.object).pos
        tgt = view.body_pose(c.target).pos
        delta = (tgt - obj)[:2]
        d = np.array([*delta / max(np.linalg.norm(delta), 1e-9), 0.0])
        half = view.extent(c.object, d)
        z = obj[2] + c.height
        behind = obj - d * (half + c.approach)
        behind[2] = z
        finish = tgt - d * half
        finish[2] = z
        start = self.sp.pos
        lift_z = max(start[2], obj[2] + half + c.clearance)
        self.rot = rot_z(float(np.arctan2(d[1], d[0])) + c.yaw)
        self.legs = [
            (np.array([start[0], start[1], lift_z]), c.speed),
            (np.array([behind[0], behind[1], lift_z]), c.speed),
            (behind, c.speed),
            (finish, c.push_speed),
        ]
        self.leg = 0
        self.wait_from: float | None = None
        self.attempt += 1
        self.info.update(attempts=self.attempt, direction=d[:2].round(4).tolist())

    def update(self, view: View) -> Command:  # noqa: D102
        c = self.spec
        if self.leg < len(self.legs):
            goal, speed = self.legs[self.leg]
            if self.sp.advance(goal, speed, view.dt) and (self.leg < len(self.legs) - 1 or view.settled()):
                self.leg += 1
        elif self.wait_from is None:
            self.wait_from = view.t
        elif view.t - self.wait_from > 0.2:
            obj = view.body_pose(c.object).pos
            tgt = view.body_pose(c.target).pos
            err = float(np.linalg.norm((obj - tgt)[:2]))
            self.info["object_error_xy_m"] = err
            if err <= c.tolerance:
                return Command((FrameTarget(c.frame, pos=self.sp.pos, rot=self.rot),), done=True)
            if self.attempt >= c.attempts:
                raise PhaseError(f"phase {self.name!r} (push): {c.object} is still {err * 1e3:.1f} mm from "
                                 f"{c.target} after {c.attempts} attempts (tolerance {c.tolerance * 1e3:g} mm)")
            back = self.sp.pos - np.array([*self.info["direction"], 0.0]) * c.approach
            self.sp.jump(back)  # retreat along the line before the next attempt
            self._plan(view)
        return Command((FrameTarget(c.frame, pos=self.sp.pos, rot=self.rot),))
