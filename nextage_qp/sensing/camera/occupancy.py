"""An occupancy map of the space over the table from depth frames: free, occupied and never-seen voxels.

:class:`VoxelMap` takes depth frames (the depth along the optical axis, NaN for no return) with the camera's
intrinsics and pose, and a mask of the pixels that may show an obstacle (the caller removes the robot's own pixels,
:func:`self_filter`, the tracked objects' and the table's). A voxel that holds ``MIN_POINTS`` masked pixels' points
gains evidence of being occupied; a voxel whose centre projects into the image in front of what the pixel sees (by
more than a cell) was seen through and gains evidence of being free; a voxel behind what the camera sees, or outside
its view, is not touched: an obstacle hidden behind another stays unknown until a view shows it. The evidence is a
clamped log-odds sum, so a voxel seen free often enough after it was occupied (an obstacle moved away) is free again.

:meth:`VoxelMap.boxes` turns the occupied voxels' connected clusters (and, for planning, the never-seen ones inside a
region) into axis-aligned boxes padded by a margin: what a planner's validity check and collision rows take as
obstacles. :meth:`VoxelMap.seen_share` is how much of a region the map has observed.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import ndimage

from nextage_qp.sensing.camera.pixels import backproject

HIT = 0.85
"""Log-odds a voxel gains per frame in which a masked pixel's point falls in it."""
MISS = 0.4
"""Log-odds a voxel loses per frame in which the camera sees through it."""
CLAMP = 3.5
"""Log-odds bound either way (an occupied voxel seen free about 9 times is free again)."""
OCCUPIED = 0.5
"""Log-odds above which a voxel is occupied."""
MIN_POINTS = 3
"""Points a voxel must hold in one frame to gain evidence of being occupied (one or two are a speck of noise)."""
NEAR = 0.05
"""Voxels nearer the camera than this [m] along its axis are not updated."""

UNKNOWN, FREE, OCCUPIED_STATE = -1, 0, 1
"""Voxel states of :meth:`VoxelMap.state`."""


