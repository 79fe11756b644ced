"""``nextage-qp step-response``: one joint steps to an absolute target, every other joint holds home."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from nextage_qp.commands.common import add_sim_args, help_text, number, print_outcome, scene_robot, sim_gains

if TYPE_CHECKING:
    pass


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    from nextage_qp.experiments.step_response import blocking_contacts, run_step

    robot = scene_robot(args)
    gains = sim_gains(args, robot)
    target = float(np.deg2rad(args.target_deg))
    metrics, sim = run_step(robot, args.joint, target, gains, duration=args.duration, shaped=args.shaped)
    if args.log:
        sim.recorder.meta |= {"joint": args.joint, "target_rad": target, "gains": gains.source, **metrics._asdict()}
        sim.recorder.save(args.log)
    if args.plot:
        from nextage_qp.viz.plots import plot_step_response

        j = robot.joint_index(args.joint)
        mode = "Ruckig-shaped" if args.shaped else "raw step"
        title = f"{args.joint}: {mode} to {args.target_deg:g}° ({gains.source})"
        plot_step_response(sim.recorder.arrays(), j, args.joint, target, args.plot, title=title)
    out = {"joint": args.joint, "target_rad": target, "gains": gains.source, "shaped": args.shaped, **metrics._asdict()}
    # A step that did not settle because the moving links press on something says so (not a gains problem).
    contacts = blocking_contacts(robot, sim, args.joint) if metrics.settling_time_s is None else []
    out["blocked_by_contact"] = "; ".join(contacts) if contacts else None
    print_outcome(out, args.json)
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``step-response`` subcommand."""
    p = subparsers.add_parser(
        "step-response",
        help="step one joint from home to an absolute target under PD control",
        description=help_text(__doc__),
    )
    p.add_argument("--joint", required=True, help="robot joint name (nextage-qp info --robot R lists them)")
    p.add_argument("--target-deg", type=number(-360, 360), required=True, help="absolute target angle [deg]")
    p.add_argument("--shaped", action="store_true", help="follow a Ruckig trajectory instead of a raw step")
    add_sim_args(p, "write position/velocity/torque plot")
    p.set_defaults(func=_run)
