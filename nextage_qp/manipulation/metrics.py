"""Outcome of a run: safety metrics while it runs, a record per phase, and the result summary (``run --json``).

Metrics are measured on the simulator's truth (contacts, true poses), never on what the controller sees.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import mujoco
import numpy as np

from nextage_qp.geometry import wrap
from nextage_qp.loop.diagnosis import limit_violation
from nextage_qp.loop.simulation import Simulation
from nextage_qp.manipulation.config import SuccessCriteria
from nextage_qp.manipulation.context import Grip
from nextage_qp.manipulation.placement import obstacle_clearance
from nextage_qp.native import kernels
from nextage_qp.robots.model import CLUTTER_GROUP, Robot
from nextage_qp.scene.files import touch_sensor

LIMIT_TOLERANCE = 1e-3
"""A joint this far [rad or m] past an end of its range counts as violating its limit."""


@dataclass
class PhaseRecord:
    """Outcome of one phase: name, kind, status (done / failed / skipped / running), start, duration and timeout [s].

    ``budget_s``: the budget a timeout the spec does not give was derived from (:meth:`Phase.budget`), else None.
    """

    name: str
    kind: str
    status: str = "skipped"
    start_s: float = 0.0
    duration_s: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)
    timeout_s: float | None = None
    budget_s: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """The record as it appears in the result's ``phases`` list."""
        return {"name": self.name, "kind": self.kind, "status": self.status, "start_s": round(self.start_s, 3),
                "duration_s": round(self.duration_s, 3),
                **({} if self.timeout_s is None else {"timeout_s": round(self.timeout_s, 1)}),
                **({} if self.budget_s is None else {"budget_s": round(self.budget_s, 1)}), **self.info}


CONTACT_WATCH = 0.02
"""Obstacle clearance [m] below which every physics step is checked for contact, at the least (farther, none can
occur within one control period: that would take 5 m/s at 250 Hz)."""
CONTACT_WATCH_SPEED = 2.0
"""Speed [m/s] no point of the robot or a held object reaches: at slower control rates the clearance watched is
this speed times the control period, where that is more than :data:`CONTACT_WATCH`."""


