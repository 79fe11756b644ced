"""``release``: open the pads away from the object, then retreat upwards."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.ik import FrameTarget
from nextage_qp.manipulation.context import Grip, Setpoint, View
from nextage_qp.manipulation.phases.base import Phase, Spec, name_field
from nextage_qp.manipulation.phases.grasp import PADS
from nextage_qp.servo import Command


class ReleaseSpec(Spec):
    """Open the pads away from the object, then retreat upwards."""

    kind: Literal["release"]
    object: str = name_field("object")
    gap: float = Field(default=0.05, gt=0, description="How far the pads back away from the object [m].")
    lift: float = Field(default=0.08, ge=0, description="How far the pads then rise [m].")
    speed: float = Field(default=0.1, gt=0)


class Release(Phase):
    """Each pad backs away by ``gap`` along the object's lateral axis, then rises by ``lift``; the clamp ends."""

    spec: ReleaseSpec

    def start(self, view: View) -> None:  # noqa: D102
        c = self.spec
        _, rot = view.body_pose(c.object)
        self.frames = view.grip.frames if view.grip is not None else PADS
        self.points = [Setpoint(view.commanded_pose(f).pos) for f in self.frames]
        self.rots = [view.commanded_pose(f).rot for f in self.frames]
        sides = (1.0, -1.0)
        opened = [sp.pos + rot @ np.array([0.0, s * c.gap, 0.0]) for sp, s in zip(self.points, sides, strict=False)]
        self.stages = [opened, [p + np.array([0.0, 0.0, c.lift]) for p in opened]]
        self.stage = 0

    def update(self, view: View) -> Command:  # noqa: D102
        if self.stage < len(self.stages):
            goals = self.stages[self.stage]
            if all([sp.advance(g, self.spec.speed, view.dt) for sp, g in zip(self.points, goals, strict=True)]):
                self.stage += 1
        targets = tuple(FrameTarget(f, pos=sp.pos, rot=r) for f, sp, r in zip(self.frames, self.points, self.rots,
                                                                               strict=True))
        return Command(targets, done=self.stage == len(self.stages) and view.settled())

    def grip(self, current: Grip | None) -> Grip | None:  # noqa: D102
        return None  # the clamp ends as the pads start to open
