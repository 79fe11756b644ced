"""Argument helpers shared by the subcommands."""

from __future__ import annotations

import argparse
import errno
import math
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nextage_qp.errors import ConfigError
from nextage_qp.io.outputs import folder_problem, name_limit

if TYPE_CHECKING:
    import numpy as np

    from nextage_qp.robots.model import Robot


def help_text(doc: str | None) -> str | None:
    """The first line of a docstring as plain text for ``--help`` (reStructuredText roles and literals removed)."""
    if not doc:
        return None
    line = doc.strip().splitlines()[0]
    return re.sub(r"(?::\w+:)?`+([^`]+)`+", r"\1", line)


PLAIN_PROGRESS_S = 10.0
"""Seconds between plain progress lines on stderr when it is not a terminal (a shorter run prints none)."""

PLOT_SUFFIXES = (".png", ".pdf", ".svg")
"""File types the plots can be written as (matplotlib picks the format from the suffix)."""


def parse_joint_assignments(robot: Robot, items: list[str], base: np.ndarray) -> np.ndarray:
    """Apply ``NAME=RAD`` strings to a copy of ``base``.

    Raises:
        ConfigError: An item is not of the form NAME=RAD.
        UnknownJointError: NAME is not a robot joint.
    """
    values: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if name in values:
            raise ConfigError(f"--q {item!r}: {name} is given twice; give each joint once")
        try:
            if not sep:
                raise ValueError
            values[name] = float(value)
        except ValueError:
            raise ConfigError(f"--q {item!r}: expected NAME=RAD, NAME a robot joint (nextage-qp info)") from None
        j = robot.joint_index(name)
        lo, hi = float(robot.lower[j]), float(robot.upper[j])
        if not lo <= values[name] <= hi:  # also refuses NaN
            raise ConfigError(f"--q {item!r}: {name} must be a finite angle in its range [{lo:.4g}, {hi:.4g}] rad")
    return robot.q_from_names(values, base=base)


def out_console(width: int = 200) -> Any:
    """A rich console on stdout that does not truncate when stdout is a pipe or a file (``width`` columns there)."""
    from rich.console import Console

    console = Console()
    return console if console.is_terminal else Console(width=width)


def number(lo: float, hi: float, *, lo_open: bool = False, integer: bool = False) -> Callable[[str], float]:
    """An argparse ``type``: a finite number in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``), or an integer."""
    show = (lambda v: str(int(v))) if integer else (lambda v: f"{v:g}")
    span = f"{'(' if lo_open else '['}{show(lo)}, {show(hi)}]"
    kind = "an integer" if integer else "a finite number"

    def parse(text: str) -> float:
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {kind} in {span}, got {text!r}") from None
        if not math.isfinite(value) or value < lo or value > hi or (lo_open and value == lo):
            raise argparse.ArgumentTypeError(f"expected {kind} in {span}, got {text!r}")
        return value

    parse.__name__ = "number"
    return parse


COORD = number(-10.0, 10.0)
"""A world coordinate or a direction component [m]: finite, within 10 m of the origin."""
SECONDS = number(0.01, 3600.0)
"""A simulated duration [s]: at least 10 ms (a few control ticks), at most an hour."""
SEED = number(0, 2**32 - 1, integer=True)
"""A random seed: an integer in [0, 2^32)."""


def output_file(*suffixes: str) -> Callable[[str], Path]:
    """An argparse ``type`` for an output file, checked before anything runs.

    The path must not be a directory, its nearest existing folder must take a new file (the writers make the
    missing folders), and its suffix one of ``suffixes`` (none given: the first is added, so the
    path reported is the path written).
    """

    def parse(text: str) -> Path:
        try:
            return checked(text)
        except OSError as exc:  # a name over the file system's limit, say
            limit = f" ({name_limit(text)})" if exc.errno == errno.ENAMETOOLONG else ""
            raise argparse.ArgumentTypeError(f"{text[:80]!r}: {exc.strerror or exc}{limit}") from None

    def checked(text: str) -> Path:
        path = Path(text)
        want = " or ".join(suffixes)
        if not text.strip() or text.endswith(("/", os.sep)) or path.is_dir():
            raise argparse.ArgumentTypeError(f"{text!r} is a directory; give a file name ending in {want}")
        if path.suffix.lower() not in suffixes:
            if path.suffix:
                raise argparse.ArgumentTypeError(f"{text!r}: expected a file ending in {want}")
            path = path.with_name(path.name + suffixes[0])
        problem = folder_problem(path.parent)
        if problem is not None:
            raise argparse.ArgumentTypeError(f"{text!r}: {problem}")
        return path

    parse.__name__ = "output file"
    return parse


