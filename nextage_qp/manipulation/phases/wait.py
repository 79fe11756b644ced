"""``wait``: hold the commanded joints for a while."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from nextage_qp.loop.servo import HOLD, Command
from nextage_qp.manipulation.context import View
from nextage_qp.manipulation.phases.base import DEFAULT_TIMEOUT, MAX_SECONDS, Phase, Spec


class WaitSpec(Spec):
    """Hold the current references for a while."""

    kind: Literal["wait"]
    duration: float = Field(gt=0, le=MAX_SECONDS, description="How long the references are held [s] (the default "
                                                              "timeout stretches to it plus 1 s).")

    @model_validator(mode="after")
    def _covered(self) -> WaitSpec:
        """Stretch the default timeout to cover the duration (plus 1 s); refuse a timeout set shorter.

        A wait whose timeout ends first could only time out.
        """
        if self.timeout is None:
            object.__setattr__(self, "timeout", max(DEFAULT_TIMEOUT, self.duration + 1.0))  # frozen model
        elif self.timeout <= self.duration:
            raise ValueError(f"timeout ({self.timeout:g} s) must exceed duration ({self.duration:g} s)")
        return self


class Wait(Phase):
    """Holds until ``duration`` has passed."""

    spec: WaitSpec

    def start(self, view: View) -> None:  # noqa: D102
        self.t0 = view.t

    def update(self, view: View) -> Command:  # noqa: D102
        return Command(done=True) if view.t - self.t0 >= self.spec.duration else HOLD
