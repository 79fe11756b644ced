"""Wall time of a default task run from the head camera against the same run from the truth, alternately.

    python tools/bench_camera.py [--runs 5] [--task push_cube --task dock_dumbbell] [--against COMMIT]
                                 [--depth rendered|stereo] [--window] [--no-hands] [--obstacles] [--scenes N]

Each run is a fresh ``nextage-qp run configs/TASK.yaml --json`` (``MUJOCO_GL=egl`` unless set), from the truth
(``perception.source=truth``, the config's default) and from the camera (``--set perception.source=camera``),
alternating so that the machine's drift affects both alike; with ``--against``, camera runs of that commit
(exported with ``git archive``) alternate with them too; ``--depth stereo`` makes every camera run's depth block
matching on the head's RGB pair (the vision extra); ``--window`` adds camera runs with
``perception.window=true`` (a tracked object's frames rendered in a window around it), ``--no-hands`` camera runs
without the hand cameras (``perception.hand_cameras=[]``), alternately too; ``--obstacles`` gives every camera run
the clutter only as the camera's map shows it (``perception.obstacles=camera``, for the clutter tasks). Prints
every run's wall and simulated time, then per task and arm the median and p99 of the wall time and of the wall
time per simulated second (a run from the camera may simulate longer: it stops to look where nothing sees the
object), the head camera's median render and estimate time per frame, its frames, the hand cameras' frames and
median time per frame, and the ratios of the medians, with the machine and the versions. No test asserts any of it.

One default run is one scene and one draw of the camera's noise: where that draw costs the camera run an approach
more than the truth's, its ratio is that approach's too. ``--scenes N`` times instead the first N episodes of each
task's sweep (``configs/sweeps/TASK.yaml``, seed 0, one worker) from the truth and from the camera, alternately per
run, and prints per episode's camera / truth ratios of wall time and of wall time per simulated second, their
median, p10 and p90, and the ratio of the totals.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ENV = dict(os.environ)  # the runs' environment, before bench_loop's import sets its thread counts
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
from bench_loop import machine  # noqa: E402
from bench_rtf_ab import export  # noqa: E402

CAMERA = ["--set", "perception.source=camera"]


def run(tree: Path, task: str, sets: list[str]) -> dict[str, float]:
    """Wall and simulated time [s], success, and the camera's per-frame medians [ms] of one default run."""
    env = {**ENV, "PYTHONPATH": str(tree), "MUJOCO_GL": ENV.get("MUJOCO_GL", "egl")}
    out = subprocess.run([sys.executable, "-m", "nextage_qp.cli", "run", f"configs/{task}.yaml", "--json", *sets],
                         cwd=tree, env=env, capture_output=True, text=True)
    if not out.stdout.strip():
        raise SystemExit(f"{tree}: run {task} {' '.join(sets)} printed nothing: {out.stderr.strip()[-300:]}")
    r = json.loads(out.stdout)
    cam = (r.get("estimation") or {}).get("camera") or {}
    hands = cam.get("hand_cameras") or {}
    return {"wall": float(r["wall_time_s"]), "sim": float(r["sim_time_s"]), "success": float(bool(r["success"])),
            "render_ms": float(cam.get("render_ms_median") or np.nan),
            "estimate_ms": float(cam.get("estimate_ms_median") or np.nan), "frames": float(cam.get("frames") or 0),
            "hand_frames": float(sum((hands.get("frames") or {}).values())),
            "hand_ms": float(hands.get("ms_median") or np.nan)}


def sweep(task: str, n: int, sets: list[str], out: Path) -> dict[int, tuple[float, float]]:
    """Per episode of the first ``n`` of ``task``'s sweep (one worker): its wall and simulated time [s]."""
    env = {**ENV, "PYTHONPATH": str(ROOT), "MUJOCO_GL": ENV.get("MUJOCO_GL", "egl")}
    cmd = [sys.executable, "-m", "nextage_qp.cli", "sweep", f"configs/sweeps/{task}.yaml", "--n", str(n), "--seed",
           "0", "--workers", "1", "--out", str(out), "--json", *sets]
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if done.returncode not in (0, 1) or not (out / "episodes.jsonl").exists():
        raise SystemExit(f"sweep {task} {' '.join(sets)} failed: {done.stderr.strip()[-300:]}")
    times = {}
    for line in (out / "episodes.jsonl").read_text().splitlines():
        e = json.loads(line)
        if e.get("result"):
            times[int(e["index"])] = (float(e["result"]["wall_time_s"]), float(e["result"]["sim_time_s"]))
    return times


