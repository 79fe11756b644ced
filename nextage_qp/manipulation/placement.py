"""Refuse what cannot be done before moving.

An object whose target rest pose overlaps an obstacle or is not over the table, or whose start pose intersects
something or is not over the table, is refused. The target rest pose is the target's x, y and yaw with the object
standing on the table top (its lowest point on the top face). The object is placed there in a scratch copy of the
scene and its distance to every obstacle geom is measured: an overlap is an
:class:`~nextage_qp.errors.InfeasibleError` (exit 2) naming the obstacle and the depth; otherwise the smallest
distance is the target's clearance, reported with the result.

A target may instead be placed where its object fits (``scene.poses.NAME.free_spot``): :func:`free_spots` searches
its region, nearest first, for a spot where the object standing upright keeps the asked clearance from every obstacle
beside it (:meth:`Robot.obstacle_groups`), measured on the obstacles' own geometry.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, InfeasibleError
from nextage_qp.kinematics.frames import Kinematics
from nextage_qp.robots.model import CLUTTER_GROUP, Robot

OVERLAP_TOLERANCE = 1e-4
"""Penetration [m] below which two geoms count as touching, not overlapping."""
SUPPORT_SLACK = 0.005
"""A fixed object's top up to this far [m] above a target marker's origin still carries the target (a shelf's board
whose marker was set on its top)."""


class Placement(NamedTuple):
    """The checked placement.

    Attributes:
        rest_pos: The object's origin when resting at the target [m].
        target_clearance_m: Smallest distance from the object at rest on the target to an obstacle [m] (None when
            the scene has no obstacle).
    """

    rest_pos: np.ndarray
    target_clearance_m: float | None


def _geom_corners(m: mujoco.MjModel, g: int) -> np.ndarray:
    """The 8 corners of a geom's local bounding box, in its body's frame."""
    centre, half = m.geom_aabb[g, :3], m.geom_aabb[g, 3:]
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, m.geom_quat[g])
    return m.geom_pos[g] + (centre + signs * half) @ rot.reshape(3, 3).T


def table_top(robot: Robot, data: mujoco.MjData) -> tuple[float, list[int]]:
    """Height of the table's top face [m] and the table's geoms (ConfigError when the scene has no table)."""
    geoms = list(robot.collision_geoms().get("table", ()))
    if not geoms:
        raise ConfigError(f"{robot.scene}: the scene has no table to place objects on")
    m = robot.model
    tops = [float(data.geom_xpos[g, 2] + np.abs(data.geom_xmat[g].reshape(3, 3)[2]) @ m.geom_size[g]) for g in geoms]
    return max(tops), geoms


def obstacle_top(robot: Robot, data: mujoco.MjData) -> float:
    """Height [m] of the highest point of the obstacles, the clutter and the fixed objects.

    The table top when the scene has none of them.
    """
    groups = robot.collision_geoms()
    geoms = [g for name in ("obstacle", CLUTTER_GROUP, *robot.fixed_objects) for g in groups.get(name, ())]
    if not geoms:
        return table_top(robot, data)[0]
    m = robot.model
    return max(float(data.geom_xpos[g, 2] + np.abs(data.geom_xmat[g].reshape(3, 3)[2]) @ m.geom_size[g])
               for g in geoms)


def rest_height(robot: Robot, data: mujoco.MjData, obj: str, on: str | None = None) -> float:
    """Height [m] of an object's origin when it stands upright on the table top (its lowest point on the top).

    With ``on`` a free object of the scene, on that object's top instead (a stack); any other body (a target
    marker): on the highest top of a fixed object's box under it and not above it (a shelf's board), or the table.
    """
    groups = robot.collision_geoms()
    if on is not None and on in robot.object_names:
        m, b = robot.model, robot.model.body(on).id
        rot = data.xmat[b].reshape(3, 3)
        top = max(float((data.xpos[b] + _geom_corners(m, g) @ rot.T)[:, 2].max()) for g in groups.get(on, ()))
    else:
        top, _ = table_top(robot, data)
        if on is not None and robot.fixed_objects:
            at = data.xpos[robot.model.body(on).id]
            boards = [g for name in robot.fixed_objects for g in groups.get(name, ())]
            tops = [_box_top(robot, data, g) for g in boards if _over_table(robot, data, [g], at[:2])]
            top = max([top, *(t for t in tops if t <= at[2] + SUPPORT_SLACK)])
    geoms = list(groups.get(obj, ()))
    return top - min(_geom_corners(robot.model, g)[:, 2].min() for g in geoms)


def _box_top(robot: Robot, data: mujoco.MjData, geom: int) -> float:
    """Height [m] of a box geom's highest point."""
    rot = data.geom_xmat[geom].reshape(3, 3)
    return float(data.geom_xpos[geom, 2] + np.abs(rot[2]) @ robot.model.geom_size[geom])


