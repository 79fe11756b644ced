"""``nextage-qp info [SCENE]``: joints with limits, actuators, sites, objects and collision groups of a scene."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from nextage_qp.commands.common import add_robot_arg, out_console, print_json, scene_robot

if TYPE_CHECKING:
    pass


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``info`` subcommand."""
    p = sub.add_parser("info", help="describe a scene: joints, actuators, sites, objects")
    p.add_argument("scene", nargs="?", default="scene", help="bundled scene name or MJCF path (default: scene)")
    add_robot_arg(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of tables")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the description of ``args.scene``."""
    from rich.markup import escape
    from rich.table import Table

    from nextage_qp.robots.describe import describe

    robot = scene_robot(args)
    info = describe(robot)
    if args.json:
        print_json(info)
        return 0
    console = out_console()
    table = Table(title=f"{args.scene}: joints", title_justify="left")
    for col in ("joint", "lower [rad]", "upper [rad]", "axis", "damping", "torque [N m]"):
        table.add_column(escape(col), justify="left" if col in ("joint", "axis") else "right")
    for j in info["joints"]:
        table.add_row(j["name"], f"{j['lower_rad']:.4f}", f"{j['upper_rad']:.4f}", str(j["axis"]),
                      f"{j['damping']:g}", f"{j['torque_limit_nm']:g}")
    console.print(table)
    console.print(f"timestep: {info['timestep_s'] * 1e3:g} ms   actuators: {len(info['actuators'])} "
                  f"(one motor per joint)   moving mass: {info['robot_moving_mass_kg']:.4f} kg   "
                  f"total mass: {info['robot_total_mass_kg']:.4f} kg")
    console.print(f"sites: {', '.join(info['sites'])}")
    objects = ", ".join(f"{k} ({v['mass_kg']:g} kg at {v['start_pos']})" for k, v in info["objects"].items())
    console.print(f"objects: {objects or 'none'}")
    console.print("collision groups: " + ", ".join(f"{k} ({n})" for k, n in info["collision_groups"].items()))
    return 0
