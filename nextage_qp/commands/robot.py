"""``nextage-qp robot init MODEL`` drafts a robot file from a model; ``nextage-qp robot check FILE`` diagnoses one."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from nextage_qp.commands.common import help_text, out_console, print_json
from nextage_qp.errors import ConfigError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``robot`` subcommand and its ``init`` and ``check`` subcommands."""
    p = sub.add_parser("robot", help="draft a robot file from a model (init) or diagnose one (check)",
                       description=help_text(__doc__))
    inner = p.add_subparsers(dest="robot_command", required=True, metavar="{init,check}")
    init = inner.add_parser("init", help="write a robot file for an MJCF or URDF model",
                            description="Find the arms, a home free of self-contact, gains, torque limits and the "
                                        "mount of a model, and write a robot file to review.")
    init.add_argument("model", metavar="MODEL", help="an MJCF (.xml) or URDF (.urdf) file")
    init.add_argument("--out", metavar="FILE", type=Path,
                      help="robot file to write, .yaml, or a folder to write NAME.yaml in (default: NAME.yaml here, "
                           "NAME the model's stem, or its folder's name for robot.xml / model.xml)")
    init.add_argument("--angle", choices=("radian", "degree"),
                      help="the model's angle unit where it states none (default: radian when its ranges say so)")
    init.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    init.set_defaults(func=run_init)
    check = inner.add_parser("check", help="diagnose a robot file or a model: one line and a fix per problem",
                             description="Exit 0: no problem; 1: problems found; 2: the file cannot be loaded.")
    check.add_argument("file", metavar="ROBOT.yaml|MODEL", help="a robot file, or an MJCF / URDF model on its own")
    check.add_argument("--json", action="store_true", help="print one JSON object instead of tables")
    check.set_defaults(func=run_check)


def run_init(args: argparse.Namespace) -> int:
    """Write the draft robot file; print what was found and where it went."""
    from rich.markup import escape

    from nextage_qp.experiments.table_ready import check_at_table, make_ready
    from nextage_qp.robots.description import load_robot
    from nextage_qp.robots.draft import draft_text, write_draft
    from nextage_qp.robots.model import Robot
    from nextage_qp.robots.survey import joint_names, survey

    model = Path(args.model)
    found = survey(model.resolve() if model.is_file() else model, angle=args.angle)
    out = args.out if args.out is not None else Path(f"{found.name}.yaml")
    if out.is_dir():  # a folder: the draft goes into it, named after the robot
        out = out / f"{found.name}.yaml"
    elif out.suffix.lower() not in (".yaml", ".yml"):
        raise ConfigError(f"--out {out}: a robot file is YAML: give a path ending in .yaml (or .yml), or a folder")
    if out.exists() and not args.force:  # before the draft's slower parts
        write_draft("", out)
    text = draft_text(found, out)
    write_draft(text, out, force=args.force)
    ready = make_ready(load_robot(out))  # composed at a table: tools, push_face, workspace, a ready home
    write_draft(draft_text(found, out, ready), out, force=True)
    console = out_console()
    console.print(f"wrote {escape(str(out))} (robot {escape(found.name)!r} from {escape(str(model))})")
    for arm in found.arms.arms:
        console.print(f"  arm {escape(arm.name)}: {len(arm.joints)} joints "
                      f"({escape(', '.join(joint_names(found, arm.joints)))}), wrist {escape(arm.wrist)}")
    if found.arms.torso:
        console.print(f"  torso: {escape(', '.join(joint_names(found, found.arms.torso)))}")
    for name, joints in found.arms.groups.items():
        console.print(f"  group {escape(name)}: {escape(', '.join(joint_names(found, joints)))}")
    console.print(f"  home: {escape(found.home.how)}"
                  + (f"; excluded pairs in contact there: {len(found.home.contacts)}" if found.home.contacts else ""))
    if found.angle:
        console.print(f"  angle: {found.angle} ({escape(found.angle_why)})")
    if ready.workspace is not None:
        ws = ready.workspace
        console.print(f"  at a table: top {ws.top} m, work region centre {list(ws.centre)} +- {list(ws.size)} "
                      f"m; tools {escape(', '.join(ready.tools.values()))}; push height {ready.push_height:.4f} m")
    for note in ready.notes:
        console.print(f"  {escape(note)}")
    Robot.from_scene("scene", robot=out)  # what was written loads (a ConfigError here: exit 2)
    problems = check_at_table(out).problems
    console.print(f"it loads; robot check finds {len(problems) or 'no'} problem{'' if len(problems) == 1 else 's'}"
                  + (":" if problems else f"; review it, then: nextage-qp robot check {escape(str(out))}"))
    for f in problems:
        console.print(f"  [red]problem[/red] {escape(f.topic)}: {escape(f.message)} -> fix: {escape(f.fix)}",
                      soft_wrap=True)
    return 0


def run_check(args: argparse.Namespace) -> int:
    """Print the diagnosis; exit 1 when it found problems."""
    from rich.markup import escape

    from nextage_qp.experiments.table_ready import check_at_table

    report = check_at_table(args.file)
    if args.json:
        print_json(report.as_dict())
        return 1 if report.problems else 0
    console = out_console()
    _print_tables(console, report)
    for f in report.findings:
        mark = "[red]problem[/red]" if f.level == "problem" else "[cyan]info[/cyan]"
        fix = f" -> fix: {escape(f.fix)}" if f.fix else ""
        console.print(f"{mark} {escape(f.topic)}: {escape(f.message)}{fix}", soft_wrap=True)
    n = len(report.problems)
    console.print("no problems" if not n else f"{n} problem{'s' if n > 1 else ''}")
    return 1 if n else 0


def _print_tables(console: Any, report: Any) -> None:
    from rich.markup import escape
    from rich.table import Table

    def num(v: float | None) -> str:
        return "-" if v is None else f"{v:.4g}"

    console.print(f"{escape(report.source)}: model {escape(report.model)}", soft_wrap=True)
    table = Table(title="joints", title_justify="left")
    for col in ("joint", "group", "type", "lower", "upper", "damping", "armature", "torque [N m]"):
        table.add_column(escape(col), justify="left" if col in ("joint", "group", "type") else "right")
    for j in report.joints:
        table.add_row(escape(j["name"]), escape(j["group"]), j["type"], num(j["lower"]), num(j["upper"]),
                      f"{j['damping']:g}", f"{j['armature']:g}", num(j["torque_limit_nm"]))
    console.print(table)
    arms = Table(title="arms", title_justify="left")
    for col in ("arm", "joints", "wrist", "tool", "pad", "wrist body"):
        arms.add_column(col)
    for a in report.arms:
        arms.add_row(escape(a["name"]), escape(f"{len(a['joints'])}: {a['joints'][0]} .. {a['joints'][-1]}"),
                     escape(a["wrist"]), escape(a["tool"]), escape(a["pad"]), escape(str(a["wrist_body"])))
    console.print(arms)
    acts = Table(title="actuators", title_justify="left")
    for col in ("actuator", "joint", "gear", "ctrl range"):
        acts.add_column(col)
    for a in report.actuators:
        acts.add_row(escape(a["name"]), escape(str(a["joint"])), f"{a['gear']:g}",
                     "-" if a["ctrlrange"] is None else f"[{a['ctrlrange'][0]:g}, {a['ctrlrange'][1]:g}]")
    console.print(acts if report.actuators else "actuators: none in the model (motors are added from torque_limits)")
    console.print(f"mass: total {report.total_mass_kg:.4g} kg, moving {report.moving_mass_kg:.4g} kg")
