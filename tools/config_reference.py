"""The config reference, generated from the schemas: every key of every file the framework reads.

Usage: python tools/config_reference.py [--check]

Writes ``docs/configs.md``: per file kind (task config, each phase kind, robot file, gains file, sweep file, study
file) a table of every key with its type, unit, default, bounds and meaning, all read from the pydantic schemas
(``Field(description=...)``; the unit is the description's bracket, e.g. ``[m]``). ``--check`` exits 1 when the file
differs from what the schemas give (the test suite runs the same check), or when a key lacks a meaning, or a number
lacks its unit.
"""

from __future__ import annotations

import argparse
import re
import sys
import types
import typing
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import annotated_types
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "configs.md"

UNIT = re.compile(r"\[([^\]]+)\]")


@dataclass(frozen=True)
class Row:
    """One key of a schema."""

    key: str
    type: str
    unit: str
    default: str
    bounds: str
    meaning: str
    numeric: bool


def _args(tp: Any) -> tuple[Any, ...]:
    return typing.get_args(tp)


def _strip(tp: Any) -> Any:
    """The type without ``Annotated`` and ``None`` in a union."""
    while typing.get_origin(tp) is typing.Annotated:
        tp = _args(tp)[0]
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        rest = [a for a in _args(tp) if a is not type(None)]
        if len(rest) == 1:
            return _strip(rest[0])
    return tp


def type_name(tp: Any) -> str:
    """A short readable name of a field's type."""
    tp = _strip(tp)
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        return " \\| ".join(f"`{a}`" for a in _args(tp))
    if origin in (typing.Union, types.UnionType):
        return " or ".join(type_name(a) for a in _args(tp) if a is not type(None))
    if origin in (list, tuple, set, frozenset):
        inner = [a for a in _args(tp) if a is not Ellipsis]
        names = sorted({type_name(a) for a in inner})
        return f"list of {' or '.join(names)}" if names else "list"
    if origin is dict:
        return f"map of {type_name(_args(tp)[1])}"
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return "mapping"
    return getattr(tp, "__name__", str(tp))


def numeric(tp: Any) -> bool:
    """Whether a field holds numbers (so its description must give a unit)."""
    tp = _strip(tp)
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        return False
    if origin in (typing.Union, types.UnionType, list, tuple, set, frozenset):
        return any(numeric(a) for a in _args(tp) if a is not Ellipsis)
    if origin is dict:
        return numeric(_args(tp)[1])
    return tp in (int, float) or (isinstance(tp, type) and issubclass(tp, (int, float)) and tp is not bool)


def bounds(info: FieldInfo, tp: Any) -> str:
    """The field's numeric bounds and length limits, e.g. ``> 0, ≤ 20``."""
    found = []
    metadata = list(info.metadata)
    while typing.get_origin(tp) is typing.Annotated:
        metadata += [m for m in _args(tp)[1:] if not isinstance(m, FieldInfo)]
        metadata += [x for m in _args(tp)[1:] if isinstance(m, FieldInfo) for x in m.metadata]
        tp = _args(tp)[0]
    for m in metadata:
        for attr, sign in (("gt", ">"), ("ge", "≥"), ("lt", "<"), ("le", "≤")):
            value = getattr(m, attr, None)
            if value is not None and isinstance(m, (annotated_types.Gt, annotated_types.Ge, annotated_types.Lt,
                                                    annotated_types.Le, annotated_types.Interval)):
                found.append(f"{sign} {value:g}" if isinstance(value, (int, float)) else f"{sign} {value}")
        if isinstance(m, annotated_types.MinLen) and m.min_length:
            found.append(f"at least {m.min_length} items")
        if isinstance(m, annotated_types.MaxLen) and m.max_length is not None:
            found.append(f"at most {m.max_length} items")
    return ", ".join(dict.fromkeys(found))


def default(info: FieldInfo) -> str:
    """The field's default as YAML would write it (``required`` where there is none)."""
    if info.is_required():
        return "required"
    value = info.default_factory() if info.default_factory is not None else info.default  # type: ignore[call-arg]
    if value is PydanticUndefined:
        return "required"
    if isinstance(value, BaseModel):
        return "see below"
    if value is None:
        return "unset"
    if isinstance(value, bool):
        return "`true`" if value else "`false`"
    if isinstance(value, (dict, list, tuple)) and not value:
        return "`[]`" if not isinstance(value, dict) else "`{}`"
    if isinstance(value, float):
        return f"`{value:g}`"
    if isinstance(value, tuple):
        value = list(value)
    return f"`{value}`".replace("'", "")


def models_in(tp: Any) -> list[tuple[str, type[BaseModel]]]:
    """The schemas nested in a field's type, with the key suffix that reaches them (``[]`` for a list item)."""
    tp = _strip(tp)
    origin = typing.get_origin(tp)
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return [("", tp)]
    if origin in (list, tuple):
        return [("[]" + s, m) for a in _args(tp) if a is not Ellipsis for s, m in models_in(a)]
    if origin is dict:
        return [(".NAME" + s, m) for s, m in models_in(_args(tp)[1])]
    if origin in (typing.Union, types.UnionType):
        return [x for a in _args(tp) for x in models_in(a)]
    return []


