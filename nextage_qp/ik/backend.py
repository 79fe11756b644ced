"""Solve one IK QP with a qpsolvers backend; DAQP is called directly with the joint box as simple bounds."""

from __future__ import annotations

import numpy as np
import qpsolvers

try:
    import daqp
except ImportError:  # pragma: no cover - daqp is a dependency, other backends still work
    daqp = None


def solve_qp(problem: qpsolvers.Problem, solver: str) -> np.ndarray | None:
    """The minimiser of ``problem`` (``lb``/``ub`` box plus ``G x <= h`` rows), or None if none was found."""
    if solver == "daqp" and daqp is not None:
        return _solve_daqp(problem)
    result = qpsolvers.solve_problem(problem, solver=solver)
    return result.x if result.found else None


def _solve_daqp(problem: qpsolvers.Problem) -> np.ndarray | None:
    """DAQP without qpsolvers' conversion: the box as DAQP's native simple bounds, rows as inequalities."""
    n = len(problem.q)
    rows = 0 if problem.G is None else len(problem.G)
    a_mat = np.zeros((0, n)) if problem.G is None else np.ascontiguousarray(problem.G)
    upper = np.concatenate([problem.ub, problem.h]) if problem.h is not None else np.asarray(problem.ub)
    lower = np.concatenate([problem.lb, np.full(rows, -1e30)])
    sense = np.zeros(n + rows, dtype=np.int32)
    x, _, exitflag, _ = daqp.solve(problem.P, problem.q, a_mat, upper, lower, sense)
    return x if exitflag > 0 else None
