"""``joints``: drive named joints to angles while the others hold."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import View
from nextage_qp.manipulation.phases.base import Phase, Spec, name_field


class JointsSpec(Spec):
    """Drive named joints to positions (others hold)."""

    kind: Literal["joints"]
    positions: dict[str, float] = name_field("joint", min_length=1, description="Joint -> angle [rad].")
    tolerance: float = Field(default=0.01, gt=0, description="Joint tolerance [rad].")


class Joints(Phase):
    """Sends the joint goal every tick.

    Done when every named joint is within ``tolerance`` of its goal, every joint within ``tolerance`` of its
    commanded position (so the next phase starts where the robot is), and the robot has settled.
    """

    spec: JointsSpec

    def start(self, view: View) -> None:  # noqa: D102
        self.names = tuple(self.spec.positions)
        self.goal = np.array(list(self.spec.positions.values()))

    def update(self, view: View) -> Command:  # noqa: D102
        err = float(np.max(np.abs(view.joint_positions(self.names) - self.goal)))
        self.info["joint_error_rad"] = err
        tol = self.spec.tolerance
        done = err < tol and view.tracking_error() < tol and view.settled()
        return Command(joints=self.spec.positions, done=done)