def _over_table(robot: Robot, data: mujoco.MjData, geoms: list[int], xy: np.ndarray) -> bool:
    m = robot.model
    for g in geoms:
        if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_BOX:
            continue
        local = data.geom_xmat[g].reshape(3, 3).T @ (np.array([*xy, data.geom_xpos[g, 2]]) - data.geom_xpos[g])
        if np.all(np.abs(local[:2]) <= m.geom_size[g][:2]):
            return True
    return False


def _closest(robot: Robot, data: mujoco.MjData, obj_geoms: Sequence[int], others: Sequence[int],
             beside: bool = False) -> tuple[float, int, np.ndarray]:
    """Smallest signed distance [m] between two geom sets (capped at 0.1 m), the other geom and the way out.

    The other geom is -1 and the unit direction away from it zero beyond the cap. ``beside``: only pairs whose
    direction is within 45 deg of level count (not a geom the object stands on or under).
    """
    best, which, away, fromto = 0.1, -1, np.zeros(3), np.zeros(6)
    for a in obj_geoms:
        for b in others:
            dist = float(mujoco.mj_geomDistance(robot.model, data, a, b, 0.1, fromto))
            if dist < best:
                gap = fromto[:3] - fromto[3:]  # from the other's point to the object's (reversed when inside)
                norm = float(np.linalg.norm(gap))
                if beside and norm > 1e-12 and abs(gap[2]) > np.sqrt(0.5) * norm:
                    continue
                best, which = dist, b
                away = gap / norm * (1.0 if dist >= 0 else -1.0) if norm > 1e-12 else np.zeros(3)
    return best, which, away


