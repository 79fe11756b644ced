r"""A wheeled base's rows in the IK QP: what its wheels allow the base's planar step to be.

The IK's base variables are the world step :math:`(\Delta x, \Delta y, \Delta\psi)` of the base's reference point
over one control period :math:`\Delta t`; at heading :math:`\psi` its forward and lateral steps are
:math:`\Delta s = \cos\psi\,\Delta x + \sin\psi\,\Delta y` and :math:`\Delta n = -\sin\psi\,\Delta x +
\cos\psi\,\Delta y`.

* **Non-holonomic constraint** (differential drive; a bicycle at its rear axle): a hard equality
  :math:`\Delta n = 0`: the base never slides sideways.
* **Wheel speeds** (the driven wheels): :math:`|\Delta s \pm l\,\Delta\psi| \le r\,\dot\varphi_{max}\,\Delta t`,
  four inequalities.
* **Curvature** (bicycle, forward only): :math:`|\Delta\psi| \le \kappa\,\Delta s` with
  :math:`\kappa = \tan\delta_{max} / L`: two inequalities, which also make :math:`\Delta s \ge 0`.

A holonomic base has none of these (its speed is the box of the QP).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from nextage_qp.mobile.base import MobileBase


class BaseRows:
    """The QP rows of a base (see the module docstring); the base's variables are the IK's first three."""

    def __init__(self, base: MobileBase) -> None:
        self.type = base.type
        self.half_track, self.radius = base.drive.half_track, base.drive.wheel_radius
        self.wheel_speed = base.limits.wheel_speed
        self.curvature = (math.tan(base.limits.steer) / base.bicycle.wheelbase) if base.bicycle is not None else None

    def rows(self, yaw: float, dt: float, nv: int) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray,
                                                           np.ndarray]:
        """``(A, b, G, h)`` at heading ``yaw`` [rad] for a step of ``dt`` [s]: ``A x = b`` and ``G x <= h``.

        ``A`` and ``b`` are None for a holonomic base; its ``G`` has no rows.
        """
        if self.type == "holonomic":
            return None, None, np.zeros((0, nv)), np.zeros(0)
        c, s = math.cos(yaw), math.sin(yaw)
        forward = np.zeros(nv)
        forward[:2] = c, s
        lateral = np.zeros((1, nv))
        lateral[0, :2] = -s, c
        turn = np.zeros(nv)
        turn[2] = 1.0
        bound = self.radius * self.wheel_speed * dt
        g = [forward + self.half_track * turn, forward - self.half_track * turn]
        g += [-row for row in g]
        h = [bound] * 4
        if self.curvature is not None:
            g += [turn - self.curvature * forward, -turn - self.curvature * forward]
            h += [0.0, 0.0]
        return lateral, np.zeros(1), np.array(g), np.array(h)
