"""Nothing in the package outside the Nextage's own files names a Nextage joint, body, site, geom or actuator."""

from __future__ import annotations

import re
from pathlib import Path

from nextage_qp.robots.compose import robot_spec
from nextage_qp.robots.description import load_robot

PACKAGE = Path(__file__).resolve().parents[1] / "nextage_qp"
NEXTAGE_FILES = {PACKAGE / "kinematics" / "nextage_chain.py"}
"""The report's transform-chain FK of the Nextage: its cross-check, the one module that may name its joints."""


def _nextage_names() -> set[str]:
    desc = load_robot("nextage")
    spec = robot_spec(desc)
    names = {e.name for kind in ("bodies", "joints", "sites", "geoms", "actuators") for e in getattr(spec, kind)}
    names |= set(desc.frames) | {f for arm in desc.arms for f in (arm.wrist, arm.tool, arm.pad)}
    return names - {"", "world"}


def test_no_nextage_names_in_the_package():
    names = _nextage_names()
    assert {"LARM_JOINT0", "CHEST_JOINT0_Link", "left_tool", "left_pad", "WAIST"} <= names  # the test has teeth
    pattern = re.compile(r"(?<![A-Za-z0-9_])(" + "|".join(sorted(map(re.escape, names), key=len, reverse=True))
                         + r")(?![A-Za-z0-9_])")
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path in NEXTAGE_FILES:
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if m := pattern.search(line):
                found.append(f"{path.relative_to(PACKAGE.parent)}:{n}: {m.group(1)}")
    assert not found, "Nextage names in the package:\n" + "\n".join(found)