def rows(model: type[BaseModel], prefix: str = "", skip: tuple[str, ...] = ()) -> Iterator[Row]:
    """Every key of ``model``, nested schemas expanded after their key."""
    for name, info in model.model_fields.items():
        if name in skip:
            continue
        key = f"{prefix}{info.alias or name}"
        tp = info.annotation
        text = " ".join((info.description or "").split())
        unit = ", ".join(UNIT.findall(text)[:1])
        yield Row(key, type_name(tp), unit or "–", default(info), bounds(info, tp), text, numeric(tp))
        for suffix, nested in models_in(tp):
            yield from rows(nested, f"{key}{suffix}.")


def table(entries: list[Row]) -> str:
    """A markdown table of ``entries``."""
    out = ["| key | type | unit | default | bounds | meaning |", "|---|---|---|---|---|---|"]
    for r in entries:
        meaning = r.meaning.replace("|", "\\|")
        out.append(f"| `{r.key}` | {r.type} | {r.unit} | {r.default} | {r.bounds or '–'} | {meaning} |")
    return "\n".join(out)


def sections() -> list[tuple[str, str, list[Row]]]:
    """(heading, introduction, rows) per file kind and phase kind."""
    from nextage_qp.manipulation.config import config_model
    from nextage_qp.manipulation.phases import REGISTRY
    from nextage_qp.robots.gains import GainsFile
    from nextage_qp.robots.robot_file import RobotFile
    from nextage_qp.sweep.spec import SweepFile
    from nextage_qp.tune.spec import StudyFile

    out = [("Task config", "A task: the scene, the robot, the criteria, the controller's settings and the phases "
            "(`configs/*.yaml`; `nextage-qp run CONFIG`).", list(rows(config_model(), skip=("phases",))))]
    out.append(("Phases", "`phases` is an ordered list; each item's `kind` picks its keys, below. Every phase has "
                "`kind`, `name` and `timeout`.", []))
    for kind, (spec, phase) in sorted(REGISTRY.items()):
        out.append((f"Phase `{kind}`", _summary(spec, phase),
                    [r for r in rows(spec, "phases[].") if r.key != "phases[].kind"]))
    out.append(("Robot file", "One robot: its model, arms, frames, groups, gains, cameras and base "
                "(`robots/*.yaml`; `--robot FILE|NAME`).", list(rows(RobotFile))))
    out.append(("Gains file", "PD gains per joint (`configs/gains/*.yaml`, or the robot file's gains folder).",
                list(rows(GainsFile))))
    out.append(("Sweep file", "Randomised episodes of a task (`configs/sweeps/*.yaml`; `nextage-qp sweep`).",
                list(rows(SweepFile))))
    out.append(("Study file", "An Optuna study over gains or task keys (`configs/studies/*.yaml`; `nextage-qp tune`).",
                list(rows(StudyFile))))
    return out


def _summary(spec: type, phase: type) -> str:
    """The first line of a phase kind's docstring: its spec's, else its phase module's (reST markup removed)."""
    import importlib

    for doc in (spec.__doc__, importlib.import_module(phase.__module__).__doc__):
        line = (doc or "").strip().splitlines()[0] if doc else ""
        if line and not line.lower().startswith("see the module"):
            return re.sub(r"(?::\w+:)?`+([^`]+)`+", r"`\1`", line)
    return ""


HEADER = """# Config reference

Generated from the schemas by `python tools/config_reference.py` (the test suite checks it is current); the guide to
writing a task is [tasks](tasks.md). Units are in brackets in each meaning; `–` where a key holds no number. Unknown
keys are errors, and so is a boolean where a number is expected (YAML 1.1's `yes`/`no`/`on`/`off` are strings).
`NAME` stands for a key of your choice (a body, an object, a joint), `[]` for every item of a list. Any key can be set
from the command line: `--set phases[0].attempts=3`.

The tool frames (`left_tool`, `right_tool` on the bundled robots) point their x axis along the contact face's outward
normal (the direction a push moves the object) and their z axis up when the hand is level; `push.yaw` and
`push.pitch` turn the tool from that convention.
"""


def render() -> str:
    """The whole reference page."""
    parts = [HEADER]
    for heading, intro, entries in sections():
        level = "###" if heading.startswith("Phase `") else "##"
        parts.append(f"{level} {heading}\n\n{intro}\n")
        if entries:
            parts.append(table(entries) + "\n")
    return "\n".join(parts)


def problems() -> list[str]:
    """Keys without a meaning, and numeric keys without a unit."""
    found = []
    for heading, _, entries in sections():
        for r in entries:
            if not r.meaning:
                found.append(f"{heading}: {r.key}: no description")
            elif r.numeric and r.unit == "–":
                found.append(f"{heading}: {r.key}: a number without its unit in brackets")
    return found


def main() -> int:
    """Write (or with ``--check`` compare) ``docs/configs.md``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare instead of writing; exit 1 on a difference")
    args = parser.parse_args()
    text = render()
    if args.check:
        bad = problems()
        for line in bad:
            print(line)
        stale = OUT.read_text() != text
        if stale:
            print(f"{OUT.relative_to(ROOT)} is stale: run python tools/config_reference.py")
        return 1 if bad or stale else 0
    OUT.write_text(text)
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