class VoxelMap:
    """Voxels of ``cell`` [m] filling the box ``lo``-``hi`` [m] (world frame), all unknown at first."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, cell: float = 0.015) -> None:
        if not cell > 0:
            raise ValueError(f"cell {cell} must be > 0")
        self.lo, self.cell = np.asarray(lo, dtype=float), float(cell)
        self.shape = tuple(int(n) for n in np.maximum(np.ceil((np.asarray(hi, dtype=float) - self.lo) / cell), 1))
        self.logodds = np.zeros(self.shape, dtype=np.float32)
        self.seen = np.zeros(self.shape, dtype=bool)
        idx = np.stack(np.meshgrid(*(np.arange(n) for n in self.shape), indexing="ij"), axis=-1).reshape(-1, 3)
        self.centres = self.lo + (idx + 0.5) * self.cell  # (N, 3), in the arrays' C order
        self.axes = [self.lo[a] + (np.arange(n) + 0.5) * self.cell for a, n in enumerate(self.shape)]
        """The centres' coordinates [m] along each axis of the grid."""
        self._rays: tuple[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None  # _project's last answer
        self.frames = 0
        self._oriented: tuple[np.ndarray, tuple[Any, ...], list] | None = None  # oriented_boxes' last answer

    def index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Voxel indices (n, 3) of world points (n, 3), and which of them lie inside the map."""
        ijk = np.floor((np.asarray(points, dtype=float) - self.lo) / self.cell).astype(int)
        inside = np.all((ijk >= 0) & (ijk < np.array(self.shape)), axis=1)
        return ijk, inside

    def integrate(self, depth: np.ndarray, K: np.ndarray, pos: np.ndarray, rot: np.ndarray,
                  mask: np.ndarray | None = None) -> None:
        """Add one depth frame [m] (H, W; NaN: no return) from a camera with intrinsics ``K`` at ``pos``, ``rot``.

        ``mask`` (H, W): the pixels whose points may be obstacles (default: every pixel with depth). Every pixel
        with depth counts for seeing through the voxels in front of it.
        """
        z, at = self._along_rays(depth, K, pos, rot)
        with np.errstate(invalid="ignore"):
            free = z < at - self.cell  # in front of what the pixel sees, by more than a cell
        flat = self.logodds.reshape(-1)
        flat[free] -= MISS
        hits = np.isfinite(depth) if mask is None else (np.asarray(mask, dtype=bool) & np.isfinite(depth))
        r, c = np.nonzero(hits)
        occupied = np.zeros(0, dtype=int)
        if len(r):
            ijk, inside = self.index(backproject(depth, K, pos, rot, r, c))
            cells, counts = np.unique(np.ravel_multi_index(ijk[inside].T, self.shape), return_counts=True)
            occupied = cells[counts >= MIN_POINTS]
            flat[occupied] += HIT + MISS * free[occupied]  # a voxel holding a surface is no free space
        np.clip(self.logodds, -CLAMP, CLAMP, out=self.logodds)
        seen = self.seen.reshape(-1)
        seen[free] = True
        seen[occupied] = True
        self.frames += 1

    def behind(self, K: np.ndarray, pos: np.ndarray, rot: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """The voxels (the map's shape) at or behind what a depth image shows: the shadow of what it shows.

        ``depth`` [m] (NaN: nothing there) is from a camera with intrinsics ``K`` at ``pos``, ``rot``.
        """
        z, at = self._along_rays(depth, K, pos, rot)
        with np.errstate(invalid="ignore"):
            return (at <= z + self.cell).reshape(self.shape)

    def _along_rays(self, depth: np.ndarray, K: np.ndarray, pos: np.ndarray,
                    rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per voxel, its centre's depth along the camera's axis [m] and the depth its pixel shows.

        The latter is NaN out of view, nearer than ``NEAR`` or where the pixel has no return.
        """
        z, view, pixel = self._project(K, pos, rot, depth.shape)
        at = np.full(len(z), np.nan)
        at[view] = depth.reshape(-1)[pixel]
        return z, at

    def _project(self, K: np.ndarray, pos: np.ndarray, rot: np.ndarray,
                 size: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per voxel its centre's depth along the camera's axis [m] and whether it is in view; the in-view ones' pixels.

        As :func:`~nextage_qp.sensing.camera.pixels.project` of :attr:`centres`, by the grid's axes (a centre's camera
        coordinates are a sum of one term per axis), and kept for the next frame from the same pose.
        """
        key = b"".join(np.ascontiguousarray(a, dtype=float).tobytes() for a in (K, pos, rot)) + str(size).encode()
        if self._rays is not None and self._rays[0] == key:
            return self._rays[1]
        terms = [(x - pos[a])[:, None] * rot[a] for a, x in enumerate(self.axes)]  # (n_a, 3) each

        def camera_axis(j: int) -> np.ndarray:  # every centre's camera coordinate j, in the arrays' C order
            return (terms[0][:, None, None, j] + terms[1][None, :, None, j] + terms[2][None, None, :, j]).reshape(-1)

        z = -camera_axis(2)
        h, w = size
        with np.errstate(divide="ignore", invalid="ignore"):
            cols = np.rint(K[0, 0] * camera_axis(0) / z + K[0, 2] - 0.5)
            rows = np.rint(-K[1, 1] * camera_axis(1) / z + K[1, 2] - 0.5)
            view = (z > NEAR) & (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        pixel = rows[view].astype(int) * w + cols[view].astype(int)
        self._rays = (key, (z, view, pixel))
        return z, view, pixel

    def explain(self, centre: np.ndarray, radius: float) -> None:
        """The voxels whose centres lie within ``radius`` [m] of ``centre`` hold a known object, not an obstacle:
        their evidence of being occupied goes (they count as seen). A voxel mapped before the object was tracked, or
        the object's faces no pixel shows free again, would otherwise stay an obstacle where the object stood.
        """  # noqa: D205
        ijk, _ = self.index(np.asarray(centre, dtype=float)[None, :])
        reach = int(np.ceil(radius / self.cell)) + 1
        lo = np.maximum(ijk[0] - reach, 0)
        hi = np.minimum(ijk[0] + reach + 1, np.array(self.shape))
        if np.any(hi <= lo):
            return
        block = tuple(slice(int(a), int(b)) for a, b in zip(lo, hi, strict=True))
        grid = np.stack(np.meshgrid(*(np.arange(s.start, s.stop) for s in block), indexing="ij"), axis=-1)
        near = np.linalg.norm(self.lo + (grid + 0.5) * self.cell - centre, axis=-1) <= radius
        odds = self.logodds[block]
        odds[near] = np.minimum(odds[near], 0.0)
        self.seen[block][near] = True

    def state(self) -> np.ndarray:
        """Per voxel: :data:`UNKNOWN` (never observed), :data:`FREE` or :data:`OCCUPIED_STATE`."""
        out = np.where(self.logodds > OCCUPIED, OCCUPIED_STATE, FREE).astype(np.int8)
        out[~self.seen] = UNKNOWN
        return out

    def occupied_points(self) -> np.ndarray:
        """Centres (n, 3) of the occupied voxels [m]."""
        return self.centres[(self.state() == OCCUPIED_STATE).reshape(-1)]

    def region(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Voxels whose centre lies in the box ``lo``-``hi`` [m]."""
        lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        i, j, k = ((x >= lo[a]) & (x <= hi[a]) for a, x in enumerate(self.axes))
        return i[:, None, None] & j[None, :, None] & k[None, None, :]

    def seen_share(self, lo: np.ndarray, hi: np.ndarray) -> float:
        """Share of the voxels in the box ``lo``-``hi`` [m] the map has observed (1 for an empty box)."""
        region = self.region(lo, hi)
        n = int(region.sum())
        return float(self.seen[region].sum()) / n if n else 1.0

    def clusters(self, unknown_in: tuple[np.ndarray, np.ndarray] | None = None,
                 min_voxels: int = 1) -> list[np.ndarray]:
        """The voxel indices (n, 3) of each connected cluster of occupied voxels (26-connected).

        With ``unknown_in`` (lo, hi) [m], the never-seen voxels inside that box count too (unseen space counts as
        occupied for planning). Clusters of fewer than ``min_voxels`` are dropped (a speck of depth noise).
        """
        solid = self.state() == OCCUPIED_STATE
        if unknown_in is not None:
            solid |= ~self.seen & self.region(*unknown_in)
        return self._clusters_of(solid, min_voxels)

    def _clusters_of(self, solid: np.ndarray, min_voxels: int) -> list[np.ndarray]:
        """The voxel indices of each 26-connected cluster of ``solid`` voxels, of at least ``min_voxels``."""
        labels, _ = ndimage.label(solid, structure=np.ones((3, 3, 3), dtype=bool))
        out = []
        for k, sl in enumerate(ndimage.find_objects(labels), start=1):
            if sl is None:
                continue
            cells = np.argwhere(labels[sl] == k)
            if len(cells) >= min_voxels:
                out.append(cells + np.array([s.start for s in sl]))
        return out

    def boxes(self, pad: float = 0.01, unknown_in: tuple[np.ndarray, np.ndarray] | None = None,
              min_voxels: int = 1) -> list[tuple[np.ndarray, np.ndarray]]:
        """Obstacles as axis-aligned boxes (centre [m], half-sizes [m]), one per cluster (:meth:`clusters`).

        Each is the cluster's voxel bounds grown by ``pad``.
        """
        out = []
        for cells in self.clusters(unknown_in, min_voxels):
            lo = self.lo + cells.min(axis=0) * self.cell - pad
            hi = self.lo + (cells.max(axis=0) + 1) * self.cell + pad
            out.append(((lo + hi) / 2, (hi - lo) / 2))
        return out

    def oriented_boxes(self, pad: float = 0.0, min_voxels: int = 1, step: float = np.radians(3.0),
                       above: float | None = None,
                       strips: int = 1) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """Obstacles as boxes turned about the vertical (centre [m], half-sizes [m], yaw [rad]), one per cluster.

        Each is the smallest-footprint rectangle (yaw searched in ``step``s over a quarter turn) holding every corner
        of the cluster's voxels, over their height, grown by ``pad``: a piece standing at an angle is no longer
        bounded by the axis-aligned box of its voxels, which is up to twice its footprint. With ``strips`` more than
        one, each cluster is up to that many boxes (:meth:`strip_boxes`). ``above`` [m]: only the voxels whose
        centres lie higher count. While the occupied voxels stay those of the last call, its boxes are given again
        without labelling the map anew.
        """
        solid = self.state() == OCCUPIED_STATE
        if above is not None:
            solid &= (self.centres[:, 2] > above).reshape(self.shape)
        key = (pad, min_voxels, step, above, strips)
        if self._oriented is not None and self._oriented[1] == key and np.array_equal(self._oriented[0], solid):
            return list(self._oriented[2])  # the occupied voxels as last time: the same boxes
        clusters = self._clusters_of(solid, min_voxels)
        out = [box for cells in clusters for box in self.strip_boxes(cells, strips, pad, step)]
        self._oriented = (solid, key, out)
        return list(out)

    def strip_boxes(self, cells: np.ndarray, most: int, pad: float = 0.0,
                    step: float = np.radians(3.0)) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """Up to ``most`` boxes turned about the vertical whose union holds the voxels ``cells``, hugging them.

        The voxels are binned a voxel wide across the longer side of the cluster's :meth:`oriented_box`, and the bins
        cut into at most ``most`` runs of neighbouring bins whose boxes (at the same yaw, each holding every corner of
        its voxels over their own height, grown by ``pad``) have the least footprint in all. A round piece's one box
        stands out past it at its corners by up to 40 % of its radius; the runs cut the corners to steps.
        """
        centre, half, yaw = self.oriented_box(cells, pad, step)
        along = 0 if half[0] >= half[1] else 1
        c, s = np.cos(yaw), np.sin(yaw)
        axes = np.array([[c, s], [-s, c]])  # rows: the box's own x and y in the world's
        square = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])
        corners = self.lo[:2] + (cells[:, None, :2] + square[None]) * self.cell  # (n, 4, 2)
        u, v = corners @ axes[along], corners @ axes[1 - along]
        mid = u.mean(axis=1)
        bins = np.floor((mid - mid.min()) / self.cell + 1e-9).astype(int)
        n = int(bins.max()) + 1
        if most <= 1 or n <= 1:
            return [(centre, half, yaw)]
        inf = np.full(n, np.inf)  # each bin's extents across (a bin may be empty)
        lo_u, hi_u, lo_v, hi_v = inf.copy(), -inf, inf.copy(), -inf
        np.minimum.at(lo_u, bins, u.min(axis=1))
        np.maximum.at(hi_u, bins, u.max(axis=1))
        np.minimum.at(lo_v, bins, v.min(axis=1))
        np.maximum.at(hi_v, bins, v.max(axis=1))

        def area(a: int, b: int) -> float:
            width = np.max(hi_u[a:b + 1]) - np.min(lo_u[a:b + 1]) + 2 * pad
            return float(width * (np.max(hi_v[a:b + 1]) - np.min(lo_v[a:b + 1]) + 2 * pad))

        # least footprint of bins 0..b in k runs, and where the last run begins (every bin ends a run: none is empty
        # at either end, and an empty one inside is joined to a neighbour by the least footprint)
        best: dict[tuple[int, int], tuple[float, int]] = {(1, b): (area(0, b), 0) for b in range(n)}
        for k in range(2, most + 1):
            for b in range(k - 1, n):
                best[(k, b)] = min((best[(k - 1, a - 1)][0] + area(a, b), a) for a in range(k - 1, b + 1))
        k = min(range(1, min(most, n) + 1), key=lambda j: best[(j, n - 1)][0])
        out, b = [], n - 1
        while k >= 1:
            a = best[(k, b)][1]
            part = cells[(bins >= a) & (bins <= b)]
            if len(part):
                out.append(self._box_at(part, yaw, pad))
            b, k = a - 1, k - 1
        return out[::-1]

    def _box_at(self, cells: np.ndarray, yaw: float, pad: float) -> tuple[np.ndarray, np.ndarray, float]:
        """The box at ``yaw`` (centre [m], half-sizes [m], yaw [rad]) holding every corner of the voxels ``cells``,
        over their height, grown by ``pad``.
        """  # noqa: D205
        square = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])
        flat = np.unique(cells[:, :2], axis=0)
        corners = (self.lo[:2] + ((flat[:, None, :] + square[None]) * self.cell).reshape(-1, 2))
        c, s = np.cos(yaw), np.sin(yaw)
        u, v = corners @ np.array([c, s]), corners @ np.array([-s, c])
        mu, mv = (u.min() + u.max()) / 2, (v.min() + v.max()) / 2
        z0 = self.lo[2] + cells[:, 2].min() * self.cell
        z1 = self.lo[2] + (cells[:, 2].max() + 1) * self.cell
        half = np.array([(u.max() - u.min()) / 2, (v.max() - v.min()) / 2, (z1 - z0) / 2]) + pad
        return np.array([mu * c - mv * s, mu * s + mv * c, (z0 + z1) / 2]), half, yaw

    def grown_clusters(self, solid: np.ndarray, into: np.ndarray, steps: int,
                       min_voxels: int = 1) -> list[np.ndarray]:
        """The voxel indices (n, 3) of each 26-connected cluster of ``solid`` voxels, grown ``steps`` voxels (face
        neighbours, step by step) into the mask ``into``: what may lie on beyond what was seen of it.
        """  # noqa: D205
        out = []
        for cells in self._clusters_of(solid, min_voxels):
            mask = np.zeros(self.shape, dtype=bool)
            mask[tuple(cells.T)] = True
            lo = np.maximum(cells.min(axis=0) - steps, 0)
            hi = np.minimum(cells.max(axis=0) + steps + 1, self.shape)
            block = tuple(slice(a, b) for a, b in zip(lo, hi, strict=True))
            grown = ndimage.binary_dilation(mask[block], iterations=max(steps, 1), mask=mask[block] | into[block])
            out.append(np.argwhere(grown) + lo)
        return out

    def unknown_clusters(self, within: np.ndarray, apart: np.ndarray, min_voxels: int = 1) -> list[np.ndarray]:
        """The voxel indices (n, 3) of each connected cluster of never-seen voxels in the mask ``within`` and outside
        the mask ``apart`` (both of the map's shape; ``within`` e.g. :meth:`region`'s, ``apart`` e.g. the space hidden
        behind the robot's own links, which the camera sees once they move).
        """  # noqa: D205
        return self._clusters_of(~self.seen & within & ~apart, min_voxels)

    def oriented_box(self, cells: np.ndarray, pad: float = 0.0,
                     step: float = np.radians(3.0)) -> tuple[np.ndarray, np.ndarray, float]:
        """The box turned about the vertical (centre [m], half-sizes [m], yaw [rad]) around the voxels ``cells``.

        The one with the smallest footprint that holds every corner of the voxels (n, 3), over their height, grown by
        ``pad`` [m].
        """
        square = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])
        yaws = np.arange(0.0, np.pi / 2, step)
        c, s = np.cos(yaws), np.sin(yaws)
        flat = np.unique(cells[:, :2], axis=0)
        corners = (self.lo[:2] + ((flat[:, None, :] + square[None]) * self.cell).reshape(-1, 2))
        u = corners @ np.stack([c, s])  # (points, yaws): along each candidate's first axis
        v = corners @ np.stack([-s, c])
        area = (u.max(0) - u.min(0)) * (v.max(0) - v.min(0))
        return self._box_at(cells, float(yaws[int(np.argmin(area))]), pad)


SELF_PAD = 3
"""Pixels by which the robot's silhouette is grown for the self-filter: its rendered edges lag the measured image by a
pixel or two (the joints' latency and noise, rasterisation)."""


def self_filter(depth: np.ndarray, robot_depth: np.ndarray, tolerance: float = 0.02, pad: int = SELF_PAD) -> np.ndarray:
    """Pixels (H, W) that do not show the robot, from the depth of its own model alone at the measured joints.

    ``robot_depth`` (NaN where the model is not in view) is grown by ``pad`` pixels, each taking the nearest depth
    around it; a pixel is the robot's where the measured depth is within ``tolerance`` [m] of, or beyond, that depth.
    A point in front of the robot's model by more than the tolerance is something else; so is one with no model near.
    """
    grown = ndimage.minimum_filter(np.where(np.isfinite(robot_depth), robot_depth, np.inf), 2 * pad + 1,
                                   mode="constant", cval=np.inf) if pad > 0 else np.nan_to_num(robot_depth, nan=np.inf)
    with np.errstate(invalid="ignore"):
        robot = np.isfinite(grown) & ~(depth < grown - tolerance)
    return np.isfinite(depth) & ~robot
