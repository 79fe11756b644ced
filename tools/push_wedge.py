"""Which pushes of a shape sweep were physically possible: success split by wedge number, shape and friction.

A flat face pushing an object at height h above the table, with table friction mu, must also hold the object from
tipping: the tool's friction on the object's back face pulls it down, which raises the table's friction in turn.
Quasi-statically the push slides the object only if

    W = mu * h / (2 * w) < 1

where w is the object's half-depth along the push (a box's half-width across the face pushed, a cylinder's radius,
a prism's apothem). At W >= 1 the object wedges between the tool and the table and tips instead: no controller
pushes it with that hand at that height. The table friction of each episode is read from its compiled scene; w is
the smallest half-depth of its shape (the box's narrower side); h defaults to 17 mm, the median height of the
Nextage hand's contacts on a pushed object (the lower edge of its camera box; tools/push_contact_height.py).

Run: python tools/push_wedge.py runs/sweeps/push_shapes-seed0 [--contact-height 0.017]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import build_robot
from nextage_qp.sweep.summary import wilson


def half_depth(decl: dict) -> float:
    """The smallest half-depth of a declared shape along a horizontal push [m]."""
    size = decl["size"]
    if decl["shape"] == "box":
        return min(size[0], size[1])
    if decl["shape"] == "prism":
        return size[0] * math.cos(math.pi / decl.get("sides", 6))
    return size[0]


def table_friction(overrides: list[str], base: Path) -> float:
    """Sliding friction between the pushed object and the table top in the episode's compiled scene."""
    cfg = load_config(base, [o for o in overrides if not o.startswith("seed=")])
    m = build_robot(cfg, str(base)).model
    obj, table = m.body(cfg.object).id, m.body("table").id
    for i in range(m.npair):
        bodies = {int(m.geom_bodyid[m.pair_geom1[i]]), int(m.geom_bodyid[m.pair_geom2[i]])}
        if bodies == {obj, table}:
            return float(m.pair_friction[i, 0])
    geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] in (obj, table)]
    return float(max(m.geom_friction[g, 0] for g in geoms))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("run", type=Path, help="a sweep's output folder (episodes.jsonl, sweep.json)")
    parser.add_argument("--contact-height", type=float, default=0.017, help="h [m]")
    args = parser.parse_args()
    base = Path(json.loads((args.run / "sweep.json").read_text())["base"])
    rows = []
    for line in (args.run / "episodes.jsonl").read_text().splitlines():
        ep = json.loads(line)
        decl = next(v for k, v in ep["params"].items() if k.startswith("scene.objects."))
        mu = table_friction(ep["overrides"], base)
        wedge = mu * args.contact_height / (2.0 * half_depth(decl))
        rows.append((ep["index"], decl["shape"], wedge, ep["status"] == "success", ep["status"], mu))
    groups: dict[str, list[bool]] = defaultdict(list)
    for _, shape, wedge, ok, status, mu in rows:
        if status == "refused":
            continue
        side = "W < 1 (pushable)" if wedge < 1.0 else "W >= 1 (wedges)"
        band = f"table friction {'< 1.5' if mu < 1.5 else '>= 1.5'}"
        for key in (side, f"{shape}, {side}", "all", band, f"{shape}, {band}"):
            groups[key].append(ok)
    print(f"{args.run}: h = {args.contact_height * 1e3:.0f} mm")
    for key in sorted(groups):
        n, k = len(groups[key]), sum(groups[key])
        lo, hi = wilson(k, n)
        print(f"  {key:36s} {k:4d}/{n:<4d} = {100.0 * k / n:5.1f} % (95 % CI {100 * lo:.1f}-{100 * hi:.1f} %)")
    failed = [(i, s, round(w, 2)) for i, s, w, ok, st, _ in rows if not ok and st != "refused"]
    print(f"  failed (index, shape, W): {failed}")
    errors = [e for e in (json.loads(x)["result"] for x in (args.run / "episodes.jsonl").read_text().splitlines())
              if e and e.get("success")]
    if errors:
        median = 1e3 * float(np.median([e["object_error_xy_m"] for e in errors]))
        print(f"  median error of the successes: {median:.2f} mm")
    return 0


if __name__ == "__main__":
    sys.exit(main())
