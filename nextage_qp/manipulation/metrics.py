"""Outcome of a run: safety metrics while it runs, a record per phase, and the result summary (``run --json``).

Metrics are measured on the simulator's truth (contacts, true poses), never on what the controller sees.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from nextage_qp.manipulation.context import Grip
from nextage_qp.robot import Robot
from nextage_qp.sim import Simulation


@dataclass
class PhaseRecord:
    """Outcome of one phase: name, kind, status (done / failed / skipped / running), start and duration [s]."""

    name: str
    kind: str
    status: str = "skipped"
    start_s: float = 0.0
    duration_s: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """The record as it appears in the result's ``phases`` list."""
        return {"name": self.name, "kind": self.kind, "status": self.status, "start_s": round(self.start_s, 3),
                "duration_s": round(self.duration_s, 3), **self.info}


class OutcomeMonitor:
    """Safety metrics over a run: obstacle clearance and contacts, and whether a clamped object was dropped.

    A clamped object counts as dropped when the midpoint of the clamp pads is more than ``drop_distance`` [m]
    from where the grasp put it in the object's frame.

    Args:
        robot: The robot and scene.
        obj: The run's object.
        drop_distance: Drop threshold [m].
    """

    def __init__(self, robot: Robot, obj: str, drop_distance: float = 0.03) -> None:
        m = robot.model
        self.robot, self.model, self.obj, self.drop_distance = robot, m, obj, drop_distance
        groups = robot.collision_geoms()
        self.obstacle = groups.get("obstacle")
        self._is_obstacle = np.zeros(m.ngeom, dtype=bool)
        self._is_obstacle[list(self.obstacle or ())] = True
        self.movers = tuple(g for k in ("left_arm", "right_arm", "torso", "head", obj) for g in groups.get(k, ()))
        self.min_clearance: float | None = None
        self.obstacle_contacts = 0
        self.dropped = False
        self._fromto = np.zeros(6)

    def attach(self, sim: Simulation) -> None:
        """Register the monitor's hooks with a simulation (the contact hook only when there is an obstacle)."""
        sim.hooks.append(self.on_tick)
        if self.obstacle is not None:
            sim.substep_hooks.append(self.on_substep)

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

    def check_hold(self, sim: Simulation, grip: Grip) -> None:
        """Flag a drop when the clamped object is far from the midpoint of the clamp pads (true poses)."""
        if len(grip.frames) < 2:
            return
        d = sim.data
        mid = np.zeros(3)
        for f in grip.frames[:2]:
            kind, fid = self.robot.frame(f)
            mid += 0.5 * (d.site_xpos[fid] if kind == "site" else d.xpos[fid])
        bid = self.model.body(grip.object).id
        rot = d.xmat[bid].reshape(3, 3)
        expected = d.xpos[bid] + rot @ np.mean([grip.offsets[p] for p in grip.frames[:2]], axis=0)
        if np.linalg.norm(mid - expected) > self.drop_distance:
            self.dropped = True


def summarize(
    *,
    task: str,
    robot: Robot,
    sim: Simulation,
    monitor: OutcomeMonitor,
    records: list[PhaseRecord],
    obj: str,
    target: str,
    success_threshold: float,
    error: str | None,
    wall_s: float,
) -> dict[str, Any]:
    """The result record printed by ``nextage-qp run --json``; ``success`` only when every criterion holds."""
    d = sim.data
    obj_pos = d.xpos[robot.model.body(obj).id].copy()
    tgt_pos = d.xpos[robot.model.body(target).id].copy()
    err = float(np.linalg.norm(obj_pos - tgt_pos))
    rec = sim.recorder.arrays()
    q = rec["q"]
    viol = int(np.count_nonzero(np.any((q < robot.lower - 1e-3) | (q > robot.upper + 1e-3), axis=1)))
    tau = np.abs(rec["tau"]).max() if len(q) else 0.0
    sim_t = sim.time
    criteria: dict[str, dict[str, Any]] = {
        "completed": {"ok": error is None},
        "object_error": {"value": err, "limit": success_threshold, "ok": err <= success_threshold},
        "not_dropped": {"ok": not monitor.dropped},
    }
    return {
        "task": task,
        "success": all(c["ok"] for c in criteria.values()),
        "failed_criteria": [name for name, c in criteria.items() if not c["ok"]],
        "object_error_m": err,
        "object_error_xy_m": float(np.linalg.norm((obj_pos - tgt_pos)[:2])),
        "final_object_position": obj_pos.tolist(),
        "target_position": tgt_pos.tolist(),
        "sim_time_s": sim_t,
        "wall_time_s": wall_s,
        "real_time_factor": sim_t / wall_s if wall_s > 0 else None,
        "min_obstacle_clearance_m": monitor.min_clearance,
        "obstacle_contacts": monitor.obstacle_contacts if monitor.obstacle is not None else 0,
        "object_dropped": monitor.dropped,
        "joint_limit_violations": viol,
        "max_abs_torque_nm": float(tau),
        "torque_saturation_ticks": int(sim.pd.any_saturated_ticks),
        "phases": [r.as_dict() for r in records],
        "criteria": criteria,
        "error": error,
    }
