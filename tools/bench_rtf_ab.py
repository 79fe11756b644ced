"""Real-time factor of the default task runs, this commit against an older one, run alternately in one sitting.

    python tools/bench_rtf_ab.py --against b572323 [--runs 5] [--task push_cube --task dock_dumbbell]
                                 [--sweep-episodes 40 --sweep-workers 2]

Both commits are exported with ``git archive`` into temporary folders and run with this environment's Python
(``nextage-qp run configs/TASK.yaml --json``), alternating old and new so that the machine's drift affects both
alike. Prints, per task and commit, every run's real-time factor (and, where the commit reports it, the share of
the run's wall time spent inside ``mj_step``), the median and the slowest, and the ratio of the medians, with
the machine and the versions. With ``--sweep-episodes N``, each commit also runs the first N episodes of the
task's sweep file (``configs/sweeps/TASK.yaml``, seed 0) on ``--sweep-workers`` processes, alternately, and
the sweep throughput (episodes per minute of wall time, the command's whole run) is compared the same way.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
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


def _env(tree: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(tree), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}


def rtf(tree: Path, task: str) -> tuple[float, float | None]:
    """Real-time factor and physics share (None where the commit does not report it) of one default run."""
    out = subprocess.run([sys.executable, "-m", "nextage_qp.cli", "run", f"configs/{task}.yaml", "--json"],
                         cwd=tree, env=_env(tree), capture_output=True, text=True)
    if not out.stdout.strip():
        raise SystemExit(f"{tree}: run {task} printed nothing: {out.stderr.strip()[-300:]}")
    result = json.loads(out.stdout)
    return float(result["real_time_factor"]), result.get("physics_share")


def sweep_rate(tree: Path, task: str, episodes: int, workers: int) -> float:
    """Episodes per minute of the whole ``nextage-qp sweep`` command on the first ``episodes`` of the task's sweep."""
    with tempfile.TemporaryDirectory() as out_dir:
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-m", "nextage_qp.cli", "sweep", f"configs/sweeps/{task}.yaml", "--n",
                              str(episodes), "--seed", "0", "--workers", str(workers), "--out", out_dir],
                             cwd=tree, env=_env(tree), capture_output=True, text=True)
        wall = time.perf_counter() - t0
    if out.returncode not in (0, 1):
        raise SystemExit(f"{tree}: sweep {task} failed: {out.stderr.strip()[-300:]}")
    return 60.0 * episodes / wall


def _medians(label: str, results: dict[tuple[str, str], list[float]], names: dict[str, str], tasks: list[str],
             unit: str) -> None:
    for task in tasks:
        med = {w: float(np.median(results[(task, w)])) for w in ("old", "new")}
        for w in ("old", "new"):
            r = results[(task, w)]
            print(f"{task:15s} {label} {w} {names[w]}: {min(r):.2f}-{max(r):.2f}{unit}, median {med[w]:.2f}{unit}")
        print(f"{task:15s} {label} new/old median ratio {med['new'] / med['old']:.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--against", required=True, help="older commit to compare with")
    ap.add_argument("--runs", type=int, default=5, help="alternations (default 5)")
    ap.add_argument("--task", action="append", help="bundled task config (default: push_cube and dock_dumbbell)")
    ap.add_argument("--sweep-episodes", type=int, default=0, help="also time this many episodes of each task's sweep")
    ap.add_argument("--sweep-workers", type=int, default=2, help="workers of those sweeps (default 2)")
    ap.add_argument("--sweep-runs", type=int, default=1, help="alternations of the sweeps (default 1)")
    args = ap.parse_args()
    tasks = args.task or ["push_cube", "dock_dumbbell"]
    import mujoco

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; python "
          f"{platform.python_version()}, mujoco {mujoco.__version__}")
    with tempfile.TemporaryDirectory() as old_dir, tempfile.TemporaryDirectory() as new_dir:
        names = {"old": export(args.against, Path(old_dir)), "new": export("HEAD", Path(new_dir))}
        trees = {"old": Path(old_dir), "new": Path(new_dir)}
        results: dict[tuple[str, str], list[float]] = {}
        shares: dict[tuple[str, str], list[float]] = {}
        for i in range(args.runs):
            for which in ("old", "new"):
                for task in tasks:
                    value, share = rtf(trees[which], task)
                    results.setdefault((task, which), []).append(value)
                    if share is not None:
                        shares.setdefault((task, which), []).append(float(share))
                    shown = "" if share is None else f", physics share {share:.3f}"
                    print(f"run {i + 1}: {which} ({names[which]}) {task}: {value:.2f}x{shown}", flush=True)
        print()
        _medians("RTF", results, names, tasks, "x")
        for (task, which), values in sorted(shares.items()):
            print(f"{task:15s} physics share {which} {names[which]}: median {np.median(values):.3f} "
                  f"(min {min(values):.3f}, {len(values)} runs)")
        if args.sweep_episodes:
            rates: dict[tuple[str, str], list[float]] = {}
            for i in range(args.sweep_runs):
                for which in ("old", "new"):
                    for task in tasks:
                        rate = sweep_rate(trees[which], task, args.sweep_episodes, args.sweep_workers)
                        rates.setdefault((task, which), []).append(rate)
                        print(f"sweep {i + 1}: {which} ({names[which]}) {task}: {args.sweep_episodes} episodes, "
                              f"{args.sweep_workers} workers: {rate:.1f} episodes/min", flush=True)
            print()
            _medians("sweep episodes/min", rates, names, tasks, "")


if __name__ == "__main__":
    main()
