"""Joint position and velocity limits of the IK QP as one box (collision rows: :mod:`nextage_qp.ik.collision`).

:class:`JointBoxLimit` merges mink's ``ConfigurationLimit`` and ``VelocityLimit`` into one box (15 bounds
instead of 60 rows), which :class:`~nextage_qp.ik.qp.QPIK` passes to the solver as ``lb``/``ub``. It subclasses
:class:`mink.Limit`, so it also works with plain :func:`mink.solve_ik`.
"""

from __future__ import annotations

from collections.abc import Sequence

import mink
import numpy as np
from mink.limits.limit import Constraint


class JointBoxLimit(mink.Limit):
    r"""Joint position and velocity limits as one box on the step :math:`\Delta q` [rad].

    .. math::

        \max(-g (q - q_{min}), -v_{max} dt) \le \Delta q \le \min(g (q_{max} - q), v_{max} dt)

    with limit gain :math:`g` and speed limit :math:`v_{max}` [rad/s] (``inf`` where unlimited).
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray, vmax: np.ndarray, gain: float = 0.95) -> None:
        self.lower, self.upper, self.vmax, self.gain = lower, upper, vmax, gain
        self._dt, self._step = 0.0, vmax * 0.0  # the step bound vmax dt [rad] of the last dt
        n = len(lower)
        self._G = np.vstack([np.eye(n), -np.eye(n)])

    def step_bound(self, dt: float) -> np.ndarray:
        r""":math:`v_{max}\,dt` [rad]: no step of ``dt`` [s] in the box moves a joint farther (a read-only array)."""
        if dt != self._dt:
            self._dt, self._step = dt, self.vmax * dt
            self._step.setflags(write=False)
        return self._step

    def bounds(self, q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        r"""``(lb, ub)`` of :math:`\Delta q` at configuration ``q`` for a step of ``dt`` [s]."""
        step = self.step_bound(dt)
        lb = q - self.lower
        lb *= -self.gain
        np.maximum(lb, -step, out=lb)
        ub = self.upper - q
        ub *= self.gain
        np.minimum(ub, step, out=ub)
        return lb, ub

    def violated(self, q: np.ndarray, lb: np.ndarray, ub: np.ndarray, names: Sequence[str]) -> list[str]:
        """One line per joint whose step bounds ``(lb, ub)`` exclude zero or cross (named by ``names``)."""
        return [
            f"joint {names[int(i)]} at {q[i]:.4f} rad outside [{self.lower[i]:.4f}, {self.upper[i]:.4f}]"
            f" with step bound {self.vmax[i]:.3g} rad/s"
            for i in np.flatnonzero((lb > 0) | (ub < 0) | (lb > ub))
        ]

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> Constraint:
        """The box as rows ``[I; -I] dq <= [ub; -lb]`` (for use with plain mink)."""
        lb, ub = self.bounds(configuration.q, dt)
        return Constraint(G=self._G, h=np.concatenate([ub, -lb]))
