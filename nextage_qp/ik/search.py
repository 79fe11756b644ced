"""The bookkeeping of an offline solve's descents: each descent's outcome, and the best of them so far."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Descent(NamedTuple):
    """The outcome of one descent of :meth:`~nextage_qp.ik.qp.QPIK.solve`.

    Attributes:
        score: Position error over ``pos_tol`` plus orientation error over ``rot_tol`` at ``q``.
        q: The best IK variables the descent reached.
        pos_err: Largest position error at ``q`` [m].
        rot_err: Largest orientation error at ``q`` [rad].
        iters: IK steps taken.
        status: ``converged``, ``max_iters`` or ``stalled``.
    """

    score: float
    q: np.ndarray
    pos_err: float
    rot_err: float
    iters: int
    status: str


class Search:
    """The best outcome of a solve's descents so far, and the iterations they took.

    Args:
        good_enough: Position [m] and orientation [rad] errors at which the search is done (or None).
    """

    def __init__(self, good_enough: tuple[float, float] | None) -> None:
        self.good_enough = good_enough
        self.best: tuple[float, np.ndarray, float, float, str] | None = None
        """(score, q, position error, orientation error, status) of the best outcome."""
        self.iters = 0

    def keep(self, outcome: tuple[float, np.ndarray, float, float, int, str]) -> bool:
        """Count a descent's ``outcome`` (score, q, errors, iterations, status); True when the search is done."""
        self.iters += outcome[4]
        if self.best is None or outcome[0] < self.best[0]:
            self.best = (outcome[0], outcome[1], outcome[2], outcome[3], outcome[5])
        best, errors = self.best, self.good_enough
        return outcome[5] == "converged" or (errors is not None and best[2] <= errors[0] and best[3] <= errors[1])
