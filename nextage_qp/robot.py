"""The Nextage robot in a MuJoCo scene: names and indices, arm groups, frames, keyframes, scene overrides.

A :class:`Robot` wraps one compiled ``MjModel`` (the robot alone or a task scene that includes it). Every
joint, actuator and body carries the URDF name, so the report's tables map 1:1. Robot configurations are
15-vectors ``q`` in :data:`JOINT_NAMES` order, independent of any free joints the scene adds for objects.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from types import MappingProxyType

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, UnknownFrameError, UnknownJointError, UnknownNameError
from nextage_qp.scene import SceneOverrides, compile_scene

SIDES = ("left", "right")
"""The two arms, in the order every per-arm loop uses."""

ARM_PREFIX = MappingProxyType({"left": "LARM", "right": "RARM"})

JOINT_NAMES: tuple[str, ...] = (
    "CHEST_JOINT0",
    "HEAD_JOINT0",
    "HEAD_JOINT1",
    *(f"LARM_JOINT{i}" for i in range(6)),
    *(f"RARM_JOINT{i}" for i in range(6)),
)
"""The 15 robot joints, in model (and URDF) order."""

GROUP_JOINTS: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "chest": ("CHEST_JOINT0",),
        "head": ("HEAD_JOINT0", "HEAD_JOINT1"),
        "left_arm": tuple(f"LARM_JOINT{i}" for i in range(6)),
        "right_arm": tuple(f"RARM_JOINT{i}" for i in range(6)),
    }
)
"""Joint groups: the chest, the head and each arm."""

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
        return cls(compile_scene(scene, overrides), scene=str(scene), overrides=overrides)

    # Names and indices.

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

    @property
    def object_names(self) -> tuple[str, ...]:
        """Free bodies of the scene (the manipulated objects, e.g. ``cube``, ``dumbbell``)."""
        free = self.model.jnt_type == mujoco.mjtJoint.mjJNT_FREE
        return tuple(self.model.body(int(b)).name for b in self.model.jnt_bodyid[free])

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

    def collision_geoms(self) -> dict[str, tuple[int, ...]]:
        """Named groups of collision geom ids, for collision avoidance and contact checks.

        Groups: ``left_arm`` / ``right_arm`` (all six links), ``left_hand`` / ``right_hand`` (the wrist link),
        ``left_forearm`` / ``right_forearm`` (links 3-5), ``torso`` (chest, waist, pedestal), ``head``,
        ``table``, ``obstacle`` and one group per object (e.g. ``cube``, ``dumbbell``) when present.
        """
        m = self.model
        colliding = [g for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]]

        def of_bodies(names: Sequence[str]) -> tuple[int, ...]:
            ids = {m.body(n).id for n in names if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n) >= 0}
            return tuple(g for g in colliding if int(m.geom_bodyid[g]) in ids)

        groups: dict[str, tuple[int, ...]] = {}
        for side in SIDES:
            pre = ARM_PREFIX[side]
            groups[f"{side}_arm"] = of_bodies([f"{pre}_JOINT{i}_Link" for i in range(6)])
            groups[f"{side}_forearm"] = of_bodies([f"{pre}_JOINT{i}_Link" for i in (3, 4, 5)])
            groups[f"{side}_hand"] = of_bodies([f"{pre}_JOINT5_Link"])
        groups["torso"] = of_bodies(["CHEST_JOINT0_Link", "WAIST", "nextage_base"])
        groups["head"] = of_bodies(["HEAD_JOINT0_Link", "HEAD_JOINT1_Link"])
        for name in ("table", "obstacle", *self.object_names):
            found = of_bodies([name])
            if found:
                groups[name] = found
        return groups


def _ro(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a
