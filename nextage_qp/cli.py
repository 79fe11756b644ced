"""The ``nextage-qp`` command line.

Each subcommand lives in :mod:`nextage_qp.commands` as a module with ``register(subparsers)``, which adds
its parser and sets ``func`` (a callable taking the parsed args and returning an exit code). Errors of the
:class:`~nextage_qp.errors.NextageQPError` family print one line and exit with code 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from nextage_qp.errors import NextageQPError

COMMANDS = ("info", "fk", "ik", "step_response", "reach", "run", "sweep")
"""Modules of :mod:`nextage_qp.commands`, in the order ``--help`` lists them."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every available subcommand registered."""
    parser = argparse.ArgumentParser(prog="nextage-qp", description=__doc__.splitlines()[0] if __doc__ else None)
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


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``nextage-qp``; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except NextageQPError as exc:
        message = " ".join(str(exc).split())  # always one line
        print(f"nextage-qp {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"nextage-qp {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
