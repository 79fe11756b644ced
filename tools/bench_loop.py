"""Benchmark of the control loop: real-time factor and per-tick cost of IK, Ruckig, PD and physics.

Measured in one run on one core:

* bare physics: ``mj_step`` on the same scene with a constant gravity-holding torque (the ceiling);
* the full loop (``nextage-qp reach``'s pipeline: QP IK -> Ruckig -> PD at every physics step -> MuJoCo,
  with recording) on reach motions of the left wrist, as simulated seconds per wall second;
* an instrumented copy of the same loop, timing each stage separately (median and p99 per call).

Example: ``.venv/bin/python tools/bench_loop.py --repeats 3 --json``
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from importlib import metadata  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from nextage_qp.commands.reach import run_reach  # noqa: E402
from nextage_qp.control import load_gains  # noqa: E402
from nextage_qp.ik import QPIK, FrameTarget, IKConfig  # noqa: E402
from nextage_qp.robot import Robot  # noqa: E402
from nextage_qp.sim import Simulation  # noqa: E402

TARGETS = [(0.45, 0.25, 1.05), (0.40, 0.15, 1.00), (0.50, 0.30, 1.10), (0.35, 0.20, 0.98), (0.55, 0.10, 1.05)]


def machine() -> dict[str, object]:
    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), cpu)
    except OSError:
        pass
    versions = {p: metadata.version(p) for p in ("mujoco", "ruckig", "numpy", "mink", "qpsolvers", "daqp")}
    return {"cpu": cpu, "logical_cpus": os.cpu_count(), "python": platform.python_version(),
            "platform": platform.platform(), **versions}


def bare_rtf(scene: str, seconds: float) -> float:
    robot = Robot.from_scene(scene)
    m, d = robot.model, mujoco.MjData(robot.model)
    robot.set_q(d, robot.keyframe_q())
    mujoco.mj_forward(m, d)
    d.ctrl[robot.actuator_ids] = d.qfrc_bias[robot.dof_idx]  # constant gravity hold, so the arms do not fall
    n = round(seconds / m.opt.timestep)
    t0 = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(m, d)
    return seconds / (time.perf_counter() - t0)


def loop_rtf(scene: str, duration: float, repeats: int) -> tuple[list[float], list[float]]:
    robot, gains = Robot.from_scene(scene), load_gains("default")
    rtfs, errors = [], []
    for k in range(repeats):
        pos = np.array(TARGETS[k % len(TARGETS)])
        t0 = time.perf_counter()
        res, _ = run_reach(robot, "left_wrist", pos, gains=gains, duration=duration)
        rtfs.append(duration / (time.perf_counter() - t0))
        errors.append(res.final_error_m)
    return rtfs, errors


def stage_costs(scene: str, duration: float) -> dict[str, dict[str, float]]:
    """Per-call wall time [us] of each stage, from an instrumented copy of ``Simulation.tick``."""
    robot, gains = Robot.from_scene(scene), load_gains("default")
    sim = Simulation(robot, gains, frames=("left_wrist",))
    ik = QPIK(robot, IKConfig())
    m, d, qi, di, ai = sim.model, sim.data, robot.qpos_idx, robot.dof_idx, robot.actuator_ids
    q_cmd = robot.keyframe_q()
    sim.reset(q_cmd)
    target = [FrameTarget(frame="left_wrist", pos=np.array(TARGETS[0]))]
    cost: dict[str, list[float]] = {"ik": [], "ruckig": [], "pd": [], "physics": [], "record": []}
    clock = time.perf_counter
    for _ in range(round(duration / sim.ctrl_dt)):
        t0 = clock()
        v = ik.step(q_cmd, target, sim.ctrl_dt)
        q_cmd = np.clip(q_cmd + v * sim.ctrl_dt, robot.lower, robot.upper)
        t1 = clock()
        sim.traj.set_target(q_cmd)
        sim.traj.update()
        refs = [sim.traj.interpolate(k * sim.sim_dt) for k in range(sim.n_substeps)]
        t2 = clock()
        cost["ik"].append(t1 - t0)
        cost["ruckig"].append(t2 - t1)
        for ref in refs:
            a = clock()
            mujoco.mj_step1(m, d)
            b = clock()
            q, qd = d.qpos[qi], d.qvel[di]
            tau = sim.pd.torque(q, qd, ref.q, ref.qd, d.qfrc_bias[di])
            d.ctrl[ai] = tau
            c = clock()
            sim.recorder.record(sim.time, q, qd, ref.q, ref.qd, tau, sim._frame_poses(), sim._object_poses())
            e = clock()
            mujoco.mj_step2(m, d)
            f = clock()
            sim._step += 1
            cost["physics"].append((b - a) + (f - e))
            cost["pd"].append(c - b)
            cost["record"].append(e - c)
    return {k: {"median_us": float(np.median(v) * 1e6), "p99_us": float(np.percentile(v, 99) * 1e6), "calls": len(v)}
            for k, v in cost.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="scene", help="bundled scene or MJCF path (default: scene)")
    parser.add_argument("--duration", type=float, default=3.0, help="simulated seconds per reach (default 3)")
    parser.add_argument("--repeats", type=int, default=5, help="reach runs for the loop RTF (default 5)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    bare = [bare_rtf(args.scene, args.duration) for _ in range(3)]
    rtfs, errors = loop_rtf(args.scene, args.duration, args.repeats)
    stages = stage_costs(args.scene, args.duration)
    out = {
        "machine": machine(),
        "scene": args.scene,
        "sim_dt_s": 0.001,
        "ctrl_dt_s": 0.004,
        "bare_mj_step_rtf_median": float(np.median(bare)),
        "loop_rtf_median": float(np.median(rtfs)),
        "loop_rtf_min": float(np.min(rtfs)),
        "loop_over_bare_ratio": float(np.median(rtfs) / np.median(bare)),
        "reach_final_error_m_max": float(np.max(errors)),
        "per_call_us": stages,
    }
    if args.json:
        print(json.dumps(out, indent=2))
        return
    for key, value in out["machine"].items():
        print(f"{key:14s} {value}")
    print(f"\nscene {args.scene}, sim_dt 1 ms, ctrl_dt 4 ms (IK + Ruckig at 250 Hz, PD at 1 kHz)")
    print(f"bare mj_step loop      RTF {out['bare_mj_step_rtf_median']:7.1f}x")
    print(f"full loop (reach)      RTF {out['loop_rtf_median']:7.1f}x  (min {out['loop_rtf_min']:.1f}x, "
          f"{out['loop_over_bare_ratio']:.2f} of bare)")
    print(f"reach final error max  {out['reach_final_error_m_max'] * 1e3:.4f} mm\n")
    print(f"{'stage':10s} {'per':>6s} {'median us':>10s} {'p99 us':>9s}")
    for name, s in stages.items():
        per = "tick" if name in ("ik", "ruckig") else "step"
        print(f"{name:10s} {per:>6s} {s['median_us']:10.1f} {s['p99_us']:9.1f}")


if __name__ == "__main__":
    main()
