"""A robot in a MuJoCo scene: names and indices, arm groups, frames, keyframes, scene overrides.

A :class:`Robot` wraps one compiled ``MjModel`` (a task scene composed around the robot of a robot file,
:mod:`nextage_qp.robots`) and the robot file's description. Every joint, actuator and body keeps the model's own
name. Robot configurations are vectors ``q`` over the robot's joints in model order (:attr:`Robot.joint_names`),
independent of any free joints the scene adds for objects.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, UnknownFrameError, UnknownJointError, UnknownNameError
from nextage_qp.io.per_joint import PerJoint, descends, per_joint, within_range  # noqa: F401 (re-exported)
from nextage_qp.mobile.base import BASE_BODY, MobileBase
from nextage_qp.robots.actuation import torque_limits, velocity_limits
from nextage_qp.robots.description import Arm, RobotDescription, load_robot
from nextage_qp.robots.modelfile import moved_by
from nextage_qp.scene.clutter import PREFIX as CLUTTER_PREFIX
from nextage_qp.scene.compile import compile_spec
from nextage_qp.scene.files import SceneOverrides, add_touch_sensors
from nextage_qp.scene.seen_obstacles import PREFIX as SEEN_PREFIX
from nextage_qp.scene.seen_obstacles import blind

SCENE_GROUP_BODIES = ("table", "obstacle")
"""Static scene bodies that become collision groups of their own when a scene has them (and every declared fixed
object: :func:`scene_groups`)."""
CLUTTER_GROUP = "clutter"
"""The collision group of the generated clutter (:mod:`nextage_qp.scene.clutter`)."""
WATCHED_BODIES = ("obstacle",)
"""Scene bodies that get a contact sensor (:func:`~nextage_qp.scene.files.add_touch_sensors`): touching them counts."""


class GroupSpec(NamedTuple):
    """A collision group given by bodies and/or whole subtrees (a body and every body below it)."""

    bodies: tuple[str, ...] = ()
    subtrees: tuple[str, ...] = ()


class Robot:
    """Names and indices of a robot in one compiled scene.

    Args:
        model: A compiled model that contains the robot's joints.
        description: The robot file's description (default: the default robot's).
        scene: Where the model came from (for messages).
        overrides: The scene overrides the model was compiled with.
        spec: Rebuilds the model's spec (kinematic copies, e.g. the IK's, are compiled from it), or None.

    Attributes:
        model: The MuJoCo model.
        description: The robot file's description.
        overrides: The scene overrides the model was compiled with (kinematic copies apply them too).
        joint_ids: Model joint id of each robot joint.
        qpos_idx: Index into ``data.qpos`` of each robot joint (read-only).
        dof_idx: Index into ``data.qvel`` / ``qfrc_*`` of each robot joint (read-only).
        actuator_ids: Actuator driving each robot joint, in joint order (read-only).
        lower, upper: Joint position limits [rad] (read-only).
        torque_limit: Actuator torque limit [N m] per joint (read-only).
        velocity_limit: The robot file's velocity limit [rad/s] per joint, inf where none (read-only).
        base: The wheeled base under the robot (:mod:`nextage_qp.mobile`), or None for a fixed robot.
    """

    def __init__(self, model: mujoco.MjModel, description: RobotDescription | None = None, scene: str = "<model>",
                 overrides: SceneOverrides | None = None, spec: Callable[[], mujoco.MjSpec] | None = None) -> None:
        self.model = model
        self.description = desc = description or load_robot()
        self.scene = scene
        self.overrides = overrides or SceneOverrides()
        self.spec = spec
        self.blinded = False
        """A controller's copy that knows no clutter, only the camera's boxes (:meth:`blinded_copy`)."""
        model_joints = {model.joint(i).name: i for i in range(model.njnt)}
        if missing := [j for j in desc.joints if j not in model_joints]:
            raise ConfigError(f"{scene}: model lacks the joints {missing} of robot {desc.name!r} ({desc.source})")
        ids = sorted(model_joints[j] for j in desc.joints)
        for j in ids:
            if int(model.jnt_type[j]) not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
                raise ConfigError(f"{desc.source}: joint {model.joint(j).name!r} is not a hinge or slide joint")
        self._names = tuple(model.joint(j).name for j in ids)
        self.joint_ids = _ro(np.array(ids, dtype=int))
        self.qpos_idx = _ro(model.jnt_qposadr[self.joint_ids].copy())
        self.dof_idx = _ro(model.jnt_dofadr[self.joint_ids].copy())
        act_of_joint = {int(model.actuator_trnid[a, 0]): a for a in range(model.nu)
                        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT}
        if undriven := [model.joint(j).name for j in ids if j not in act_of_joint]:
            raise ConfigError(f"{scene}: no actuator drives the joints {undriven}")
        self.actuator_ids = _ro(np.array([act_of_joint[j] for j in ids], dtype=int))
        limited = model.jnt_limited[self.joint_ids].astype(bool)
        self.lower = _ro(np.where(limited, model.jnt_range[self.joint_ids, 0], -np.pi))
        self.upper = _ro(np.where(limited, model.jnt_range[self.joint_ids, 1], np.pi))
        self.torque_limit = _ro(torque_limits(model, self.actuator_ids, self.joint_ids, desc))
        self.velocity_limit = _ro(velocity_limits(desc, self._names))
        self._joint_index = {name: i for i, name in enumerate(self._names)}
        check_arm_frames(model, desc)
        self.base = MobileBase(model, desc.base, (desc.mount.pos, desc.mount.yaw), desc.source) if desc.base else None

    @classmethod
    def from_scene(cls, scene: str | Path = "scene", overrides: SceneOverrides | None = None,
                   robot: str | Path | RobotDescription | None = None) -> Robot:
        """Compose a scene (bundled name or path) around a robot (robot file, bundled name, or the default robot).

        Raises:
            ConfigError: The robot file or the scene is invalid, or they do not compile together.
        """
        from nextage_qp.robots.compose import compose

        desc = robot if isinstance(robot, RobotDescription) else load_robot(robot)
        overrides = overrides or SceneOverrides()
        spec = functools.partial(compose, desc, scene, overrides)
        composed = spec()
        add_touch_sensors(composed, WATCHED_BODIES)
        model = compile_spec(composed, f"scene {str(scene)!r} with robot {desc.name!r}")
        return cls(model, desc, scene=str(scene), overrides=overrides, spec=spec)

    @property
    def name(self) -> str:
        """The robot's name."""
        return self.description.name

    @property
    def arms(self) -> tuple[Arm, ...]:
        """The robot's arms, the first one on the +y side."""
        return self.description.arms

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The robot's joints, in q order (the model's)."""
        return self._names

    @property
    def nq(self) -> int:
        """Number of robot joints."""
        return len(self._names)

    def joint_index(self, name: str) -> int:
        """Position of a joint in the robot's q vector.

        Raises:
            UnknownJointError: The name is not a robot joint; the message lists the valid ones.
        """
        try:
            return self._joint_index[name]
        except KeyError:
            raise UnknownJointError(name, self._names) from None

    def group(self, name: str) -> np.ndarray:
        """Indices into q of a joint group (each arm's ``NAME_arm`` and the robot file's, e.g. ``chest``)."""
        groups = self.description.groups
        if name not in groups:
            raise UnknownNameError("joint group", name, groups)
        return np.array([self._joint_index[j] for j in groups[name]])

    def moved_groups(self, moving: Iterable[int]) -> list[int]:
        """Indices into q of the joint groups a motion of joints ``moving`` must plan over, with ``moving`` itself.

        A group counts when one of its joints moves; an arm also when a moving joint carries it (a torso that turns
        swings both arms: each may have to move aside and come back).
        """
        m, moving = self.model, {int(j) for j in moving}
        ids = {int(self.joint_ids[j]) for j in moving}

        def carried(j: int) -> bool:  # a moving joint on a body above j's
            return not ids.isdisjoint(moved_by(m, int(m.body_parentid[m.jnt_bodyid[self.joint_ids[j]]])))

        out = set(moving)
        arms = {arm.group for arm in self.arms}
        for name, joints in self.description.groups.items():
            idx = [self._joint_index[j] for j in joints]
            if moving & set(idx) or (name in arms and any(carried(j) for j in idx)):
                out.update(idx)
        return sorted(out)

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

    def frame_body(self, name: str) -> int:
        """The body a frame (a site or a body, see :meth:`frame`) lives on.

        Raises:
            UnknownFrameError: The name is neither a site nor a body.
        """
        kind, i = self.frame(name)
        return int(self.model.site_bodyid[i]) if kind == "site" else i

    def chain_joints(self, frame: str) -> list[int]:
        """Indices into q of the robot joints that move ``frame`` (those above it in the kinematic tree)."""
        chain = set(moved_by(self.model, self.frame_body(frame)))
        return [k for k, j in enumerate(self.joint_ids) if int(j) in chain]

    @functools.cached_property
    def object_names(self) -> tuple[str, ...]:
        """Free bodies of the scene (the manipulated objects, e.g. ``cube``, ``dumbbell``)."""
        free = self.model.jnt_type == mujoco.mjtJoint.mjJNT_FREE
        names = (self.model.body(int(b)).name for b in self.model.jnt_bodyid[free])
        return tuple(n for n in names if self.description.base is None or n != BASE_BODY)  # not the robot's base

    @property
    def fixed_objects(self) -> tuple[str, ...]:
        """Declared fixed objects of the scene (static obstacles: ``scene.objects`` with ``fixed: true``)."""
        return tuple(n for n, decl in self.overrides.objects.items()
                     if decl.fixed and mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, n) >= 0)

    def blinded_copy(self) -> Robot:
        """This robot on a copy of its model blind to the clutter, with the seen-obstacle pool in its place.

        For the controller of a run whose obstacles come from its camera (:mod:`nextage_qp.scene.seen_obstacles`):
        the same names and indices, the physics' model untouched.
        """
        twin = copy.copy(self)
        twin.model = copy.copy(self.model)
        blind(twin.model)
        twin.blinded = True
        return twin

    def obstacle_groups(self) -> tuple[str, ...]:
        """The collision groups of the scene's obstacles it has: the obstacle, the clutter, the fixed objects."""
        groups = self.collision_geoms()
        return tuple(g for g in ("obstacle", CLUTTER_GROUP, *self.fixed_objects) if groups.get(g))

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
        """Robot q of a keyframe of the robot file (``home``: the model's keyframe, or joint -> rad), or ``zero``."""
        keys = self.description.keyframes
        if name == "zero" and name not in keys:  # built in: every joint at 0, clipped into its range
            return np.clip(np.zeros(self.nq), self.lower, self.upper)
        if name not in keys:
            raise UnknownNameError("keyframe", name, [*keys, *(("zero",) if "zero" not in keys else ())])
        key, where = keys[name], f"{self.description.source}: keyframes.{name}"
        if isinstance(key, str):  # the model's own keyframe
            kid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_KEY, name)
            if kid < 0:
                raise ConfigError(f"{where}: the model has no keyframe {name!r}")
        q = self.model.key_qpos[kid, self.qpos_idx].copy() if isinstance(key, str) else self.q_from_names(key)
        return within_range(q, self.lower, self.upper, self._names, where)

    def q_from_names(self, values: Mapping[str, float], base: np.ndarray | None = None) -> np.ndarray:
        """A q vector from ``{joint name: angle [rad]}`` on top of ``base`` (default: zeros)."""
        q = np.zeros(self.nq) if base is None else np.array(base, dtype=float)
        for name, value in values.items():
            q[self.joint_index(name)] = float(value)
        return q

    def q_to_names(self, q: Sequence[float] | np.ndarray) -> dict[str, float]:
        """``{joint name: angle [rad]}`` of a q vector."""
        return {name: float(v) for name, v in zip(self._names, q, strict=True)}

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

        Groups: the robot file's (e.g. ``left_arm``, ``left_hand``, ``torso``), ``table`` and ``obstacle`` when
        the scene has them, one group per object (e.g. ``cube``), and the ``extra`` groups.

        Raises:
            UnknownNameError: A group names a body that is not in the scene.
        """
        if extra:
            return collision_geoms(self, extra)
        m = self.model  # without extra groups, kept while the geoms' collision bits stay the same
        key = m.geom_contype.tobytes() + m.geom_conaffinity.tobytes()
        kept = self.__dict__.get("_collision_groups")
        if kept is None or kept[0] != key:
            kept = (key, collision_geoms(self))
            self.__dict__["_collision_groups"] = kept
        return dict(kept[1])

    @property
    def robot_groups(self) -> tuple[str, ...]:
        """The robot file's collision groups (the robot's own geoms)."""
        return tuple(self.description.collision_groups)


def tool_frames(robot: Robot) -> tuple[str, ...]:
    """Each arm's tool and pad frames, the frames a manipulation run records and marks (each once)."""
    return tuple(dict.fromkeys(f for arm in robot.arms for f in (arm.tool, arm.pad)))


