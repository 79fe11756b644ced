"""External shoves: the impulses of a ``faults.shoves`` list, applied through MuJoCo's ``xfrc_applied``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from nextage_qp.faults import Shove


class Shoves:
    """Applies a config's shoves through ``xfrc_applied`` (force = impulse / window, over whole control ticks).

    Args:
        shoves: The config's shoves.
        body_ids: Body name -> MuJoCo body id.
        ctrl_dt: The control period [s] (the window is rounded to whole ticks).
    """

    def __init__(self, shoves: Sequence[Shove], body_ids: Mapping[str, int], ctrl_dt: float) -> None:
        self.shoves, self.body_ids, self.ctrl_dt = list(shoves), body_ids, ctrl_dt
        self._left = [0 for _ in self.shoves]  # ticks of force still to apply (-1: done)
        self.applied: list[dict[str, Any]] = []

    def update(self, data: Any, t: float, phase: tuple[str, str, float] | None) -> None:
        """Before a tick at ``t`` [s]: start due shoves and set the force of the running ones.

        ``phase`` is the current phase's (name, kind, start time [s]), or None.
        """
        for i, s in enumerate(self.shoves):
            bid = self.body_ids[s.body]
            if self._left[i] == 0 and self._due(s, t, phase):
                ticks = max(1, round(s.duration_s / self.ctrl_dt))
                self._left[i] = ticks
                self.applied.append({"body": s.body, "t_s": round(t, 6), "impulse_ns": list(s.impulse_ns),
                                     "phase": phase[0] if phase else None})
            if self._left[i] > 0:
                ticks = max(1, round(s.duration_s / self.ctrl_dt))
                data.xfrc_applied[bid, :3] = np.asarray(s.impulse_ns) / (ticks * self.ctrl_dt)
                self._left[i] -= 1
                if self._left[i] == 0:
                    self._left[i] = -1
            elif self._left[i] == -1:
                data.xfrc_applied[bid, :3] = 0.0
                self._left[i] = -2

    @staticmethod
    def _due(s: Shove, t: float, phase: tuple[str, str, float] | None) -> bool:
        if s.at_s is not None:
            return t + 1e-9 >= s.at_s
        return phase is not None and s.phase in phase[:2] and t + 1e-9 >= phase[2] + s.after_s
