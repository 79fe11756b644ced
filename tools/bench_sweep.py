"""Benchmark of the sweep backends: parallel efficiency of W workers against 1 on the same episodes.

Runs the same episodes of a sweep file once with 1 worker and once with W workers (local process pool), in one
sitting, and prints the wall time of each, the per-episode wall times (median and p99) and the parallel
efficiency ``T_1 / (W * T_W)``. It also checks that both runs gave identical episodes.

Example: ``.venv/bin/python tools/bench_sweep.py --sweep configs/sweeps/push_cube.yaml --n 20 --workers 2``
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from nextage_qp.sweep.run import plan, run_sweep
from nextage_qp.sweep.spec import SweepSpec


def timed(spec: SweepSpec, seed: int, n: int, workers: int) -> tuple[float, list]:
    t0 = time.perf_counter()
    episodes = run_sweep(plan(spec, seed, range(n)), store=None, workers=workers)
    return time.perf_counter() - t0, episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", default="configs/sweeps/push_cube.yaml", help="sweep file")
    parser.add_argument("--n", type=int, default=20, help="episodes (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="sweep seed (default 0)")
    parser.add_argument("--workers", type=int, default=2, help="workers of the parallel run (default 2)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    spec = SweepSpec(args.sweep)
    t1, one = timed(spec, args.seed, args.n, 1)
    tw, many = timed(spec, args.seed, args.n, args.workers)
    identical = [e.comparable() for e in one] == [e.comparable() for e in many]
    per1 = [e.wall_time_s for e in one]
    perw = [e.wall_time_s for e in many]
    out = {
        "sweep": args.sweep, "episodes": args.n, "workers": args.workers, "cpus": os.cpu_count(),
        "wall_1_worker_s": t1, f"wall_{args.workers}_workers_s": tw,
        "speedup": t1 / tw, "parallel_efficiency": t1 / (args.workers * tw),
        "episode_wall_s_1_worker": {"median": float(np.median(per1)), "p99": float(np.percentile(per1, 99))},
        f"episode_wall_s_{args.workers}_workers": {"median": float(np.median(perw)),
                                                   "p99": float(np.percentile(perw, 99))},
        "identical_episodes": identical,
    }
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"{args.sweep}: {args.n} episodes, {os.cpu_count()} CPUs")
    print(f"1 worker     {t1:7.1f} s   episode median {np.median(per1):.2f} s, p99 {np.percentile(per1, 99):.2f} s")
    print(f"{args.workers} workers    {tw:7.1f} s   episode median {np.median(perw):.2f} s, "
          f"p99 {np.percentile(perw, 99):.2f} s")
    print(f"speedup {t1 / tw:.2f}x, parallel efficiency {t1 / (args.workers * tw):.2f} "
          f"(T1 / ({args.workers} x T{args.workers})); identical episodes: {identical}")


if __name__ == "__main__":
    main()