def scenes(tasks: list[str], n: int, runs: int, camera: list[str]) -> None:
    """Time the first ``n`` episodes of each task's sweep from the truth and the camera (see the module doc)."""
    with tempfile.TemporaryDirectory() as tmp:
        for task in tasks:
            ratios: list[float] = []
            per: list[float] = []
            totals = [0.0, 0.0]
            for i in range(runs):
                truth = sweep(task, n, [], Path(tmp) / f"{task}-truth-{i}")
                cam = sweep(task, n, camera, Path(tmp) / f"{task}-camera-{i}")
                for k in sorted(set(truth) & set(cam)):
                    (tw, ts), (cw, cs) = truth[k], cam[k]
                    ratios.append(cw / tw)
                    per.append((cw / cs) / (tw / ts))
                    totals[0] += tw
                    totals[1] += cw
                print(f"run {i + 1}: {task}: {len(set(truth) & set(cam))} episodes from both", flush=True)
            print(f"{task:14s} camera / truth over {len(ratios)} episodes: wall median {np.median(ratios):.2f} "
                  f"(p10 {np.percentile(ratios, 10):.2f}, p90 {np.percentile(ratios, 90):.2f}); wall per simulated s "
                  f"median {np.median(per):.2f}; totals {totals[1]:.0f} s / {totals[0]:.0f} s = "
                  f"{totals[1] / totals[0]:.2f}")


def _stat(values: list[float]) -> str:
    return f"median {np.median(values):.3f}, p99 {np.percentile(values, 99):.3f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5, help="alternations (default 5)")
    ap.add_argument("--task", action="append", help="bundled task config (default: push_cube and dock_dumbbell)")
    ap.add_argument("--against", help="also time camera runs of this older commit, alternately")
    ap.add_argument("--depth", choices=("rendered", "stereo"), default="rendered",
                    help="the camera runs' perception.depth (default rendered)")
    ap.add_argument("--window", action="store_true", help="also time camera runs with perception.window=true")
    ap.add_argument("--no-hands", action="store_true", help="also time camera runs without the hand cameras")
    ap.add_argument("--obstacles", action="store_true",
                    help="camera runs plan with the camera's obstacle map (perception.obstacles=camera)")
    ap.add_argument("--scenes", type=int, default=0,
                    help="time the first N episodes of each task's sweep instead of its default run")
    args = ap.parse_args()
    camera = [*CAMERA, "--set", f"perception.depth={args.depth}",
              *(["--set", "perception.obstacles=camera"] if args.obstacles else [])]
    tasks = args.task or ["push_cube", "dock_dumbbell"]
    print(f"machine: {json.dumps(machine())}; MUJOCO_GL={ENV.get('MUJOCO_GL', 'egl')}; depth {args.depth}"
          f"{'; obstacles from the camera' if args.obstacles else ''}")
    if args.scenes > 0:
        scenes(tasks, args.scenes, args.runs, camera)
        return
    with tempfile.TemporaryDirectory() as old_dir:
        arms = {"truth": (ROOT, []), "camera": (ROOT, camera)}
        if args.window:
            arms["camera windowed"] = (ROOT, [*camera, "--set", "perception.window=true"])
        if args.no_hands:
            arms["camera no hands"] = (ROOT, [*camera, "--set", "perception.hand_cameras=[]"])
        if args.against:
            arms[f"camera@{export(args.against, Path(old_dir))}"] = (Path(old_dir), camera)
        results: dict[tuple[str, str], list[dict[str, float]]] = {}
        for i in range(args.runs):
            for task in tasks:
                for arm, (tree, sets) in arms.items():
                    r = run(tree, task, sets)
                    results.setdefault((task, arm), []).append(r)
                    frame = "" if np.isnan(r["render_ms"]) else (
                        f", {r['frames']:.0f} frames: render {r['render_ms']:.1f} ms, "
                        f"estimate {r['estimate_ms']:.1f} ms")
                    if r["hand_frames"]:
                        frame += f"; {r['hand_frames']:.0f} hand frames, {r['hand_ms']:.1f} ms"
                    print(f"run {i + 1}: {task} {arm}: wall {r['wall']:.2f} s for {r['sim']:.1f} s simulated "
                          f"(success {bool(r['success'])}){frame}", flush=True)
        print()
        for task in tasks:
            wall = {arm: [r["wall"] for r in results[(task, arm)]] for arm in arms}
            per = {arm: [r["wall"] / r["sim"] for r in results[(task, arm)]] for arm in arms}
            for arm in arms:
                rs = results[(task, arm)]
                ms = {k: np.median([r[k] for r in rs]) for k in ("render_ms", "estimate_ms", "frames", "hand_frames",
                                                                   "hand_ms")}
                frame = "" if arm == "truth" else \
                    f"; {ms['frames']:.0f} head frames, render {ms['render_ms']:.1f} ms, estimate " \
                    f"{ms['estimate_ms']:.1f} ms" + (f"; {ms['hand_frames']:.0f} hand frames, {ms['hand_ms']:.1f} ms"
                                                    if ms["hand_frames"] else "")
                print(f"{task:14s} {arm:16s} wall [s] {_stat(wall[arm])}; wall per simulated s {_stat(per[arm])}"
                      f"{frame}; {int(sum(r['success'] for r in rs))}/{len(rs)} succeeded")
            for arm in arms:
                if arm != "truth":
                    print(f"{task:14s} {arm} / truth: wall {np.median(wall[arm]) / np.median(wall['truth']):.2f}, "
                          f"wall per simulated s {np.median(per[arm]) / np.median(per['truth']):.2f} (medians)")
            if args.against:
                old = next(a for a in arms if a.startswith("camera@"))
                print(f"{task:14s} camera / {old}: wall {np.median(wall['camera']) / np.median(wall[old]):.2f} "
                      f"(medians)")


if __name__ == "__main__":
    main()
