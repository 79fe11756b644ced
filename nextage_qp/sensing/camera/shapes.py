"""Known shape models of the objects: signed distance, surface samples, resting height, from the model's geoms.

A shape is the union of an object's geoms (box, cylinder, capsule, sphere, ellipsoid approximated by a sphere,
convex mesh such as a prism) in the object's frame. Only the model's constant geometry is read (types, sizes,
local poses, mesh vertices), never the simulation's state.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.spatial import ConvexHull

from nextage_qp.geometry import geom_parts
from nextage_qp.native.sdf import pack, union_sdf

_T = mujoco.mjtGeom
_KINDS = {_T.mjGEOM_BOX: "box", _T.mjGEOM_CYLINDER: "cylinder", _T.mjGEOM_CAPSULE: "capsule",
          _T.mjGEOM_SPHERE: "sphere", _T.mjGEOM_ELLIPSOID: "sphere", _T.mjGEOM_MESH: "mesh"}


_ORIGIN, _IDENTITY = np.zeros(3), np.eye(3)


@dataclass(frozen=True)
class Part:
    """One convex part: its type, size, and pose in the object's frame."""

    kind: str
    size: np.ndarray  # MuJoCo's geom size; a convex mesh's vertices
    pos: np.ndarray
    rot: np.ndarray
    planes: np.ndarray | None = None  # (k, 4) outward normals and offsets of a convex mesh: n . p <= d inside


def _sdf_local(part: Part, p: np.ndarray) -> np.ndarray:
    """Signed distance [m] of points ``p`` (n, 3) in the part's frame (negative inside)."""
    s = part.size
    if part.kind == "box":
        q = np.abs(p) - s[:3]
        return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
    if part.kind == "cylinder":
        d = np.stack([np.linalg.norm(p[:, :2], axis=1) - s[0], np.abs(p[:, 2]) - s[1]], axis=1)
        return np.linalg.norm(np.maximum(d, 0.0), axis=1) + np.minimum(d.max(axis=1), 0.0)
    if part.kind == "capsule":
        z = np.clip(p[:, 2], -s[1], s[1])
        return np.linalg.norm(p - np.stack([0 * z, 0 * z, z], axis=1), axis=1) - s[0]
    if part.kind == "sphere":
        return np.linalg.norm(p, axis=1) - s[0]
    assert part.planes is not None  # convex mesh: the farthest face plane (exact on the faces)
    return (p @ part.planes[:, :3].T - part.planes[:, 3]).max(axis=1)


class ShapeModel:
    """An object's shape (see the module docstring), with its yaw symmetry [rad] (0: none)."""

    def __init__(self, parts: list[Part], symmetry: float) -> None:
        self.parts, self.symmetry = parts, symmetry
        self._packed = pack(parts)  # the parts as arrays, for the compiled signed distance
        self.samples = self._sample()
        self.normals = self._gradient(self.samples)
        self.lean = np.einsum("ij,ij->i", self.normals, self.samples)  # each sample's normal . its position [m]
        self.bottom = float(self.samples[:, 2].min())  # lowest point below the origin [m] (< 0)
        self.radius = float(np.linalg.norm(self.samples[:, :2], axis=1).max())
        self.reach = float(np.linalg.norm(self.samples, axis=1).max())  # from the origin in any direction [m]

    def box_corners(self, pos: np.ndarray, rot: np.ndarray, margin: float) -> np.ndarray:
        """The eight world corners (8, 3) of the shape's bounding box in its own frame, grown by ``margin`` [m].

        The box placed at ``pos`` and turned by ``rot``.
        """
        lo, hi = self.samples.min(axis=0) - margin, self.samples.max(axis=0) + margin
        local = np.array([np.where(np.array(s, dtype=bool), hi, lo) for s in np.ndindex(2, 2, 2)])
        return local @ np.asarray(rot, dtype=float).T + pos

    @property
    def search_radius(self) -> float:
        """Distance [m] from a tracked object's predicted position within which the estimator looks for its points.

        One and a half times its planar radius (room for the prediction's error), or its farthest point where that is
        farther (a tall object's top: a held object's top face pins its height, which the table does not), and 3 cm
        more.
        """
        return max(self.radius * 1.5, self.reach) + 0.03

    @classmethod
    def of_body(cls, model: mujoco.MjModel, name: str, symmetry: float) -> ShapeModel:
        """The shape of the body ``name``'s colliding geoms (:func:`~nextage_qp.geometry.geom_parts`)."""
        parts = []
        for geom_type, centre, rot, size in geom_parts(model, name):
            kind = _KINDS.get(geom_type)
            if kind is None:
                continue
            planes = None
            if kind == "mesh":  # size: the vertices
                hull = ConvexHull(np.asarray(size, dtype=float))
                planes = np.column_stack([hull.equations[:, :3], -hull.equations[:, 3]])
            parts.append(Part(kind, np.asarray(size, dtype=float), centre, rot, planes))
        return cls(parts, symmetry)

    def sdf(self, p: np.ndarray) -> np.ndarray:
        """Signed distance [m] of points ``p`` (n, 3) in the object's frame to the union of its parts."""
        return self.sdf_at(p, _ORIGIN, _IDENTITY)

    def sdf_at(self, p: np.ndarray, t: np.ndarray, rot: np.ndarray) -> np.ndarray:
        """Signed distance [m] of world points ``p`` (n, 3) to the shape placed at ``t`` turned by ``rot``.

        The same as ``sdf((p - t) @ rot)``, compiled (:func:`~nextage_qp.native.sdf.union_sdf`).
        """
        pts = np.ascontiguousarray(p, dtype=float).reshape(-1, 3)
        return union_sdf(pts, np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(rot, dtype=float),
                         *self._packed)

    def sdf_array(self, p: np.ndarray) -> np.ndarray:
        """:meth:`sdf` by array operations per part (the reference the compiled one is tested against)."""
        return np.min([_sdf_local(part, (p - part.pos) @ part.rot) for part in self.parts], axis=0)

    def _gradient(self, p: np.ndarray) -> np.ndarray:
        """Unit gradient of the signed distance at ``p`` (the outward normal on the surface)."""
        d = self.sdf(p)
        g = np.stack([(self.sdf(p + e) - d) / 1e-5 for e in np.eye(3) * 1e-5], axis=1)
        return g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-9)

    def _sample(self, n: int = 4000) -> np.ndarray:
        """Points on the surface (object frame), by projecting a random cloud in the bounding box onto it."""
        rng = np.random.default_rng(0)
        ext = max(float(np.abs(part.pos).max() + np.abs(part.size).max()) for part in self.parts) * 1.2
        p = rng.uniform(-ext, ext, (n, 3))
        for _ in range(8):  # Newton steps along the numerical gradient onto the zero level set
            p = p - self.sdf(p)[:, None] * self._gradient(p)
        return p[np.abs(self.sdf(p)) < 1e-4]