def add_scene_arg(parser: argparse.ArgumentParser, default: str = "scene") -> None:
    """Add ``--scene`` (bundled scene name or MJCF path) and ``--robot`` (robot file or bundled name)."""
    parser.add_argument("--scene", default=default, help=f"bundled scene name or MJCF path (default: {default})")
    add_robot_arg(parser)


def add_robot_arg(parser: argparse.ArgumentParser) -> None:
    """Add ``--robot`` (a robot file or a bundled robot name)."""
    parser.add_argument(
        "--robot", default=None, metavar="FILE|NAME", help="robot file (.yaml) or bundled robot name (default: nextage)"
    )


def scene_robot(args: argparse.Namespace) -> Robot:
    """The robot of ``--robot`` in the scene of ``--scene`` (or a positional ``scene``)."""
    from nextage_qp.robots.model import Robot

    return Robot.from_scene(args.scene, robot=args.robot)


def sim_gains(args: argparse.Namespace, robot: Robot) -> Any:
    """The gains of ``--gains`` for the robot (none: the robot file's own)."""
    from nextage_qp.robots.gains import load_gains, robot_gains

    return robot_gains(robot) if args.gains is None else load_gains(args.gains, robot)


def add_sim_args(parser: argparse.ArgumentParser, plot_help: str) -> None:
    """Add the options shared by the simulated commands: gains, duration, plot, log, JSON and scene."""
    parser.add_argument(
        "--gains",
        default=None,
        help="gains YAML path or a name in the robot's gains folder (Nextage: default, report, "
        "stiff_wrist, tuned); default: the robot file's gains",
    )
    parser.add_argument("--duration", type=SECONDS, default=3.0, help="simulated time [s] (default 3, at most 3600)")
    parser.add_argument("--plot", metavar="PNG", type=output_file(*PLOT_SUFFIXES), help=plot_help)
    parser.add_argument("--log", metavar="NPZ", type=output_file(".npz"),
                        help="write the recorded run (.npz + .json summary)")
    parser.add_argument("--json", action="store_true", help="print the outcome as JSON")
    add_scene_arg(parser)


def print_outcome(out: dict[str, Any], as_json: bool, keys: tuple[str, ...] | None = None) -> None:
    """Print an outcome as one JSON object, or as aligned ``key value`` lines (only ``keys`` if given)."""
    if as_json:
        print_json(out)
        return
    for key in keys or tuple(out):
        value = out[key]
        if value is None and key.endswith("_s"):
            value = "never"  # a time that was never reached (e.g. settling)
        print(f"{key:18s} {value:.6g}" if isinstance(value, float) else f"{key:18s} {value}")


def print_json(obj: Any) -> None:
    """Print one strict JSON object: numpy values converted, NaN and infinities written as null.

    Raises:
        ConfigError: Standard output cannot be written (a full disk; a reader that left raises BrokenPipeError).
    """
    from nextage_qp.io.json_out import dumps

    try:
        print(dumps(obj), flush=True)
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise ConfigError(f"standard output: cannot write the JSON result ({exc.strerror or exc})") from None


def add_backend_args(parser: argparse.ArgumentParser, workers_help: str) -> None:
    """Add ``--workers``, ``--backend`` and ``--ray-address`` (checked by :func:`check_backend_args`)."""
    from nextage_qp.sweep import BACKENDS

    parser.add_argument("--workers", type=int, help=workers_help)
    parser.add_argument("--backend", choices=BACKENDS, default="local", help="local process pool (default) or ray")
    parser.add_argument("--ray-address", help="Ray cluster to join (default: $RAY_ADDRESS, else a local instance)")


def check_backend_args(args: argparse.Namespace) -> None:
    """One-line errors for ``--workers`` out of range and ``--ray-address`` without ``--backend ray``."""
    if args.workers is not None and not 1 <= args.workers <= 1024:
        raise ConfigError(f"--workers must be between 1 and 1024, got {args.workers}")
    if args.ray_address and args.backend != "ray":
        raise ConfigError("--ray-address needs --backend ray")
