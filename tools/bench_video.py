"""Benchmark of ``run --video``: wall time of a task run with a video against the same run without, back to back.

Runs ``nextage-qp run CONFIG`` and ``nextage-qp run CONFIG --video`` alternately ``--repeat`` times each (whole
commands, start-up included, as a user sees them) and prints the median and p99 of each and the ratio of the
medians. Set ``MUJOCO_GL=egl`` on a machine without display.

Example: ``MUJOCO_GL=egl .venv/bin/python tools/bench_video.py --config push_cube --repeat 3``
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

import mujoco
import numpy as np


def timed(argv: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "nextage_qp.cli", *argv], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="push_cube", help="config path or bundled name (default push_cube)")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each kind (default 3)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    plain: list[float] = []
    video: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run.mp4"
        for _ in range(args.repeat):
            plain.append(timed(["run", args.config]))
            video.append(timed(["run", args.config, "--video", str(out)]))

    def stats(x: list[float]) -> dict[str, float]:
        return {"median": float(np.median(x)), "p99": float(np.percentile(x, 99))}

    result = {"config": args.config, "repeat": args.repeat, "cpus": os.cpu_count(), "machine": platform.machine(),
              "python": platform.python_version(), "mujoco": mujoco.__version__,
              "MUJOCO_GL": os.environ.get("MUJOCO_GL"), "without_video_s": stats(plain),
              "with_video_s": stats(video), "ratio_of_medians": float(np.median(video) / np.median(plain))}
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"run {args.config}: {args.repeat} runs each, alternating; {os.cpu_count()} CPUs, mujoco "
          f"{mujoco.__version__}, MUJOCO_GL={result['MUJOCO_GL']}")
    for name, x in (("without --video", plain), ("with --video", video)):
        print(f"{name:<16} median {np.median(x):6.2f} s   p99 {np.percentile(x, 99):6.2f} s")
    print(f"ratio {result['ratio_of_medians']:.2f}x (with / without, medians)")


if __name__ == "__main__":
    main()
