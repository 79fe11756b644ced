"""``perception.map``: the obstacles the head camera sees, as an occupancy map built over a run, and how good it is.

:class:`ObstacleMapper` takes the camera's whole frames (a windowed frame shows only the tracked objects) and adds each
to a :class:`~.occupancy.VoxelMap` of the space over the table within the arms' reach, the work region and the places
the task puts objects in: the pixels the robot's own model explains are dropped (:func:`~.occupancy.self_filter`, the
model rendered alone at the measured joints), and so are the table's (within ``TABLE_BAND`` of the plane the estimator
found) and the tracked objects' (within their shape's radius and ``OBJECT_PAD`` of the pose fitted in that frame). What
is left is what the robot was not told about: obstacles.

Its report scores the map against the scene, after the run (the map never reads the scene): per obstacle at least
``TALL`` high, whether a whole frame showed it (present: a point of its faces where the frame's depth is) and
whether an occupied voxel lies in it or within a voxel of it (detected), and the volume of occupied voxels that lie
in nothing (false occupied).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np

from nextage_qp.sensing.camera.estimate import Frame
from nextage_qp.sensing.camera.occupancy import OCCUPIED_STATE, VoxelMap, self_filter
from nextage_qp.sensing.camera.pixels import backproject, plane_height, project

CELL = 0.015
"""Voxel size [m]."""
TABLE_BAND = 0.012
"""Points this near the table plane [m] are the table's."""
OBJECT_PAD = 0.015
"""Points within a tracked object's radius and this much more [m] of its fitted pose are the object's."""
TALL = 0.03
"""Obstacles at least this tall [m] are scored."""
REACH = 0.15
"""The map reaches this far [m] beyond the work region (and the task's places) on each side, and ``HEIGHT`` above the
table."""
HEIGHT = 0.35
BOX_PAD = 0.0
"""The controller's obstacle boxes are each cluster's voxels grown by this [m]: none, a voxel that holds a point of a
surface is whole in the box, so the box already bounds what was seen by up to a voxel's edge."""
STRIPS = 3
"""The most boxes a cluster is given (:meth:`~.occupancy.VoxelMap.strip_boxes`): a round piece's single box stands out
past it at its corners."""
MIN_VOXELS = 2
"""Clusters of fewer voxels are depth noise, not obstacles."""
HIDDEN_REACH = CELL
"""How far [m] a seen obstacle may reach on into never-seen space the robot's links or a tracked object hide beside
it, when a free spot chosen earlier is judged again (:meth:`ObstacleMapper.boxes`): a piece half behind an arm is seen
only up to the arm's edge."""
FLOOR = 2 * CELL
"""Space within this [m] of the table top is the table's for the map's coverage and its unknown space: a ray ends on
the table a cell behind the voxels just over it, which are never seen through."""


