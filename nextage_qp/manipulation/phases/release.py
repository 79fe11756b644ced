"""``release``: open the pads away from a set-down object along the clamp axis, then lift them."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.ik import FrameTarget
from nextage_qp.manipulation.context import Grip, Setpoint, View
from nextage_qp.manipulation.phases.base import Phase, Spec, name_field
from nextage_qp.manipulation.phases.grasp import PADS, SIDES
from nextage_qp.servo import Command


class ReleaseSpec(Spec):
    """Open the pads away from the object along the clamp axis, then retreat upwards."""

    kind: Literal["release"]
    object: str = name_field("object")
    gap: float = Field(default=0.05, gt=0, le=0.3, description="How far the pads back away from the object [m].")
    lift: float = Field(default=0.08, ge=0, le=0.5, description="How far the pads then rise [m].")
    open_speed: float = Field(default=0.02, gt=0, le=0.5, description="Opening speed [m/s] (slow: no tug).")
    speed: float = Field(default=0.1, gt=0, le=0.5, description="Lifting speed [m/s].")


class Release(Phase):
    """Open along the clamp axis, then lift; the clamp ends as the pads start to open.

    Each pad backs away by ``gap`` at ``open_speed``, then rises by ``lift``.
    """

    spec: ReleaseSpec

    def start(self, view: View) -> None:  # noqa: D102
        c = self.spec
        _, rot = view.body_pose(c.object)
        grip = view.grip
        self.frames = grip.frames if grip is not None else PADS
        lateral = rot @ grip.lateral if grip is not None else rot[:, 1]
        self.points = [Setpoint(view.commanded_pose(f).pos) for f in self.frames]
        self.rots = [view.commanded_pose(f).rot for f in self.frames]
        opened = [sp.pos + s * c.gap * lateral for sp, s in zip(self.points, SIDES, strict=False)]
        self.stages = [(opened, c.open_speed), ([p + np.array([0.0, 0.0, c.lift]) for p in opened], c.speed)]
        self.stage = 0

    def update(self, view: View) -> Command:  # noqa: D102
        if self.stage < len(self.stages):
            goals, speed = self.stages[self.stage]
            if all([sp.advance(g, speed, view.dt) for sp, g in zip(self.points, goals, strict=True)]):
                self.stage += 1
        targets = tuple(FrameTarget(f, pos=sp.pos, rot=r) for f, sp, r in zip(self.frames, self.points, self.rots,
                                                                               strict=True))
        allow = frozenset({self.spec.object}) if self.stage == 0 else frozenset()  # touching it while opening
        return Command(targets, allow=allow, done=self.stage == len(self.stages) and view.settled())

    def grip(self, current: Grip | None) -> Grip | None:  # noqa: D102
        return None  # the clamp ends as the pads start to open
