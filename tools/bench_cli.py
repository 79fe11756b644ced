"""How fast the command line answers: whole processes, median and p99 of several runs, on an idle machine.

Usage: python tools/bench_cli.py [--runs 5]

Times ``nextage-qp --help``, ``nextage-qp info``, ``nextage-qp robot check nextage`` and the default push's process,
and for the push also the process's wall time minus the run's own ``wall_time_s`` (what starting up costs: imports,
compiled kernels loaded from numba's cache, the scene composed). For comparison, in the same sitting: a bare Python,
and a Python that only imports what a run cannot do without (MuJoCo, mink, numba), the floor of that start-up.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "nextage_qp.cli"]


def timed(argv: list[str]) -> tuple[float, str]:
    """Wall time [s] of one process, and its standard output."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    start = time.perf_counter()
    done = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True)
    took = time.perf_counter() - start
    if done.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(argv)}: exit {done.returncode}: {done.stderr.strip()[-300:]}")
    return took, done.stdout


def stats(values: list[float]) -> str:
    """Median and p99 [s] of ``values``."""
    ordered = sorted(values)
    p99 = ordered[min(len(ordered) - 1, round(0.99 * (len(ordered) - 1)))]
    return f"median {statistics.median(values):6.3f} s   p99 {p99:6.3f} s"


def main() -> int:
    """Time every command :data:`runs` times, interleaved, and print median and p99 of each."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="processes per command (default 5)")
    args = parser.parse_args()
    cases = {
        "python (bare)": [sys.executable, "-c", "pass"],
        "import mujoco, mink, numba": [sys.executable, "-c", "import mujoco, mink, numba"],
        "nextage-qp --help": [*CLI, "--help"],
        "nextage-qp info": [*CLI, "info"],
        "nextage-qp robot check nextage": [*CLI, "robot", "check", "nextage"],
        "nextage-qp run push_cube": [*CLI, "run", "configs/push_cube.yaml", "--json"],
    }
    times: dict[str, list[float]] = {name: [] for name in cases}
    overhead: list[float] = []
    for _ in range(args.runs):  # interleaved, so a slow spell of the machine hits every command alike
        for name, argv in cases.items():
            took, out = timed(argv)
            times[name].append(took)
            if name.endswith("push_cube"):
                overhead.append(took - float(json.loads(out)["wall_time_s"]))
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
          f"{args.runs} runs each")
    for name, values in times.items():
        print(f"{name:34s} {stats(values)}")
    print(f"{'push: process minus its wall_time_s':34s} {stats(overhead)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
