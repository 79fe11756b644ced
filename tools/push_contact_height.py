"""How high above the table a robot's hand meets the object it pushes: the h of tools/push_wedge.py.

Runs a task and, at every control tick, reads the contacts between the config's object and the robot's bodies, and
between the object and the body it rests on; prints the median, 10th and 90th percentile of the robot contacts'
height above the resting contacts (the table's top).

Run: python tools/push_contact_height.py configs/push_cube.yaml [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from nextage_qp.api import load_task


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("config", help="a push task config")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override")
    args = parser.parse_args()
    task = load_task(args.config, overrides=args.set)
    runner = task.runner()
    m = runner.sim.model
    obj = m.body(task.config.object).id
    table_z: list[float] = []
    tool_z: list[float] = []

    def on_tick(r, _phase) -> None:
        d = r.sim.data
        for c in d.contact[: d.ncon]:
            b1, b2 = int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])
            if obj not in (b1, b2):
                continue
            other = b2 if b1 == obj else b1
            if m.body_weldid[other] == 0:  # a fixed body: what the object rests on
                table_z.append(float(c.pos[2]))
            elif m.body_rootid[other] != other:  # a moving link of a fixed robot (another free object: neither)
                tool_z.append(float(c.pos[2]))

    record = runner.run(on_tick)
    if not tool_z or not table_z:
        print(f"{args.config}: no robot contact with {task.config.object} recorded", file=sys.stderr)
        return 1
    h = np.asarray(tool_z) - float(np.median(table_z))
    print(f"{args.config} {' '.join(args.set)}: success {record['success']}; contact height over the table "
          f"median {np.median(h) * 1e3:.1f} mm (p10 {np.percentile(h, 10) * 1e3:.1f}, p90 "
          f"{np.percentile(h, 90) * 1e3:.1f}) over {len(h)} contacts")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