class OutcomeMonitor:
    """Safety metrics over a run: obstacle clearance and contacts, and whether a clamped object was dropped.

    A clamped object counts as dropped when the midpoint of the clamp pads is more than ``drop_distance`` [m] from where
    it was in the object's frame when the grip was made (true poses, not the grip's offsets from an estimate).

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
        self.movers = tuple(sorted({g for k in (*robot.robot_groups, obj) for g in groups.get(k, ())}))
        pairs = np.array([(og, g) for og in (self.obstacle or ()) for g in self.movers], dtype=int).reshape(-1, 2)
        self._pair1, self._pair2 = pairs[:, 0].copy(), pairs[:, 1].copy()
        self._pair_rsum = m.geom_rbound[self._pair1] + m.geom_rbound[self._pair2]
        self.min_clearance: float | None = None
        self.obstacle_contacts = 0
        self.dropped = False
        self._fromto = np.zeros(6)
        sensor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, touch_sensor("obstacle"))
        self._touch = None if sensor < 0 else slice(int(m.sensor_adr[sensor]), int(m.sensor_adr[sensor]) + 2)
        self._watch = True  # something may touch the obstacle before the next tick: check every physics step
        self._held: tuple[Grip, list[tuple[str, int]], int, np.ndarray] | None = None
        clutter = groups.get(CLUTTER_GROUP, ())
        self.clutter_contacts = 0
        """Physics steps in which the robot or the object it holds touched the clutter."""
        self.clutter_touches: dict[tuple[int, int], list[float]] = {}
        """Per (body of the robot or held object, clutter body) touching: [first, last time [s], steps, deepest [m]]."""
        self._is_clutter = np.zeros(m.ngeom, dtype=bool)
        self._is_clutter[list(clutter)] = True
        self._robot_geom = np.zeros(m.ngeom, dtype=bool)
        self._robot_geom[[g for k in robot.robot_groups for g in groups.get(k, ())]] = True
        self.has_clutter = bool(clutter)
        self.starts: dict[str, np.ndarray] = {}
        """Where each free object started [m] (:meth:`record_starts`)."""
        self.grip: Grip | None = None
        """The clamp in force (set by the runner): its object counts as the robot's for the clutter's contacts."""

    def record_starts(self, sim: Simulation) -> None:
        """Remember where every free object starts (the knocked criterion compares its end with it)."""
        self.starts = {n: sim.data.qpos[self.robot.object_qpos_slice(n)][:3].copy() for n in self.robot.object_names}

    def attach(self, sim: Simulation) -> None:
        """Register the monitor's hooks with a simulation.

        The obstacle's contacts are counted at every physics step only while something is within the watched
        clearance of the obstacle (:meth:`on_tick` decides). Where the model has the obstacle's contact sensor
        (:func:`~nextage_qp.scene.files.touch_sensor`) the simulation's physics loop reads it (``sim.touch_adr``), else
        :meth:`on_substep` reads MuJoCo's contact list (a hook :meth:`on_tick` adds and removes).
        """
        sim.hooks.append(self.on_tick)
        self._touch_base = sim.touch_steps
        if self.has_clutter:  # every physics step: the clutter is many bodies, no single contact sensor watches it
            sim.substep_hooks.append(self.on_clutter_step)
        if self.obstacle is not None and self._touch is not None:
            sim.touch_adr = self._touch.start  # the physics loop counts the touching steps itself
        elif self.obstacle is not None:
            sim.substep_hooks.append(self.on_substep)

    def on_clutter_step(self, sim: Simulation) -> None:
        """Hook run at every physics step: count the steps in which the robot (or what it holds) touches clutter."""
        d = sim.data
        if d.ncon == 0:
            return
        geoms = d.contact.geom[: d.ncon]
        mine = self._robot_geom[geoms]
        if self.grip is not None:
            held = self.model.geom_bodyid[geoms] == self.model.body(self.grip.object).id
            mine = mine | held
        clutter = self._is_clutter[geoms]
        dist = d.contact.dist[: d.ncon]
        touching = ((mine[:, 0] & clutter[:, 1]) | (mine[:, 1] & clutter[:, 0])) & (dist < 0)
        if not np.any(touching):
            return
        self.clutter_contacts += 1
        pairs: dict[tuple[int, int], float] = {}
        for k in np.flatnonzero(touching):  # which body touched which piece, and how deep
            a, b = self.model.geom_bodyid[geoms[k]]
            pair = (int(a), int(b)) if clutter[k, 1] else (int(b), int(a))
            pairs[pair] = min(pairs.get(pair, 0.0), float(dist[k]))
        for pair, depth in pairs.items():
            touch = self.clutter_touches.setdefault(pair, [d.time, d.time, 0, 0.0])
            touch[1], touch[2], touch[3] = d.time, touch[2] + 1, min(touch[3], depth)

    def clutter_report(self) -> list[dict[str, Any]]:
        """Each body that touched the clutter, with the piece, when, for how many steps and how deep; most first."""
        name = functools.partial(mujoco.mj_id2name, self.model, mujoco.mjtObj.mjOBJ_BODY)
        return [{"body": name(a), "clutter": name(b), "from_s": round(t0, 3), "to_s": round(t1, 3),
                 "steps": int(n), "depth_m": round(-depth, 5)}
                for (a, b), (t0, t1, n, depth) in sorted(self.clutter_touches.items(), key=lambda kv: -kv[1][2])]

    def on_substep(self, sim: Simulation) -> None:
        """Hook run at every physics step: count the steps in which anything touches the obstacle.

        Skipped while the last tick found every mover farther than the watched clearance from the obstacle
        (``CONTACT_WATCH``, or ``CONTACT_WATCH_SPEED`` times the control period: nothing here moves that far
        within one control period). Reads MuJoCo's contact list (a model without the obstacle's contact sensor).
        """
        d = sim.data
        if not self._watch or d.ncon == 0:
            return
        geoms = d.contact.geom[: d.ncon]
        touching = self._is_obstacle[geoms]
        if np.any((touching[:, 0] != touching[:, 1]) & (d.contact.dist[: d.ncon] < 0)):
            self.obstacle_contacts += 1

    def on_tick(self, sim: Simulation) -> None:
        """Hook run by the simulation after every control tick: minimum clearance to the obstacle.

        Also decides whether the next tick's physics steps need the contact count (:meth:`on_substep`).
        """
        if self.obstacle is None:
            return
        d, m = sim.data, self.model
        best = self.min_clearance if self.min_clearance is not None else 1.0
        watch = max(CONTACT_WATCH, CONTACT_WATCH_SPEED * sim.ctrl_dt)
        # Bounding spheres first: only pairs whose spheres come within the best clearance so far (or within the
        # watched clearance) need the narrow phase, nearest first so the bound tightens early (compiled).
        if kernels.NATIVE:
            best, nearest = kernels.clearance(kernels.GEOM_DISTANCE, m._address, d._address, d.geom_xpos, self._pair1,
                                              self._pair2, self._pair_rsum, best, watch, self._fromto)
        else:
            best, nearest = kernels.clearance_python(m, d, self._pair1, self._pair2, self._pair_rsum, best, watch,
                                                     self._fromto)
        self.min_clearance = best
        self._watch = nearest < watch
        if self._touch is not None:
            self.obstacle_contacts = sim.touch_steps - self._touch_base
            sim.touch_adr = self._touch.start if self._watch else -1
            return
        hooked = self.on_substep in sim.substep_hooks
        if self._watch and not hooked:
            sim.substep_hooks.append(self.on_substep)
        elif hooked and not self._watch:
            sim.substep_hooks.remove(self.on_substep)

    def check_hold(self, sim: Simulation, grip: Grip) -> None:
        """Flag a drop: the object far from where it was in the pads (truth) when the grip was made."""
        if len(grip.frames) < 2:
            return
        d = sim.data
        if self._held is None or self._held[0] is not grip:  # ids and the pads' midpoint in the object, once per grip
            frames, bid = [self.robot.frame(f) for f in grip.frames[:2]], self.model.body(grip.object).id
            self._held = (grip, frames, bid, d.xmat[bid].reshape(3, 3).T @ (_midpoint(d, frames) - d.xpos[bid]))
        _, frames, bid, offset = self._held
        expected = d.xpos[bid] + d.xmat[bid].reshape(3, 3) @ offset
        if np.linalg.norm(_midpoint(d, frames) - expected) > self.drop_distance:
            self.dropped = True


def _midpoint(d: mujoco.MjData, frames: list[tuple[str, int]]) -> np.ndarray:  # of frames as Robot.frame names them
    a, b = (d.site_xpos[fid] if kind == "site" else d.xpos[fid] for kind, fid in frames)  # the clamp's two pads
    return 0.5 * (a + b)


class ObjectState(NamedTuple):
    """The object at the end of a run, against its target (true state).

    Attributes:
        position, target_position: World positions [m].
        error_m, error_xy_m: 3-D and planar distance [m].
        yaw_error_rad: Yaw difference modulo the object's symmetry [rad].
        tilt_rad: Angle between the object's z axis and the vertical [rad].
        resting: On the table (on the target, when that is an object) and at rest (below 1 cm/s and 0.1 rad/s).
    """

    position: np.ndarray
    target_position: np.ndarray
    error_m: float
    error_xy_m: float
    yaw_error_rad: float
    tilt_rad: float
    resting: bool


def object_state(robot: Robot, sim: Simulation, obj: str, target: str) -> ObjectState:
    """Where the object ended up, how it is turned and tilted, and whether it rests on the table."""
    m, d = robot.model, sim.data
    bid, tid = m.body(obj).id, m.body(target).id
    pos, tgt = d.xpos[bid].copy(), d.xpos[tid].copy()
    rot, trot = d.xmat[bid].reshape(3, 3), d.xmat[tid].reshape(3, 3)
    yaw = np.arctan2(rot[1, 0], rot[0, 0]) - np.arctan2(trot[1, 0], trot[0, 0])
    groups = robot.collision_geoms()  # its support: the table or a fixed object, or the target object (a stack)
    supports = [target] if target in robot.object_names else ["table", *robot.fixed_objects]
    table = {g for name in supports for g in groups.get(name, ())}
    on_table = any((int(m.geom_bodyid[c.geom1]) == bid and c.geom2 in table)
                   or (int(m.geom_bodyid[c.geom2]) == bid and c.geom1 in table) for c in d.contact[: d.ncon])
    dof = int(m.jnt_dofadr[m.body_jntadr[bid]]) if m.body_jntnum[bid] else -1
    lin, ang = (d.qvel[dof : dof + 3], d.qvel[dof + 3 : dof + 6]) if dof >= 0 else (np.zeros(3), np.zeros(3))
    still = bool(np.linalg.norm(lin) < 0.01 and np.linalg.norm(ang) < 0.1)
    return ObjectState(pos, tgt, float(np.linalg.norm(pos - tgt)), float(np.linalg.norm((pos - tgt)[:2])),
                       abs(wrap(float(yaw), robot.yaw_symmetry(obj))), float(np.arccos(np.clip(rot[2, 2], -1, 1))),
                       bool(on_table and still))


def judge(criteria: SuccessCriteria, state: ObjectState, *, completed: bool, dropped: bool, limit_violations: int,
          obstacle_contacts: int, limit_detail: str | None = None, clutter_contacts: int = 0,
          clutter_touches: Sequence[Mapping[str, Any]] = (),
          others: Mapping[str, ObjectState] | None = None,
          knocked: Mapping[str, float] | None = None, clearance: float | None = None) -> dict[str, dict[str, Any]]:
    """Every success criterion with its value, limit and verdict (``ok``); a violated joint limit's ``detail``.

    ``clutter_touches``: which bodies touched the clutter (:meth:`OutcomeMonitor.clutter_report`), named in the
    criterion's detail. ``others``: the states of ``criteria.objects``, judged as the task's object is (criteria
    ``NAME:object_error`` and so on); ``knocked``: how far [m] each bystander ended from its start; ``clearance``:
    the object's distance [m] to the obstacles beside it at the end.
    """
    out: dict[str, dict[str, Any]] = {
        "completed": {"ok": completed},
        "object_error": {"value": state.error_xy_m, "limit": criteria.planar_error,
                         "ok": state.error_xy_m <= criteria.planar_error},
        "not_dropped": {"ok": not dropped},
        "joint_limits": {"value": limit_violations, "limit": 0, "ok": limit_violations == 0},
    }
    if limit_detail:
        out["joint_limits"]["detail"] = limit_detail
    if criteria.yaw_error is not None:
        out["yaw_error"] = {"value": state.yaw_error_rad, "limit": criteria.yaw_error,
                            "ok": state.yaw_error_rad <= criteria.yaw_error}
    if criteria.tilt is not None:
        out["tilt"] = {"value": state.tilt_rad, "limit": criteria.tilt, "ok": state.tilt_rad <= criteria.tilt}
    if criteria.resting:
        out["resting"] = {"ok": state.resting}
    if criteria.clutter_contacts is not None:
        out["clutter_contacts"] = {"value": clutter_contacts, "limit": criteria.clutter_contacts,
                                   "ok": clutter_contacts <= criteria.clutter_contacts}
        if clutter_touches:
            out["clutter_contacts"]["detail"] = _touch_text(clutter_touches)
    if criteria.obstacle_clearance is not None:
        value = 0.0 if clearance is None else clearance
        out["obstacle_clearance"] = {"value": value, "limit": criteria.obstacle_clearance,
                                     "ok": value >= criteria.obstacle_clearance}
    if criteria.obstacle_contacts is not None:
        out["obstacle_contacts"] = {"value": obstacle_contacts, "limit": criteria.obstacle_contacts,
                                    "ok": obstacle_contacts <= criteria.obstacle_contacts}
    for name, other in (others or {}).items():
        out[f"{name}:object_error"] = {"value": other.error_xy_m, "limit": criteria.planar_error,
                                       "ok": other.error_xy_m <= criteria.planar_error}
        if criteria.yaw_error is not None:
            out[f"{name}:yaw_error"] = {"value": other.yaw_error_rad, "limit": criteria.yaw_error,
                                        "ok": other.yaw_error_rad <= criteria.yaw_error}
        if criteria.tilt is not None:
            out[f"{name}:tilt"] = {"value": other.tilt_rad, "limit": criteria.tilt,
                                   "ok": other.tilt_rad <= criteria.tilt}
        if criteria.resting:
            out[f"{name}:resting"] = {"ok": other.resting}
    if criteria.knocked is not None and knocked:
        worst = max(knocked, key=lambda n: knocked[n])
        out["knocked"] = {"value": knocked[worst], "limit": criteria.knocked, "ok": knocked[worst] <= criteria.knocked,
                          "detail": f"{worst} moved {knocked[worst] * 1e3:.0f} mm"}
    return out


def summarize(
    *,
    task: str,
    robot: Robot,
    sim: Simulation,
    monitor: OutcomeMonitor,
    records: list[PhaseRecord],
    obj: str,
    target: str,
    criteria: SuccessCriteria,
    error: str | None,
    wall_s: float,
    extra: dict[str, Any] | None = None,
    handled: frozenset[str] = frozenset(),
) -> dict[str, Any]:
    """The result record printed by ``nextage-qp run --json``; ``success`` only when every criterion holds.

    ``handled``: the objects the phases name (besides ``obj`` and the judged ones, every other free object is a
    bystander, judged by ``criteria.knocked``).
    """
    state = object_state(robot, sim, obj, target)
    others = {name: object_state(robot, sim, name, tgt) for name, tgt in criteria.objects.items()}
    bystanders = set(monitor.starts) - handled - {obj} - set(criteria.objects)
    knocked = {n: float(np.linalg.norm(sim.data.qpos[robot.object_qpos_slice(n)][:3] - monitor.starts[n]))
               for n in sorted(bystanders)}
    rec = sim.recorder.arrays()
    q = rec["q"]
    viol = int(np.count_nonzero(np.any((q < robot.lower - LIMIT_TOLERANCE) | (q > robot.upper + LIMIT_TOLERANCE),
                                       axis=1)))
    detail = (limit_violation(robot.joint_names, np.ravel(rec["t"]), q, robot.lower, robot.upper, LIMIT_TOLERANCE)
              if viol else None)
    tau = np.abs(rec["tau"]).max() if len(q) else 0.0
    contacts = monitor.obstacle_contacts if monitor.obstacle is not None else 0
    touches = monitor.clutter_report() if monitor.has_clutter else []
    clearance = obstacle_clearance(robot, sim.data, obj) if obj in robot.object_names else None
    verdict = judge(criteria, state, completed=error is None, dropped=monitor.dropped, limit_violations=viol,
                    obstacle_contacts=contacts, limit_detail=detail, clutter_contacts=monitor.clutter_contacts,
                    clutter_touches=touches,
                    others=others, knocked=knocked, clearance=clearance)
    sim_t = sim.time
    return {
        "task": task,
        "success": all(c["ok"] for c in verdict.values()),
        "failed_criteria": [name for name, c in verdict.items() if not c["ok"]],
        "object_error_m": state.error_m,
        "object_error_xy_m": state.error_xy_m,
        "object_yaw_error_rad": state.yaw_error_rad,
        "object_tilt_rad": state.tilt_rad,
        "object_resting": state.resting,
        "final_object_position": state.position.tolist(),
        "target_position": state.target_position.tolist(),
        "sim_time_s": sim_t,
        "wall_time_s": wall_s,
        "real_time_factor": sim_t / wall_s if wall_s > 0 else None,
        "physics_share": sim.physics_s / wall_s if wall_s > 0 else None,
        "min_obstacle_clearance_m": monitor.min_clearance,
        "obstacle_contacts": contacts,
        **({"object_obstacle_clearance_m": clearance} if clearance is not None and robot.obstacle_groups() else {}),
        **({"clutter_contacts": monitor.clutter_contacts} if monitor.has_clutter else {}),
        **({"clutter_touches": touches} if touches else {}),
        **({"objects": {n: {"error_xy_m": o.error_xy_m, "yaw_error_rad": o.yaw_error_rad, "tilt_rad": o.tilt_rad,
                            "resting": o.resting} for n, o in others.items()}} if others else {}),
        **({"knocked_m": {n: round(v, 5) for n, v in knocked.items()}} if knocked else {}),
        "object_dropped": monitor.dropped,
        "joint_limit_violations": viol,
        "max_abs_torque_nm": float(tau),
        "torque_saturation_ticks": int(sim.pd.any_saturated_ticks),
        **(extra or {}),
        "phases": [r.as_dict() for r in records],
        "criteria": verdict,
        "error": error,
    }


@dataclass(frozen=True)
class RunResult(Mapping[str, Any]):
    """The outcome of one run: typed fields over its result record (what ``nextage-qp run --json`` prints).

    Read as a mapping, it is that record (``result["object_error_m"]``); the fields every consumer needs are typed.

    Attributes:
        record: The whole result record (:func:`summarize`).
    """

    record: Mapping[str, Any]

    @property
    def success(self) -> bool:
        """Every phase completed and every success criterion held."""
        return bool(self.record["success"])

    @property
    def error(self) -> str | None:
        """Which phase failed and why, or None."""
        return self.record["error"]

    @property
    def failed_criteria(self) -> list[str]:
        """The criteria that did not hold, in order."""
        return list(self.record["failed_criteria"])

    @property
    def failed_phase(self) -> str | None:
        """The phase the run failed in, or None."""
        return next((p["name"] for p in self.record["phases"] if p["status"] == "failed"), None)

    @property
    def object_error_xy_m(self) -> float:
        """The object's planar distance to its target at the end [m]."""
        return float(self.record["object_error_xy_m"])

    @property
    def object_yaw_error_rad(self) -> float:
        """The object's yaw error modulo its symmetry [rad]."""
        return float(self.record["object_yaw_error_rad"])

    @property
    def phases(self) -> list[dict[str, Any]]:
        """Per phase: name, kind, status, start and duration [s] and the phase's own figures."""
        return list(self.record["phases"])

    @property
    def sim_time_s(self) -> float:
        """Simulated time of the run [s]."""
        return float(self.record["sim_time_s"])

    @property
    def wall_time_s(self) -> float:
        """Wall time of the run [s]."""
        return float(self.record["wall_time_s"])

    def unmet_criteria(self) -> str:
        """``criteria not met: NAME VALUE > LIMIT, ...``: the criteria it failed, in order."""
        return unmet_criteria(self.record)

    def as_dict(self) -> dict[str, Any]:
        """A copy of the record, for JSON."""
        return dict(self.record)

    def __getitem__(self, key: str) -> Any:
        return self.record[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.record)

    def __len__(self) -> int:
        return len(self.record)


def _touch_text(touches: Sequence[Mapping[str, Any]]) -> str:
    """The bodies that touched the clutter, most steps first: ``WRIST on clutter_2 at 7.41-33.80 s, ...``."""
    first = touches[0]
    text = (f"{first['body']} on {first['clutter']} at {first['from_s']:.2f}-{first['to_s']:.2f} s, "
            f"{first['steps']} step{'' if first['steps'] == 1 else 's'}, {first['depth_m'] * 1e3:.1f} mm deep")
    more = len(touches) - 1
    return text + (f"; {more} more {'pair' if more == 1 else 'pairs'} touching" if more else "")


def unmet_criteria(record: Mapping[str, Any]) -> str:
    """``criteria not met: NAME VALUE > LIMIT, ...`` of a result record (the criteria it failed, in order)."""
    return "criteria not met: " + ", ".join(_criterion_text(record, n) for n in record.get("failed_criteria", []))


def _criterion_text(record: Mapping[str, Any], name: str) -> str:
    crit = record.get("criteria", {}).get(name, {})
    text = f"{name} {crit['value']:.4g} > {crit['limit']:.4g}" if "value" in crit and "limit" in crit else name
    return f"{text} ({crit['detail']})" if crit.get("detail") else text
