r"""Execute a manipulation config: phases -> QP IK -> Ruckig -> PD -> MuJoCo, with outcome metrics.

Each control tick the current phase turns live poses into frame targets, one QP IK step integrates the
commanded joints :math:`q_{cmd} \leftarrow q_{cmd} + v\,\Delta t_{ctrl}`, Ruckig re-targets to
:math:`q_{cmd}` and the PD loop tracks the reference at every physics step.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from nextage_qp.control import load_gains
from nextage_qp.errors import ConfigError, NextageQPError, PhaseError, UnknownNameError
from nextage_qp.ik import QPIK
from nextage_qp.manipulation.config import ManipulationConfig
from nextage_qp.manipulation.context import RunContext
from nextage_qp.manipulation.phases import RUNNERS, PhaseRunner
from nextage_qp.robot import JOINT_NAMES, Robot
from nextage_qp.scene import BodyPose, SceneOverrides
from nextage_qp.sim import Simulation

TickCallback = Callable[["Runner", PhaseRunner | None], None]


def build_robot(cfg: ManipulationConfig, source: str) -> Robot:
    """Compile the config's scene with its pose and mass overrides, and check every name it uses.

    Raises:
        ConfigError: A body, frame or object named in the config is not in the scene (the message names
            the dotted key and the valid names).
    """
    poses = {name: BodyPose(pos=p.pos, yaw=p.yaw) for name, p in cfg.scene.poses.items()}
    try:
        overrides = SceneOverrides(poses=poses, masses=dict(cfg.scene.masses),
                                   friction_scale=dict(cfg.scene.friction_scale))
        robot = Robot.from_scene(cfg.scene.file, overrides)
    except UnknownNameError as exc:
        raise ConfigError(f"{source}: scene: {exc}") from None
    _check_names(cfg, robot, source)
    return robot


def _check_names(cfg: ManipulationConfig, robot: Robot, source: str) -> None:
    bodies, frames, objects = set(robot.body_names), set(robot.frame_names), robot.object_names

    def need(ok: bool, key: str, value: str, valid: Any) -> None:
        if not ok:
            raise ConfigError(f"{source}: {key}: {value!r} is not valid; valid: {', '.join(valid)}")

    need(cfg.object in objects, "object", cfg.object, objects)
    need(cfg.target in bodies, "target", cfg.target, sorted(bodies))
    for i, phase in enumerate(cfg.phases):
        ph: Any = phase
        key = f"phases[{i}]"
        if isinstance(getattr(ph, "frame", None), str):
            need(ph.frame in frames, f"{key}.frame", ph.frame, robot.site_names)
        for j, f in enumerate(getattr(ph, "frames", None) or ()):
            need(f in frames, f"{key}.frames[{j}]", f, robot.site_names)
        for t, spec in enumerate(getattr(ph, "targets", None) or []):
            need(spec.frame in frames, f"{key}.targets[{t}].frame", spec.frame, robot.site_names)
            need(spec.relative_to in bodies | {"world"}, f"{key}.targets[{t}].relative_to", spec.relative_to,
                 ["world", *sorted(bodies)])
        for w, wp in enumerate(getattr(ph, "waypoints", None) or []):
            need(wp.relative_to in bodies | {"world"}, f"{key}.waypoints[{w}].relative_to", wp.relative_to,
                 ["world", *sorted(bodies)])
        if getattr(ph, "object", None) is not None:
            need(ph.object in objects, f"{key}.object", ph.object, objects)
        if getattr(ph, "target", None) is not None:
            need(ph.target in bodies, f"{key}.target", ph.target, sorted(bodies))
        for joint in getattr(ph, "positions", None) or {}:
            need(joint in JOINT_NAMES, f"{key}.positions", joint, JOINT_NAMES)


@dataclass
class PhaseRecord:
    """Outcome of one phase: name, kind, status (done / failed / skipped), start and duration [s]."""

    name: str
    kind: str
    status: str = "skipped"
    start_s: float = 0.0
    duration_s: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)


class Runner:
    """Runs one :class:`ManipulationConfig` and measures the outcome.

    Args:
        cfg: The validated config.
        source: Where it came from (for messages).
        robot: A robot built from the config (default: :func:`build_robot`).
    """

    def __init__(self, cfg: ManipulationConfig, source: str = "<config>", robot: Robot | None = None) -> None:
        self.cfg, self.source = cfg, source
        self.robot = robot or build_robot(cfg, source)
        try:
            gains = load_gains(cfg.gains)
            self.ik = QPIK(self.robot, cfg.ik)
        except UnknownNameError as exc:
            raise ConfigError(f"{source}: ik: {exc}") from None
        frames = [f for f in ("left_tool", "right_tool", "left_pad", "right_pad") if f in self.robot.site_names]
        self.sim = Simulation(self.robot, gains, cfg.trajectory, sim_dt=cfg.timing.sim_dt, ctrl_dt=cfg.timing.ctrl_dt,
                              frames=frames)
        q0 = self.robot.keyframe_q(cfg.start)
        self.sim.reset(q0)
        self.ctx = RunContext(self.robot, self.sim, self.ik, q0.copy())
        self.records = [PhaseRecord(cfg.phase_name(i), p.kind) for i, p in enumerate(cfg.phases)]
        self.metrics = OutcomeMonitor(self.robot, cfg.object)
        self.sim.hooks.append(self.metrics.on_tick)
        if self.metrics.obstacle is not None:
            self.sim.substep_hooks.append(self.metrics.on_substep)
        self.error: str | None = None
        self.wall_s = 0.0
        self.current: PhaseRunner | None = None

    def _object_poses(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        d = self.sim.data
        return {name: (d.qpos[s][:3], d.qpos[s][3:7]) for name, s in self.sim.objects}

    def tick(self, phase: PhaseRunner | None) -> bool:
        """One control tick of ``phase`` (or a hold when None); returns the phase's done flag."""
        ctx, done = self.ctx, False
        targets = None
        if phase is not None:
            targets, done = phase.update(ctx)
        if targets is not None:
            v = self.ik.step(ctx.q_cmd, targets, ctx.dt, extra_tasks=ctx.extra_tasks, object_poses=self._object_poses())
            ctx.q_cmd = np.clip(ctx.q_cmd + v * ctx.dt, self.robot.lower, self.robot.upper)
        self.sim.set_target(ctx.q_cmd)
        self.sim.tick()
        self.metrics.holding = ctx.holding
        if ctx.holding is not None:
            self.metrics.check_hold(ctx)
        return done

    def run(self, on_tick: TickCallback | None = None) -> dict[str, Any]:
        """Run every phase, then settle; returns the result summary (also on failure, with ``error``)."""
        wall0 = time.perf_counter()
        try:
            for i, pcfg in enumerate(self.cfg.phases):
                rec = self.records[i]
                phase = RUNNERS[pcfg.kind](pcfg, rec.name)
                self.current = phase
                rec.start_s, rec.status = self.sim.time, "running"
                phase.start(self.ctx)
                while True:
                    done = self.tick(phase)
                    if on_tick:
                        on_tick(self, phase)
                    if done:
                        break
                    if self.sim.time - rec.start_s > pcfg.timeout:
                        rec.status, rec.info = "failed", dict(phase.info)
                        raise PhaseError(f"phase {rec.name!r} ({pcfg.kind}) timed out after {pcfg.timeout:g} s "
                                         f"of simulated time; last state: {_brief(phase.info)}")
                rec.status, rec.duration_s, rec.info = "done", self.sim.time - rec.start_s, dict(phase.info)
            self.current = None
            end = self.sim.time + self.cfg.timing.settle
            while self.sim.time < end:
                self.tick(None)
                if on_tick:
                    on_tick(self, None)
        except NextageQPError as exc:
            self.error = str(exc)
            for rec in self.records:
                if rec.status == "running":
                    rec.status, rec.duration_s = "failed", self.sim.time - rec.start_s
        finally:
            self.wall_s = time.perf_counter() - wall0
        return self.summary()

    def summary(self) -> dict[str, Any]:
        """The result record printed by ``nextage-qp run --json``."""
        obj, _ = self.ctx.body_pose(self.cfg.object)
        tgt, _ = self.ctx.body_pose(self.cfg.target)
        err = float(np.linalg.norm(obj - tgt))
        rec = self.sim.recorder.arrays()
        q = rec["q"]
        viol = int(np.count_nonzero(np.any((q < self.robot.lower - 1e-3) | (q > self.robot.upper + 1e-3), axis=1)))
        tau = np.abs(rec["tau"]).max() if len(q) else 0.0
        m = self.metrics
        sim_t = self.sim.time
        criteria: dict[str, dict[str, Any]] = {
            "completed": {"ok": self.error is None},
            "object_error": {"value": err, "limit": self.cfg.success_threshold,
                             "ok": err <= self.cfg.success_threshold},
            "not_dropped": {"ok": not m.dropped},
        }
        return {
            "task": self.cfg.task,
            "success": all(c["ok"] for c in criteria.values()),
            "failed_criteria": [name for name, c in criteria.items() if not c["ok"]],
            "object_error_m": err,
            "object_error_xy_m": float(np.linalg.norm((obj - tgt)[:2])),
            "final_object_position": obj.tolist(),
            "target_position": tgt.tolist(),
            "sim_time_s": sim_t,
            "wall_time_s": self.wall_s,
            "real_time_factor": sim_t / self.wall_s if self.wall_s > 0 else None,
            "min_obstacle_clearance_m": m.min_clearance,
            "obstacle_contacts": m.obstacle_contacts if m.obstacle is not None else 0,
            "object_dropped": m.dropped,
            "joint_limit_violations": viol,
            "max_abs_torque_nm": float(tau),
            "torque_saturation_ticks": int(self.sim.pd.any_saturated_ticks),
            "phases": [{"name": r.name, "kind": r.kind, "status": r.status, "start_s": round(r.start_s, 3),
                        "duration_s": round(r.duration_s, 3), **r.info} for r in self.records],
            "criteria": criteria,
            "error": self.error,
        }


