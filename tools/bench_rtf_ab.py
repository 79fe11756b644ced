"""Real-time factor of the default task runs, this commit against an older one, run alternately in one sitting.

    python tools/bench_rtf_ab.py --against 2b299b2 [--runs 5] [--task push_cube --task dock_dumbbell]

Both commits are exported with ``git archive`` into temporary folders and run with this environment's Python
(``nextage-qp run configs/TASK.yaml --json``), alternating old and new so that the machine's drift affects both
alike. Prints, per task and commit, every run's real-time factor, the median and the slowest, and the ratio of
the medians, with the machine and the versions.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def export(commit: str, into: Path) -> str:
    """Export ``commit`` into ``into``; returns its short hash."""
    short = subprocess.run(["git", "rev-parse", "--short", commit], cwd=ROOT, check=True, capture_output=True,
                           text=True).stdout.strip()
    archive = subprocess.run(["git", "archive", commit], cwd=ROOT, check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return short


def rtf(tree: Path, task: str) -> float:
    env = {**os.environ, "PYTHONPATH": str(tree), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    out = subprocess.run([sys.executable, "-m", "nextage_qp.cli", "run", f"configs/{task}.yaml", "--json"],
                         cwd=tree, env=env, capture_output=True, text=True)
    if not out.stdout.strip():
        raise SystemExit(f"{tree}: run {task} printed nothing: {out.stderr.strip()[-300:]}")
    return float(json.loads(out.stdout)["real_time_factor"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--against", required=True, help="older commit to compare with")
    ap.add_argument("--runs", type=int, default=5, help="alternations (default 5)")
    ap.add_argument("--task", action="append", help="bundled task config (default: push_cube and dock_dumbbell)")
    args = ap.parse_args()
    tasks = args.task or ["push_cube", "dock_dumbbell"]
    import mujoco

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; python "
          f"{platform.python_version()}, mujoco {mujoco.__version__}")
    with tempfile.TemporaryDirectory() as old_dir, tempfile.TemporaryDirectory() as new_dir:
        names = {"old": export(args.against, Path(old_dir)), "new": export("HEAD", Path(new_dir))}
        trees = {"old": Path(old_dir), "new": Path(new_dir)}
        results: dict[tuple[str, str], list[float]] = {}
        for i in range(args.runs):
            for which in ("old", "new"):
                for task in tasks:
                    value = rtf(trees[which], task)
                    results.setdefault((task, which), []).append(value)
                    print(f"run {i + 1}: {which} ({names[which]}) {task}: {value:.2f}x", flush=True)
        print()
        for task in tasks:
            med = {w: float(np.median(results[(task, w)])) for w in ("old", "new")}
            for w in ("old", "new"):
                r = results[(task, w)]
                print(f"{task:15s} {w} {names[w]}: {min(r):.2f}-{max(r):.2f}x, median {med[w]:.2f}x, "
                      f"slowest {min(r):.2f}x")
            print(f"{task:15s} new/old median ratio {med['new'] / med['old']:.3f}")


if __name__ == "__main__":
    main()
