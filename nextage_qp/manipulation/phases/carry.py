"""``carry``: move a clamped object through waypoints while the pads keep their relative pose."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.geometry import path_length, yaw_of
from nextage_qp.io.schema import YamlModel
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import Setpoint, View, resolve_point
from nextage_qp.manipulation.phases.base import SETTLE_S, Phase, Spec, name_field

Vec3 = tuple[float, float, float]


class Waypoint(YamlModel):
    """Where the grasped object's origin should pass: a body-relative or world position and yaw."""

    relative_to: str = name_field("reference", default="world",
                                  description="Body whose live pose the waypoint is relative to, or world.")
    offset: Vec3 = Field(default=(0.0, 0.0, 0.0), description="Object origin's offset from the reference [m].")
    axes: Literal["world", "yaw"] = Field(
        default="world", description="Axes the offset is expressed in: the world's, or turned by the reference's yaw.")
    yaw: float | None = Field(default=None, description="Object yaw relative to the reference yaw [rad].")
    heading: Literal["reference", "radial"] = Field(
        default="reference",
        description="Yaw base: the reference body's yaw, or radial (facing away from the robot's chest axis).",
    )
    correct: bool = Field(default=False, description="Here, shift the rest of the path by the live planar error.")


class CarrySpec(Spec):
    """Move a clamped object through waypoints while the pads keep their relative pose."""

    grip = "needs"

    kind: Literal["carry"]
    object: str = name_field("object", description="The object an earlier grasp phase clamped.")
    waypoints: list[Waypoint] = Field(
        min_length=1, description="Where the object's origin passes, in order, with its yaw there.")
    tolerance: float = Field(default=0.003, gt=0, description="Planar object error accepted when correcting [m].")
    corrections: int = Field(default=3, ge=0, description="Closed-loop shifts of the rest of the path allowed in the "
                             "phase, at waypoints marked correct [count].")
    speed: float = Field(default=0.1, gt=0, description="Cartesian speed of the object setpoint [m/s].")
    relative_cost: float = Field(
        default=10.0, ge=0, description="Weight of the pads' relative pose task [1/m, 1/rad] (holds the grip).")


class Carry(Phase):
    r"""The object setpoint :math:`(p, \psi)` walks the waypoints at ``speed``.

    Each pad's target is :math:`p + R_z(\psi)\,o_i` with its grasp offset :math:`o_i`, and a relative-pose target
    holds the first pad's pose in the second pad's frame as the clamp left it.
    """

    spec: CarrySpec

    def start(self, view: View) -> None:  # noqa: D102
        c = self.spec
        self.clamp = self.held(view, c.object, c.relative_cost)
        obj, rot = view.body_pose(c.object)
        self.sp, yaw0 = Setpoint(obj), yaw_of(rot)
        self.goals = [resolve_point(view, w) for w in c.waypoints]
        self.nominal = list(self.goals)
        self.leg, self.leg_from, self.yaw = 0, (obj.copy(), yaw0), yaw0
        self.corrections = 0

    def budget(self, view: View) -> float:
        """The path through the waypoints at ``speed``, then coming to rest at it and at each correction."""
        points = [self.sp.pos, *(g for g, _ in self.goals)]
        return path_length(points) / self.spec.speed + (1 + self.spec.corrections) * SETTLE_S

    def update(self, view: View) -> Command:  # noqa: D102
        c = self.spec
        if self.leg < len(self.goals):
            goal, goal_yaw = self.goals[self.leg]
            start, start_yaw = self.leg_from
            if self.sp.advance(goal, c.speed, view.dt) and self._leg_finished(view):
                self.leg += 1
                self.leg_from = (goal.copy(), goal_yaw)
            span = float(np.linalg.norm(goal - start))
            frac = 1.0 if span < 1e-9 else 1.0 - float(np.linalg.norm(goal - self.sp.pos)) / span
            self.yaw = start_yaw + frac * (goal_yaw - start_yaw)
        targets, relative = self.clamp.targets(view, self.sp.pos, self.yaw)
        done = self.leg == len(self.goals) and view.settled()
        return Command(targets, (relative,), allow=frozenset({c.object}), done=done)

    def _leg_finished(self, view: View) -> bool:
        """At a waypoint marked ``correct``: once settled, shift it and the rest by the object's planar error."""
        c = self.spec
        if not c.waypoints[min(self.leg, len(c.waypoints) - 1)].correct or self.leg >= len(c.waypoints):
            return True
        if not view.settled():
            return False
        obj = view.body_pose(c.object).pos
        goal = self.nominal[self.leg][0]  # the waypoint itself, not the already shifted setpoint goal
        err = np.array([*(goal - obj)[:2], 0.0])
        self.info["object_error_xy_m"] = float(np.linalg.norm(err))
        if np.linalg.norm(err) <= c.tolerance or self.corrections >= c.corrections:
            return True
        self.corrections += 1
        self.info["corrections"] = self.corrections
        self.goals = self.goals[: self.leg] + [(g + err, y) for g, y in self.goals[self.leg :]]
        return False
