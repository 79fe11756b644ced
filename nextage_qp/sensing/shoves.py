"""External shoves: the impulses of a ``faults.shoves`` list, applied through MuJoCo's ``xfrc_applied``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from nextage_qp.sensing.faults import Shove


class Shoves:
    """Applies a config's shoves through ``xfrc_applied`` (force = impulse / window, over whole control ticks).

    Args:
        shoves: The config's shoves.
        body_ids: Body name -> MuJoCo body id.
        ctrl_dt: The control period [s] (the window is rounded to whole ticks).
    """

    def __init__(self, shoves: Sequence[Shove], body_ids: Mapping[str, int], ctrl_dt: float) -> None:
        self.shoves, self.body_ids, self.ctrl_dt = list(shoves), body_ids, ctrl_dt
        self._ticks = [max(1, round(s.duration_s / ctrl_dt)) for s in self.shoves]
        self._force = [np.asarray(s.impulse_ns) / (n * ctrl_dt) for s, n in zip(self.shoves, self._ticks, strict=True)]
        self._left: list[int | None] = [None for _ in self.shoves]  # ticks of force still to apply; -1: done
        self.applied: list[dict[str, Any]] = []
        self._spans: list[tuple[str, float, float]] = []  # (body, first tick, end of the force window) [s]

    def update(self, data: Any, t: float, phase: tuple[str, str, float] | None) -> None:
        """Before a tick at ``t`` [s]: start due shoves, set the force of the running ones, clear finished ones.

        ``phase`` is the current phase's (name, kind, start time [s]), or None.
        """
        for i, s in enumerate(self.shoves):
            left = self._left[i]
            if left is None:
                if not self._due(s, t, phase):
                    continue
                left = self._ticks[i]
                self.applied.append({"body": s.body, "t_s": round(t, 6), "impulse_ns": list(s.impulse_ns),
                                     "phase": phase[0] if phase else None})
                self._spans.append((s.body, t, t + left * self.ctrl_dt))
            bid = self.body_ids[s.body]
            if left > 0:
                data.xfrc_applied[bid, :3] = self._force[i]
                self._left[i] = left - 1
            elif left == 0:
                data.xfrc_applied[bid, :3] = 0.0
                self._left[i] = -1

    def windows(self, settle: float) -> list[tuple[str, float, float]]:
        """(body, start, end) [s] of each applied shove: its force window and ``settle`` seconds after it."""
        return [(body, t0, t1 + settle) for body, t0, t1 in self._spans]

    @staticmethod
    def _due(s: Shove, t: float, phase: tuple[str, str, float] | None) -> bool:
        if s.at_s is not None:
            return t + 1e-9 >= s.at_s
        return phase is not None and s.phase in phase[:2] and t + 1e-9 >= phase[2] + s.after_s
