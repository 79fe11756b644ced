"""The planner's collision world: MuJoCo's collision detection on a copy of the run's model, at any joints.

The world is the composed scene as the controller believes it now: the table, the obstacles and every object the
robot does not hold at its measured pose. A state is valid when

* no robot geom comes within ``clearance`` of an obstacle or an object (the ``allow`` bodies aside: the object a
  push or a grasp goes to) nor within ``table_clearance`` of the table,
* no two robot geoms that the model lets collide penetrate each other by more than ``SELF_SLOP`` (self-collision;
  the model's and the robot file's excluded pairs are MuJoCo's ``<exclude>``),
* a held object, carried rigidly by the frame that holds it, comes within ``clearance`` of nothing but the robot.

The ground (the world body's own geoms) is not an obstacle: a wheeled base stands on it.

Distances are MuJoCo's own: the copy's robot and held-object geoms get a collision margin (:data:`LOOKAHEAD`), so
``mj_collision`` reports every pair nearer than that with its signed distance. A dense check of a segment advances
conservatively: no point moves farther between two checked states than the room the last one left, nor less than
:data:`RESOLUTION`.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from nextage_qp.geometry import Pose
from nextage_qp.ik.kinematic_model import lever_bounds
from nextage_qp.native.kernels import worst_contact
from nextage_qp.robots.model import Robot, robot_bodies

RESOLUTION = 0.003
"""Dense checks move no point of the robot (or of what it holds) more than this between two checked states [m],
or no more than the room a state leaves (conservative advancement)."""
SELF_SLOP = 0.01
"""Two robot links count as colliding only past this penetration [m]: soft contacts between neighbouring links that a
folded arm presses together (the robot file's excluded pairs aside) are the physics', not an obstacle's."""
CHAIN_SLOP = 0.03
"""The penetration [m] past which two links of one chain (one below the other: a wrist folded back onto its upper
arm) collide, where a check asks for it (:attr:`CollisionWorld.chain_slop`): the IK keeps no collision row between a
chain's own links, so the routes it drives press them together softly."""
RESTING = 0.003
"""A held object may sink this far into the table [m]: it stands on it before a lift and after a set-down (the
contact's soft penetration)."""
LOOKAHEAD = 0.05
"""Distances up to this [m] are measured (MuJoCo's collision margin on the robot's and a held object's geoms): a
state this clear of everything lets a dense check skip ahead as far."""


@dataclass(frozen=True)
class Held:
    """An object the robot carries rigidly: its pose in the frame that holds it.

    Attributes:
        object: The object's body name.
        frame: The robot frame (site or body) that carries it.
        offset: The object's pose in that frame.
    """

    object: str
    frame: str
    offset: Pose


@dataclass(frozen=True)
class Collision:
    """Why a state is not valid: the two bodies, the signed distance [m] and the clearance it needed [m]."""

    body1: str
    body2: str
    distance: float
    needed: float

    def __str__(self) -> str:
        if self.distance < 0:
            return f"{self.body1} {-self.distance * 1e3:.0f} mm into {self.body2}"
        return f"{self.body1} {self.distance * 1e3:.0f} mm from {self.body2} (clearance {self.needed * 1e3:g} mm)"


class CollisionWorld:
    """Validity of robot joint configurations against the world (see the module docstring).

    Args:
        robot: The robot in its composed scene.
        clearance: Least distance [m] kept from obstacles and objects.
        table_clearance: Least distance [m] kept from the table (0: touching is allowed, not penetrating).
    """

    def __init__(self, robot: Robot, clearance: float = 0.01, table_clearance: float = 0.0) -> None:
        self.robot, self.clearance, self.table_clearance = robot, clearance, table_clearance
        self.model = copy.copy(robot.model)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._robot_bodies = np.zeros(m.nbody, dtype=bool)
        self._robot_bodies[list(robot_bodies(robot))] = True
        groups = robot.collision_geoms()
        self._table = np.zeros(m.nbody, dtype=bool)
        for g in groups.get("table", ()):
            self._table[int(m.geom_bodyid[g])] = True
        self._objects = {name: robot.object_qpos_slice(name) for name in robot.object_names}
        robot_geoms = self._robot_bodies[m.geom_bodyid]
        m.geom_margin[robot_geoms] = np.maximum(m.geom_margin[robot_geoms], max(LOOKAHEAD, clearance))
        self._base_margin = m.geom_margin.copy()
        self._lever = lever_bounds(robot.model)[robot_geoms][:, robot.dof_idx]  # (robot geoms, joints)
        self._robot_lever = self._lever.max(axis=0)
        self.held: Held | None = None
        self._allowed_body = np.zeros(m.nbody, dtype=bool)
        self._near_body = np.zeros(m.nbody, dtype=bool)
        self._held_body = np.zeros(m.nbody, dtype=bool)
        self._mine = self._robot_bodies.copy()
        self._held_reach = 0.0
        self._chain = np.zeros((m.nbody, m.nbody), dtype=bool)  # one body below the other
        for b in range(1, m.nbody):
            a = int(m.body_parentid[b])
            while a > 0:
                self._chain[a, b] = self._chain[b, a] = True
                a = int(m.body_parentid[a])
        self.chain_slop = SELF_SLOP
        """Penetration [m] two links of one chain may reach (:data:`CHAIN_SLOP` for a check that allows it)."""
        self.checks = 0
        """States checked so far."""

    def set_world(self, poses: Mapping[str, Pose], q: np.ndarray, *, held: Held | None = None,
                  allow: Iterable[str] = (), near: Iterable[str] = (), qpos: np.ndarray | None = None) -> None:
        """Place the objects at ``poses`` (those not given stay where the model has them), the robot at ``q``.

        ``held``: the object the robot carries (its pose then follows its frame); ``allow``: bodies (and their
        subtrees) the robot may touch; ``near``: bodies it may come near (no clearance) but not touch, e.g. the
        object a push or a grasp goes to; ``qpos``: the whole state to start from (a mobile robot's base where it is).
        """
        d = self.data
        if qpos is not None:
            d.qpos[:] = qpos
        d.qpos[self.robot.qpos_idx] = q
        for name, pose in poses.items():
            if name in self._objects:
                sl = self._objects[name]
                quat = np.zeros(4)
                mujoco.mju_mat2Quat(quat, np.asarray(pose.rot, dtype=float).ravel())
                d.qpos[sl] = np.r_[pose.pos, quat]
        self.held = held
        self._allowed_body = self._subtrees(allow)
        self._near_body = self._subtrees(near)
        self._held_body = self._subtrees([held.object] if held is not None else [])
        self._mine = self._robot_bodies | self._held_body
        m = self.model
        m.geom_margin[:] = self._base_margin
        self._held_reach = 0.0
        if held is not None:  # the held object keeps the clearance too
            held_geoms = self._held_body[m.geom_bodyid]
            m.geom_margin[held_geoms] = np.maximum(m.geom_margin[held_geoms], max(LOOKAHEAD, self.clearance))
            self._held_reach = float(max(m.geom_rbound[held_geoms], default=0.0)) + float(
                np.linalg.norm(held.offset.pos))

    def _subtrees(self, names: Iterable[str]) -> np.ndarray:
        """Boolean body mask of the named bodies and every body below them (names the model lacks are skipped)."""
        mask = np.zeros(self.model.nbody, dtype=bool)
        for name in names:
            bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
            if bid >= 0:
                mask[list(_subtree(self.model, bid))] = True
        return mask

    def lever(self) -> np.ndarray:
        """Per robot joint, the farthest any point it moves (a held object's included) can be from its axis [m]."""
        return self._robot_lever + self._held_reach  # a held object: as far again as it reaches from its pad

    def room(self, q: np.ndarray) -> tuple[float, Collision | None]:
        """How far [m] any point may move from robot joints ``q`` [rad] before a constraint can break.

        Negative: by how much one is broken, with the worst violation (else None). Two robot links may approach
        each other from both sides: their room is half their distance.
        """
        self.checks += 1
        m, d = self.model, self.data
        d.qpos[self.robot.qpos_idx] = q
        if self.held is not None:
            mujoco.mj_kinematics(m, d)
            pose = _frame_pose(m, d, self.held.frame)
            rot = pose.rot @ self.held.offset.rot
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, rot.ravel())
            d.qpos[self._objects[self.held.object]] = np.r_[pose.pos + pose.rot @ self.held.offset.pos, quat]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        free = LOOKAHEAD - max(self.clearance, self.table_clearance)
        if d.ncon == 0:
            return free, None
        contact = d.contact
        slack, k, needed = worst_contact(contact.geom, contact.dist, m.geom_bodyid, self._mine, self._held_body,
                                         self._allowed_body, self._near_body, self._table, self._chain,
                                         self.clearance, self.table_clearance, self.chain_slop, SELF_SLOP, RESTING)
        if k < 0:
            return free, None
        if slack >= 0:
            return min(free, float(slack)), None
        b1, b2 = (int(m.geom_bodyid[g]) for g in contact.geom[k])
        return float(slack), Collision(_name(m, b1), _name(m, b2), float(contact.dist[k]), float(needed))

    def first_collision(self, q: np.ndarray) -> Collision | None:
        """The worst violation at robot joints ``q`` [rad], or None when ``q`` is valid."""
        return self.room(q)[1]

    def valid(self, q: np.ndarray) -> bool:
        """Whether robot joints ``q`` [rad] are a valid state."""
        return self.first_collision(q) is None

    def steps(self, qa: np.ndarray, qb: np.ndarray) -> int:
        """How many intervals a straight joint-space segment needs for :data:`RESOLUTION`.

        A robot geom moves at most its levers times the joints' travel (:func:`~nextage_qp.ik.kinematic_model.
        lever_bounds`); a held object as far as the farthest point of the chain that carries it, plus its reach.
        """
        dq = np.abs(np.asarray(qb, dtype=float) - np.asarray(qa, dtype=float))
        travel = float((self._lever @ dq).max()) if len(self._lever) else 0.0
        if self.held is not None:
            travel = max(travel, float(self.lever() @ dq))
        return max(1, int(np.ceil(travel / RESOLUTION)))

    def first_on_segment(self, qa: np.ndarray, qb: np.ndarray) -> tuple[float, Collision] | None:
        """The first invalid state on the straight segment ``qa`` -> ``qb``, as (fraction, why), or None.

        Dense: no point of the robot moves more than :data:`RESOLUTION` between two checked states.
        """
        qa, qb = np.asarray(qa, dtype=float), np.asarray(qb, dtype=float)
        travel = self.steps(qa, qb) * RESOLUTION  # the most any point moves along the segment [m], rounded up
        s = 0.0
        while True:
            room, why = self.room(qa + s * (qb - qa))
            if why is not None:
                return s, why
            if s >= 1.0:
                return None
            s = min(1.0, s + max(room, RESOLUTION) / travel)

    def first_on_path(self, path: Sequence[np.ndarray]) -> tuple[int, float, Collision] | None:
        """The first invalid state along a path of joint waypoints: (segment, fraction, why), or None.

        A path of one state is that state alone.
        """
        if len(path) == 1:
            why = self.first_collision(np.asarray(path[0], dtype=float))
            return None if why is None else (0, 0.0, why)
        for i in range(len(path) - 1):
            hit = self.first_on_segment(path[i], path[i + 1])
            if hit is not None:
                return i, hit[0], hit[1]
        return None


def _subtree(model: mujoco.MjModel, body: int) -> frozenset[int]:
    found = {body}
    for b in range(body + 1, model.nbody):
        if int(model.body_parentid[b]) in found:
            found.add(b)
    return frozenset(found)


def _frame_pose(model: mujoco.MjModel, data: mujoco.MjData, frame: str) -> Pose:
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame)
    if sid >= 0:
        return Pose(data.site_xpos[sid].copy(), data.site_xmat[sid].reshape(3, 3).copy())
    bid = model.body(frame).id
    return Pose(data.xpos[bid].copy(), data.xmat[bid].reshape(3, 3).copy())


def _name(model: mujoco.MjModel, body: int) -> str:
    return model.body(body).name or f"body {body}"
