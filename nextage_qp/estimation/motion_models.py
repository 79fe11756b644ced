"""Motion models of :class:`~nextage_qp.estimation.imm.PoseKalman`.

Six decoupled position-velocity filters per model.
"""

from __future__ import annotations

import numpy as np


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


class ConstantVelocity:
    """Six decoupled constant-velocity Kalman filters (one per pose axis) with one process noise per axis."""

    def __init__(self, q: np.ndarray, r: np.ndarray) -> None:
        self.q, self.r = q, r
        self.x = np.zeros((6, 2))
        self.p = np.zeros((6, 2, 2))

    def predicted(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """State and covariance ``dt`` [s] ahead."""
        x = self.x.copy()
        x[:, 0] += dt * x[:, 1]
        p, q = self.p, self.q
        out = np.empty_like(p)
        out[:, 0, 0] = p[:, 0, 0] + dt * (p[:, 1, 0] + p[:, 0, 1]) + dt * dt * p[:, 1, 1] + q * dt**3 / 3.0
        out[:, 0, 1] = out[:, 1, 0] = p[:, 0, 1] + dt * p[:, 1, 1] + q * dt**2 / 2.0
        out[:, 1, 1] = p[:, 1, 1] + q * dt
        return x, out

    def pin(self) -> None:
        """Keep the state within the model (a no-op here; the resting model zeroes its velocity)."""

    def update(self, dt: float, z: np.ndarray, r: np.ndarray | None = None) -> np.ndarray:
        """Predict by ``dt``, apply ``z`` (noise ``r``, default the model's); each axis's log-likelihood (6,)."""
        x, p = self.predicted(dt)
        nu = z - x[:, 0]
        nu[3:] = wrap(nu[3:])
        s = p[:, 0, 0] + (self.r if r is None else r)
        k = p[:, :, 0] / s[:, None]  # (6, 2): gain of each axis
        self.x = x + k * nu[:, None]
        self.p = p - k[:, :, None] * p[:, None, 0, :]  # (I - K H) P
        return -0.5 * (nu * nu / s + np.log(2.0 * np.pi * s))


class Resting(ConstantVelocity):
    """Constant position: zero velocity, the position a random walk of density ``q`` [m^2/s]."""

    def predicted(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """State and covariance ``dt`` [s] ahead: the position waits, its variance grows by ``q dt``."""
        x = self.x.copy()
        x[:, 1] = 0.0
        p = np.zeros_like(self.p)
        p[:, 0, 0] = self.p[:, 0, 0] + self.q * dt
        return x, p

    def pin(self) -> None:
        """Zero the velocity and its covariance."""
        self.x[:, 1] = 0.0
        self.p[:, 1, :] = 0.0
        self.p[:, :, 1] = 0.0


def outer(d: np.ndarray) -> np.ndarray:
    """Per-axis outer products (6, 2, 2) of state differences (6, 2)."""
    return d[:, :, None] * d[:, None, :]
