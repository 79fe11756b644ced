"""Actuation from the robot file: each joint's torque limit, from the model or from the robot file."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.robots.description import RobotDescription


def velocity_limits(desc: RobotDescription, joints: Sequence[str]) -> np.ndarray:
    """Each joint's velocity limit [rad/s] from the robot file's ``velocity_limits`` (inf where it gives none)."""
    given = desc.velocity_limits
    if isinstance(given, Mapping):
        if unknown := sorted(set(given) - set(joints)):
            raise ConfigError(f"{desc.source}: velocity_limits: {unknown} are not robot joints; joints: "
                              f"{', '.join(joints)}")
        return np.array([float(given.get(j, np.inf)) for j in joints])
    return np.full(len(joints), np.inf if given is None else float(given))


def torque_limits(
    model: mujoco.MjModel, actuators: np.ndarray, joints: np.ndarray, desc: RobotDescription
) -> np.ndarray:
    """Each joint's torque limit [N m]: the robot file's ``torque_limits`` where given, else the model's.

    The model's is the tightest of the actuator's force range, the joint's actuator-force range and a motor's
    control range.

    Raises:
        ConfigError: A joint where none of them gives a limit.
    """
    out = np.empty(len(joints))
    given = desc.torque_limits
    names = [model.joint(j).name for j in joints.tolist()]
    if isinstance(given, Mapping) and (unknown := sorted(set(given) - set(names))):
        raise ConfigError(f"{desc.source}: torque_limits: {unknown} are not robot joints; joints: {', '.join(names)}")
    for k, (a, j) in enumerate(zip(actuators.tolist(), joints.tolist(), strict=True)):
        name = model.joint(j).name
        motor = (
            int(model.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED)
            and int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_NONE)
            and bool(model.actuator_ctrllimited[a])
        )
        found = [float(np.max(np.abs(model.actuator_forcerange[a])))] if model.actuator_forcelimited[a] else []
        if model.jnt_actfrclimited[j]:
            found.append(float(np.max(np.abs(model.jnt_actfrcrange[j]))))
        if motor:
            found.append(float(np.max(np.abs(model.actuator_ctrlrange[a])) * abs(model.actuator_gear[a, 0])))
        if isinstance(given, float | int):
            out[k] = float(given)
        elif isinstance(given, Mapping) and name in given:
            out[k] = float(given[name])
        elif found:
            out[k] = min(found)
        else:
            raise ConfigError(
                f"{desc.source}: joint {name!r}: the model gives no torque limit; give "
                f"torque_limits (N m, one value or per joint) in the robot file"
            )
        if not out[k] > 0:
            raise ConfigError(f"{desc.source}: joint {name!r}: torque limit must be > 0 N m, got {out[k]}")
    return out
