"""``move``: straight-line moves of one or two frames to world or body-relative goals."""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from nextage_qp.errors import InfeasibleError
from nextage_qp.io.schema import YamlModel
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import Setpoint, View, frame_target, resolve_point
from nextage_qp.manipulation.phases.base import SETTLE_S, Phase, Spec, name_field

Vec3 = tuple[float, float, float]
Metres = Annotated[float, Field(ge=-10.0, le=10.0)]
"""A coordinate or offset [m]: within 10 m (as the command line's positions)."""


class TargetSpec(YamlModel):
    """Where one tool frame should go, in the world or relative to a named body's live pose.

    The target position is ``ref.pos + R_ref @ offset`` where ``R_ref`` is the reference body's yaw
    (``axes: yaw``) or the identity (``axes: world``). The orientation is either ``yaw`` (the frame's axes
    = the reference yaw turned by ``yaw`` [rad] about world z, z up), a world ``quat`` (w, x, y, z), or a
    tool ``axis`` (frame coordinates) that must point along a world ``direction``; or none.
    """

    frame: str = name_field("frame", description="Site or body of the robot to move, e.g. an arm's tool frame.")
    relative_to: str = name_field("reference", default="world", description="'world' or a body name.")
    offset: tuple[Metres, Metres, Metres] = Field(default=(0.0, 0.0, 0.0), description="Position offset [m].")
    axes: Literal["world", "yaw"] = Field(default="yaw", description="Axes the offset is expressed in.")
    yaw: float | None = Field(default=None, ge=-7.0, le=7.0,
                              description="Frame yaw relative to the reference yaw [rad].")
    quat: tuple[float, float, float, float] | None = Field(
        default=None, description="World orientation, a unit quaternion [1] (w, x, y, z).")
    axis: Vec3 | None = Field(
        default=None, description="Tool axis in the frame's coordinates [1] (non-zero; its length does not matter).")
    direction: Vec3 | None = Field(
        default=None, description="World direction the axis points along [1] (non-zero; given with axis).")

    @model_validator(mode="after")
    def _one_orientation(self) -> TargetSpec:
        given = [n for n in ("yaw", "quat", "axis") if getattr(self, n) is not None]
        if len(given) > 1:
            raise ValueError(f"give at most one of yaw, quat, axis+direction; got {', '.join(given)}")
        if (self.axis is None) != (self.direction is None):
            raise ValueError("axis and direction must be given together")
        for name in ("axis", "direction"):
            vec = getattr(self, name)
            if vec is not None and math.hypot(*vec) < 1e-6:
                raise ValueError(f"{name} must be a non-zero vector, got {list(vec)}")
        if self.quat is not None and not math.isclose(math.hypot(*self.quat), 1.0, abs_tol=1e-3):
            raise ValueError(f"quat must be a unit quaternion (w, x, y, z), got {self.quat}")
        return self


class MoveSpec(Spec):
    """Move one or both tool frames to targets along straight lines."""

    kind: Literal["move"]
    targets: list[TargetSpec] = Field(
        min_length=1, max_length=2, description="One or two targets, one per frame, reached at the same time.")
    tolerance: float = Field(default=0.005, gt=0, le=0.1, description="Position tolerance of the real frames [m].")
    speed: float = Field(default=0.15, gt=0, le=1.0, description="Cartesian speed of the moving setpoint [m/s].")

    @model_validator(mode="after")
    def _one_target_per_frame(self) -> MoveSpec:
        frames = [t.frame for t in self.targets]
        if len(set(frames)) < len(frames):
            raise ValueError(f"targets: two targets for frame {frames[0]!r}; give each frame one target (a frame "
                             "goes to one place at a time: use two move phases)")
        return self


class Move(Phase):
    """Each frame's setpoint walks from its commanded pose to its goal at ``speed``.

    Done when every real frame is within ``tolerance`` of its goal and the robot has settled.
    """

    spec: MoveSpec

    def start(self, view: View) -> None:  # noqa: D102
        self.points = [Setpoint(view.commanded_pose(t.frame).pos) for t in self.spec.targets]
        for t in self.spec.targets:  # a goal beyond the frame's reach sphere: refused, rather than a timeout
            try:
                view.check_reach(t.frame, resolve_point(view, t)[0], t.frame)
            except InfeasibleError as exc:
                raise self.failure(str(exc), InfeasibleError) from None

    def budget(self, view: View) -> float:
        """The farthest frame's line to its goal at ``speed``, then coming to rest."""
        far = max(float(np.linalg.norm(resolve_point(view, t)[0] - sp.pos))
                  for t, sp in zip(self.spec.targets, self.points, strict=True))
        return far / self.spec.speed + SETTLE_S

    def update(self, view: View) -> Command:  # noqa: D102
        targets, done = [], True
        for spec, sp in zip(self.spec.targets, self.points, strict=True):
            goal, _ = resolve_point(view, spec)
            done &= sp.advance(goal, self.spec.speed, view.dt)
            targets.append(frame_target(view, spec, sp.pos))
            err = float(np.linalg.norm(view.frame_pose(spec.frame).pos - goal))
            done &= err < self.spec.tolerance
            self.info[f"{spec.frame}_error_m"] = err
        return Command(tuple(targets), done=done and view.settled())
