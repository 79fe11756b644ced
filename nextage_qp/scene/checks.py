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
