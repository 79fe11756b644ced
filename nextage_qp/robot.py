"""The Nextage robot in a MuJoCo scene: names and indices, arm groups, frames, keyframes, scene overrides.

A :class:`Robot` wraps one compiled ``MjModel`` (the robot alone or a task scene that includes it). Every
joint, actuator and body carries the URDF name, so the report's tables map 1:1. Robot configurations are
15-vectors ``q`` in :data:`~nextage_qp.nextage.JOINT_NAMES` order, independent of any free joints the scene
adds for objects.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, UnknownFrameError, UnknownJointError, UnknownNameError
from nextage_qp.nextage import GROUP_JOINTS, JOINT_NAMES, ROBOT_COLLISION_GROUPS, SCENE_GROUP_BODIES
from nextage_qp.scene import SceneOverrides, compile_scene


class GroupSpec(NamedTuple):
    """A collision group given by bodies and/or whole subtrees (a body and every body below it)."""

    bodies: tuple[str, ...] = ()
    subtrees: tuple[str, ...] = ()


class Robot:
    """Names and indices of the Nextage in one compiled scene.

    Args:
        model: A compiled model that contains the 15 Nextage joints.
        scene: Where the model came from (for messages).

    Attributes:
        model: The MuJoCo model.
        overrides: The scene overrides the model was compiled with (kinematic copies apply them too).
        joint_ids: Model joint id of each of :data:`JOINT_NAMES`.
        qpos_idx: Index into ``data.qpos`` of each robot joint (read-only).
        dof_idx: Index into ``data.qvel`` / ``qfrc_*`` of each robot joint (read-only).
        actuator_ids: Actuator driving each robot joint, in joint order (read-only).
        lower, upper: Joint position limits [rad] (read-only).
        torque_limit: Actuator torque limit [N m] per joint (read-only).
    """

    def __init__(
        self, model: mujoco.MjModel, scene: str = "<model>", overrides: SceneOverrides | None = None
    ) -> None:
        self.model = model
        self.scene = scene
        self.overrides = overrides or SceneOverrides()
        model_joints = [model.joint(i).name for i in range(model.njnt)]
        missing = [j for j in JOINT_NAMES if j not in model_joints]
        if missing:
            raise ConfigError(f"{scene}: model lacks Nextage joints {missing}")
        self.joint_ids = _ro(np.array([model.joint(j).id for j in JOINT_NAMES]))
        self.qpos_idx = _ro(model.jnt_qposadr[self.joint_ids].copy())
        self.dof_idx = _ro(model.jnt_dofadr[self.joint_ids].copy())
        act_of_joint = {int(model.actuator_trnid[a, 0]): a for a in range(model.nu)}
        self.actuator_ids = _ro(np.array([act_of_joint[int(j)] for j in self.joint_ids]))
        self.lower = _ro(model.jnt_range[self.joint_ids, 0].copy())
        self.upper = _ro(model.jnt_range[self.joint_ids, 1].copy())
        self.torque_limit = _ro(model.actuator_ctrlrange[self.actuator_ids, 1].copy())
        self._joint_index = {name: i for i, name in enumerate(JOINT_NAMES)}

    @classmethod
    def from_scene(cls, scene: str | Path = "scene", overrides: SceneOverrides | None = None) -> Robot:
        """Load a bundled scene by name (``scene``, ``push_cube``, ``dock_dumbbell``, ``nextage``) or path."""
        return cls(compile_scene(scene, overrides, touch=("obstacle",)), scene=str(scene), overrides=overrides)

    # Names and indices.

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The robot's joints, in q order."""
        return JOINT_NAMES

    @property
    def nq(self) -> int:
        """Number of robot joints (15)."""
        return len(JOINT_NAMES)

    def joint_index(self, name: str) -> int:
        """Position of a joint in the robot's q vector.

        Raises:
            UnknownJointError: The name is not a robot joint; the message lists the valid ones.
        """
        try:
            return self._joint_index[name]
        except KeyError:
            raise UnknownJointError(name, JOINT_NAMES) from None

    def group(self, name: str) -> np.ndarray:
        """Indices into q of a joint group (``chest``, ``head``, ``left_arm``, ``right_arm``)."""
        if name not in GROUP_JOINTS:
            raise UnknownNameError("joint group", name, GROUP_JOINTS)
        return np.array([self._joint_index[j] for j in GROUP_JOINTS[name]])

    @property
    def site_names(self) -> tuple[str, ...]:
        """Names of all named sites."""
        return tuple(n for n in (self.model.site(i).name for i in range(self.model.nsite)) if n)

    @property
    def body_names(self) -> tuple[str, ...]:
        """Names of all named bodies except the world."""
        return tuple(n for n in (self.model.body(i).name for i in range(1, self.model.nbody)) if n)

    @property
    def frame_names(self) -> tuple[str, ...]:
        """Every name accepted as a frame: sites first, then bodies."""
        return self.site_names + self.body_names

    def frame(self, name: str) -> tuple[str, int]:
        """Resolve a frame name to ``("site" | "body", id)``; sites win when a name is both.

        Raises:
            UnknownFrameError: The name is neither a site nor a body.
        """
        sid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, name)
        if sid >= 0:
            return "site", sid
        bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if bid > 0:
            return "body", bid
        raise UnknownFrameError(name, self.frame_names)

    @functools.cached_property
    def object_names(self) -> tuple[str, ...]:
        """Free bodies of the scene (the manipulated objects, e.g. ``cube``, ``dumbbell``)."""
        free = self.model.jnt_type == mujoco.mjtJoint.mjJNT_FREE
        return tuple(self.model.body(int(b)).name for b in self.model.jnt_bodyid[free])

    def yaw_symmetry(self, name: str) -> float:
        """The yaw [rad] after which an object looks the same (custom numeric ``NAME_yaw_symmetry``; 2 pi if none)."""
        nid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_NUMERIC, f"{name}_yaw_symmetry")
        return float(self.model.numeric_data[self.model.numeric_adr[nid]]) if nid >= 0 else 2.0 * np.pi

    def object_qpos_slice(self, name: str) -> slice:
        """Slice of ``data.qpos`` holding the free joint (pos, quat) of an object."""
        if name not in self.object_names:
            raise UnknownNameError("object", name, self.object_names)
        body = self.model.body(name).id
        jnt = int(self.model.body_jntadr[body])
        adr = int(self.model.jnt_qposadr[jnt])
        return slice(adr, adr + 7)

    # Configurations.

    def keyframe_q(self, name: str = "home") -> np.ndarray:
        """Robot q of a keyframe (``home``, ``zero``)."""
        kid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_KEY, name)
        if kid < 0:
            valid = [self.model.key(i).name for i in range(self.model.nkey)]
            raise UnknownNameError("keyframe", name, valid)
        return self.model.key_qpos[kid, self.qpos_idx].copy()

    def q_from_names(self, values: Mapping[str, float], base: np.ndarray | None = None) -> np.ndarray:
        """A q vector from ``{joint name: angle [rad]}`` on top of ``base`` (default: zeros)."""
        q = np.zeros(self.nq) if base is None else np.array(base, dtype=float)
        for name, value in values.items():
            q[self.joint_index(name)] = float(value)
        return q

    def q_to_names(self, q: Sequence[float] | np.ndarray) -> dict[str, float]:
        """``{joint name: angle [rad]}`` of a q vector."""
        return {name: float(v) for name, v in zip(JOINT_NAMES, q, strict=True)}

    def get_q(self, data: mujoco.MjData) -> np.ndarray:
        """Robot joint positions [rad] read from a simulation."""
        return data.qpos[self.qpos_idx].copy()

    def get_qd(self, data: mujoco.MjData) -> np.ndarray:
        """Robot joint velocities [rad/s] read from a simulation."""
        return data.qvel[self.dof_idx].copy()

    def set_q(self, data: mujoco.MjData, q: np.ndarray) -> None:
        """Write robot joint positions into a simulation (objects untouched)."""
        data.qpos[self.qpos_idx] = q

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> bool:
        """True when every joint of q is inside its range (with tolerance ``tol`` [rad])."""
        return bool(np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol))

    # Collision geometry.

    def collision_geoms(self, extra: Mapping[str, GroupSpec] | None = None) -> dict[str, tuple[int, ...]]:
        """Named groups of collision geom ids, for collision avoidance and contact checks.

        Groups: those of :data:`~nextage_qp.nextage.ROBOT_COLLISION_GROUPS` (``left_arm`` / ``right_arm``,
        ``left_forearm`` / ``right_forearm``, ``left_hand`` / ``right_hand``, ``torso``, ``head``), ``table`` and
        ``obstacle`` when the scene has them, one group per object (e.g. ``cube``), and the ``extra`` groups.

        Raises:
            UnknownNameError: An extra group names a body that is not in the scene.
        """
        m = self.model
        colliding = [g for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]]

        def of_bodies(ids: set[int]) -> tuple[int, ...]:
            return tuple(g for g in colliding if int(m.geom_bodyid[g]) in ids)

        def ids(names: Sequence[str], strict: bool, what: str) -> set[int]:
            found = set()
            for n in names:
                bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n)
                if bid < 0 and strict:
                    raise UnknownNameError(what, n, self.body_names)
                if bid >= 0:
                    found.add(bid)
            return found

        groups = {name: of_bodies(ids(bodies, False, "body")) for name, bodies in ROBOT_COLLISION_GROUPS.items()}
        for name in (*SCENE_GROUP_BODIES, *self.object_names):
            if found := of_bodies(ids([name], False, "body")):
                groups[name] = found
        for name, spec in (extra or {}).items():
            roots = ids(spec.subtrees, True, f"body (collision group {name!r} subtree)")
            below = {b for b in range(m.nbody) if any(descends(m, b, r) for r in roots)}
            groups[name] = of_bodies(ids(spec.bodies, True, f"body (collision group {name!r})") | below)
        return groups


PerJoint = float | tuple[float, ...] | dict[str, float]
"""A per-joint setting: one value for every joint, a list in joint order, or ``{joint: value}``."""


def per_joint(value: PerJoint, default: float, names: Sequence[str]) -> np.ndarray:
    """The per-joint array of a setting; joints a mapping leaves out get ``default`` (one meaning everywhere).

    Raises:
        ConfigError: A list of the wrong length or a mapping with an unknown joint.
    """
    if isinstance(value, dict):
        out = np.full(len(names), float(default))
        for joint, v in value.items():
            if joint not in names:
                raise UnknownJointError(joint, names)
            out[list(names).index(joint)] = v
        return out
    arr = np.broadcast_to(np.asarray(value, dtype=float), (len(names),)) if np.ndim(value) == 0 else np.asarray(value)
    if arr.shape != (len(names),):
        raise ConfigError(f"a per-joint list needs {len(names)} values, got {len(arr)}")
    return np.array(arr, dtype=float)


def descends(m: mujoco.MjModel, body: int, root: int) -> bool:
    """Whether ``body`` is ``root`` or lies in its subtree (every body descends from the world, 0)."""
    while body > 0:
        if body == root:
            return True
        body = int(m.body_parentid[body])
    return root == 0


def _ro(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a
