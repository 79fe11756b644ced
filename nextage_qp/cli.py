"""The ``nextage-qp`` command line.

Each subcommand lives in :mod:`nextage_qp.commands` as a module with ``register(subparsers)``, which adds
its parser and sets ``func`` (a callable taking the parsed args and returning an exit code). Errors of the
:class:`~nextage_qp.errors.NextageQPError` family print one line and exit with code 2.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import sys
import warnings
from collections.abc import Sequence
from importlib import metadata
from typing import NoReturn

from nextage_qp.errors import NextageQPError, one_line
from nextage_qp.io.outputs import name_limit

DESCRIPTION = ("Task-space control of dual-arm robots in MuJoCo: QP differential IK, jerk-limited "
               "references, PD torque control; YAML-configured manipulation tasks and randomised sweeps.")
"""What ``nextage-qp --help`` says first."""

COMMANDS = ("info", "fk", "ik", "step_response", "reach", "bimanual", "run", "sweep", "tune", "robot")
"""Modules of :mod:`nextage_qp.commands`, in the order ``--help`` lists them."""


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit 2), pointing at ``--help``."""

    def error(self, message: str) -> NoReturn:  # noqa: D102
        self.exit(2, f"{self.prog}: error: {one_line(message)}; see '{self.prog} --help'\n")


def version() -> str:
    """The installed package's version."""
    try:
        return metadata.version("nextage_qp")
    except metadata.PackageNotFoundError:
        return "unknown"


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every available subcommand registered."""
    parser = OneLineParser(prog="nextage-qp", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"nextage-qp {version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"nextage_qp.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"nextage_qp.commands.{name}":
                continue
            raise
        module.register(sub)
    return parser


QUIET_WARNINGS = (
    r"Converted matrix .* to scipy\.sparse",  # qpsolvers, when the QP goes to OSQP: a cost, not a fault
    r"The default value of raise_error will change",  # osqp's notice of its own future default
    r"Tight layout not applied",  # matplotlib, for figures whose legends do not fit tightly
    r"\(655\d\d\) b'",  # GLFW without a display: the camera's own one-line error says what to install and set
)
"""Library warnings the command line keeps off stderr (an error there is one line; these are not errors)."""


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``nextage-qp``; returns the process exit code."""
    for message in QUIET_WARNINGS:
        warnings.filterwarnings("ignore", message=message)
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a usage error already printed as one line
        return exc.code if isinstance(exc.code, int) else 2
    try:
        from nextage_qp.native.loading import require_mujoco

        require_mujoco()
        from nextage_qp.native.mj_warnings import capture_mujoco_warnings

        capture_mujoco_warnings()  # a diverging simulation fails with one line quoting MuJoCo, not with its own print
        code = int(args.func(args))
        sys.stdout.flush()  # inside the try: a reader that left (``| head``) is caught below
        return code
    except NextageQPError as exc:
        message = one_line(exc)  # always one line
        print(f"nextage-qp {args.command}: error: {message}", file=sys.stderr)
        return 2
    except OSError as exc:
        if exc.errno != errno.ENAMETOOLONG:
            raise
        print(f"nextage-qp {args.command}: error: file name too long: {str(exc.filename)[:80]}... "
              f"({name_limit(exc.filename)})", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"nextage-qp {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. ``nextage-qp fk | head``: the reader left, nothing more to say
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so the flush at exit does not raise again
        return 141


if __name__ == "__main__":
    sys.exit(main())
