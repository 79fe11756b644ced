"""Checks on a scene's objects before anything moves: none may start inside the table, an obstacle or another."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError

OVERLAP_TOLERANCE = 0.001
"""Penetration [m] a resting contact may show before an object counts as starting inside something."""


def check_clear(model: mujoco.MjModel, robot_joints: Sequence[str], object_names: Sequence[str], source: str,
                tolerance: float = OVERLAP_TOLERANCE) -> None:
    """Raise if a free object starts more than ``tolerance`` inside anything but the robot.

    The robot (every body in the subtree of ``robot_joints``) is left out: its start posture is set later, and the
    phases move it clear.

    Raises:
        ConfigError: Names the object, what it starts inside and by how much.
    """
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    robot_roots = {int(model.body_rootid[model.jnt_bodyid[model.joint(j).id]]) for j in robot_joints}
    objects = {model.body(name).id: name for name in object_names}
    worst: tuple[float, str, str] | None = None
    for contact in data.contact[: data.ncon]:
        bodies = [int(model.geom_bodyid[g]) for g in contact.geom]
        if any(int(model.body_rootid[b]) in robot_roots and b != 0 for b in bodies):
            continue
        for mine, partner in (bodies, bodies[::-1]):
            if mine in objects and -contact.dist > tolerance and (worst is None or -contact.dist > worst[0]):
                worst = (-float(contact.dist), objects[mine], _name(model, partner))
    if worst is not None:
        depth, name, other = worst
        raise ConfigError(f"{source}: object {name!r} starts {depth * 1e3:.1f} mm inside {other}: move it "
                          f"(scene.poses.{name}.pos; scene.objects.{name}.pos where no pose is given) or "
                          "make it smaller")
    bad = ~np.isfinite(data.qpos)
    if bad.any():
        raise ConfigError(f"{source}: the scene's start state is not finite (check scene.poses and scene.objects)")


def _name(model: mujoco.MjModel, body: int) -> str:
    return "the world's ground" if body == 0 else repr(model.body(body).name or f"body {body}")


def check_robot_clear(model: mujoco.MjModel, data: mujoco.MjData, robot_body: np.ndarray, source: str,
                      tolerance: float = OVERLAP_TOLERANCE) -> None:
    """Raise if anything of the scene starts more than ``tolerance`` inside the robot at its start posture.

    ``data`` holds the start state; ``robot_body`` marks the robot's bodies (by body id). An object or obstacle that
    the robot's start posture would be inside gets thrown as the simulation starts.

    Raises:
        ConfigError: Names the body, the robot link it starts inside, by how much, and what to change.
    """
    mujoco.mj_forward(model, data)
    worst: tuple[float, str, str] | None = None
    for i in range(data.ncon):
        contact = data.contact[i]
        b1, b2 = (int(model.geom_bodyid[g]) for g in contact.geom)
        if robot_body[b1] == robot_body[b2] or -contact.dist <= tolerance:
            continue
        link, other = (b1, b2) if robot_body[b1] else (b2, b1)
        if other != 0 and (worst is None or -contact.dist > worst[0]):
            worst = (-float(contact.dist), model.body(other).name, _name(model, link))
    if worst is not None:
        depth, body, where = worst
        key = "scene.clutter.region" if body.startswith("clutter_") else f"scene.poses.{body}"
        raise ConfigError(f"{source}: {body!r} starts {depth * 1e3:.1f} mm inside the robot's {where} at its start "
                          f"posture: move it ({key}) or start the robot elsewhere (start)")
