"""Step responses of every arm joint of a robot with its robot file's gains: a table, and whether each meets the bar.

Each arm joint steps (raw, the report's test) from ``home`` by ``--amplitude`` towards the side with more range,
every other joint holding ``home``; the figures are those of ``nextage-qp step-response``. A step meets the bar
when its final error is within ``--final-error`` and its overshoot within ``--overshoot``.

    .venv/bin/python tools/step_table.py --robot yumi [--amplitude 0.3] [--json out.json]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from nextage_qp.experiments.step_response import run_step
from nextage_qp.robots.gains import robot_gains
from nextage_qp.robots.model import Robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default=None, help="robot file or bundled name (default: nextage)")
    ap.add_argument("--amplitude", type=float, default=0.3, help="step size [rad] (default 0.3)")
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time per step [s] (default 3)")
    ap.add_argument("--final-error", type=float, default=0.005, help="bar on the final error [rad] (default 0.005)")
    ap.add_argument("--overshoot", type=float, default=5.0, help="bar on the overshoot [%%] (default 5)")
    ap.add_argument("--json", metavar="PATH", help="also write the rows as JSON")
    args = ap.parse_args()
    robot = Robot.from_scene("scene", robot=args.robot)
    gains = robot_gains(robot)
    home = robot.keyframe_q("home")
    rows = []
    for arm in robot.arms:
        for joint in arm.joints:
            j = robot.joint_index(joint)
            up, down = robot.upper[j] - home[j], home[j] - robot.lower[j]
            target = float(home[j] + (args.amplitude if up >= down else -args.amplitude))
            target = float(np.clip(target, robot.lower[j], robot.upper[j]))
            m, _ = run_step(robot, joint, target, gains, duration=args.duration)
            ok = m.final_error_rad <= args.final_error and m.overshoot_pct <= args.overshoot
            rows.append({"joint": joint, "step_rad": target - float(home[j]), "kp": float(gains.kp[j]),
                         "kd": float(gains.kd[j]), **m._asdict(), "meets": ok})
    print(f"robot {robot.name}: raw steps of {args.amplitude:g} rad from home, gains {gains.source}; bar: final error "
          f"<= {args.final_error:g} rad, overshoot <= {args.overshoot:g} %")
    print(f"{'joint':24} {'step':>6} {'kp':>8} {'kd':>7} {'final err':>10} {'overshoot':>9} {'settle 2%':>9} "
          f"{'sat':>5} meets")
    for r in rows:
        settle = "never" if r["settling_time_s"] is None else f"{r['settling_time_s']:.3f}"
        print(f"{r['joint']:24} {r['step_rad']:+6.2f} {r['kp']:8.2f} {r['kd']:7.2f} {r['final_error_rad']:10.1e} "
              f"{r['overshoot_pct']:8.2f}% {settle:>9} {r['saturated_steps']:5d} {'yes' if r['meets'] else 'NO'}")
    met = sum(r["meets"] for r in rows)
    print(f"{met}/{len(rows)} steps meet the bar; largest final error {max(r['final_error_rad'] for r in rows):.1e} "
          f"rad, largest overshoot {max(r['overshoot_pct'] for r in rows):.2f} %")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"robot": robot.name, "gains": gains.source, "amplitude_rad": args.amplitude, "rows": rows},
                      fh, indent=2)


if __name__ == "__main__":
    main()
