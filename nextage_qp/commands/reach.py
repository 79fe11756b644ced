"""``nextage-qp reach``: move a frame to a Cartesian target through QP IK → Ruckig → PD → MuJoCo."""

from __future__ import annotations

import argparse
from typing import NamedTuple

import numpy as np

from nextage_qp.commands.common import add_sim_args, print_outcome
from nextage_qp.control import Gains, load_gains
from nextage_qp.errors import ConfigError
from nextage_qp.ik import QPIK, FrameTarget, IKConfig
from nextage_qp.robot import Robot
from nextage_qp.sim import Simulation
from nextage_qp.trajectory import TrajectoryLimits


class ReachResult(NamedTuple):
    """Outcome of a reach.

    Attributes:
        final_error_m: ‖p_frame − p_target‖ at the end [m].
        time_to_1mm_s: First time after which the distance stays below 1 mm [s] (None if never).
        max_abs_torque_nm: Peak |torque| over all joints [N·m].
        saturated_steps: Physics steps with at least one torque clamped to its actuator range.
        ik_converged_q: The commanded joint vector at the end [rad].
    """

    final_error_m: float
    time_to_1mm_s: float | None
    max_abs_torque_nm: float
    saturated_steps: int
    ik_converged_q: np.ndarray


def run_reach(
    robot: Robot,
    frame: str,
    pos: np.ndarray,
    *,
    gains: Gains,
    limits: TrajectoryLimits | None = None,
    axis: np.ndarray | None = None,
    direction: np.ndarray | None = None,
    duration: float = 3.0,
    ctrl_dt: float = 0.004,
) -> tuple[ReachResult, Simulation]:
    r"""Reach ``pos`` [m] with ``frame`` from the home pose, streaming IK through Ruckig to the PD loop.

    Every control tick the QP IK gives a joint velocity :math:`v` [rad/s] at the commanded configuration
    and the command integrates it, :math:`q_{cmd} \leftarrow q_{cmd} + v\,\Delta t_{ctrl}`; Ruckig turns
    :math:`q_{cmd}` into a jerk-limited reference that the PD law tracks at every physics step.

    Raises:
        UnknownFrameError: ``frame`` is not a site or body.
        ConfigError: Bad duration, or only one of ``axis`` / ``direction`` given.
    """
    if not duration > 0:
        raise ConfigError(f"--duration must be > 0 s, got {duration}")
    if (axis is None) != (direction is None):
        raise ConfigError("--axis and --direction go together: the frame's axis is turned along the direction")
    robot.frame(frame)
    sim = Simulation(robot, gains, limits, ctrl_dt=ctrl_dt, frames=(frame,))
    ik = QPIK(robot, IKConfig())
    q_cmd = robot.keyframe_q("home")
    sim.reset(q_cmd)
    target = FrameTarget(frame=frame, pos=np.asarray(pos, dtype=float), axis=axis, direction=direction)
    while sim.time < duration - 1e-9:
        v = ik.step(q_cmd, [target], ctrl_dt)
        q_cmd = np.clip(q_cmd + v * ctrl_dt, robot.lower, robot.upper)
        sim.set_target(q_cmd)
        sim.tick()
    a = sim.recorder.arrays()
    dist = np.linalg.norm(a[f"frame_{frame}"][:, :3] - target.pos, axis=1)
    outside = np.flatnonzero(dist >= 1e-3)
    if not outside.size:
        t1: float | None = 0.0
    elif outside[-1] == len(dist) - 1:
        t1 = None
    else:
        t1 = float(a["t"][outside[-1] + 1])
    result = ReachResult(
        final_error_m=float(dist[-1]),
        time_to_1mm_s=t1,
        max_abs_torque_nm=float(np.abs(a["tau"]).max()),
        saturated_steps=int(sim.pd.any_saturated_ticks),
        ik_converged_q=q_cmd,
    )
    sim.recorder.meta |= {"frame": frame, "target_pos_m": list(map(float, pos)), "final_error_m": result.final_error_m}
    return result, sim


def _vec(values: list[float] | None) -> np.ndarray | None:
    return None if values is None else np.asarray(values, dtype=float)


def _run(args: argparse.Namespace) -> int:
    robot = Robot.from_scene(args.scene)
    gains = load_gains(args.gains)
    limits = TrajectoryLimits(
        max_velocity=args.max_velocity, max_acceleration=args.max_acceleration, max_jerk=args.max_jerk
    )
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
        from nextage_qp.plots import plot_reach

        dist = np.linalg.norm(a[f"frame_{args.frame}"][:, :3] - np.asarray(args.pos), axis=1)
        title = f"reach: {args.frame} → ({', '.join(f'{x:g}' for x in args.pos)}) m, QP IK → Ruckig → PD"
        plot_reach(a["t"], dist, args.plot, frame=args.frame, tau=a["tau"], title=title)
    v = limits.arrays()[0]
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
    print_outcome(out, args.json, ("frame", "final_error_m", "time_to_1mm_s", "max_abs_torque_nm", "saturated_steps"))
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``reach`` subcommand."""
    p = subparsers.add_parser(
        "reach",
        help="move a frame to a Cartesian target (QP IK -> Ruckig -> PD -> MuJoCo)",
        description=__doc__.splitlines()[0] if __doc__ else None,
    )
    p.add_argument("--frame", default="left_wrist", help="site or body to move (default: left_wrist)")
    p.add_argument("--pos", type=float, nargs=3, required=True, metavar=("X", "Y", "Z"), help="target [m], world")
    p.add_argument("--axis", type=float, nargs=3, metavar=("AX", "AY", "AZ"), help="tool axis in the frame")
    p.add_argument("--direction", type=float, nargs=3, metavar=("DX", "DY", "DZ"), help="world direction for --axis")
    p.add_argument("--max-velocity", type=float, default=1.0, help="reference velocity limit [rad/s]")
    p.add_argument("--max-acceleration", type=float, default=4.0, help="reference acceleration limit [rad/s^2]")
    p.add_argument("--max-jerk", type=float, default=40.0, help="reference jerk limit [rad/s^3]")
    add_sim_args(p, "write distance-to-target plot")
    p.set_defaults(func=_run)
