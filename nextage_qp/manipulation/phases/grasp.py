"""``grasp``: clamp an object between two pads: open approach, close past the surface, hold."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.geometry import rot_z, yaw_of
from nextage_qp.ik import FrameTarget, RelativeTarget
from nextage_qp.manipulation.context import Grip, Setpoint, View
from nextage_qp.manipulation.phases.base import MAX_SECONDS, Phase, Spec, name_field
from nextage_qp.nextage import ARMS
from nextage_qp.servo import Command

PADS = tuple(arm.pad_site for arm in ARMS)


class GraspSpec(Spec):
    """Clamp an object between two pad frames by squeezing along the object's lateral (y) axis."""

    kind: Literal["grasp"]
    object: str = name_field("object")
    frames: tuple[str, str] = name_field("frame", default=PADS, description="Pads on the +y and -y side.")
    half_width: float = Field(gt=0, description="Half the object's width between the pads [m].")
    height: float = Field(default=0.0, description="Pad height relative to the object origin [m].")
    gap: float = Field(default=0.04, gt=0, description="Pad distance from the surface before closing [m].")
    squeeze: float = Field(default=0.01, ge=0, description="How far the pad targets go inside the surface [m].")
    hold: float = Field(default=0.3, ge=0, le=MAX_SECONDS, description="Time the squeeze is held [s].")
    speed: float = Field(default=0.1, gt=0, description="Approach speed [m/s].")


class Grasp(Phase):
    """Clamp between the pads, leaving a :class:`~nextage_qp.manipulation.context.Grip`.

    The pads approach ``gap`` outside the object's sides, close to ``squeeze`` inside them at half speed and
    hold for ``hold``.
    """

    spec: GraspSpec

    def start(self, view: View) -> None:  # noqa: D102
        c = self.spec
        obj, rot = view.body_pose(c.object)
        self.rz = rot_z(yaw_of(rot))

        def at(dy: float) -> list[np.ndarray]:
            return [obj + self.rz @ np.array([0.0, s * dy, c.height]) for s in (1.0, -1.0)]

        self.stages = [(at(c.half_width + c.gap), c.speed), (at(c.half_width - c.squeeze), c.speed / 2)]
        self.stage = 0
        self.hold_from: float | None = None
        self.points = [Setpoint(view.commanded_pose(f).pos) for f in c.frames]
        self.made: Grip | None = None

    def update(self, view: View) -> Command:  # noqa: D102
        c = self.spec
        if self.stage < len(self.stages):
            goals, speed = self.stages[self.stage]
            reached = all([sp.advance(g, speed, view.dt) for sp, g in zip(self.points, goals, strict=True)])
            if reached and (self.stage > 0 or view.settled()):
                self.stage += 1
                self.hold_from = view.t
        targets = tuple(FrameTarget(f, pos=sp.pos, rot=self.rz) for f, sp in zip(c.frames, self.points, strict=True))
        done = self.hold_from is not None and self.stage == len(self.stages) and view.t - self.hold_from >= c.hold
        if done:
            obj, rot = view.body_pose(c.object)
            poses = {f: view.commanded_pose(f) for f in c.frames}
            self.made = Grip(
                object=c.object,
                frames=tuple(c.frames),
                offsets={f: rot.T @ (sp.pos - obj) for f, sp in zip(c.frames, self.points, strict=True)},
                rotations={f: rot.T @ self.rz for f in c.frames},
                relative=RelativeTarget.between(c.frames[0], c.frames[1], poses, cost=1.0),
            )
        return Command(targets, done=done)

    def grip(self, current: Grip | None) -> Grip | None:  # noqa: D102
        return self.made if self.made is not None else current
