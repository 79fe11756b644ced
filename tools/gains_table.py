"""Markdown tables of a PD-gains study: the gains side by side, and each step's settling time, base against best.

    python tools/gains_table.py runs/studies/pd_gains/summary.json [--compare report]

Reads the study summary written by ``nextage-qp tune configs/studies/pd_gains.yaml`` (its best trial, its base
trial 0 and the held-out check) and the bundled gains files; prints the tables of docs/control.md.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from nextage_qp.loop.pd import load_gains


def _steps(details: dict) -> dict[tuple[str, float], dict]:
    return {(r["joint"], round(r["target_deg"], 2)): r for r in details["per_step"]}


def _settle(row: dict | None) -> str:
    if row is None:
        return "–"
    s = row.get("settling_time_s")
    mark = "" if row["met"] else " ✗"
    return ("never" if s is None else f"{s:.3f}") + mark


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("summary", type=Path, help="summary.json of a steps study")
    ap.add_argument("--tuned", default=None, help="tuned gains file (default: best.yaml next to the summary)")
    ap.add_argument("--compare", default="report", help="third gains file shown (default: report)")
    args = ap.parse_args()
    s = json.loads(args.summary.read_text())
    tuned_gains = load_gains(args.tuned or args.summary.parent / "best.yaml")
    joint_names = list(tuned_gains.names)
    tuned = tuned_gains.as_dict()
    base = load_gains("default").as_dict()
    other = load_gains(args.compare).as_dict()
    print(f"| joint | tuned kp / kd | default kp / kd | {args.compare} kp / kd |")
    print("|---|---|---|---|")
    for j in joint_names:
        cells = [f"{g[j]['kp']:.4g} / {g[j]['kd']:.4g}" for g in (tuned, base, other)]
        print(f"| {j} | " + " | ".join(cells) + " |")
    print()
    best, base_d = _steps(s["best"]["details"]), _steps(s["base"]["details"])
    print("| joint | target [deg] | settling 2 % [s], default | tuned | overshoot [%], default | tuned |")
    print("|---|---|---|---|---|---|")
    for key in sorted(best, key=lambda k: (joint_names.index(k[0]), -k[1])):
        b, t = base_d.get(key), best[key]
        print(f"| {key[0]} | {key[1]:+.2f} | {_settle(b)} | {_settle(t)} | "
              f"{(b or {}).get('overshoot_pct', float('nan')):.2f} | {t['overshoot_pct']:.2f} |")
    print()
    for name, d in (("objective's steps", (s["base"]["details"], s["best"]["details"])),
                    ("held-out steps", (s["held_out"]["base"]["details"], s["held_out"]["best"]["details"]))
                    if s.get("held_out") else ()):
        b, t = d
        print(f"{name}: default {b['met']}/{b['steps']} meet the criteria, mean settling "
              f"{_mean(b)}; tuned {t['met']}/{t['steps']}, mean settling {_mean(t)}; "
              f"largest final error tuned {max(r['final_error_rad'] for r in t['per_step']):.1e} rad, "
              f"largest overshoot tuned {max(r['overshoot_pct'] for r in t['per_step']):.2f} %")
    print(f"skipped (outside the joint's range): {', '.join(s.get('skipped_steps', {}).get('objective', [])) or '-'}")


def _mean(d: dict) -> str:
    v = d.get("mean_settling_time_s")
    return "-" if v is None else f"{v:.4f} s" + f" (max {np.max([r['settling_time_s'] for r in d['per_step']]):.3f})"


if __name__ == "__main__":
    main()
