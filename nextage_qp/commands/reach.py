"""``nextage-qp reach``: move a frame to a Cartesian target through QP IK → Ruckig → PD → MuJoCo."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from nextage_qp.commands.common import COORD, add_sim_args, help_text, number, print_outcome, scene_robot, sim_gains

if TYPE_CHECKING:
    import numpy as np


REACHED_M = 0.002
"""Final position error [m] within which ``reach`` counts the target as reached (exit 0; otherwise exit 1)."""


def _vec(values: list[float] | None) -> np.ndarray | None:
    import numpy as np

    return None if values is None else np.asarray(values, dtype=float)


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    from nextage_qp.experiments.reach import run_reach
    from nextage_qp.kinematics.frames import Kinematics
    from nextage_qp.loop.reference import TrajectoryLimits

    robot = scene_robot(args)
    gains = sim_gains(args, robot)
    limits = TrajectoryLimits(
        max_velocity=args.max_velocity, max_acceleration=args.max_acceleration, max_jerk=args.max_jerk
    )
    args.frame = args.frame or robot.arms[0].wrist
    Kinematics(robot).check_reach(args.frame, np.asarray(args.pos, dtype=float), robot.keyframe_q("home"),
                                  f"--pos for {args.frame}")
    res, sim = run_reach(
        robot,
        args.frame,
        np.asarray(args.pos, dtype=float),
        gains=gains,
        limits=limits,
        axis=_vec(args.axis),
        direction=_vec(args.direction),
        duration=args.duration,
    )
    a = sim.recorder.arrays()
    if args.log:
        sim.recorder.save(args.log)
    if args.plot:
        from nextage_qp.viz.plots import plot_reach

        dist = np.linalg.norm(a[f"frame_{args.frame}"][:, :3] - np.asarray(args.pos), axis=1)
        title = f"reach: {args.frame} → ({', '.join(f'{x:g}' for x in args.pos)}) m, QP IK → Ruckig → PD"
        plot_reach(a["t"], dist, args.plot, frame=args.frame, tau=a["tau"], title=title)
    v = limits.arrays(robot.joint_names)[0]
    out = {
        "frame": args.frame,
        "target_pos_m": list(args.pos),
        "final_error_m": res.final_error_m,
        "time_to_1mm_s": res.time_to_1mm_s,
        "max_abs_torque_nm": res.max_abs_torque_nm,
        "saturated_steps": res.saturated_steps,
        "max_ref_velocity_ratio": float(np.max(np.abs(a["qd_ref"]) / v)),
        "final_q": robot.q_to_names(sim.q),
    }
    out["reached"] = bool(res.final_error_m <= REACHED_M)
    print_outcome(out, args.json, ("frame", "final_error_m", "time_to_1mm_s", "max_abs_torque_nm", "saturated_steps"))
    if not out["reached"]:
        print(f"nextage-qp reach: error: {args.frame} ended {res.final_error_m * 1e3:.1f} mm from the target "
              f"(reached means within {REACHED_M * 1e3:g} mm): out of reach or blocked", file=sys.stderr)
        return 1
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``reach`` subcommand."""
    p = subparsers.add_parser(
        "reach",
        help="move a frame to a Cartesian target (QP IK -> Ruckig -> PD -> MuJoCo)",
        description=help_text(__doc__),
    )
    p.add_argument("--frame", default=None, help="site or body to move (default: the first arm's wrist frame)")
    p.add_argument("--pos", type=COORD, nargs=3, required=True, metavar=("X", "Y", "Z"), help="target [m], world")
    p.add_argument("--axis", type=COORD, nargs=3, metavar=("AX", "AY", "AZ"), help="tool axis in the frame")
    p.add_argument("--direction", type=COORD, nargs=3, metavar=("DX", "DY", "DZ"), help="world direction for --axis")
    p.add_argument("--max-velocity", type=number(0.01, 100), default=1.0,
                   help="reference velocity limit [rad/s], in (0, 100]")
    p.add_argument("--max-acceleration", type=number(0.01, 1e4), default=4.0,
                   help="reference acceleration limit [rad/s^2], in [0.01, 1e4]")
    p.add_argument("--max-jerk", type=number(0.01, 1e6), default=40.0,
                   help="reference jerk limit [rad/s^3], in [0.01, 1e6]")
    add_sim_args(p, "write distance-to-target plot")
    p.set_defaults(func=_run)
