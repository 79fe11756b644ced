"""The joint angles of a config, checked against the robot's joints and their ranges before anything moves.

The angles are ``start``, ``ik.posture_target`` and a ``joints`` phase's ``positions``. An angle outside its
joint's range cannot be reached: as a start the IK's first step is infeasible, as a phase's goal the phase waits
for its timeout. Both are bad input (exit 2), not a task that failed.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any

from nextage_qp.errors import ConfigError
from nextage_qp.robots.model import Robot

SLACK = 1e-9
"""An angle this far past a limit [rad] still counts as in range (a keyframe written at the limit)."""


def angles_in(cfg: Any) -> Iterator[tuple[str, Mapping[str, float]]]:
    """Every (dotted key, joint -> angle) mapping of the config."""
    if isinstance(cfg.start, Mapping):
        yield "start", cfg.start
    if isinstance(cfg.ik.posture_target, Mapping):
        yield "ik.posture_target", cfg.ik.posture_target
    for i, phase in enumerate(cfg.phases):
        positions = getattr(phase, "positions", None)
        if phase.kind == "joints" and isinstance(positions, Mapping):
            yield f"phases[{i}].positions", positions


def check_angles(cfg: Any, robot: Robot, source: str) -> None:
    """Refuse a joint the robot does not have, or an angle outside its joint's range.

    Raises:
        ConfigError: ``source: key.JOINT: value is outside the joint's range [lo, hi] rad``, or the unknown joint
            with the valid ones.
    """
    for key, angles in angles_in(cfg):
        for name, value in angles.items():
            if name not in robot.joint_names:
                raise ConfigError(f"{source}: {key}: unknown joint {name!r}; valid: {', '.join(robot.joint_names)}")
            j = robot.joint_index(name)
            lo, hi = float(robot.lower[j]), float(robot.upper[j])
            if not (math.isfinite(value) and lo - SLACK <= value <= hi + SLACK):
                raise ConfigError(f"{source}: {key}.{name}: {value:g} is outside the joint's range "
                                  f"[{lo:.4g}, {hi:.4g}] rad; give an angle in it")
