"""Errors of one object's pose estimate against the truth, gathered through a run for its ``estimation`` report."""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from typing import Any

SHOVE_SETTLE_S = 0.5
"""How long after a shove's force window the estimate is counted as *in the shove* [s]. A shove flings an object
(a 0.15 N s shove sends a 60 g cube off at 2.5 m/s) that no camera has seen yet; friction stops it within about
0.3 s, and the filter has caught up a few measurements later."""


class EstimateErrors:
    """Squared position errors and absolute yaw errors of the measurements and of the estimate.

    ``raw``: each measurement against the pose it describes (the camera's noise); ``estimate``: the pose the phases
    saw, every tick; ``held``: the latest measurement against the truth at every tick (what the phases would see
    without a filter: noise, latency and the wait for the next measurement).
    """

    def __init__(self) -> None:
        self.raw_sq: list[float] = []
        self.raw_yaw: list[float] = []
        self.t: list[float] = []
        self.est_sq: list[float] = []
        self.est_yaw: list[float] = []
        self.held_sq: list[float] = []

    def measurement(self, sq: float, yaw: float) -> None:
        """A measurement's squared position error [m²] and absolute yaw error [rad]."""
        self.raw_sq.append(sq)
        self.raw_yaw.append(yaw)

    def tick(self, t: float, sq: float, yaw: float, held_sq: float) -> None:
        """The estimate's errors at ``t`` [s] and the squared error of the latest raw measurement then."""
        self.t.append(t)
        self.est_sq.append(sq)
        self.est_yaw.append(yaw)
        self.held_sq.append(held_sq)

    def report(self, shoves: Sequence[tuple[float, float]] = (),
               views: Sequence[tuple[float, bool]] | None = None) -> dict[str, Any]:
        """RMS and max errors [m, rad] of the run so far.

        ``estimate_outside_shoves_rms_m`` leaves out the ticks within the ``shoves`` spans (start, end) [s] of
        this object (None when every tick is inside one); ``shove_ticks`` counts the ticks left out.
        ``views``: a robot camera's frames (time [s], whether the object was in view and uncovered in it); then
        ``estimate_unoccluded_rms_m`` is the estimate's RMS over the ticks whose latest frame had it so, and
        ``unoccluded_ticks`` their number.
        """
        outside = [sq for t, sq in zip(self.t, self.est_sq, strict=True) if not any(a <= t < b for a, b in shoves)]
        seen = {}
        if views is not None:
            times, clear = [v[0] for v in views], [v[1] for v in views]
            kept = [sq for t, sq in zip(self.t, self.est_sq, strict=True)
                    if (k := bisect.bisect_right(times, t + 1e-9)) > 0 and clear[k - 1]]
            seen = {"estimate_unoccluded_rms_m": _rms(kept), "unoccluded_ticks": len(kept)}
        return {**seen,
            "estimate_rms_m": _rms(self.est_sq), "estimate_max_m": _max_sqrt(self.est_sq),
            "estimate_outside_shoves_rms_m": _rms(outside), "shove_ticks": len(self.est_sq) - len(outside),
            "estimate_yaw_rms_rad": _rms([y * y for y in self.est_yaw]),
            "raw_rms_m": _rms(self.raw_sq), "raw_max_m": _max_sqrt(self.raw_sq),
            "raw_yaw_rms_rad": _rms([y * y for y in self.raw_yaw]),
            "held_rms_m": _rms(self.held_sq), "held_max_m": _max_sqrt(self.held_sq),
        }


def _rms(squares: list[float]) -> float | None:
    return math.sqrt(sum(squares) / len(squares)) if squares else None


def _max_sqrt(squares: list[float]) -> float | None:
    return math.sqrt(max(squares)) if squares else None
