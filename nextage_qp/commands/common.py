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


def add_sim_args(parser: argparse.ArgumentParser, plot_help: str) -> None:
    """Add the options shared by the simulated commands: gains, duration, plot, log, JSON and scene."""
    parser.add_argument("--gains", default="default", help="gains YAML path or bundled name: default, report")
    parser.add_argument("--duration", type=float, default=3.0, help="simulated time [s] (default 3)")
    parser.add_argument("--plot", metavar="PNG", help=plot_help)
    parser.add_argument("--log", metavar="NPZ", help="write the recorded run (.npz + .json summary)")
    parser.add_argument("--json", action="store_true", help="print the outcome as JSON")
    add_scene_arg(parser)


def print_outcome(out: dict[str, Any], as_json: bool, keys: tuple[str, ...] | None = None) -> None:
    """Print an outcome as one JSON object, or as aligned ``key value`` lines (only ``keys`` if given)."""
    if as_json:
        print_json(out)
        return
    for key in keys or tuple(out):
        value = out[key]
        print(f"{key:18s} {value:.6g}" if isinstance(value, float) else f"{key:18s} {value}")


def print_json(obj: Any) -> None:
    """Print one JSON object, converting numpy values."""
    print(json.dumps(obj, indent=2, default=_to_builtin))


def _to_builtin(x: Any) -> Any:
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")
