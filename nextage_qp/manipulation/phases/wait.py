"""``wait``: hold the commanded joints for a while."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from nextage_qp.manipulation.context import View
from nextage_qp.manipulation.phases.base import MAX_SECONDS, Phase, Spec
from nextage_qp.servo import HOLD, Command


class WaitSpec(Spec):
    """Hold the current references for a while."""

    kind: Literal["wait"]
    duration: float = Field(gt=0, le=MAX_SECONDS, description="[s]")


class Wait(Phase):
    """Holds until ``duration`` has passed."""

    spec: WaitSpec

    def start(self, view: View) -> None:  # noqa: D102
        self.t0 = view.t

    def update(self, view: View) -> Command:  # noqa: D102
        return Command(done=True) if view.t - self.t0 >= self.spec.duration else HOLD
