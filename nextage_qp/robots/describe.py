"""A scene described as plain data: joints with limits, actuators, sites, objects, collision groups, masses."""

from __future__ import annotations

from typing import Any

import numpy as np

from nextage_qp.robots.model import Robot


def describe(robot: Robot) -> dict[str, Any]:
    """Everything ``info`` prints, as plain data."""
    m = robot.model
    joints = [
        {
            "name": name,
            "lower_rad": float(robot.lower[i]),
            "upper_rad": float(robot.upper[i]),
            "axis": m.jnt_axis[robot.joint_ids[i]].tolist(),
            "damping": float(m.dof_damping[robot.dof_idx[i]]),
            "torque_limit_nm": float(robot.torque_limit[i]),
        }
        for i, name in enumerate(robot.joint_names)
    ]
    base = int(m.body_rootid[m.jnt_bodyid[robot.joint_ids[0]]])  # the robot's top body (its mount)
    robot_bodies = [b for b in range(m.nbody) if m.body_rootid[b] == base]
    moving = [b for b in robot_bodies if m.body_weldid[b] != 0]
    return {
        "scene": robot.scene,
        "robot": robot.name,
        "arms": {a.name: {"joints": list(a.joints), "wrist": a.wrist, "tool": a.tool, "pad": a.pad}
                 for a in robot.arms},
        "timestep_s": float(m.opt.timestep),
        "joints": joints,
        "actuators": [m.actuator(int(a)).name for a in robot.actuator_ids],
        "sites": list(robot.site_names),
        "objects": {
            name: {"mass_kg": float(m.body(name).mass[0]), "start_pos": m.body(name).pos.tolist()}
            for name in robot.object_names
        },
        "collision_groups": {k: len(v) for k, v in robot.collision_geoms().items()},
        "robot_moving_mass_kg": float(np.sum(m.body_mass[moving])),
        "robot_total_mass_kg": float(np.sum(m.body_mass[robot_bodies])),
    }