def check_placement(robot: Robot, obj: str, target: str, start_q: np.ndarray, source: str) -> Placement:
    """Check the object's start pose and its rest pose at the target (see the module docstring).

    Raises:
        InfeasibleError: The target rest pose overlaps an obstacle or is not over the table, or the start pose
            overlaps the robot, an obstacle or the table (one line with the word "overlaps" and the depth) or is
            not over the table, or below its top.
    """
    m = robot.model
    data = mujoco.MjData(m)
    robot.set_q(data, start_q)
    mujoco.mj_forward(m, data)
    tid = m.body(target).id
    groups = robot.collision_geoms()
    obj_geoms = list(groups.get(obj, ()))
    obstacles = list(groups.get("obstacle", ()))
    top, table = table_top(robot, data)
    others = [g for g in range(m.ngeom) if (m.geom_contype[g] or m.geom_conaffinity[g]) and g not in obj_geoms]
    dist, geom, _ = _closest(robot, data, obj_geoms, others)
    if dist < -1e-3:  # resting contact allows a little penetration
        raise InfeasibleError(f"{source}: scene.poses.{obj}: the start pose of {obj} overlaps "
                          f"{_name(m, geom)} by {-dist * 1e3:.1f} mm")
    start = data.xpos[m.body(obj).id]
    if not _over_table(robot, data, table, start[:2]):
        raise InfeasibleError(f"{source}: scene.poses.{obj}: {obj} starts at ({start[0]:.3f}, {start[1]:.3f}), not "
                              "over the table; move it onto the table top")
    if start[2] < top:  # under the table (its top slab would have overlapped it otherwise)
        raise InfeasibleError(f"{source}: scene.poses.{obj}: {obj} starts at height {start[2]:.3f} m, below the table "
                              f"top at {top:.3f} m; put it on the table top")
    rest = data.xpos[tid].copy()
    rest[2] = rest_height(robot, data, obj, target)
    tyaw = float(np.arctan2(data.xmat[tid][3], data.xmat[tid][0]))
    if not _over_table(robot, data, table, rest[:2]):
        raise InfeasibleError(f"{source}: target: {obj} at the target ({rest[0]:.3f}, {rest[1]:.3f}) is not over the "
                          "table; move the target onto the table top")
    _within_reach(robot, start_q, obj_geoms, rest, source, obj)
    adr = robot.object_qpos_slice(obj)
    data.qpos[adr] = [*rest, np.cos(tyaw / 2), 0.0, 0.0, np.sin(tyaw / 2)]
    mujoco.mj_forward(m, data)
    clearance = None
    if obstacles:
        clearance, geom, _ = _closest(robot, data, obj_geoms, obstacles)
        if clearance < -OVERLAP_TOLERANCE:
            raise InfeasibleError(f"{source}: target: {obj} resting at the target ({rest[0]:.3f}, {rest[1]:.3f}, yaw "
                              f"{np.degrees(tyaw):.1f} deg) overlaps {_name(m, geom)} by {-clearance * 1e3:.1f} mm; "
                              "no placement there is possible")
    return Placement(rest, clearance)


FREE_SPOT_STEP = 0.005
"""Spacing [m] of the grid a free spot is searched on."""
FREE_SPOT_MARGIN = 0.005
"""Room [m] a free spot keeps beyond the asked clearance: an object set down a few millimetres off (and a degree or
two turned) still keeps the clearance asked for."""
FREE_SPOT_APART = 0.05
"""Least distance [m] between the free spots offered in turn (the next one for a spot the robot cannot use)."""


def free_spots(robot: Robot, obj: str, yaw: float, region: tuple[tuple[float, float], tuple[float, float]],
               near: tuple[float, float], clearance: float, where: str) -> Iterator[tuple[np.ndarray, float]]:
    """Spots [x, y] in ``region``, nearest ``near`` first and ``FREE_SPOT_APART`` apart, where ``obj`` standing on the
    table at ``yaw`` keeps ``clearance`` [m] and ``FREE_SPOT_MARGIN`` from every obstacle beside it, each with its
    clearance (capped at 0.1 m).

    Searched on a ``FREE_SPOT_STEP`` grid; the next spot is there for a first one the robot cannot use.

    Raises:
        InfeasibleError: No spot of the region keeps the clearance (``where`` names the config key); the message
            gives the roomiest spot found. Raised by the first ``next``.
    """  # noqa: D205
    (x0, y0), (x1, y1) = region
    xs = np.arange(x0, x1 + 1e-9, FREE_SPOT_STEP)
    ys = np.arange(y0, y1 + 1e-9, FREE_SPOT_STEP)
    grid = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    grid = grid[np.argsort(np.linalg.norm(grid - np.asarray(near), axis=1), kind="stable")]
    data = mujoco.MjData(robot.model)
    mujoco.mj_forward(robot.model, data)
    z = rest_height(robot, data, obj)
    groups = robot.obstacle_groups()
    best, roomiest = -np.inf, grid[0]
    found: list[np.ndarray] = []
    for p in grid:
        if any(float(np.linalg.norm(p - f)) < FREE_SPOT_APART for f in found):
            continue
        dist = clearance_at(robot, data, obj, np.array([p[0], p[1], z]), yaw, groups, beside=True)[0]
        if dist >= clearance + FREE_SPOT_MARGIN:
            found.append(p)
            yield p.copy(), dist
        elif dist > best:
            best, roomiest = dist, p
    if not found:
        raise InfeasibleError(f"{where}: no spot of the region {[list(region[0]), list(region[1])]} keeps {obj} "
                              f"{clearance * 1e3:.0f} mm from the obstacles (the roomiest, ({roomiest[0]:.3f}, "
                              f"{roomiest[1]:.3f}), keeps {best * 1e3:.0f} mm); enlarge the region or lower the "
                              "clearance")


