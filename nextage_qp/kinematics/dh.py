r"""Forward kinematics from a modified (Craig) Denavit-Hartenberg table, as taught in the lecture.

Row i of the table holds :math:`(\alpha_{i-1}, a_{i-1}, d_i, \theta_i^{0})` and the link transform is

.. math::

    {}^{i-1}T_i = R_x(\alpha_{i-1})\, D_x(a_{i-1})\, R_z(\theta_i)\, D_z(d_i),
    \qquad \theta_i = \theta_i^{0} + q_i

with angles in [rad] and lengths in [m]. All joints are revolute.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from nextage_qp.errors import ConfigError


class DHRow(NamedTuple):
    """One row of a modified DH table: alpha_{i-1} [rad], a_{i-1} [m], d_i [m], theta offset [rad]."""

    alpha: float
    a: float
    d: float
    theta: float = 0.0


def dh_transform(row: DHRow, q: float) -> np.ndarray:
    """Homogeneous transform :math:`{}^{i-1}T_i` of one modified-DH row at joint angle ``q`` [rad]."""
    ca, sa = np.cos(row.alpha), np.sin(row.alpha)
    ct, st = np.cos(row.theta + q), np.sin(row.theta + q)
    return np.array(
        [
            [ct, -st, 0.0, row.a],
            [st * ca, ct * ca, -sa, -sa * row.d],
            [st * sa, ct * sa, ca, ca * row.d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def dh_fk(table: Sequence[DHRow], q: Sequence[float] | np.ndarray, *, upto: int | None = None) -> np.ndarray:
    """Transform of frame ``upto`` (default: the last) in frame 0: the product of the link transforms.

    Raises:
        ConfigError: ``q`` does not have one angle per table row.
    """
    q = np.asarray(q, dtype=float)
    if q.shape != (len(table),):
        raise ConfigError(f"DH table has {len(table)} rows but q has shape {q.shape}")
    t = np.eye(4)
    for row, qi in list(zip(table, q, strict=True))[: upto if upto is not None else len(table)]:
        t = t @ dh_transform(row, float(qi))
    return t


PUMA560_A2 = 0.4318
PUMA560_A3 = 0.0203
PUMA560_D3 = 0.1500
PUMA560_D4 = 0.4318

PUMA560: tuple[DHRow, ...] = (
    DHRow(0.0, 0.0, 0.0),
    DHRow(-np.pi / 2, 0.0, 0.0),
    DHRow(0.0, PUMA560_A2, PUMA560_D3),
    DHRow(-np.pi / 2, PUMA560_A3, PUMA560_D4),
    DHRow(np.pi / 2, 0.0, 0.0),
    DHRow(-np.pi / 2, 0.0, 0.0),
)
"""The PUMA 560 in Craig's modified DH parameters (Introduction to Robotics, Fig. 3.21) [m, rad]."""
