"""How fast the planner plans in clutter: plan time (median, p95, p99) and validity checks per second.

Usage: python tools/bench_plan.py [--pairs 40] [--obstacles 6]

Four sets, each over ``--pairs`` start and goal configurations that are valid in the cluttered scene of
``configs/push_clutter.yaml`` (``--obstacles`` pieces, a new clutter seed every 10 pairs):

* ``single-arm transit``: the left arm's six joints drawn at random within their limits, the rest at home (many
  such pairs lie in regions no path joins: behind the back, under the table);
* ``single-arm task``: the joints the offline IK finds for the left tool at random points over the table's work
  region (3-30 cm over it), the transits a phase asks for;
* ``dual-arm carry``: both arms and the chest drawn at random, with the cube carried rigidly 10 cm under the left
  pad (the held object collides with the world too);
* ``dual-arm task``: both pads 10 cm apart across a random point over the work region, the cube held, as a clamp
  carries it.

Each pair is planned twice: as the phases ask (``auto``: the straight segment when nothing touches along it, a
planned path otherwise) and always planned (RRT-Connect, shortcutting and the dense check). Printed per set and mode:
plan time median / p95 / p99 [ms], the share found, and the validity checks per second.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

from nextage_qp.geometry import Pose
from nextage_qp.ik import QPIK, FrameTarget
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import build_robot
from nextage_qp.planning.rrt import plan_path
from nextage_qp.planning.world import CollisionWorld, Held
from nextage_qp.robots.model import Robot

ROOT = Path(__file__).resolve().parents[1]


def quantile(values: list[float], q: float) -> float:
    """The ``q`` quantile of ``values`` (nearest rank)."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def sample(world: CollisionWorld, robot: Robot, home: np.ndarray, joints: list[int],
           rng: np.random.Generator) -> np.ndarray:
    """A valid configuration: ``joints`` drawn uniformly within their limits, the others at ``home``."""
    while True:
        q = home.copy()
        q[joints] = rng.uniform(robot.lower[joints], robot.upper[joints])
        if world.valid(q):
            return q


REGION = ((0.25, -0.15), (0.60, 0.35))
"""The work region's x-y rectangle [m] the task sets draw points from."""


def task_sample(world: CollisionWorld, ik: QPIK, home: np.ndarray, frames: list[str], top: float,
                rng: np.random.Generator) -> np.ndarray:
    """A valid configuration the offline IK finds for ``frames`` at a random point over the work region."""
    (x0, y0), (x1, y1) = REGION
    while True:
        c = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1), top + rng.uniform(0.03, 0.30)])
        offsets = [np.zeros(3)] if len(frames) == 1 else [np.array([0.0, 0.05, 0.0]), np.array([0.0, -0.05, 0.0])]
        targets = [FrameTarget(f, pos=c + o) for f, o in zip(frames, offsets, strict=True)]
        result = ik.solve(targets, home)
        if result.pos_err_m < 0.005 and world.valid(result.q):
            return np.asarray(result.q)


def main() -> int:
    """Plan every pair of both sets in both modes and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=40, help="start/goal pairs per set (default 40)")
    parser.add_argument("--obstacles", type=int, default=6, help="pieces of clutter (default 6)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    results: dict[tuple[str, str], list[tuple[float, bool, int]]] = {}
    for block in range((args.pairs + 9) // 10):
        cfg = load_config(ROOT / "configs" / "push_clutter.yaml",
                          [f"scene.clutter.count={args.obstacles}", f"scene.clutter.seed={block}"])
        robot = build_robot(cfg, "bench")
        home = robot.keyframe_q("home")
        left = [robot.joint_index(f"LARM_JOINT{i}") for i in range(6)]
        both = [*left, *(robot.joint_index(f"RARM_JOINT{i}") for i in range(6)), robot.joint_index("CHEST_JOINT0")]
        carried = Held("cube", "left_pad", Pose(np.array([0.0, 0.0, -0.10]), np.eye(3)))
        sets = {"single-arm transit": (left, None, None), "single-arm task": (left, None, ["left_tool"]),
                "dual-arm carry": (both, carried, None), "dual-arm task": (both, carried, ["left_pad", "right_pad"])}
        ik = QPIK(robot, cfg.ik)
        top = float(robot.model.body("table").pos[2] + robot.model.geom("table_top").size[2])
        for name, (joints, held, frames) in sets.items():
            world = CollisionWorld(robot, clearance=cfg.planning.clearance)
            world.set_world({}, home, held=held)

            for k in range(min(10, args.pairs - 10 * block)):
                a, b = ((sample(world, robot, home, joints, rng) if frames is None else
                         task_sample(world, ik, home, frames, top, rng)) for _ in range(2))
                joints_ab = robot.moved_groups(sorted(set(joints) | set(np.flatnonzero(np.abs(b - a) > 1e-6))))
                for mode in ("auto", "always"):
                    checks0, t0 = world.checks, time.perf_counter()
                    plan = plan_path(world, a, b, lower=robot.lower, upper=robot.upper, joints=joints_ab, seed=k + 1,
                                     straight_first=mode == "auto", time_limit=cfg.planning.time_limit)
                    took = time.perf_counter() - t0
                    results.setdefault((name, mode), []).append((took, plan.found, world.checks - checks0))
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
          f"{args.pairs} pairs per set, {args.obstacles} obstacles")
    print(f"{'set':20s} {'mode':7s} {'median ms':>10s} {'p95 ms':>8s} {'p99 ms':>8s} {'found':>7s} {'checks/s':>9s}")
    for (name, mode), rows in results.items():
        times = [r[0] * 1e3 for r in rows]
        found = sum(r[1] for r in rows) / len(rows)
        rate = sum(r[2] for r in rows) / sum(r[0] for r in rows)
        print(f"{name:20s} {mode:7s} {statistics.median(times):10.1f} {quantile(times, 0.95):8.1f} "
              f"{quantile(times, 0.99):8.1f} {100 * found:6.0f}% {rate:9.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
