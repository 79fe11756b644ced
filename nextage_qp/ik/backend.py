r"""Solve one IK QP with a qpsolvers backend; DAQP is called directly on reused arrays.

The problem is :math:`\min_x \tfrac12 x^T H x + c^T x` subject to :math:`lb \le x \le ub` (the joint box),
:math:`G x \le h` (collision rows) and :math:`A x = b` (a wheeled base's non-holonomic constraint). DAQP takes
the box as its native simple bounds and the rows as general inequalities (an equality: a row with equal bounds);
its bound and sense vectors are kept between calls, so a step allocates only what DAQP returns.
"""

from __future__ import annotations

import numpy as np
import qpsolvers

try:
    import daqp
except ImportError:  # pragma: no cover - daqp is a dependency, other backends still work
    daqp = None

_NO_LOWER = -1e30
"""DAQP's 'no lower bound' for a one-sided row."""
EQUALITY = 5
"""DAQP's sense of an equality row (active and immutable)."""


class QPSolver:
    """A reusable solver for IK QPs of ``n`` variables (any installed qpsolvers backend; DAQP called directly).

    Args:
        solver: qpsolvers backend name.
        n: Number of variables.
    """

    def __init__(self, solver: str, n: int) -> None:
        self.solver, self.n = solver, n
        self._direct = solver == "daqp" and daqp is not None
        self._no_rows = np.zeros((0, n))
        self._eq_rows = 0  # equality rows of the last call (their senses are in _sense)
        self._resize(16)

    def _resize(self, rows: int) -> None:
        n = self.n
        self._upper, self._lower = np.empty(n + rows), np.full(n + rows, _NO_LOWER)
        self._sense = np.zeros(n + rows, dtype=np.int32)

    def solve(self, H: np.ndarray, c: np.ndarray, lb: np.ndarray, ub: np.ndarray, G: np.ndarray | None = None,
              h: np.ndarray | None = None, A: np.ndarray | None = None,
              b: np.ndarray | None = None) -> np.ndarray | None:
        """The minimiser, or None when the solver found none (infeasible or failed)."""
        if not self._direct:
            result = qpsolvers.solve_problem(qpsolvers.Problem(H, c, G, h, A, b, lb=lb, ub=ub), solver=self.solver)
            return result.x if result.found else None
        n = self.n
        eq = 0 if A is None or b is None else len(b)  # equalities first: rows with equal bounds and sense 5
        ineq = 0 if G is None or h is None else len(h)
        rows = eq + ineq
        if n + rows > len(self._upper):
            self._resize(2 * rows)
        upper, lower, sense = self._upper[: n + rows], self._lower[: n + rows], self._sense[: n + rows]
        upper[:n], lower[:n] = ub, lb
        if eq or self._eq_rows:  # equality senses set, or left by the last call, in the reused vector
            self._sense[n:] = 0
            sense[n : n + eq] = EQUALITY
            upper[n : n + eq] = lower[n : n + eq] = b
            self._eq_rows = eq
        lower[n + eq :] = _NO_LOWER
        if ineq:
            upper[n + eq :] = h
        if not eq:
            a_mat = np.ascontiguousarray(G) if ineq else self._no_rows
        else:
            a_mat = np.ascontiguousarray(np.vstack([m for m in (A, G) if m is not None]) if ineq else A)
        x, _, exitflag, _ = daqp.solve(H, c, a_mat, upper, lower, sense)
        return x if exitflag > 0 else None
