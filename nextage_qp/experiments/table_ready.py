"""What makes a drafted robot ready for a table: tool frames, how they push, a workspace and a ready home.

``robot init`` drafts a robot file from a model alone (:mod:`nextage_qp.robots.draft`); this module then composes the
draft in a task scene and adds what a table task needs, each derived from the model's geometry:

* **tool frames** (``ARM_tool`` for each arm): on each hand's outermost collision surface along the axis of
  the arm's last joint, x along that axis (the face's normal), z as near the world's up as the hand at home allows;
* **push_face**: the lowest height over a :data:`CUBE` m cube's centre at which both tools, level, reach the work
  region's centre with their arms :data:`TABLE_GAP` off the table;
* **workspace**: the table top's height (among a few below the shoulders) over which both tools, level and facing the
  middle, reach the best rectangle of a grid in front of the robot (:func:`_score`), centred on the midline between
  the arms (where a clamp or a hand-over meets), where, besides, a tool reaches behind an object from each of its
  four sides (a push's approach: corrections in every direction); the table stands clear of the robot's body;
* a **ready home**: both tools :data:`READY_HEIGHT` over the work region, level, facing each other, solved by the IK
  from the draft's home, kept only when free of self-contact; one the motors hold against gravity wins, then the least
  singular; its manipulability is reported.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Literal

import mujoco
import numpy as np

from nextage_qp.geometry import geom_part, support
from nextage_qp.robots.check_report import CheckReport, check_robot
from nextage_qp.robots.description import RobotDescription, load_robot
from nextage_qp.robots.draft import TABLE_GAP, Ready
from nextage_qp.robots.model import robot_bodies
from nextage_qp.robots.model_checks import Finding
from nextage_qp.robots.modelfile import descendants, self_contacts
from nextage_qp.robots.physics_checks import file_or_model_limit
from nextage_qp.robots.robot_file import FrameFile, WorkspaceFile

CUBE = 0.07
"""Edge [m] of the cube the push height is worked out for (the bundled push tasks')."""
GRID = 0.06
"""Spacing [m] of the grid of table points the tools are asked to reach."""
REACH_TOL = 0.005
"""A tool reaches a point when the IK brings it this near [m] (where its axis is a target of the IK too, that is not
judged): for the draft's table and home, and for ``robot check``'s work region."""
DROPS = (0.2, 0.3, 0.4)
"""Table tops tried, this far [m] below the shoulders (:func:`_shoulder`)."""
BASE_DROP = 0.01
"""A table top tried this far [m] under the arms' first joints (arms mounted on the table, as an ALOHA's)."""
EDGE_GAP = 0.02
"""Gap [m] between the table's front edge and the robot's body (or its arms' first links) in front of it."""
READY_TABLE_GAP = 0.03
"""Least distance [m] of the ready home from the table."""
READY_STARTS = 3
"""Seeded poses within the limits the ready home is also solved from (besides the draft's home)."""
MIN_TOP = 0.05
"""Lowest table top [m] tried (the floor is z = 0)."""
PITCHES = (0.0, 0.2, 0.4)
"""Pitches [rad] of the tool (its face's normal tipped down) at which the push height is sought, level first."""
LEAD_STEP = 0.01
"""Tip [unit vector share] of the push direction up and down by which a hand's leading point is found."""
DEEP_CELLS = 3
"""Grid cells (:data:`GRID` apart) a work region spans each way before a larger area counts for more."""
APPROACH_GAP = 0.04
"""Gap [m] between a pushing tool and the object's face before a push (the push phase's default ``approach``)."""
SIDE_FACINGS = tuple(np.array(f) for f in ((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0)))
"""The directions along the table a tool faces behind an object, one per side, for the work region."""
SIDE_RESTARTS = 2
"""Random restarts of the IK that seeks a side's approach (after the descent from home): an approach out of reach
costs all of them."""
SIDE_NAMES = ("+x", "-x", "+y", "-y")
"""The push directions of :data:`SIDE_FACINGS`, as ``robot check`` names them."""
READY_HEIGHT = 0.20
"""The ready home holds the tools this far [m] over the table top."""
FLEX_COS = 0.5
"""An arm's last joint whose axis is within 60 deg of square to the way from it to its hand's geometry flexes the
hand (a TIAGo's wrist): the tool faces where the hand points, not along that axis."""
TABLE_TOP = "table_top"
"""The geom of the bundled scenes' table body that is its top."""


def _support(m: mujoco.MjModel, d: mujoco.MjData, g: int, u: np.ndarray) -> float:
    """The farthest any point of geom ``g`` reaches along world direction ``u`` (its support), as ``x . u``."""
    return support(geom_part(m, g, d.geom_xpos[g], d.geom_xmat[g]), u)


def _colliding(m: mujoco.MjModel, bodies: list[int]) -> list[int]:
    return [g for b in bodies for g in range(int(m.body_geomadr[b]), int(m.body_geomadr[b] + m.body_geomnum[b]))
            if m.geom_contype[g] or m.geom_conaffinity[g]]


def _perpendicular(axis: np.ndarray, *wanted: np.ndarray) -> np.ndarray:
    """The first of ``wanted`` (else a world axis) made perpendicular to the unit ``axis``, as a unit vector."""
    for w in (*wanted, np.eye(3)[int(np.argmin(np.abs(axis)))]):
        v = w - (w @ axis) * axis
        if np.linalg.norm(v) > 0.3:
            return v / np.linalg.norm(v)
    raise AssertionError("unreachable: the world axis least along the axis is never parallel to it")


def tool_frames(m: mujoco.MjModel, d: mujoco.MjData, desc: RobotDescription) -> Ready:
    """Each arm's tool frame on its hand's outermost surface (see the module doc).

    Along the arm's last joint's axis; where that joint flexes the hand (:data:`FLEX_COS`), where the hand points.
    """
    from nextage_qp.sensing.sensors import WrenchSensor

    ready = Ready()
    sensed = {s.body for s in WrenchSensor.of_model(m)}
    for k_arm, arm in enumerate(desc.arms):
        k = len(arm.joints) - 1
        joint = m.joint(arm.joints[k]).id
        body = int(m.jnt_bodyid[joint])
        geoms = _colliding(m, descendants(m, body))
        if not geoms:  # a hand without geometry (a gripper left out): the link it hangs from carries the face
            body = int(m.body_parentid[body])
            geoms = _colliding(m, descendants(m, body))
        while not geoms and k > 0:  # a wrist without geometry either: the first link up the arm with some (a GR1's
            k -= 1  # forearm)
            joint = m.joint(arm.joints[k]).id
            body = int(m.jnt_bodyid[joint])
            geoms = _colliding(m, descendants(m, body))
        if not geoms:
            ready.notes.append(f"{arm.name}: no collision geometry on the arm: the wrist is the tool")
            continue
        anchor, axis = d.xanchor[joint].copy(), d.xaxis[joint].copy()
        before = d.xanchor[m.joint(arm.joints[k - 1]).id] if k > 0 else d.xpos[int(m.body_parentid[body])]
        hand = np.mean([d.geom_xpos[g] for g in geoms], axis=0) - anchor  # where the hand's geometry lies
        out = anchor - before  # along the arm, out to the hand (a spherical wrist: towards the hand's geometry)
        if abs(out @ axis) < 0.01:
            out = hand
        if out @ axis < 0:
            axis = -axis
        if abs(axis @ hand) < FLEX_COS * np.linalg.norm(hand):  # a last joint that flexes the hand: its face is
            hand = hand - (hand @ axis) * axis  # square to where the hand points, not to the flex axis
            axis = hand / np.linalg.norm(hand)
        reach = max(_support(m, d, g, axis) for g in geoms) - anchor @ axis
        point = anchor + reach * axis
        up = _perpendicular(axis, np.array([0.0, 0.0, 1.0]), *d.xmat[body].reshape(3, 3).T)
        rot = np.column_stack([axis, np.cross(up, axis), up])
        brot = d.xmat[body].reshape(3, 3)
        local = brot.T @ rot
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, local.ravel())
        name = f"{arm.name}_tool"
        px, py, pz = (round(float(v), 5) for v in brot.T @ (point - d.xpos[body]))
        w, qx, qy, qz = (round(float(v), 6) for v in quat)
        ready.frames[name] = FrameFile(body=m.body(body).name, pos=(px, py, pz), quat=(w, qx, qy, qz))
        ready.tools[arm.name] = name
        if k_arm < 2:  # the clamp's pad on the same face: its y axis along the clamp's, the robot's +y
            side = 1.0 if k_arm == 0 else -1.0  # the first arm's face looks towards -y, the second's towards +y
            pad = local @ np.array([[0.0, -side, 0.0], [side, 0.0, 0.0], [0.0, 0.0, 1.0]])  # about z by side x 90 deg
            mujoco.mju_mat2Quat(quat, pad.ravel())
            w, qx, qy, qz = (round(float(v), 6) for v in quat)
            ready.frames[f"{arm.name}_pad"] = FrameFile(body=m.body(body).name, pos=(px, py, pz), quat=(w, qx, qy, qz))
            ready.pads[arm.name] = f"{arm.name}_pad"
            if body not in sensed:
                ready.wrench_sensors.append(f"{arm.name}_pad")
    return ready


