"""``nextage-qp ik``: solve inverse kinematics for one or two frames and print q and the residuals."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING

from nextage_qp.commands.common import COORD, add_scene_arg, number, out_console, print_json, scene_robot
from nextage_qp.errors import ConfigError

if TYPE_CHECKING:
    import numpy as np

    from nextage_qp.ik import FrameTarget, IKConfig, IKResult
    from nextage_qp.robots.model import Robot


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``ik`` subcommand."""
    p = subparsers.add_parser("ik", help="inverse kinematics of one or two frames (QP or a baseline)")
    p.add_argument("--frame", required=True, help="body or site of the scene, e.g. an arm's wrist frame")
    p.add_argument("--pos", nargs=3, type=COORD, required=True, metavar=("X", "Y", "Z"), help="target position [m]")
    p.add_argument("--axis", nargs=3, type=COORD, metavar=("AX", "AY", "AZ"), help="tool axis (frame coords) to aim")
    p.add_argument("--dir", nargs=3, type=COORD, default=None, metavar=("DX", "DY", "DZ"),
                   help="world direction for --axis (default 0 0 1)")  # fmt: skip
    p.add_argument("--quat", nargs=4, type=number(-1e3, 1e3), metavar=("W", "X", "Y", "Z"), help="target orientation")
    p.add_argument("--frame2", help="second frame, solved in the same QP")
    p.add_argument("--pos2", nargs=3, type=COORD, metavar=("X", "Y", "Z"))
    p.add_argument("--axis2", nargs=3, type=COORD, metavar=("AX", "AY", "AZ"))
    p.add_argument("--dir2", nargs=3, type=COORD, default=None, metavar=("DX", "DY", "DZ"))
    p.add_argument("--quat2", nargs=4, type=number(-1e3, 1e3), metavar=("W", "X", "Y", "Z"))
    p.add_argument("--from", dest="start", default="home", help="start keyframe: home or zero (default home)")
    p.add_argument("--method", choices=("qp", "pinv", "dls", "lm"), default="qp", help="IK method (default qp)")
    p.add_argument("--solver", default="daqp", help="QP backend for --method qp (default daqp)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    add_scene_arg(p)
    p.set_defaults(func=run)


def _target(frame: str, pos: list[float], axis: list[float] | None, direction: list[float] | None,
            quat: list[float] | None, flag: str) -> FrameTarget:  # fmt: skip
    import numpy as np

    from nextage_qp.ik import FrameTarget

    if axis is not None and quat is not None:
        raise ConfigError(f"--axis{flag} and --quat{flag} exclude each other")
    if direction is not None and axis is None:
        raise ConfigError(f"--dir{flag} needs --axis{flag}")
    rot = None
    if quat is not None:
        norm = float(np.linalg.norm(quat))
        if norm < 1e-6:
            raise ConfigError(f"--quat{flag} {' '.join(f'{v:g}' for v in quat)}: not a rotation (zero length); "
                              "give a unit quaternion W X Y Z, e.g. 1 0 0 0")
        w, x, y, z = np.asarray(quat) / norm
        rot = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ])  # fmt: skip
    return FrameTarget(
        frame, pos=np.asarray(pos), rot=rot,
        axis=None if axis is None else np.asarray(axis),
        direction=None if axis is None else np.asarray(direction if direction is not None else (0.0, 0.0, 1.0)),
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Solve and print; returns 0 when converged, 1 otherwise."""
    from nextage_qp.ik import QPIK
    from nextage_qp.ik.baselines import dls_ik, lm_ik, pinv_ik
    from nextage_qp.kinematics.frames import Kinematics

    robot = scene_robot(args)
    targets = [_target(args.frame, args.pos, args.axis, args.dir, args.quat, "")]
    if args.frame2 is not None:
        if args.pos2 is None:
            raise ConfigError("--frame2 needs --pos2 X Y Z")
        if args.frame2 == args.frame:
            raise ConfigError(f"--frame2 {args.frame2!r} is --frame itself; give two different frames (one frame "
                              "has one pose)")
        targets.append(_target(args.frame2, args.pos2, args.axis2, args.dir2, args.quat2, "2"))
    elif args.pos2 is not None:
        raise ConfigError("--pos2 needs --frame2 FRAME")
    if args.start not in ("home", "zero"):
        raise ConfigError(f"--from {args.start!r}: expected home or zero")
    q0 = robot.keyframe_q(args.start)
    kin = Kinematics(robot)
    for t in targets:
        if t.pos is not None:
            kin.check_reach(t.frame, t.pos, q0, f"--pos{'2' if t is not targets[0] else ''} for {t.frame}")
    result: IKResult
    if args.method == "qp":
        result = QPIK(robot, _config(args.solver)).solve(targets, q0)
    else:
        for t in targets:
            robot.frame(t.frame)
        baselines: dict[str, Callable[[Robot, list[FrameTarget], np.ndarray], IKResult]] = {
            "pinv": pinv_ik, "dls": dls_ik, "lm": lm_ik,
        }  # fmt: skip
        result = baselines[args.method](robot, targets, q0)
    if args.json:
        print_json({
            "q": robot.q_to_names(result.q), "converged": result.converged, "pos_err_m": result.pos_err_m,
            "rot_err_rad": result.rot_err_rad, "iters": result.iters, "status": result.status,
            "time_s": result.time_s, "method": args.method,
        })  # fmt: skip
    else:
        _print_table(robot, result, args.method)
    return 0 if result.converged else 1


def _config(solver: str) -> IKConfig:
    from nextage_qp.ik import IKConfig

    try:
        return IKConfig(solver=solver)
    except ValueError as exc:  # pydantic's ValidationError
        raise ConfigError(f"--solver: {exc.errors()[0]['msg'] if hasattr(exc, 'errors') else exc}") from None


def _print_table(robot: Robot, result: IKResult, method: str) -> None:
    import numpy as np
    from rich.table import Table

    table = Table(title=f"IK ({method}): {result.status}")
    table.add_column("joint")
    table.add_column("rad", justify="right")
    table.add_column("deg", justify="right")
    for name, value in zip(robot.joint_names, result.q, strict=True):
        table.add_row(name, f"{value:+.4f}", f"{np.degrees(value):+.1f}")
    console = out_console()
    console.print(table)
    console.print(f"position error {result.pos_err_m * 1e3:.3f} mm, orientation error "
                  f"{np.degrees(result.rot_err_rad):.3f} deg, converged: {result.converged}, "
                  f"{result.iters} iterations, {result.time_s * 1e3:.1f} ms")  # fmt: skip
