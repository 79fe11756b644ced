"""Check that a refactor changed no behaviour: every shipped config's default run logs the same arrays as at REF.

Usage: python tools/same_logs.py REF [--only NAME ...]

REF is a commit (e.g. HEAD~1). Each run below is made twice, once from a worktree of REF and once from this checkout,
with ``nextage-qp run CONFIG --log``; the logs are compared array by array (bit for bit, NaN equal to NaN) and the
result records field by field, leaving out what measures wall time or names an output path.
Exit 0 when every run is the same, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

RUNS = {
    "push": ["configs/push_cube.yaml"],
    "dock": ["configs/dock_dumbbell.yaml"],
    "pick_place": ["configs/pick_place_box.yaml"],
    "stack": ["configs/stack_boxes.yaml"],
    "fetch_push": ["configs/fetch_push.yaml"],
    "park": ["configs/park_car.yaml"],
    "yumi_push": ["configs/push_across.yaml", "--robot", "yumi"],
    "aloha_push": ["configs/push_across.yaml", "--robot", "aloha"],
    "aloha_park": ["configs/aloha/park.yaml"],
    "camera_push": ["configs/push_cube.yaml", "--set", "perception.source=camera"],
    "camera_dock": ["configs/dock_dumbbell.yaml", "--set", "perception.source=camera"],
    "stereo_push": ["configs/push_cube.yaml", "--set", "perception.source=camera", "--set", "perception.depth=stereo"],
    "push_clutter": ["configs/push_clutter.yaml"],
    "place_free_spot": ["configs/place_free_spot.yaml"],
    "camera_push_clutter": ["configs/push_clutter.yaml", "--set", "perception.source=camera"],
}
"""Every shipped config's default run (and the cameras' push and dock, and the clutter push), by name."""

TIMING = ("wall", "time_s", "_ms_", "check_ms", "real_time_factor", "physics_share", "timing", "outputs", "log")
"""Result keys that measure wall time or name output files: left out of the comparison."""


def run(tree: Path, name: str, out: Path) -> dict[str, Any]:
    """Run one config from a source tree; returns its result record (the log is ``out/NAME.npz``)."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    done = subprocess.run([sys.executable, "-m", "nextage_qp.cli", "run", *RUNS[name], "--json",
                           "--log", str(out / f"{name}.npz")], cwd=tree, env=env, capture_output=True, text=True)
    if done.returncode not in (0, 1):
        raise SystemExit(f"{name} from {tree}: exit {done.returncode}: {done.stderr.strip()[-300:]}")
    return json.loads(done.stdout)


def strip(value: Any) -> Any:
    """The record without the keys of :data:`TIMING`."""
    if isinstance(value, dict):
        return {k: strip(v) for k, v in value.items() if not any(t in k for t in TIMING)}
    if isinstance(value, list):
        return [strip(v) for v in value]
    return value


def changed(a: Any, b: Any, at: str = "") -> list[str]:
    """Dotted keys where two records differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [k for key in sorted(set(a) | set(b))
                for k in changed(a.get(key), b.get(key), f"{at}.{key}".lstrip("."))]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [k for i, (x, y) in enumerate(zip(a, b, strict=True)) for k in changed(x, y, f"{at}[{i}]")]
    return [] if a == b else [at or "(record)"]


def same_arrays(a: Path, b: Path) -> list[str]:
    """Names of the arrays that differ between two logs (or are in one only)."""
    x, y = np.load(a, allow_pickle=True), np.load(b, allow_pickle=True)
    differ = []
    for key in sorted(set(x.files) | set(y.files)):
        if key not in x.files or key not in y.files or x[key].shape != y[key].shape:
            differ.append(key)
            continue
        try:
            equal = np.array_equal(x[key], y[key], equal_nan=True)
        except TypeError:  # non-numeric arrays
            equal = np.array_equal(x[key], y[key])
        if not equal:
            differ.append(key)
    return differ


def main() -> int:
    """Compare every run of :data:`RUNS` (or ``--only`` those) between REF and this checkout."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("ref", help="the commit to compare with (e.g. HEAD~1)")
    parser.add_argument("--only", nargs="+", choices=sorted(RUNS), help="these runs only")
    args = parser.parse_args()
    names = args.only or list(RUNS)
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "ref"
        subprocess.run(["git", "worktree", "add", "--detach", str(base), args.ref], cwd=ROOT, check=True,
                       capture_output=True)
        try:
            for name in names:
                logs = {}
                for label, tree in (("ref", base), ("now", ROOT)):
                    out = Path(tmp) / label
                    out.mkdir(exist_ok=True)
                    logs[label] = (strip(run(tree, name, out)), out / f"{name}.npz")
                differ = same_arrays(logs["ref"][1], logs["now"][1])
                records = logs["ref"][0] == logs["now"][0]
                failed += bool(differ) or not records
                keys = ", ".join(changed(logs["ref"][0], logs["now"][0]))
                print(f"{name:12s} arrays {'same' if not differ else 'DIFFER: ' + ', '.join(differ)}; "
                      f"record {'same' if records else 'DIFFERS: ' + keys}", flush=True)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(base)], cwd=ROOT, capture_output=True)
    print("every run the same" if not failed else f"{failed} of {len(names)} runs differ")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