def _largest_rectangle(ok: np.ndarray, middle: int | None = None) -> tuple[int, int, int, int] | None:
    """The best all-True axis-aligned block of a boolean grid (:func:`_score`): (i0, i1, j0, j1), inclusive, or None.

    ``middle``: a column the block is centred on (its columns ``j0`` and ``j1`` equally far from it).
    """
    best, found = (0, 0), None
    n, k = ok.shape
    for i0, j0 in itertools.product(range(n), range(k)):
        if not ok[i0, j0] or (middle is not None and j0 > middle):
            continue
        for i1 in range(i0, n):
            if not ok[i1, j0]:
                break
            for j1 in range(j0, k):
                if not ok[i0:i1 + 1, j0:j1 + 1].all():
                    break
                if middle is not None and j0 + j1 != 2 * middle:
                    continue
                score = _score((i0, i1, j0, j1))
                if score > best:
                    best, found = score, (i0, i1, j0, j1)
    return found


def make_ready(desc: RobotDescription) -> Ready:
    """Tool frames, push_face, workspace and a ready home for a drafted robot (see the module docstring)."""
    import dataclasses

    from nextage_qp.ik import QPIK, FrameTarget
    from nextage_qp.ik.config import CollisionPairConfig, IKConfig
    from nextage_qp.robots.model import Robot
    from nextage_qp.scene.files import BodyPose, SceneOverrides

    bare = Robot.from_scene("push_cube", None, desc)
    m, d = bare.model, mujoco.MjData(bare.model)
    bare.set_q(d, bare.keyframe_q("home"))
    mujoco.mj_kinematics(m, d)
    ready = tool_frames(m, d, desc)
    frames = {**desc.frames, **ready.frames}
    arms = tuple(dataclasses.replace(a, tool=ready.tools.get(a.name, a.tool)) for a in desc.arms)
    desc = dataclasses.replace(desc, frames=frames, arms=arms)
    robot = Robot.from_scene("push_cube", None, desc)
    m, d = robot.model, mujoco.MjData(robot.model)
    home = robot.keyframe_q("home")
    robot.set_q(d, home)
    mujoco.mj_kinematics(m, d)
    ik = QPIK(robot, IKConfig())
    faces = {arm.tool: np.array([0.0, -1.0 if k == 0 else 1.0, 0.0]) for k, arm in enumerate(arms)}

    last: dict[tuple[str, tuple[float, ...]], np.ndarray] = {}  # per tool and facing, the last point's solution

    def reached(tool: str, p: np.ndarray, facing: np.ndarray) -> bool:
        """From the last point's joints (the grid is walked row by row), else from home: no random restarts."""
        key = (tool, tuple(facing))
        target = [FrameTarget(tool, pos=p, axis=np.array([1.0, 0.0, 0.0]), direction=facing)]
        for start in ([last[key]] if key in last else []) + [home]:
            result = ik.solve(target, start, restarts=0)
            if result.pos_err_m <= REACH_TOL:
                last[key] = np.asarray(result.q)
                return True
        return False

    def reaches(points: list[np.ndarray]) -> bool:
        return all(reached(tool, p, faces[tool]) for tool, p in zip(faces, points, strict=False))

    def every_side(p: np.ndarray) -> bool:  # a push's approach behind an object at p, from each side
        return all(any(reached(tool, p - f * (CUBE / 2 + APPROACH_GAP), f) for tool in faces) for f in SIDE_FACINGS)

    own = robot_bodies(robot)
    arm_bodies = {b for arm in arms for b in descendants(m, int(m.jnt_bodyid[m.joint(arm.joints[1]).id]))}
    body_geoms = _colliding(m, sorted(own - arm_bodies))
    shoulders = float(np.mean([_shoulder(m, d, a.joints)[2] for a in arms]))
    found: list[tuple | None] = [None, None]  # the largest region reached from every side; facing the middle only
    bases = [d.xanchor[m.joint(a.joints[0]).id] for a in arms]
    middle = float(np.mean([b[1] for b in bases]))  # dual-arm tasks (a clamp, a hand-over) meet between the arms
    behind = min(float(b[0]) for b in bases)  # the table's edge where nothing but the arms stands low
    tops = [shoulders - drop for drop in DROPS]  # below the shoulders; else at the arms' bases (arms on the table)
    for top in [*tops, min(float(b[2]) for b in bases) - BASE_DROP]:
        if top < MIN_TOP or (any(found) and top not in tops):
            continue
        under = [g for g in body_geoms if -_support(m, d, g, np.array([0.0, 0.0, -1.0])) < top + 0.05]
        edge = (max(_support(m, d, g, np.array([1.0, 0.0, 0.0])) for g in under) if under else behind) + EDGE_GAP
        xs = edge + GRID * np.arange(1, 13)
        ys = middle + GRID * np.arange(-7, 8)  # centred on the midline between the arms
        ok, sides = np.zeros((len(xs), len(ys)), dtype=bool), np.zeros((len(xs), len(ys)), dtype=bool)
        for i, x in enumerate(xs):
            for j, y in enumerate(ys):
                p = np.array([x, y, top + CUBE / 2])
                ok[i, j] = reaches([p, p])
                sides[i, j] = ok[i, j] and every_side(p)
        for k, grid in enumerate((sides, ok)):
            rect, largest = _largest_rectangle(grid, middle=len(ys) // 2), found[k]
            if rect is not None and (largest is None or _score(rect) > _score(largest[0])):
                found[k] = (rect, top, edge, xs, ys)
    best = found[0]
    ready.every_side = best is not None and _score(best[0])[0] >= DEEP_CELLS
    if not ready.every_side:  # none, or too shallow to push in: where both reach
        best = found[1] or best
        ready.notes.append(f"no region {(DEEP_CELLS - 1) * GRID * 100:.0f} cm across where a tool reaches behind an "
                           "object from every side: the work region is where both tools reach, facing the middle")
    if best is None:
        ready.notes.append("no table height found where both tools reach a point of the table, level")
        return ready
    (i0, i1, j0, j1), top, edge, xs, ys = best
    slab = m.geom(TABLE_TOP)  # the scene's table top, in its body's frame: its front edge and top placed
    centre = ((xs[i0] + xs[i1]) / 2, (ys[j0] + ys[j1]) / 2)
    size = (max(GRID / 2, (xs[i1] - xs[i0]) / 2), max(GRID / 2, (ys[j1] - ys[j0]) / 2))
    ready.workspace = WorkspaceFile(
        centre=(round(float(centre[0]), 3), round(float(centre[1]), 3)),
        size=(round(float(size[0]), 3), round(float(size[1]), 3)), top=round(float(top), 3),
        table=(round(float(edge + slab.size[0] - slab.pos[0]), 3), 0.0,
               round(float(top - slab.size[2] - slab.pos[2]), 3)))
    placed = Robot.from_scene("push_cube", SceneOverrides(poses={"table": BodyPose(pos=ready.workspace.table)}),
                              desc)  # the push height and the ready home are judged at the table where it stands
    groups = placed.collision_geoms()
    pairs = tuple(CollisionPairConfig(a=f"{arm.name}_arm", b="table", min_distance=TABLE_GAP)
                  for arm in arms if f"{arm.name}_arm" in groups)
    kept = QPIK(placed, IKConfig(collision_pairs=pairs))
    ready.push_height, ready.push_pitch = _lowest_push(kept, arms, faces, centre, top, home)
    ready.home, note = _ready_home(placed, QPIK(placed, IKConfig()), arms, faces, centre, size, top, home)
    ready.notes.append(note)
    return ready


def _shoulder(m: mujoco.MjModel, d: mujoco.MjData, joints: tuple[str, ...] | list[str]) -> np.ndarray:
    """Where the arm's upper arm pivots: its first joint turning about an axis nearer level than upright.

    A pan joint on a tall link under it, as a Baxter's, stands well below the shoulder; the first joint where no
    joint turns about a level axis.
    """
    for name in joints:
        j = m.joint(name).id
        if abs(float(d.xaxis[j][2])) < np.sqrt(0.5):
            return np.asarray(d.xanchor[j])
    return np.asarray(d.xanchor[m.joint(joints[0]).id])


def _lowest_push(ik, arms, faces, centre, top, home) -> tuple[float, float]:
    """The lowest tool height over a :data:`CUBE` cube's centre at which every tool reaches the region's centre.

    Returns the height [m] and the tool's pitch [rad] there. Each tool facing the middle, its arm kept
    :data:`TABLE_GAP` off the table by the IK; level first; where no height is reached level, each of the
    :data:`PITCHES` tipped down (a long hand whose arm meets the table before its tip comes low enough, level, reaches
    lower tipped down), and of those the one whose hands lead into the cube lowest (:func:`_leading_height`: a face
    tipped down meets the cube with its upper rim, which tips a cube pushed too high); at most a quarter of the cube
    over its centre.
    """
    from nextage_qp.ik import FrameTarget

    best: tuple[float, float, float] | None = None  # (leading height, tool height, pitch)
    for pitch in PITCHES:
        down = np.array([0.0, 0.0, -np.sin(pitch)])
        for height in np.arange(0.0, CUBE / 4 + 1e-9, 0.002):
            p = np.array([centre[0], centre[1], top + CUBE / 2 + height])
            solved = []  # each tool's joints there, until one misses
            for arm in arms:
                result = ik.solve([FrameTarget(arm.tool, pos=p, axis=np.array([1.0, 0.0, 0.0]),
                                               direction=np.cos(pitch) * faces[arm.tool] + down)], home)
                if result.pos_err_m > REACH_TOL:
                    break
                solved.append((arm.tool, np.asarray(result.q)))
            else:
                if pitch == 0.0:
                    return float(height), 0.0
                lead = max(_leading_height(ik.robot, q, tool, faces[tool]) for tool, q in solved)
                if best is None or lead < best[0]:
                    best = (lead, float(height), float(pitch))
                break
    return (best[1], best[2]) if best is not None else (CUBE / 4, 0.0)


def _leading_height(robot, q: np.ndarray, tool: str, push: np.ndarray) -> float:
    """The height [m] of the hand's point that leads along ``push`` at the joints ``q``: where it meets an object.

    The hand is the tool frame's body and those below it; the point is the gradient of the hand's support function
    (a central difference tipping ``push`` up and down), so a flat face square to ``push`` gives its centre's height.
    """
    m = robot.model
    d = mujoco.MjData(m)
    d.qpos[robot.qpos_idx] = q
    mujoco.mj_kinematics(m, d)
    geoms = _colliding(m, descendants(m, robot.frame_body(tool)))

    def reach(v: np.ndarray) -> float:
        n = float(np.linalg.norm(v))
        return n * max(support(geom_part(m, g, d.geom_xpos[g], d.geom_xmat[g].reshape(3, 3)), v / n) for g in geoms)

    up = np.array([0.0, 0.0, LEAD_STEP])
    return (reach(push + up) - reach(push - up)) / (2 * LEAD_STEP)


def _score(rect: tuple[int, int, int, int]) -> tuple[int, int]:
    """How good a work region is: its shorter side, up to :data:`DEEP_CELLS` cells, then its area in cells.

    A strip one cell deep leaves no room to push across it, however long.
    """
    i0, i1, j0, j1 = rect
    rows, cols = i1 - i0 + 1, j1 - j0 + 1
    return min(rows, cols, DEEP_CELLS), rows * cols


def _manipulability(robot, q: np.ndarray, frames: list[str]) -> list[float]:
    """Per frame, the product of the singular values of its 6-D Jacobian over the joints that move it, at ``q``.

    With six or more such joints it is Yoshikawa's sqrt(det(J J^T)); with fewer (a tool on the link before the last
    joint: that joint cannot move it) it is sqrt(det(J^T J)), so that a joint which does not move the frame does not
    read as a singularity. Zero at a singularity.
    """
    from nextage_qp.kinematics.frames import Kinematics

    kin = Kinematics(robot)
    out = []
    for frame in frames:
        jac = kin.jacobian(frame, q)[:, robot.chain_joints(frame)]
        out.append(float(np.prod(np.linalg.svd(jac, compute_uv=False))))  # min(6, n) values
    return out


def _load_ratio(robot, d: mujoco.MjData) -> float:
    """The largest ratio of a robot joint's gravity torque at ``d``'s pose to its torque limit (1: at the limit).

    ``d``'s ``qpos`` must be set; a joint without a limit does not count.
    """
    m = robot.model
    mujoco.mj_forward(m, d)
    ratios = [0.0]
    for j in robot.joint_ids:
        limit = file_or_model_limit(m, int(j), robot.description.torque_limits)
        if limit:
            ratios.append(abs(float(d.qfrc_bias[m.jnt_dofadr[j]])) / limit)
    return max(ratios)


def _table_gap(robot, d: mujoco.MjData) -> tuple[float, str]:
    """The least distance [m] between the arms' collision geoms and the table's at ``d``, and the body that nears it.

    ``d``'s kinematics must be done.
    """
    m = robot.model
    table = robot.collision_geoms().get("table", ())
    best, name = np.inf, ""
    moved = {b for arm in robot.arms for b in descendants(m, int(m.jnt_bodyid[m.joint(arm.joints[0]).id]))}
    for g in _colliding(m, sorted(moved)):
        for t in table:
            dist = mujoco.mj_geomDistance(m, d, g, t, READY_TABLE_GAP + 0.01, None)
            if dist < best:
                best, name = dist, m.body(int(m.geom_bodyid[g])).name
    return float(best), name


def _ready_home(robot, ik, arms, faces, centre, size, top, home) -> tuple[dict[str, float] | None, str]:
    """Both tools over the work region, level and facing each other, free of contact, the least singular found.

    A pose the motors hold against gravity (each robot joint's gravity torque within its limit) wins over one they do
    not, whatever its manipulability; among those held, the least singular wins.

    Tried at three heights and three spreads, each from the draft's home and from :data:`READY_STARTS` seeded poses
    within the limits; None where every solution misses, or touches the robot itself or the table.
    """
    from nextage_qp.ik import FrameTarget

    m = robot.model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    starts = [home, *(np.where(np.isfinite(robot.lower), rng.uniform(robot.lower, robot.upper), home)
                      for _ in range(READY_STARTS))]
    tools = [arm.tool for arm in arms]
    own = {m.body(b).name for b in robot_bodies(robot)}
    why, best = "the IK does not reach it", None
    for height, spread in itertools.product((READY_HEIGHT, 1.25 * READY_HEIGHT, 0.75 * READY_HEIGHT), (0.5, 0.8, 0.3)):
        targets = [FrameTarget(arm.tool, pos=np.array([centre[0], centre[1] + (1 if k == 0 else -1) * spread * size[1],
                                                       top + height]),
                               axis=np.array([1.0, 0.0, 0.0]), direction=faces[arm.tool])
                   for k, arm in enumerate(arms)]
        for start in starts:
            result = ik.solve(targets, start, restarts=0)
            if result.pos_err_m > REACH_TOL:
                continue
            qpos = d.qpos.copy()
            qpos[robot.qpos_idx] = result.q
            touching = [p for p in self_contacts(m, d, qpos) if own.issuperset(p)]  # the robot's own links
            if touching:
                why = f"it touches {touching[0][0]} to {touching[0][1]}"
                continue
            gap, near = _table_gap(robot, d)
            if gap < READY_TABLE_GAP:
                why = f"{near} comes within {gap * 1e3:.0f} mm of the table"
                continue
            measure = _manipulability(robot, np.asarray(result.q), tools)
            rank = (max(_load_ratio(robot, d), 1.0), -min(measure))  # held by the motors first, then least singular
            if best is None or rank < best[3]:
                best = (np.asarray(result.q), height, measure, rank)
    if best is None:
        return None, f"no ready home over the work region ({why}); home stays the draft's"
    q, height, measure, _ = best
    values = {name: round(float(v), 5) for name, v in zip(robot.joint_names, q, strict=True)}
    return values, (f"ready home: both tools {height:.2f} m over the work region, level, facing each other; "
                    "manipulability (product of the singular values of the 6-D Jacobian over the joints that move "
                    "each tool) " + ", ".join(f"{v:.3g}" for v in measure))


WORKSPACE_HEIGHT = 0.035
"""Height over the table top [m] at which ``robot check`` asks the tools to reach the work region (a 7 cm cube's
centre)."""


def workspace_reach(desc: RobotDescription) -> list[Finding]:
    """Whether the workspace the robot file declares is where task configs written in it can work.

    The table of a task scene must stand with its top at ``workspace.top``, and every arm's tool must reach the work
    region's centre and its four corners, :data:`WORKSPACE_HEIGHT` over the table top (position only, from home).
    """
    from nextage_qp.ik import QPIK, FrameTarget
    from nextage_qp.ik.config import CollisionPairConfig, IKConfig
    from nextage_qp.robots.model import Robot
    from nextage_qp.scene.files import BodyPose, SceneOverrides

    ws = desc.workspace
    if ws is None:
        return [Finding("info", "workspace", "no workspace: task configs written in the workspace frame "
                                             "(scene.frame: workspace, e.g. configs/push_across.yaml) refuse this "
                                             "robot", "add workspace: {centre: [x, y], size: [hx, hy], top: z}")]
    poses = {} if ws.table is None else {"table": BodyPose(pos=ws.table)}
    robot = Robot.from_scene("push_cube", SceneOverrides(poses=poses), desc)
    m = robot.model
    top = float(m.body("table").pos[2] + m.geom("table_top").pos[2] + m.geom("table_top").size[2])
    found = []
    if abs(top - ws.top) > 0.002:
        found.append(Finding("problem", "workspace", f"workspace.top: {ws.top:g} m, but the table's top stands at "
                                                     f"{top:.3f} m", "set workspace.top to the table's top, or move "
                                                                     "the table (workspace.table)"))
    (cx, cy), (hx, hy) = ws.centre, ws.size
    points = {"centre": (cx, cy), **{f"corner ({sx:+.0f}, {sy:+.0f})": (cx + sx * hx, cy + sy * hy)
                                     for sx in (-1, 1) for sy in (-1, 1)}}
    solver = QPIK(robot, IKConfig())
    home = robot.keyframe_q("home")
    for arm in desc.arms:
        short = []
        for name, (x, y) in points.items():
            result = solver.solve([FrameTarget(arm.tool, pos=np.array([x, y, ws.top + WORKSPACE_HEIGHT]))], home)
            if result.pos_err_m > REACH_TOL:
                short.append(f"{name} by {result.pos_err_m * 1e3:.0f} mm")
        if short:
            level: Literal["problem", "info"] = "problem" if short[0].startswith("centre") else "info"
            found.append(Finding(level, "workspace",
                                 f"{arm.name} arm's {arm.tool} falls short of the work region's {', '.join(short)}",
                                 "move workspace.centre or shrink workspace.size to where the tools reach"))
    tools, groups = [arm.tool for arm in desc.arms], robot.collision_geoms()
    kept = QPIK(robot, IKConfig(collision_pairs=tuple(  # the arms kept off the body, as a task's pairs keep them
        CollisionPairConfig(a=f"{arm.name}_arm", b="torso") for arm in desc.arms
        if f"{arm.name}_arm" in groups and "torso" in groups)))
    one_way = []
    for name, (x, y) in points.items():
        missing = unreached_sides(robot, kept, home, tools, np.array([x, y, ws.top + CUBE / 2]))
        if missing:
            one_way.append(f"{name} towards {', '.join(missing)}")
    if one_way:
        found.append(Finding("info", "workspace", "no tool reaches behind a 7 cm object to push it at the work "
                                                  f"region's {'; '.join(one_way)}: a push that ends off the target "
                                                  "there cannot be corrected that way",
                             "move workspace.centre or shrink workspace.size to where a tool reaches every side "
                             "(robot init drafts such a region)"))
    return found


def unreached_sides(robot, ik, home: np.ndarray, tools: list[str], p: np.ndarray) -> list[str]:
    """The push directions (:data:`SIDE_NAMES`) in which no tool reaches behind a :data:`CUBE` object at ``p``.

    A tool reaches when the IK (from ``home``, with :data:`SIDE_RESTARTS` restarts) brings it :data:`APPROACH_GAP` off
    the object's face, facing along the push, with the robot's bodies free of contact with each other.
    """
    from nextage_qp.ik import FrameTarget

    m = robot.model
    d = mujoco.MjData(m)
    own = {m.body(b).name for b in robot_bodies(robot)}
    missing = []
    for name, f in zip(SIDE_NAMES, SIDE_FACINGS, strict=True):
        for tool in tools:
            result = ik.solve([FrameTarget(tool, pos=p - f * (CUBE / 2 + APPROACH_GAP), axis=np.array([1.0, 0.0, 0.0]),
                                           direction=f)], home, restarts=SIDE_RESTARTS)
            if result.pos_err_m > REACH_TOL:
                continue
            qpos = d.qpos.copy()
            qpos[robot.qpos_idx] = result.q
            if not [c for c in self_contacts(m, d, qpos) if own.issuperset(c)]:
                break
        else:
            missing.append(name)
    return missing


def clamp_ready(desc: RobotDescription) -> list[Finding]:
    """Whether the robot can make the clamp of the shared grasp tasks.

    A declared pad on each arm, on a body whose force/torque sensor feels the squeeze (the runner refuses a grasp
    otherwise, before anything moves).
    """
    from nextage_qp.robots.model import Robot
    from nextage_qp.sensing.sensors import unsensed

    bare = [arm.name for arm in desc.arms[:2] if not arm.clamps]
    if bare:
        return [Finding("info", "clamp", f"arm{'s' if len(bare) > 1 else ''} {', '.join(bare)} declare"
                        f"{'' if len(bare) > 1 else 's'} no pad: task configs that clamp (configs/pick_place_box.yaml, "
                        "stack_boxes.yaml) refuse this robot", "arms[].pad: a frame on the face that clamps, on a body "
                        "with a force/torque sensor")]
    arms = desc.arms[:2]
    numb = dict(unsensed(Robot.from_scene("push_cube", None, desc), [arm.pad for arm in arms]))  # pad -> its body
    return [Finding("problem", "clamp", f"arm {arm.name}'s pad {arm.pad!r} is on body {numb[arm.pad]!r}, which has "
                    "no force/torque sensor: a clamp cannot feel its squeeze", "add a force and a torque sensor at a "
                    "site on that body to the model, or move the pad")
            for arm in arms if arm.pad in numb]


def check_at_table(ref: str | Path) -> CheckReport:
    """``robot check``: :func:`~nextage_qp.robots.check_report.check_robot`, then a robot file's workspace and clamp.

    The workspace is judged at its table (:func:`workspace_reach`), the clamp by its pads (:func:`clamp_ready`).
    """
    report = check_robot(ref)
    if Path(ref).suffix.lower() not in (".xml", ".urdf") and not report.problems:
        desc = load_robot(ref)
        report.findings += workspace_reach(desc) + clamp_ready(desc)
    return report
