"""Collision groups (the robot file's bodies and subtrees, the scene's static bodies, one per object) and arm frames."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import mujoco

from nextage_qp.errors import ConfigError, UnknownNameError

if TYPE_CHECKING:
    from nextage_qp.robot import Robot


def collision_geoms(robot: Robot, extra: Mapping[str, Any] | None = None) -> dict[str, tuple[int, ...]]:
    """Named groups of a robot's scene's collision geom ids (see :meth:`Robot.collision_geoms`).

    Groups: the robot file's (e.g. ``left_arm``, ``left_hand``, ``torso``), a mobile robot's ``mobile_base``
    (its base's body, wheels and steering, not the robot on it), ``table`` and ``obstacle`` when the scene has
    them, one group per object (e.g. ``cube``), and the ``extra`` groups.

    Raises:
        UnknownNameError: A group names a body that is not in the scene.
    """
    from nextage_qp.mobile.build import BASE_BODY
    from nextage_qp.per_joint import descends
    from nextage_qp.robot import SCENE_GROUP_BODIES, GroupSpec

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
    for name in (*SCENE_GROUP_BODIES, *robot.object_names):
        if found := of_bodies(ids([name], False, "body")):
            groups[name] = found
    for name, spec in (extra or {}).items():
        groups[name] = group(name, spec)
    return groups


def robot_roots(robot: Robot) -> list[int]:
    """The top bodies of the robot a mobile base carries (the base's children that are not its wheels)."""
    from nextage_qp.mobile.build import BASE_BODY

    m = robot.model
    base = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, BASE_BODY)
    return [b for b in range(m.nbody) if int(m.body_parentid[b]) == base and b != base
            and not m.body(b).name.startswith(BASE_BODY)]


def check_arm_frames(model: mujoco.MjModel, desc: Any) -> None:
    """Raise :class:`ConfigError` when an arm's wrist, tool or pad frame is neither a site nor a body of the model."""
    for i, arm in enumerate(desc.arms):
        for key in ("wrist", "tool", "pad"):
            name = getattr(arm, key)
            if (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name) < 0
                    and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) <= 0):
                raise ConfigError(f"{desc.source}: arms[{i}].{key}: {name!r} is neither a site nor a body of the "
                                  f"model; name one of its sites or bodies, or add it under frames: (body, pos)")


def scene_bodies(robot: Robot) -> tuple[str, ...]:
    """Named bodies of the scene, not of the robot: where objects may go.

    None that a robot joint (or a mobile robot's base) moves, nor the robot's fixed links those hang from.
    """
    from nextage_qp.mobile.build import BASE_BODY

    m = robot.model
    movers = {int(m.jnt_bodyid[m.joint(j).id]) for j in robot.joint_names}
    if robot.description.base is not None:
        movers.add(m.body(BASE_BODY).id)
    own = set()
    for b in movers:  # the robot: its moving bodies' chains down to the world
        while b > 0:
            own.add(b)
            b = int(m.body_parentid[b])
    names = []
    for b in range(1, m.nbody):
        up = b
        while up > 0 and up not in own:
            up = int(m.body_parentid[up])
        if up == 0 and m.body(b).name:
            names.append(m.body(b).name)
    return tuple(names)