def _ro(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def collision_geoms(robot: Robot, extra: Mapping[str, Any] | None = None) -> dict[str, tuple[int, ...]]:
    """Named groups of a robot's scene's collision geom ids (see :meth:`Robot.collision_geoms`).

    Groups: the robot file's (e.g. ``left_arm``, ``left_hand``, ``torso``), a mobile robot's ``mobile_base``
    (its base's body, wheels and steering, not the robot on it), ``table`` and ``obstacle`` when the scene has
    them, one group per object (e.g. ``cube``), and the ``extra`` groups.

    Raises:
        UnknownNameError: A group names a body that is not in the scene.
    """
    m = robot.model
    colliding = [g for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]]

    def of_bodies(ids: set[int]) -> tuple[int, ...]:
        return tuple(g for g in colliding if int(m.geom_bodyid[g]) in ids)

    def ids(names: Sequence[str], strict: bool, what: str) -> set[int]:
        found = set()
        for n in names:
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n)
            if bid < 0 and strict:
                raise UnknownNameError(what, n, robot.body_names)
            if bid >= 0:
                found.add(bid)
        return found

    def group(name: str, spec: GroupSpec) -> tuple[int, ...]:
        roots = ids(spec.subtrees, True, f"body (collision group {name!r} subtree)")
        below = {b for b in range(m.nbody) if any(descends(m, b, r) for r in roots)}
        return of_bodies(ids(spec.bodies, True, f"body (collision group {name!r})") | below)

    groups = {
        name: group(name, GroupSpec(g.bodies, g.subtrees)) for name, g in robot.description.collision_groups.items()
    }
    if robot.base is not None:  # the base and its wheels: every body below it but those of the robot it carries
        carried = {b for b in range(m.nbody) if any(descends(m, b, r) for r in robot_roots(robot))}
        groups[BASE_BODY] = of_bodies({b for b in range(m.nbody) if descends(m, b, robot.base.body)} - carried)
    for name in (*SCENE_GROUP_BODIES, *robot.object_names, *robot.fixed_objects):
        if found := of_bodies(ids([name], False, "body")):
            groups[name] = found
    clutter = {b for b in range(m.nbody) if m.body(b).name.startswith((CLUTTER_PREFIX, SEEN_PREFIX))}
    groups[CLUTTER_GROUP] = of_bodies(clutter)  # the generated clutter (scene.clutter), one group: empty for none;
    # a blinded copy's clutter collides with nothing, its seen-obstacle pool takes the group's place
    for name, spec in (extra or {}).items():
        groups[name] = group(name, spec)
    return groups


