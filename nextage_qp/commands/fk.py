"""``nextage-qp fk FRAME``: world pose of a body or site for given joint angles."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from nextage_qp.commands.common import add_scene_arg, parse_joint_assignments, print_json, scene_robot

if TYPE_CHECKING:
    pass


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``fk`` subcommand."""
    p = sub.add_parser("fk", help="forward kinematics of a body or site")
    p.add_argument("frame", help="body or site name of the scene (nextage-qp info lists the sites)")
    p.add_argument("--q", nargs="+", action="extend", default=[], metavar="NAME=RAD",
                   help="joint angles on top of the keyframe (repeatable)")
    p.add_argument("--keyframe", default="zero", help="base configuration: home or zero (default: zero)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    add_scene_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the pose of ``args.frame``."""
    import numpy as np

    from nextage_qp.kinematics.frames import Kinematics

    robot = scene_robot(args)
    robot.frame(args.frame)  # unknown frames fail before any other work
    q = parse_joint_assignments(robot, args.q, robot.keyframe_q(args.keyframe))
    pose = Kinematics(robot).fk(args.frame, q)
    out = {
        "frame": args.frame,
        "q": robot.q_to_names(q),
        "position_m": pose.pos,
        "rotation_matrix": pose.rot,
        "quaternion_wxyz": pose.quat,
    }
    if args.json:
        print_json(out)
        return 0
    with np.printoptions(precision=6, suppress=True):
        print(f"{args.frame}  (keyframe {args.keyframe}{', ' + ' '.join(args.q) if args.q else ''})")
        print(f"position [m]     {pose.pos}")
        print(f"quaternion wxyz  {pose.quat}")
        print("rotation matrix")
        print(pose.rot)
    return 0