def spot_room(robot: Robot, obj: str, yaw: float, xy: np.ndarray) -> float:
    """Smallest distance [m] from ``obj`` standing on the table at ``xy`` and ``yaw`` to the obstacles beside it
    (capped at 0.1 m): what :func:`free_spots` judges a spot by.
    """  # noqa: D205
    data = mujoco.MjData(robot.model)
    mujoco.mj_forward(robot.model, data)
    pos = np.array([xy[0], xy[1], rest_height(robot, data, obj)])
    return clearance_at(robot, data, obj, pos, yaw, robot.obstacle_groups(), beside=True)[0]


def obstacle_clearance(robot: Robot, data: mujoco.MjData, obj: str) -> float:
    """Smallest distance [m] from ``obj`` as it is in ``data`` to the obstacles beside it (capped at 0.1 m)."""
    geoms = robot.collision_geoms()
    others = [g for group in robot.obstacle_groups() for g in geoms.get(group, ())]
    return _closest(robot, data, geoms.get(obj, ()), others, beside=True)[0]


def clearance_at(robot: Robot, data: mujoco.MjData, obj: str, pos: np.ndarray, yaw: float,
                 groups: Sequence[str], beside: bool = False) -> tuple[float, np.ndarray]:
    """Smallest distance [m] from ``obj`` upright at ``pos`` and ``yaw`` to the geoms of ``groups`` (capped at 0.1 m).

    With it, the unit direction away from the nearest one (zero beyond the cap). ``data`` holds the rest of the
    scene and is changed: the object's pose is set in it. ``beside``: only obstacles beside the object count (the
    direction away from them within 45 deg of level), not one it stands on or under.
    """
    geoms = robot.collision_geoms()
    data.qpos[robot.object_qpos_slice(obj)] = [*pos, np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    mujoco.mj_kinematics(robot.model, data)
    others = [g for group in groups for g in geoms.get(group, ())]
    dist, _, away = _closest(robot, data, geoms.get(obj, ()), others, beside)
    return dist, away


def _within_reach(robot: Robot, q: np.ndarray, obj_geoms: list[int], rest: np.ndarray, source: str, obj: str) -> None:
    """Refuse a target no hand can come near: beyond every arm frame's reach sphere by more than the object's extent.

    The spheres are :meth:`~nextage_qp.kinematics.frames.Kinematics.reach`'s (a mobile base's frames reach anywhere).
    """
    m, kin = robot.model, Kinematics(robot)
    extent = max((float(np.linalg.norm(m.geom_pos[g]) + m.geom_rbound[g]) for g in obj_geoms), default=0.0)
    gaps = []
    for frame in dict.fromkeys(f for arm in robot.arms for f in (arm.tool, arm.pad, arm.wrist)):
        centre, radius, joint = kin.reach(frame, q)
        gaps.append((float(np.linalg.norm(rest - centre)) - radius, frame, radius, joint))
    gap, frame, radius, joint = min(gaps, default=(0.0, "", 0.0, None))
    if gap > extent + 1e-3:
        raise InfeasibleError(f"{source}: target: {obj} at the target ({rest[0]:.3f}, {rest[1]:.3f}) is out of every "
                              f"hand's reach ({frame}, the nearest, reaches at most {radius:.3f} m from {joint}; the "
                              f"target is {gap:.3f} m beyond); move the target closer to the robot")


def _name(m: mujoco.MjModel, geom: int) -> str:
    body = m.body(int(m.geom_bodyid[geom])).name
    return body if not m.geom(geom).name or m.geom(geom).name == body else f"{body} ({m.geom(geom).name})"