class ObstacleMapper:
    """The occupancy map of one camera (see the module docstring).

    Args:
        robot: The :class:`~nextage_qp.robots.model.Robot` (its workspace, objects and obstacle groups).
        radii: Each tracked object's radius [m] (its shape model's).
        places: More rectangles of the table ((x0, y0), (x1, y1)) [m] the task puts objects in (a ``free_spot``
            target's region): mapped, and never-seen space there is occupied, as over the work region.
    """

    def __init__(self, robot: Any, radii: Mapping[str, float],
                 places: Sequence[tuple[tuple[float, float], tuple[float, float]]] = ()) -> None:
        corners = _table_corners(robot)
        table = float(corners[:, 2].max()) if len(corners) else 0.0  # the table top's height [m] (0: no table)
        ws = robot.description.workspace if robot.description is not None else None
        if ws is not None:
            centre, half = np.array(ws.centre, dtype=float), np.array(ws.size, dtype=float)
        else:  # a robot file without a workspace: the space in front of the robot
            centre, half = np.array([0.5, 0.0]), np.array([0.35, 0.5])
        self.work = (centre - half, centre + half)  # the work region's footprint (x-y) [m]
        self.places = [self.work, *((np.array(a, dtype=float), np.array(b, dtype=float)) for a, b in places)]
        """The footprints (x-y lo, hi) [m] over which never-seen space is occupied: the work region, then ``places``."""
        lo_xy = np.min([a for a, _ in self.places], axis=0) - REACH
        hi_xy = np.max([b for _, b in self.places], axis=0) + REACH
        # an arm's elbow swings past the work region: whatever it may meet is mapped
        reach = _reachable_table(robot, corners)
        if reach is not None:
            lo_xy, hi_xy = np.minimum(lo_xy, reach[0]), np.maximum(hi_xy, reach[1])
        lo, hi = np.array([*lo_xy, table - CELL]), np.array([*hi_xy, table + HEIGHT])
        self.map = VoxelMap(lo, hi, CELL)
        self.table = table
        self.radii = dict(radii)
        self.robot = robot
        self.apart = np.zeros(self.map.shape, dtype=bool)
        """The voxels some whole frame showed at or behind the robot's links or a tracked object: space hidden by the
        robot or the objects it was told about, not an obstacle when never seen (:meth:`unknown_boxes`)."""
        self.visible: set[int] = set()  # obstacle bodies a whole frame showed (scored with the truth, see update)

    def region(self) -> tuple[np.ndarray, np.ndarray]:
        """The mapped space over the table (lo, hi) [m]: the map's box from ``FLOOR`` above the table top."""
        lo = self.map.lo.copy()
        lo[2] = self.table + FLOOR
        return lo, self.map.lo + np.array(self.map.shape) * self.map.cell

    def seen_share(self, lo: np.ndarray | None = None, hi: np.ndarray | None = None) -> float:
        """Share of the mapped space over the table the camera has observed, or of its part in the box ``lo``-``hi``."""
        r_lo, r_hi = self.region()
        if lo is not None and hi is not None:
            r_lo, r_hi = np.maximum(r_lo, lo), np.minimum(r_hi, hi)
        return self.map.seen_share(r_lo, r_hi) if np.all(r_hi > r_lo) else 1.0

    def boxes(self, hidden: bool = False) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """The map's obstacles as boxes turned about the vertical (centre [m], half-sizes [m], yaw [rad]) for the
        controller (:meth:`VoxelMap.oriented_boxes`), up to ``STRIPS`` per cluster.

        Each reaches down to the table: a camera above sees an obstacle's top and the faces turned to it, and the
        steep faces only at grazing angles (a few points per voxel, which the rays past them carve free); what lies
        under a seen surface is hidden from it, and counts as occupied. The voxels within a cell of the table top are
        left out of the clusters: the table's own points a plane's error lifts over its band fill them, and would join
        every piece on the table into one.

        With ``hidden``, each cluster is first grown by up to ``HIDDEN_REACH`` into the never-seen space beside it that
        the robot's links or the tracked objects hide: where the rest of a piece seen only up to an arm's edge may
        stand (what a free spot is judged against once chosen, :class:`~nextage_qp.manipulation.runner.Runner`).
        """  # noqa: D205
        floor = float(self.map.lo[2])
        if not hidden:
            return [_down_to(box, floor) for box in self.map.oriented_boxes(pad=BOX_PAD, min_voxels=MIN_VOXELS,
                                                                            above=self.table + CELL, strips=STRIPS)]
        over = (self.map.centres[:, 2] > self.table + CELL).reshape(self.map.shape)
        solid = (self.map.state() == OCCUPIED_STATE) & over
        steps = max(round(HIDDEN_REACH / self.map.cell), 1)
        clusters = self.map.grown_clusters(solid, self.apart & ~self.map.seen & over, steps, MIN_VOXELS)
        return [_down_to(box, floor) for cells in clusters for box in self.map.strip_boxes(cells, STRIPS, BOX_PAD)]

    def unknown_boxes(self) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """The never-seen space over ``places`` as boxes: for planning, what the camera never saw is occupied.

        One box turned about the vertical per connected cluster of never-seen voxels (of ``MIN_VOXELS`` or more, from
        ``FLOOR`` above the table up), reaching down to the table; the voxels a frame showed at or behind the robot's
        links or a tracked object are left out: space hidden by what the robot knows, seen once it moves.
        """
        return [_down_to(self.map.oriented_box(cells), self.table)
                for cells in self.map.unknown_clusters(self._unknown_in(), self.apart, MIN_VOXELS)]

    def _unknown_in(self) -> np.ndarray:
        """The voxels over ``places`` (from ``FLOOR`` above the table up): never seen there, space is occupied."""
        lo, hi = self.region()
        within = np.zeros(self.map.shape, dtype=bool)
        for a, b in self.places:
            within |= self.map.region(np.r_[a, lo[2]], np.r_[b, hi[2]])
        return within

    def update(self, frame: Frame, own: np.ndarray, plane: tuple[np.ndarray, float] | None,
               poses: Mapping[str, np.ndarray | None],
               truth: tuple[mujoco.MjModel, mujoco.MjData] | None = None,
               priors: Mapping[str, np.ndarray | None] | None = None) -> None:
        """Add a whole frame: ``own`` is the robot's model alone at the measured joints (depth [m], NaN: none),
        ``plane`` the table plane the estimator found, ``poses`` the tracked objects' pose vectors in that frame and
        ``priors`` where the filter expected them (an object hidden in this frame is still where it was believed).
        The space of each tracked object is cleared of obstacle evidence (:meth:`VoxelMap.explain`).

        ``truth`` (the scene, for the report's score alone, after the map took the frame): which obstacles the frame
        shows, a point of their faces where the depth is.
        """  # noqa: D205
        known = [(name, np.asarray(p, dtype=float)) for source in (poses, priors or {}) for name, p in source.items()
                 if p is not None]
        keep = self_filter(frame.depth, own)
        theirs = np.zeros(frame.depth.shape, dtype=bool)  # the pixels of the tracked objects
        if plane is not None:
            with np.errstate(invalid="ignore"):
                keep &= plane_height(frame.depth, frame.K, frame.cam_pos, frame.cam_rot, *plane) > TABLE_BAND
        r, c = np.nonzero(keep)
        if len(r):
            points = backproject(frame.depth, frame.K, frame.cam_pos, frame.cam_rot, r, c)
            gone = np.zeros(len(points), dtype=bool)
            for name, pose in known:
                gone |= np.linalg.norm(points - pose[:3], axis=1) < self.radii.get(name, 0.05) + OBJECT_PAD
            keep[r[gone], c[gone]] = False
            theirs[r[gone], c[gone]] = True
        self.map.integrate(frame.depth, frame.K, frame.cam_pos, frame.cam_rot, keep)
        shown = np.where(np.isfinite(own), own, np.where(theirs, frame.depth, np.nan))  # the robot, the objects
        self.apart |= self.map.behind(frame.K, frame.cam_pos, frame.cam_rot, shown)
        for name, pose in known:
            self.map.explain(pose[:3], self.radii.get(name, 0.05) + OBJECT_PAD)
        if truth is not None:
            self._shown(frame, *truth)

    def _shown(self, frame: Frame, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Note the obstacles ``frame`` shows: a point of their bounding box's faces where the frame's depth is."""
        groups = self.robot.collision_geoms()
        h, w = frame.depth.shape
        for group in self.robot.obstacle_groups():
            for g in groups.get(group, ()):
                body = int(model.geom_bodyid[g])
                if body in self.visible:
                    continue
                points = _face_points(model, data, g)
                rows, cols, z = project(points, frame.K, frame.cam_pos, frame.cam_rot)
                ok = (z > 0) & (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
                with np.errstate(invalid="ignore"):
                    if np.any(np.abs(frame.depth[rows[ok], cols[ok]] - z[ok]) < 0.01):
                        self.visible.add(body)

    def _obstacles(self, model: mujoco.MjModel, data: mujoco.MjData) -> list[tuple[str, int, float, np.ndarray,
                                                                                     np.ndarray]]:
        """Per obstacle body of the scene: its name, id, height over the map's first layer [m], and its voxels.

        Its voxels: those in its geoms' bounding boxes, and those within a voxel of them (for the score alone: the map
        never reads the scene).
        """
        groups = self.robot.collision_geoms()
        centres = self.map.centres
        top = float(self.map.lo[2] + CELL)
        out = []
        for group in self.robot.obstacle_groups():
            for body in sorted({int(model.geom_bodyid[g]) for g in groups.get(group, ())}):
                geoms = [g for g in groups[group] if int(model.geom_bodyid[g]) == body]
                inside = np.zeros(len(centres), dtype=bool)
                near = np.zeros(len(centres), dtype=bool)
                height = 0.0
                for g in geoms:
                    inside |= _in_geom(model, data, g, centres, 0.0)
                    near |= _in_geom(model, data, g, centres, CELL)
                    height = max(height, _geom_top(model, data, g) - top)
                out.append((model.body(body).name, body, height, inside, near))
        return out

    def report(self, model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, Any]:
        """The map scored against the scene as it is in ``data`` (see the module docstring)."""
        groups = self.robot.collision_geoms()
        centres = self.map.centres
        occ = (self.map.state() == OCCUPIED_STATE).reshape(-1)
        explained = np.zeros(len(centres), dtype=bool)
        obstacles = []
        for name, body, height, inside, near in self._obstacles(model, data):
            explained |= near
            if height < TALL or not inside.any():
                continue
            obstacles.append({"name": name, "height_m": round(height, 3), "seen": body in self.visible,
                              "detected": bool(occ[near].any())})
        for name in self.robot.object_names:  # the objects, and the things they stand on, explain voxels too
            for g in groups.get(name, ()):
                explained |= _in_geom(model, data, g, centres, 2 * CELL)
        present = [o for o in obstacles if o["seen"]]
        return {"frames": self.map.frames, "cell_m": CELL,
                "seen_share": round(float(self.map.seen.mean()), 4),
                "obstacles_present": len(present), "obstacles_detected": sum(o["detected"] for o in present),
                "obstacles_unseen": len(obstacles) - len(present),
                "false_occupied_cm3": round(float((occ & ~explained).sum()) * CELL**3 * 1e6, 1),
                "occupied_cm3": round(float(occ.sum()) * CELL**3 * 1e6, 1), "obstacles": obstacles}

    def met(self, model: mujoco.MjModel, data: mujoco.MjData, lo: np.ndarray, hi: np.ndarray) -> list[dict[str, Any]]:
        """The obstacles at least ``TALL`` high reaching into the box ``lo``-``hi`` [m], and whether the map holds them.

        The box: a motion's swept space. Each obstacle says whether the map holds it now (``detected``: an occupied
        voxel in it or within a voxel of it) or, not detected, whether it stands wholly in never-seen space over
        ``places`` (``unknown``: planned around as occupied with ``perception.unknown: occupied``). Scored with the
        scene in ``data``, for the report alone.
        """
        centres = self.map.centres
        box = np.all((centres >= lo) & (centres <= hi), axis=1)
        if not box.any():
            return []
        occ = (self.map.state() == OCCUPIED_STATE).reshape(-1)
        unknown = (~self.map.seen & self._unknown_in()).reshape(-1)
        over = centres[:, 2] >= self.table + FLOOR  # (the space a ray ending on the table never carves is the table's)
        out = []
        for name, _, height, inside, near in self._obstacles(model, data):
            if height < TALL or not (inside & box).any():
                continue
            detected, high = bool(occ[near].any()), inside & over
            out.append({"name": name, "detected": detected,
                        "unknown": not detected and bool(high.any() and np.all(unknown[high]))})
        return out


def _down_to(box: tuple[np.ndarray, np.ndarray, float], floor: float) -> tuple[np.ndarray, np.ndarray, float]:
    """A box turned about the vertical (centre [m], half-sizes [m], yaw [rad]) grown down to ``floor`` [m]."""
    centre, half, yaw = box
    top, bottom = centre[2] + half[2], min(centre[2] - half[2], floor)
    return (np.array([centre[0], centre[1], (top + bottom) / 2]), np.array([half[0], half[1], (top - bottom) / 2]),
            yaw)


def _table_corners(robot: Any) -> np.ndarray:
    """The corners [m] (k, 3) of the bounding boxes of the scene's table geoms, in the world (none: no table)."""
    model = robot.model
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    tables = robot.collision_geoms().get("table", ())
    return np.concatenate([_box_points(model, data, g, CORNERS) for g in tables]) if tables else np.zeros((0, 3))


