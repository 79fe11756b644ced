"""Fitting the known shapes to depth points: the table plane by RANSAC, an object's pose by robust Gauss-Newton.

Arrays only (no simulator): :mod:`nextage_qp.sensing.camera.estimate` calls these on the points of one depth frame.
"""

from __future__ import annotations

import numpy as np

from nextage_qp.geometry import rot_of, rot_z
from nextage_qp.sensing.camera.shapes import ShapeModel

HUBER = 0.003
"""Residual [m] beyond which a point's weight falls off (robust fit)."""


def table_plane(points: np.ndarray, rng: np.random.Generator, iters: int = 80, tol: float = 0.005,
                max_tilt: float = 0.2) -> tuple[np.ndarray, float] | None:
    """The largest near-horizontal plane (unit normal n with n_z > 0, offset d: n . p = d) by RANSAC, or None."""
    if len(points) < 3:
        return None
    a, b, c = (points[rng.integers(0, len(points), iters)] for _ in range(3))  # every hypothesis at once
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    ok = norm > 1e-9
    n = n[ok] / norm[ok, None]
    n *= np.where(n[:, 2] >= 0, 1.0, -1.0)[:, None]
    keep = np.arccos(np.minimum(1.0, n[:, 2])) <= max_tilt
    n, a = n[keep], a[ok][keep]
    if not len(n):
        return None
    counts = (np.abs(points @ n.T - np.einsum("ij,ij->i", n, a)) < tol).sum(axis=0)
    k = int(np.argmax(counts))
    best = (n[k], float(n[k] @ a[k]))
    inliers = points[np.abs(points @ best[0] - best[1]) < tol]  # least squares on the inliers
    centre = inliers.mean(axis=0)
    n = np.linalg.svd(inliers - centre, full_matrices=False)[2][2]  # (the full U would be N x N)
    n = n if n[2] > 0 else -n
    return n, float(n @ centre)


def pose_rot(x: np.ndarray) -> np.ndarray:
    """The rotation of a fit's pose vector: (x, y, z, yaw), an upright object, or (x, y, z, roll, pitch, yaw)."""
    return rot_z(x[3]) if len(x) == 4 else rot_of(x[3:6])


def residuals(shape: ShapeModel, points: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Signed distances [m] of ``points`` to ``shape`` at pose ``x`` (see :func:`pose_rot`): > 0 outside."""
    return shape.sdf_at(points, x[:3], pose_rot(x))


def _both(shape: ShapeModel, points: np.ndarray, free: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Surface residuals of ``points``, then how deep the shape reaches into ``free`` space (seen through)."""
    r = residuals(shape, np.concatenate([points, free]) if len(free) else points, x)  # one call for both
    r[len(points):] = np.minimum(r[len(points):], 0.0)
    return r


def fit(shape: ShapeModel, points: np.ndarray, x0: np.ndarray, free: np.ndarray | None = None,
        iters: int = 12) -> tuple[np.ndarray, float]:
    """Pose of ``shape`` fitting ``points`` from ``x0`` (robust Gauss-Newton), and its RMS [m].

    The pose has the form of ``x0``: (x, y, z, yaw) for an upright object (one resting on the table), or (x, y, z,
    roll, pitch, yaw) for one that may tilt (one the robot holds: it turns in the grip).

    ``free``: points the camera saw through (just in front of the table it saw), which the shape may not contain:
    they pin a partial view (the hand covering part of the object) along the directions its own points leave free.
    """
    x = np.asarray(x0, dtype=float).copy()
    free = np.zeros((0, 3)) if free is None else free
    damping = 1e-6 * np.eye(len(x))
    for _ in range(iters):
        r, J, w = _linearised(shape, points, free, x)
        H = J.T @ (J * w[:, None]) + damping
        dx = -np.linalg.solve(H, J.T @ (w * r))
        x += dx
        if np.abs(dx[:3]).max() < 1e-5 and np.abs(dx[3:]).max() < 1e-4:
            break
    r = residuals(shape, points, x)
    return x, float(np.sqrt(np.mean(r * r)))


_STEPS = {4: np.array([1e-4, 1e-4, 1e-4, 1e-3]), 6: np.array([1e-4, 1e-4, 1e-4, 1e-3, 1e-3, 1e-3])}
"""Finite-difference steps of x, y, z [m] and the angles [rad], per form of the pose vector."""


def _linearised(shape: ShapeModel, points: np.ndarray, free: np.ndarray,
                x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals at ``x``, their Jacobian over the pose vector's entries and the robust (Huber) weights."""
    r = _both(shape, points, free, x)
    steps = _STEPS[len(x)]
    J = np.stack([(_both(shape, points, free, x + e) - r) / h for e, h in zip(np.diag(steps), steps, strict=True)],
                 axis=1)
    return r, J, np.minimum(1.0, HUBER / np.maximum(np.abs(r), 1e-12))


def planar_std(shape: ShapeModel, points: np.ndarray, x: np.ndarray, rms: float,
               free: np.ndarray | None = None, floor: float = 0.001) -> float:
    """Largest standard deviation [m] of a fit's horizontal position in any direction, from its residuals' spread.

    The fit's covariance, ``max(rms, floor)^2 (J^T W J)^-1``: large along a direction that the points seen (and the
    free space) leave unconstrained, e.g. a box seen only on faces parallel to it, the rest hidden by a hand.
    """
    _, J, w = _linearised(shape, points, np.zeros((0, 3)) if free is None else free, x)
    with np.errstate(all="ignore"):
        try:
            cov = max(rms, floor) ** 2 * np.linalg.inv(J.T @ (J * w[:, None]) + 1e-12 * np.eye(len(x)))
        except np.linalg.LinAlgError:
            return float("inf")
    return float(np.sqrt(max(np.linalg.eigvalsh(cov[:2, :2]).max(), 0.0)))
