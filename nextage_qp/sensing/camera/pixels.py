"""Pixels and world points of a pinhole depth camera (MuJoCo's convention: x right, y up, looking along -z)."""

from __future__ import annotations

import numpy as np


def backproject(depth: np.ndarray, K: np.ndarray, pos: np.ndarray, rot: np.ndarray,
                rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """World points (n, 3) of pixels (rows, cols) with depth (the distance along the optical axis)."""
    z = depth[rows, cols].astype(float)
    x = (cols + 0.5 - K[0, 2]) / K[0, 0] * z
    y = -(rows + 0.5 - K[1, 2]) / K[1, 1] * z
    return pos + np.stack([x, y, -z], axis=1) @ rot.T


def project(points: np.ndarray, K: np.ndarray, pos: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, ...]:
    """Pixel rows, cols and depth of world points (depth <= 0: behind the camera)."""
    c = (points - pos) @ rot
    z = -c[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        cols = K[0, 0] * c[:, 0] / z + K[0, 2] - 0.5
        rows = -K[1, 1] * c[:, 1] / z + K[1, 2] - 0.5
    return np.rint(rows).astype(int), np.rint(cols).astype(int), z


def plane_height(depth: np.ndarray, K: np.ndarray, pos: np.ndarray, rot: np.ndarray, normal: np.ndarray,
                 offset: float) -> np.ndarray:
    """Height [m] of every pixel's point over the plane ``normal . p = offset`` (H, W); NaN where the depth is NaN.

    :func:`backproject` of every pixel, dotted with the normal, without forming the points: the camera-frame point
    is ``z (u, v, -1)`` with ``u``, ``v`` per column and per row, so the height is ``pos . n - offset + z (u w_x + v
    w_y - w_z)`` with ``w`` the normal in the camera frame.
    """
    w = rot.T @ normal
    h, wd = depth.shape
    u = (np.arange(wd) + 0.5 - K[0, 2]) / K[0, 0] * w[0]
    v = -(np.arange(h) + 0.5 - K[1, 2]) / K[1, 1] * w[1] - w[2]
    return float(pos @ normal - offset) + depth.astype(float) * (v[:, None] + u[None, :])