def _reachable_table(robot: Any, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The footprint (x-y lo, hi) [m] of the table top within reach of the robot's arms, or None (no table).

    ``corners``: the table's (:func:`_table_corners`). Each arm's wrist and tool stay in a sphere
    (:meth:`~nextage_qp.kinematics.frames.Kinematics.reach`, which bounds every link between them and the first joint
    too); the spheres' x-y extent, within the table's (a base on wheels reaches the whole table).
    """
    from nextage_qp.kinematics.frames import Kinematics

    if not len(corners):
        return None
    t_lo, t_hi = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
    kin, q = Kinematics(robot), robot.keyframe_q("zero")  # (a sphere's centre is its first joint's anchor)
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for arm in robot.arms:
        for frame in dict.fromkeys((arm.wrist, arm.tool)):
            centre, radius, _ = kin.reach(frame, q)
            if not np.isfinite(radius):
                return t_lo, t_hi
            lo, hi = np.minimum(lo, centre[:2] - radius), np.maximum(hi, centre[:2] + radius)
    if not np.all(hi > lo):
        return None
    return np.maximum(lo, t_lo), np.minimum(hi, t_hi)


CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
"""A box's eight corners in half-sizes along its axes."""


def _face_fractions() -> np.ndarray:
    """Each face of a box, in half-sizes along its axes: its centre and four points halfway out."""
    out = []
    for axis in range(3):
        u, v = [k for k in range(3) if k != axis]
        for sign in (1.0, -1.0):
            for a, b in ((0.0, 0.0), (0.5, 0.5), (0.5, -0.5), (-0.5, 0.5), (-0.5, -0.5)):
                p = np.zeros(3)
                p[axis], p[u], p[v] = sign, a, b
                out.append(p)
    return np.array(out)


FACES = _face_fractions()


def _box_points(model: mujoco.MjModel, data: mujoco.MjData, g: int, fractions: np.ndarray) -> np.ndarray:
    """Points [m] of geom ``g``'s bounding box (its own frame) at ``fractions`` of its half-sizes, in the world."""
    rot = data.geom_xmat[g].reshape(3, 3)
    centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
    return data.geom_xpos[g] + (centre + fractions * half) @ rot.T


def _face_points(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> np.ndarray:
    """Points [m] on geom ``g``'s bounding box's faces in the world: each face's centre and four points halfway out."""
    return _box_points(model, data, g, FACES)


def _in_geom(model: mujoco.MjModel, data: mujoco.MjData, g: int, points: np.ndarray, margin: float) -> np.ndarray:
    """Which points lie in geom ``g``'s bounding box (its own frame), grown by ``margin`` [m]."""
    rot = data.geom_xmat[g].reshape(3, 3)
    centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
    reach = np.abs(rot) @ (half + margin)  # the grown box's half-extents along the world's axes
    mid = data.geom_xpos[g] + rot @ centre
    out = np.all(np.abs(points - mid) <= reach + 1e-9, axis=1)  # within its world-aligned bounds: the candidates
    local = (points[out] - data.geom_xpos[g]) @ rot
    out[out] = np.all(np.abs(local - centre) <= half + margin, axis=1)
    return out


def _geom_top(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> float:
    """Height of geom ``g``'s highest bounding-box corner [m]."""
    rot = data.geom_xmat[g].reshape(3, 3)
    centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
    return float(data.geom_xpos[g, 2] + rot[2] @ centre + np.abs(rot[2]) @ half)
