"""Actuation from the robot file: each joint's torque limit, from the model or from the robot file."""

from __future__ import annotations

from collections.abc import Mapping

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.robots.description import RobotDescription


def torque_limits(
    model: mujoco.MjModel, actuators: np.ndarray, joints: np.ndarray, desc: RobotDescription
) -> np.ndarray:
    """Each joint's torque limit [N m], the tightest the model gives, else the robot file's ``torque_limits``.

    The model's limits: the actuator's force range, the joint's actuator-force range, a motor's control range.

    Raises:
        ConfigError: A joint where none of them gives a limit.
    """
    out = np.empty(len(joints))
    given = desc.torque_limits
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
        if found:
            out[k] = min(found)
        elif isinstance(given, float | int):
            out[k] = float(given)
        elif isinstance(given, Mapping) and name in given:
            out[k] = float(given[name])
        else:
            raise ConfigError(
                f"{desc.source}: joint {name!r}: the model gives no torque limit; give "
                f"torque_limits (N m, one value or per joint) in the robot file"
            )
        if not out[k] > 0:
            raise ConfigError(f"{desc.source}: joint {name!r}: torque limit must be > 0 N m, got {out[k]}")
    return out
