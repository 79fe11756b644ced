"""Benchmark the IK methods: success on random reachable targets, and the cost of one QP IK step vs plain mink.

Targets are FK poses of random in-limit configurations (fixed seed), solved from ``home``:
one wrist (alternating between the first two arms) and both wrists at once, each position-only and full-pose.
Success is 1 mm / 1 deg. The step timing runs our QPIK.step and plain ``mink.solve_ik`` with the same tasks and
limits on the same states, interleaved, in the same process.

    .venv/bin/python tools/bench_ik.py --targets 1000 --json bench.json
    .venv/bin/python tools/bench_ik.py --robot yumi --targets 1000      # any robot file
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections.abc import Callable
from importlib import metadata

import mink
import numpy as np

from nextage_qp.ik import QPIK, CollisionPairConfig, FrameTarget, IKConfig, IKResult
from nextage_qp.ik.baselines import dls_ik, lm_ik, pinv_ik
from nextage_qp.kinematics.frames import Kinematics
from nextage_qp.robots.model import Robot


def wrists(robot: Robot) -> tuple[str, str]:
    """The wrist frames of the robot's first two arms."""
    return robot.arms[0].wrist, robot.arms[1].wrist


def pairs(robot: Robot) -> list[tuple[str, str]]:
    """Collision pairs of the step timing: each arm against the scene's bodies, the torso, the head and the other arm
    (those of them the robot file and the scene have)."""
    groups = robot.collision_geoms()
    arms = [a.group for a in robot.arms]
    out = [(a, b) for b in ("table", "obstacle") for a in arms]
    out += [(a, "torso") for a in arms] + [(a, b) for i, a in enumerate(arms) for b in arms[i + 1:]]
    out += [(a, o) for o in robot.object_names for a in arms] + [("head", a) for a in arms]
    return [(a, b) for a, b in out if groups.get(a) and groups.get(b)]


def target_sets(robot: Robot, n: int, seed: int) -> dict[str, list[list[FrameTarget]]]:
    kin, rng = Kinematics(robot), np.random.default_rng(seed)
    sets: dict[str, list[list[FrameTarget]]] = {k: [] for k in ("one_pos", "one_pose", "two_pos", "two_pose")}
    for i in range(n):
        q = rng.uniform(robot.lower, robot.upper)
        poses = {f: kin.fk(f, q) for f in wrists(robot)}
        one = wrists(robot)[i % 2]
        sets["one_pos"].append([FrameTarget(one, pos=poses[one].pos)])
        sets["one_pose"].append([FrameTarget(one, pos=poses[one].pos, rot=poses[one].rot)])
        sets["two_pos"].append([FrameTarget(f, pos=poses[f].pos) for f in wrists(robot)])
        sets["two_pose"].append([FrameTarget(f, pos=poses[f].pos, rot=poses[f].rot) for f in wrists(robot)])
    return sets


def pct(values: list[float], p: float) -> float:
    return float(np.percentile(values, p))


def bench_success(robot: Robot, n: int, seed: int) -> dict[str, dict[str, dict[str, float]]]:
    home = robot.keyframe_q("home")
    qp = QPIK(robot, IKConfig())
    methods: dict[str, Callable[[list[FrameTarget]], IKResult]] = {
        "qp": lambda t: qp.solve(t, home),
        "pinv": lambda t: pinv_ik(robot, t, home),
        "dls": lambda t: dls_ik(robot, t, home),
        "lm": lambda t: lm_ik(robot, t, home),
    }
    out: dict[str, dict[str, dict[str, float]]] = {}
    for set_name, targets in target_sets(robot, n, seed).items():
        out[set_name] = {}
        for name, solve in methods.items():
            results = [solve(t) for t in targets]
            ok = [r.pos_err_m <= 1e-3 and r.rot_err_rad <= np.deg2rad(1.0) for r in results]
            iters, times = [float(r.iters) for r in results], [r.time_s * 1e3 for r in results]
            out[set_name][name] = {
                "success": float(np.mean(ok)), "iters_median": pct(iters, 50), "iters_p99": pct(iters, 99),
                "ms_median": pct(times, 50), "ms_p99": pct(times, 99),
            }  # fmt: skip
    return out


