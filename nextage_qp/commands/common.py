"""Argument helpers shared by the subcommands."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.robot import Robot


def parse_joint_assignments(robot: Robot, items: list[str], base: np.ndarray) -> np.ndarray:
    """Apply ``NAME=RAD`` strings to a copy of ``base``.

    Raises:
        ConfigError: An item is not of the form NAME=RAD.
        UnknownJointError: NAME is not a robot joint.
    """
    values: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            values[name] = float(value)
        except ValueError:
            raise ConfigError(f"--q {item!r}: expected NAME=RAD, e.g. LARM_JOINT1=-0.4") from None
    return robot.q_from_names(values, base=base)


def add_scene_arg(parser: argparse.ArgumentParser, default: str = "scene") -> None:
    """Add ``--scene`` (bundled scene name or MJCF path)."""
    parser.add_argument("--scene", default=default, help=f"bundled scene name or MJCF path (default: {default})")


def print_json(obj: Any) -> None:
    """Print one JSON object, converting numpy values."""
    print(json.dumps(obj, indent=2, default=_to_builtin))


def _to_builtin(x: Any) -> Any:
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")
