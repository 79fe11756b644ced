"""Benchmark of the control loop: real-time factor and per-tick cost of IK, Ruckig, PD and physics.

Measured in one run on one core:

* bare physics: ``mj_step`` on the same scene with a constant gravity-holding torque (the ceiling);
* the full loop (``nextage-qp reach``'s pipeline: the servo tick's QP IK -> Ruckig -> PD at every physics step
  -> MuJoCo, with recording) on reach motions of the left wrist, as simulated seconds per wall second;
* a tick's 20 physics steps as the simulation's compiled loop, as the Python loop and as ``mj_step(nstep=20)``
  from the same state, alternately (the compiled loop's own work, which the physics share counts as physics);
* the same loop with the simulation's stage timer on, timing the servo (IK) and each stage of the real
  ``Simulation.tick`` separately (median and p99 per call);
* with ``--task CONFIG``, the physics share of a whole task run at the config's own settings (the wall time
  spent inside ``mj_step``, every call timed where the simulation makes it, over the run's wall time), and the
  same stage profile of that run (the manipulation runner), plus the time
  between ticks, where the phase computes its next command and may plan offline (``phase+plan``); ``--set``
  overrides keys of those configs (e.g. ``--set timing.ctrl_dt=0.01``); and the ceilings this profile puts on
  the run's ratio to bare physics (its own physics alone, and physics plus IK).

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

from nextage_qp.experiments.reach import run_reach  # noqa: E402
from nextage_qp.ik import QPIK, FrameTarget, IKConfig  # noqa: E402
from nextage_qp.loop import stepping  # noqa: E402
from nextage_qp.loop.pd import load_gains  # noqa: E402
from nextage_qp.loop.servo import Command, Servo  # noqa: E402
from nextage_qp.loop.simulation import Simulation, StageTimer  # noqa: E402
from nextage_qp.manipulation.config import load_config  # noqa: E402
from nextage_qp.manipulation.runner import Runner  # noqa: E402
from nextage_qp.robots.model import Robot  # noqa: E402

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


def stepping_overhead(scene: str, n: int = 20, repeats: int = 300) -> dict[str, dict[str, float]]:
    """A tick's ``n`` physics steps three ways, alternately, from the same state: the compiled loop the simulation
    runs (controls set and forces kept every step), the Python loop it falls back to, and ``mj_step(m, d, nstep=n)``
    (MuJoCo's own loop, one control for all steps: what the compiled loop's own work is measured against)."""
    robot = Robot.from_scene(scene)
    sim = Simulation(robot, load_gains("default"))
    m, d = sim.model, sim.data
    start = mujoco.MjData(m)
    mujoco.mj_copyData(start, m, d)
    ctrl, act_force = sim._act.ctrl, sim._act.force
    ramp, force = np.repeat(ctrl[None, :].copy(), n, axis=0), np.zeros((n, ctrl.size))

    def python_loop() -> None:
        for k in range(n):
            ctrl[:] = ramp[k]
            mujoco.mj_step(m, d)
            force[k] = act_force

    ways = {"compiled loop": lambda: stepping.substeps(stepping.STEP, m._address, d._address, ctrl, ramp, act_force,
                                                       force, d.sensordata, -1),
            "python loop": python_loop, "mj_step nstep": lambda: mujoco.mj_step(m, d, nstep=n)}
    samples: dict[str, list[float]] = {k: [] for k in ways}
    for _ in range(repeats):
        for name, way in ways.items():
            mujoco.mj_copyData(d, m, start)
            t0 = time.perf_counter()
            way()
            samples[name].append(time.perf_counter() - t0)
    return _stats(samples)


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


def _stats(samples: dict[str, list[float]]) -> dict[str, dict[str, float]]:
    return {k: {"median_us": float(np.median(v) * 1e6), "p99_us": float(np.percentile(v, 99) * 1e6),
                "mean_us": float(np.mean(v) * 1e6), "calls": len(v)} for k, v in samples.items()}


def stage_costs(scene: str, duration: float) -> dict[str, dict[str, float]]:
    """Per-call wall time [us] of the servo tick (IK) and of each stage of the real ``Simulation.tick``."""
    robot, gains = Robot.from_scene(scene), load_gains("default")
    sim = Simulation(robot, gains, frames=("left_wrist",))
    q0 = robot.keyframe_q()
    sim.reset(q0)
    servo = Servo(QPIK(robot, IKConfig()), sim, q0)
    command = Command((FrameTarget(frame="left_wrist", pos=np.array(TARGETS[0])),))
    sim.timer = timer = StageTimer()
    clock = time.perf_counter
    servo_s = []
    for _ in range(round(duration / sim.ctrl_dt)):
        t0 = clock()
        servo.step(command)
        servo_s.append(clock() - t0)
        sim.tick()
    return _stats({"servo (ik)": servo_s, **timer.samples})


def task_costs(config: str, sets: list[str]) -> tuple[dict[str, dict[str, float]], float]:
    """Stage profile of a whole task run, and its real-time factor (the runner's servo timed per tick)."""
    runner = Runner(load_config(config, sets), config)
    runner.sim.timer = timer = StageTimer()
    servo_s: list[float] = []
    step = runner.servo.step

    def timed_step(*args, **kwargs):  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        out = step(*args, **kwargs)
        servo_s.append(time.perf_counter() - t0)
        return out

    runner.servo.step = timed_step  # type: ignore[method-assign]
    # Between two ticks the runner's phase decides the next command (and may plan offline): timed as the gap.
    between: list[float] = []
    last_end: list[float] = []
    tick = runner.tick

    def timed_tick(command):  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        if last_end:
            between.append(t0 - last_end[0])
        tick(command)
        last_end[:] = [time.perf_counter()]

    runner.tick = timed_tick  # type: ignore[method-assign]
    last_end[:] = [time.perf_counter()]  # the first phase's start (and its planning) counts too
    result = runner.run()
    stats = _stats({"servo (ik)": servo_s, **timer.samples, "phase+plan": between})
    return stats, float(result["real_time_factor"] or 0.0)


def ceilings(stages: dict[str, dict[str, float]], bare_rtf: float, sim_dt: float, ctrl_dt: float) -> dict[str, float]:
    """What bounds a task run's ratio to bare physics, from its stage profile (means per tick).

    ``physics_only``: the ratio if nothing but the task's own ``mj_step`` calls ran (its states, with the arm
    moving and in contact, cost more than the bare loop's); ``physics_and_ik``: with the IK step added too.
    """
    bare_step_us = sim_dt * 1e6 / bare_rtf
    physics_us, ik_us = stages["physics"]["mean_us"], stages["servo (ik)"]["mean_us"]
    task_step_us = physics_us * sim_dt / ctrl_dt
    return {"bare_step_us": bare_step_us, "task_step_us": task_step_us,
            "physics_only": bare_step_us / task_step_us,
            "physics_and_ik": ctrl_dt * 1e6 / (physics_us + ik_us) / bare_rtf}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="scene", help="bundled scene or MJCF path (default: scene)")
    parser.add_argument("--duration", type=float, default=3.0, help="simulated seconds per reach (default 3)")
    parser.add_argument("--repeats", type=int, default=5, help="reach runs for the loop RTF (default 5)")
    parser.add_argument("--task", action="append", default=[], metavar="CONFIG",
                        help="also profile a whole task run of this config (repeatable)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a key of every --task config, e.g. --set timing.ctrl_dt=0.01 (repeatable)")
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
        "physics_steps_of_a_tick_us": stepping_overhead(args.scene) if stepping.NATIVE else None,
        "tasks": {},
    }
    for config in args.task:
        cfg = load_config(config, args.overrides)
        scene = str(cfg.scene.file)
        task_bare = float(np.median([bare_rtf(scene, args.duration) for _ in range(3)]))
        result = Runner(cfg, config).run()  # no stage timer
        plain, share = float(result["real_time_factor"] or 0.0), float(result["physics_share"] or 0.0)
        task_stages, timed = task_costs(config, args.overrides)
        out["tasks"][config] = {"scene": scene, "set": args.overrides, "ctrl_dt_s": cfg.timing.ctrl_dt,
                                "bare_mj_step_rtf_median": task_bare, "real_time_factor": plain,
                                "physics_share": share, "success": bool(result["success"]),
                                "task_over_bare_ratio": plain / task_bare, "real_time_factor_with_timer": timed,
                                "per_call_us": task_stages,
                                "ceilings": ceilings(task_stages, task_bare, cfg.timing.sim_dt, cfg.timing.ctrl_dt)}
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
    _print_stages(stages)
    steps = out["physics_steps_of_a_tick_us"]
    if steps:
        print("\n20 physics steps from the same state, alternately (the compiled loop's own work against MuJoCo's)")
        _print_stages(steps)
        ratio = steps["compiled loop"]["median_us"] / steps["mj_step nstep"]["median_us"]
        print(f"compiled loop / mj_step nstep: {ratio:.3f} (median)")
    for config, task in out["tasks"].items():
        sets = "".join(f" --set {item}" for item in task["set"])
        print(f"\ntask {config}{sets} (ctrl_dt {task['ctrl_dt_s'] * 1e3:g} ms): RTF {task['real_time_factor']:.1f}x; "
              f"bare mj_step on its scene "
              f"({task['scene']}) {task['bare_mj_step_rtf_median']:.1f}x; ratio {task['task_over_bare_ratio']:.3f} "
              f"(stage-timed run: {task['real_time_factor_with_timer']:.1f}x)")
        print(f"physics share: {task['physics_share']:.3f} of the run's wall time inside mj_step (every call timed "
              f"where it is made; success {task['success']})")
        _print_stages(task["per_call_us"])
        c = task["ceilings"]
        print(f"ceilings: its own physics alone {c['task_step_us']:.1f} us per mj_step against {c['bare_step_us']:.1f} "
              f"bare -> ratio {c['physics_only']:.2f} at most; physics + IK alone -> {c['physics_and_ik']:.2f}")


def _print_stages(stages: dict[str, dict[str, float]]) -> None:
    print(f"{'stage':14s} {'calls':>8s} {'median us':>10s} {'p99 us':>9s} {'mean us':>9s}")
    for name, s in stages.items():
        print(f"{name:14s} {s['calls']:8d} {s['median_us']:10.1f} {s['p99_us']:9.1f} {s['mean_us']:9.1f}")


if __name__ == "__main__":
    main()