def bench_step(robot: Robot, n: int, seed: int, collisions: bool,
               given: tuple[CollisionPairConfig, ...] | None = None) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    if given is not None:  # a task config's own pairs, with their distances
        configs, chosen = given, [(p.a, p.b) for p in given]
    else:
        chosen = pairs(robot)
        configs = tuple(CollisionPairConfig(a=a, b=b, min_distance=0.005, detection_distance=0.05) for a, b in chosen)
    cfg = IKConfig(velocity_limit=1.0, collision_pairs=configs if collisions else ())
    ours = QPIK(robot, cfg)
    model, dt = ours.model, 0.004
    config = mink.Configuration(model)
    tasks = [
        mink.FrameTask(f, robot.frame(f)[0], cfg.position_cost, cfg.orientation_cost, lm_damping=cfg.lm_damping)
        for f in wrists(robot)
    ]
    posture = mink.PostureTask(model, cost=cfg.posture_cost)
    posture.set_target(robot.keyframe_q("home"))
    groups = robot.collision_geoms()
    limits: list[mink.Limit] = [
        mink.ConfigurationLimit(model, gain=cfg.limit_gain),
        mink.VelocityLimit(model, {j: 1.0 for j in (model.joint(i).name for i in range(model.njnt))}),
    ]
    if collisions:  # mink's limit takes one minimum and detection distance: one limit per distinct pair of them
        by_distances: dict[tuple[float, float], list[tuple[list[int], list[int]]]] = {}
        for c in configs:
            by_distances.setdefault((c.min_distance, c.detection_distance), []).append(
                (list(groups[c.a]), list(groups[c.b])))
        for (dmin, ddet), geom_pairs in by_distances.items():
            limits.append(mink.CollisionAvoidanceLimit(model, geom_pairs, 0.85, dmin, ddet))
    home = robot.keyframe_q("home")
    kin = Kinematics(robot)
    ours_us, mink_us, active, queries = [], [], [], []
    # A control run: q moves at 1 rad/s (per joint, max) through random waypoints, one state per 4 ms tick;
    # the targets are the wrist poses at the next waypoint.
    q_prev = home
    targets: list[FrameTarget] = []
    states: list[tuple[np.ndarray, list[FrameTarget]]] = []
    while len(states) < n:
        goal = np.clip(home + rng.normal(0.0, 0.4, robot.nq), robot.lower, robot.upper)
        targets = [FrameTarget(f, pos=kin.fk(f, goal).pos, rot=kin.fk(f, goal).rot) for f in wrists(robot)]
        ticks = int(np.ceil(np.max(np.abs(goal - q_prev)) / (1.0 * dt)))
        states += [(q_prev + (goal - q_prev) * (k / ticks), targets) for k in range(1, ticks + 1)]
        q_prev = goal
    for q, targets in states[:n]:
        # Both sides are timed from the targets as the caller has them (position, rotation matrix) to the velocity.
        t0 = time.perf_counter()
        ours.step(q, targets, dt)
        t1 = time.perf_counter()
        for task, t in zip(tasks, targets, strict=True):
            assert t.rot is not None and t.pos is not None
            task.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(t.rot), t.pos))
        config.update(q)
        mink.solve_ik(config, [*tasks, posture], dt, "daqp", damping=cfg.damping, limits=limits)
        t2 = time.perf_counter()
        ours_us.append((t1 - t0) * 1e6)
        mink_us.append((t2 - t1) * 1e6)
        active.append(len(ours.collision.active) if ours.collision else 0)
        queries.append(ours.collision.queries if ours.collision else 0)
    return {
        "geom_pairs": float(ours.collision.num_pairs if ours.collision else 0),
        "active_rows_mean": float(np.mean(active)),
        "narrow_phase_queries_mean": float(np.mean(queries)),
        "ours_us_median": pct(ours_us, 50), "ours_us_p99": pct(ours_us, 99),
        "mink_us_median": pct(mink_us, 50), "mink_us_p99": pct(mink_us, 99),
        "ratio_median": pct(ours_us, 50) / pct(mink_us, 50), "ratio_p99": pct(ours_us, 99) / pct(mink_us, 99),
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--targets", type=int, default=1000, help="random reachable targets per set (default 1000)")
    parser.add_argument("--steps", type=int, default=2000, help="IK steps timed per case (default 2000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--scene", default="dock_dumbbell", help="scene (default dock_dumbbell)")
    parser.add_argument("--robot", default=None, help="robot file or bundled name (default: nextage)")
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON ('-' for stdout only)")
    parser.add_argument("--step-only", action="store_true", help="time the IK step only (skip the success sets)")
    parser.add_argument("--pairs-of", metavar="CONFIG", default=None,
                        help="also time the step with a task config's collision pairs (configs/dock_dumbbell.yaml)")
    args = parser.parse_args()
    robot = Robot.from_scene(args.scene, robot=args.robot)
    machine = {"platform": platform.platform(), "python": platform.python_version(), "cpu_count": os.cpu_count(),
               "processor": platform.processor() or platform.machine(),
               **{p: metadata.version(p) for p in ("mujoco", "mink", "qpsolvers", "daqp", "numpy")}}  # fmt: skip
    start = time.perf_counter()
    step = {"two_wrists_posture_limits": bench_step(robot, args.steps, args.seed, False),
            "plus_collision_pairs": bench_step(robot, args.steps, args.seed, True)}  # fmt: skip
    if args.pairs_of:
        from nextage_qp.manipulation.config import load_config

        task = load_config(args.pairs_of)
        step[f"pairs_of_{task.task}"] = bench_step(robot, args.steps, args.seed, True, task.ik.collision_pairs)
    success = {} if args.step_only else bench_success(robot, args.targets, args.seed)
    report = {"robot": robot.name, "machine": machine, "targets": args.targets, "seed": args.seed, "step": step,
              "success": success, "wall_s": time.perf_counter() - start}  # fmt: skip
    if args.json == "-":
        print(json.dumps(report, indent=2))
        return
    print(f"robot: {robot.name}; machine: {machine['platform']}, {machine['cpu_count']} CPUs, "
          f"Python {machine['python']}; "
          + ", ".join(f"{p} {machine[p]}" for p in ("mujoco", "mink", "qpsolvers", "daqp", "numpy")))
    if success:
        print(f"success at 1 mm / 1 deg on {args.targets} random reachable targets per set (seed {args.seed}), "
              "from home:")
        print(f"{'set':10} {'method':6} {'success':>8} {'iters med':>9} {'iters p99':>9} {'ms med':>8} {'ms p99':>8}")
    for set_name, methods in success.items():
        for name, r in methods.items():
            print(f"{set_name:10} {name:6} {r['success'] * 100:7.1f}% {r['iters_median']:9.0f} {r['iters_p99']:9.0f} "
                  f"{r['ms_median']:8.2f} {r['ms_p99']:8.2f}")  # fmt: skip
    print(f"IK step (two wrist poses + posture + limits, dt 4 ms), {args.steps} states, daqp:")
    for case, r in step.items():
        print(f"  {case:26} pairs {r['geom_pairs']:4.0f} (queries {r['narrow_phase_queries_mean']:.1f}, rows "
              f"{r['active_rows_mean']:.1f}) ours "
              f"{r['ours_us_median']:.0f} us p99 {r['ours_us_p99']:.0f} us | mink.solve_ik median "
              f"{r['mink_us_median']:.0f} us p99 {r['mink_us_p99']:.0f} us | ratio median {r['ratio_median']:.2f}, "
              f"p99 {r['ratio_p99']:.2f}")
    print(f"wall time {report['wall_s']:.0f} s")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=2)


if __name__ == "__main__":
    main()