def robot_roots(robot: Robot) -> list[int]:
    """The top bodies of the robot a mobile base carries (the base's children that are not its wheels)."""
    m = robot.model
    base = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, BASE_BODY)
    return [b for b in range(m.nbody) if int(m.body_parentid[b]) == base and b != base
            and not m.body(b).name.startswith(BASE_BODY)]


def check_arm_frames(model: mujoco.MjModel, desc: RobotDescription) -> None:
    """Raise :class:`ConfigError` when an arm's wrist, tool or pad frame is neither a site nor a body of the model."""
    for i, arm in enumerate(desc.arms):
        for key in ("wrist", "tool", "pad"):
            name = getattr(arm, key)
            if (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name) < 0
                    and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) <= 0):
                raise ConfigError(f"{desc.source}: arms[{i}].{key}: {name!r} is neither a site nor a body of the "
                                  f"model; name one of its sites or bodies, or add it under frames: (body, pos)")


def robot_bodies(robot: Robot) -> frozenset[int]:
    """Ids of the robot's bodies.

    Those a robot joint (or a mobile robot's base) moves, the fixed links they hang from down to the world, and every
    body below them (hands, pads, tool frames).
    """
    m = robot.model
    movers = {int(m.jnt_bodyid[m.joint(j).id]) for j in robot.joint_names}
    if robot.description.base is not None:
        movers.add(m.body(BASE_BODY).id)
    own = set()
    for b in movers:  # the robot: its moving bodies' chains down to the world
        while b > 0:
            own.add(b)
            b = int(m.body_parentid[b])
    found = set()
    for b in range(1, m.nbody):
        up = b
        while up > 0 and up not in own:
            up = int(m.body_parentid[up])
        if up > 0:
            found.add(b)
    return frozenset(found)


def scene_bodies(robot: Robot) -> tuple[str, ...]:
    """Named bodies of the scene, not of the robot: where objects may go (:func:`robot_bodies` left out)."""
    m, own = robot.model, robot_bodies(robot)
    return tuple(m.body(b).name for b in range(1, m.nbody) if b not in own and m.body(b).name)
