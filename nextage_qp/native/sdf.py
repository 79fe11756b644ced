"""The signed distance of a union of convex parts, compiled (numba): one call per fit residual, not an array each part.

:class:`~nextage_qp.sensing.camera.shapes.ShapeModel` packs its parts into arrays (:func:`pack`) and
:func:`union_sdf` evaluates them point by point, the formulas of the shapes' own doc (box, cylinder, capsule, sphere,
convex mesh by its face planes). A fit evaluates the shape some eighty times per depth frame: the array version spent
most of a camera dock's estimate time in numpy's per-call overhead on a few hundred points.
"""

from __future__ import annotations

import numpy as np
from numba import njit

BOX, CYLINDER, CAPSULE, SPHERE, MESH = range(5)
"""Part kind codes (:func:`pack`)."""
KINDS = {"box": BOX, "cylinder": CYLINDER, "capsule": CAPSULE, "sphere": SPHERE, "mesh": MESH}
"""Part kind names to codes."""


def pack(parts) -> tuple[np.ndarray, ...]:
    """Arrays of ``parts`` (each with ``kind``, ``size``, ``pos``, ``rot``, ``planes``) for :func:`union_sdf`.

    Returns (kinds, sizes (k, 3), positions (k, 3), rotations (k, 3, 3), first plane per part (k + 1),
    planes (m, 4)); a mesh's size (its vertices) is not needed, its planes are.
    """
    kinds = np.array([KINDS[p.kind] for p in parts], dtype=np.int64)
    sizes = np.zeros((len(parts), 3))
    for k, p in enumerate(parts):
        if p.kind != "mesh":
            s = np.asarray(p.size, dtype=float).ravel()[:3]
            sizes[k, : len(s)] = s
    pos = np.array([np.asarray(p.pos, dtype=float) for p in parts]).reshape(len(parts), 3)
    rot = np.array([np.asarray(p.rot, dtype=float) for p in parts]).reshape(len(parts), 3, 3)
    blocks = [np.asarray(p.planes, dtype=float) if p.kind == "mesh" else np.zeros((0, 4)) for p in parts]
    first = np.cumsum([0, *(len(b) for b in blocks)]).astype(np.int64)
    planes = np.concatenate(blocks) if blocks else np.zeros((0, 4))
    return kinds, sizes, pos, rot, first, np.ascontiguousarray(planes)


@njit(cache=True)
def union_sdf(points: np.ndarray, t: np.ndarray, R: np.ndarray, kinds: np.ndarray, sizes: np.ndarray,
              pos: np.ndarray, rot: np.ndarray, first: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """Signed distance [m] of world ``points`` (n, 3) to the union placed at ``t`` turned by ``R`` (negative inside).

    The object-frame point is ``(p - t) @ R``, each part's ``(that - pos) @ rot``, as the array version computes them.
    """  # (compiled: coverage does not see its lines)
    n, k = points.shape[0], kinds.shape[0]
    out = np.empty(n)
    for i in range(n):
        px, py, pz = points[i, 0] - t[0], points[i, 1] - t[1], points[i, 2] - t[2]
        lx = px * R[0, 0] + py * R[1, 0] + pz * R[2, 0]
        ly = px * R[0, 1] + py * R[1, 1] + pz * R[2, 1]
        lz = px * R[0, 2] + py * R[1, 2] + pz * R[2, 2]
        best = np.inf
        for j in range(k):
            qx, qy, qz = lx - pos[j, 0], ly - pos[j, 1], lz - pos[j, 2]
            a = qx * rot[j, 0, 0] + qy * rot[j, 1, 0] + qz * rot[j, 2, 0]
            b = qx * rot[j, 0, 1] + qy * rot[j, 1, 1] + qz * rot[j, 2, 1]
            c = qx * rot[j, 0, 2] + qy * rot[j, 1, 2] + qz * rot[j, 2, 2]
            kind = kinds[j]
            if kind == BOX:
                ex, ey, ez = abs(a) - sizes[j, 0], abs(b) - sizes[j, 1], abs(c) - sizes[j, 2]
                mx, my, mz = max(ex, 0.0), max(ey, 0.0), max(ez, 0.0)
                d = np.sqrt(mx * mx + my * my + mz * mz) + min(max(ex, max(ey, ez)), 0.0)
            elif kind == CYLINDER:
                er, ez = np.sqrt(a * a + b * b) - sizes[j, 0], abs(c) - sizes[j, 1]
                mr, mz = max(er, 0.0), max(ez, 0.0)
                d = np.sqrt(mr * mr + mz * mz) + min(max(er, ez), 0.0)
            elif kind == CAPSULE:
                z = min(max(c, -sizes[j, 1]), sizes[j, 1])
                d = np.sqrt(a * a + b * b + (c - z) * (c - z)) - sizes[j, 0]
            elif kind == SPHERE:
                d = np.sqrt(a * a + b * b + c * c) - sizes[j, 0]
            else:  # a convex mesh: the farthest face plane
                d = -np.inf
                for m in range(first[j], first[j + 1]):
                    d = max(d, a * planes[m, 0] + b * planes[m, 1] + c * planes[m, 2] - planes[m, 3])
            best = min(best, d)
        out[i] = best
    return out
