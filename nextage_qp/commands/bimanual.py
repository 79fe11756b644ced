"""``nextage-qp bimanual``: both end-effectors move together, the second held to the first by a relative task."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from nextage_qp.commands.common import (
    COORD,
    PLOT_SUFFIXES,
    add_scene_arg,
    help_text,
    number,
    output_file,
    print_outcome,
    scene_robot,
    sim_gains,
)

if TYPE_CHECKING:
    pass

HELD_M = 0.002
"""Relative error [m] within which the coupling counts as held (exit 0; otherwise exit 1)."""


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    from nextage_qp.experiments.bimanual import run_bimanual

    robot = scene_robot(args)
    gains = sim_gains(args, robot)
    frames = None
    if args.frames is not None:
        frames = (args.frames[0], args.frames[1])
    res, sim = run_bimanual(robot, np.asarray(args.move, dtype=float), gains=gains, frames=frames, speed=args.speed)
    if args.log:
        sim.recorder.save(args.log)
    if args.plot:
        from nextage_qp.viz.plots import plot_bimanual

        plot_bimanual(sim.recorder.arrays(), res.frames, args.plot,
                      title=f"{robot.name}: {res.frames[0]} moved by {tuple(args.move)} m, {res.frames[1]} coupled")
    out = {"robot": robot.name, **res._asdict(), "held": res.max_relative_error_m <= HELD_M}
    print_outcome(out, args.json)
    if not out["held"]:
        print(f"nextage-qp bimanual: error: {res.frames[1]} strayed {res.max_relative_error_m * 1e3:.2f} mm from its "
              f"pose relative to {res.frames[0]} (held means within {HELD_M * 1e3:g} mm)", file=sys.stderr)
        return 1
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``bimanual`` subcommand."""
    p = subparsers.add_parser(
        "bimanual",
        help="move both end-effectors together, coupled by a relative-frame task",
        description=help_text(__doc__),
    )
    p.add_argument("--move", type=COORD, nargs=3, default=[0.05, 0.0, 0.05], metavar=("DX", "DY", "DZ"),
                   help="displacement of the first frame [m], world (default 0.05 0 0.05)")
    p.add_argument("--frames", nargs=2, metavar=("LEAD", "FOLLOW"),
                   help="the two frames (default: the first two arms' wrist frames)")
    p.add_argument("--speed", type=number(0, 1, lo_open=True), default=0.05, help="speed [m/s], in (0, 1]")
    p.add_argument("--gains", default=None, help="gains YAML path or a name in the robot's gains folder "
                   "(default: the robot file's gains)")
    p.add_argument("--plot", metavar="PNG", type=output_file(*PLOT_SUFFIXES), help="write the relative error plot")
    p.add_argument("--log", metavar="NPZ", type=output_file(".npz"), help="write the recorded run (.npz + .json)")
    p.add_argument("--json", action="store_true", help="print the outcome as JSON")
    add_scene_arg(p)
    p.set_defaults(func=_run)