def _brief(info: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in info.items()) or "n/a"


class OutcomeMonitor:
    """Per-tick safety metrics: obstacle clearance and contacts, and whether a held object was dropped.

    A held object counts as dropped when the midpoint of the clamp pads is more than ``drop_distance`` [m]
    from where the grasp put it in the object's frame.
    """

    def __init__(self, robot: Robot, obj: str, drop_distance: float = 0.03) -> None:
        m = robot.model
        self.model, self.obj, self.drop_distance = m, obj, drop_distance
        groups = robot.collision_geoms()
        self.obstacle = groups.get("obstacle")
        self._is_obstacle = np.zeros(m.ngeom, dtype=bool)
        self._is_obstacle[list(self.obstacle or ())] = True
        self.movers = tuple(g for k in ("left_arm", "right_arm", "torso", "head", obj) for g in groups.get(k, ()))
        self.min_clearance: float | None = None
        self.obstacle_contacts = 0
        self.dropped = False
        self.holding: str | None = None
        self._fromto = np.zeros(6)

    def on_substep(self, sim: Simulation) -> None:
        """Hook run at every physics step: count the steps in which anything touches the obstacle."""
        d = sim.data
        if self.obstacle is None or d.ncon == 0:
            return
        geoms = d.contact.geom[: d.ncon]
        touching = self._is_obstacle[geoms]
        if np.any((touching[:, 0] != touching[:, 1]) & (d.contact.dist[: d.ncon] < 0)):
            self.obstacle_contacts += 1

    def on_tick(self, sim: Simulation) -> None:
        """Hook run by the simulation after every control tick: minimum clearance to the obstacle."""
        if self.obstacle is None:
            return
        d, m = sim.data, self.model
        best = self.min_clearance if self.min_clearance is not None else 1.0
        for og in self.obstacle:
            for g in self.movers:
                gap = np.linalg.norm(d.geom_xpos[og] - d.geom_xpos[g]) - m.geom_rbound[og] - m.geom_rbound[g]
                if gap > best:
                    continue
                best = min(best, float(mujoco.mj_geomDistance(m, d, og, g, best, self._fromto)))
        self.min_clearance = best

    def check_hold(self, ctx: RunContext) -> None:
        """Flag a drop when the held object is far from the midpoint of the clamp pads."""
        pads = list(ctx.grasp_offsets)
        if len(pads) < 2:
            return
        mid = 0.5 * (ctx.frame_pose(pads[0])[0] + ctx.frame_pose(pads[1])[0])
        obj, rot = ctx.body_pose(ctx.holding or self.obj)
        expected = obj + rot @ np.mean([ctx.grasp_offsets[p] for p in pads], axis=0)
        if np.linalg.norm(mid - expected) > self.drop_distance:
            self.dropped = True
