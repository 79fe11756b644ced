"""Step-response studies: raw steps of every joint from ``home`` under a trial's PD gains, scored by settling time.

Each trial's gains are the base gains file with the searched keys set (``joints.JOINT.kp`` ...). Every
joint steps to +-amplitude (from home, for joints whose absolute target the robot's own body blocks); a target
outside the joint's range is left out and listed. A step meets its criteria when it settles into the 2 % band,
its final error is within ``final_error_rad`` and its overshoot within ``overshoot_pct``. The trial's value is
the mean over steps of the settling time, where a step that misses a criterion costs the whole run duration
times (1 + how far it misses), so any feasible set of gains beats any infeasible one of similar speed.
"""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from nextage_qp.errors import ConfigError, one_line
from nextage_qp.io.yaml_file import read_yaml_mapping, validate
from nextage_qp.loop.pd import Gains, GainsFile, gains_path
from nextage_qp.sweep.episode import Episode
from nextage_qp.sweep.keys import lookup
from nextage_qp.tune.evaluate import Score, apply_params
from nextage_qp.tune.spec import StepsEval

STEP_WALL_LIMIT = 60.0
"""Wall-time limit of one step run [s] (a run takes well under a second)."""


@dataclass(frozen=True)
class StepTask:
    """One step run for a worker (plain data, picklable); shaped like a sweep task for the backends."""

    index: int
    joint: str
    target_rad: float
    gains: Gains
    duration: float
    final_error_rad: float
    overshoot_pct: float
    scene: str
    wall_limit: float = STEP_WALL_LIMIT
    seed: int = 0
    overrides: tuple[str, ...] = ()

    @property
    def params(self) -> dict[str, Any]:
        """What the step is: joint and target [rad]."""
        return {"joint": self.joint, "target_rad": self.target_rad}


_ROBOTS: dict[str, Any] = {}


def run_step_task(task: StepTask) -> Episode:
    """Run one step in this process (never raises): ``success`` when it meets its criteria."""
    from nextage_qp.experiments.step_response import run_step
    from nextage_qp.robots.model import Robot

    start = time.perf_counter()
    record = Episode(task.index, 0, task.params, [], status="error", worker=f"{socket.gethostname()}:{os.getpid()}")
    try:
        robot = _ROBOTS.get(task.scene) or _ROBOTS.setdefault(task.scene, Robot.from_scene(task.scene))
        m, _ = run_step(robot, task.joint, task.target_rad, task.gains, duration=task.duration)
        record.result = m._asdict()
        missed = _missed(m._asdict(), task.final_error_rad, task.overshoot_pct)
        record.status = "failed" if missed else "success"
        record.failed_criteria = missed
        record.reason = ", ".join(missed) or None
    except Exception as exc:
        record.reason = f"{type(exc).__name__}: {one_line(exc)}"
    record.wall_time_s = time.perf_counter() - start
    return record


def _missed(m: dict[str, Any], final_error: float, overshoot: float) -> list[str]:
    missed = []
    if m["settling_time_s"] is None:
        missed.append("not settled")
    if not m["final_error_rad"] <= final_error:
        missed.append(f"final error {m['final_error_rad']:.2g} rad > {final_error:g}")
    if not m["overshoot_pct"] <= overshoot:
        missed.append(f"overshoot {m['overshoot_pct']:.2f} % > {overshoot:g} %")
    return missed


class StepsEvaluator:
    """Step responses under a base gains file (see the module docstring)."""

    kind = "steps"
    wall_limit = STEP_WALL_LIMIT
    episode_fn = staticmethod(run_step_task)

    def __init__(self, evaluation: StepsEval, held_amplitude_deg: float | None, folder: Path) -> None:
        from nextage_qp.robots.model import Robot

        self.eval = evaluation
        self.robot = Robot.from_scene(evaluation.scene)
        local = folder / evaluation.gains
        self.base_path = local if local.is_file() else gains_path(evaluation.gains, self.robot.description.gains_dir)
        self.base_doc = read_yaml_mapping(self.base_path, "a mapping with keys 'joints' and 'gravity_compensation'")
        self.base = validate(GainsFile, self.base_doc, str(self.base_path))
        names = self.robot.joint_names
        for name in [*evaluation.relative, *(evaluation.joints or ())]:
            if name not in names:
                raise ConfigError(f"steps: unknown joint {name!r}; valid joints: {', '.join(names)}")
        self.skipped: dict[str, list[str]] = {}
        self.steps = self._steps(evaluation.amplitude_deg, "objective")
        self.held_steps = self._steps(held_amplitude_deg, "held_out") if held_amplitude_deg else []

    def _steps(self, amplitude_deg: float, where: str) -> list[tuple[str, float]]:
        home = self.robot.keyframe_q("home")
        out, skipped = [], []
        for name in self.eval.joints or self.robot.joint_names:
            j = self.robot.joint_index(name)
            for sign in (1.0, -1.0):
                target = float(np.deg2rad(sign * amplitude_deg)) + (home[j] if name in self.eval.relative else 0.0)
                if not self.robot.lower[j] <= target <= self.robot.upper[j] or abs(target - home[j]) < 1e-6:
                    skipped.append(f"{name} {np.rad2deg(target):+.1f} deg")
                else:
                    out.append((name, target))
        self.skipped[where] = skipped
        if not out:
            raise ConfigError(f"steps: no step at {amplitude_deg:g} deg is inside the joints' ranges")
        return out

    def base_value(self, key: str) -> Any:
        """The key's value in the base gains file."""
        value = lookup(self.base, key.split("."), lambda msg: ConfigError(f"space.{key}: {msg}"))
        if value is None:
            raise ConfigError(
                f"space.{key}: not in the base gains file; search joints.JOINT.kp or joints.JOINT.kd, "
                f"JOINT one of {', '.join(self.robot.joint_names)}"
            )
        return value

    def check_value(self, key: str, value: Any) -> None:
        """Raise ConfigError when the gains file with ``key = value`` is invalid."""
        validate(GainsFile, apply_params(self.base_doc, {key: value}, "space"), "the gains file")

    def gains(self, params: dict[str, Any]) -> Gains:
        """The base gains with ``params`` set."""
        return Gains.from_file(
            validate(GainsFile, apply_params(self.base_doc, params), "tuned gains"), "tuned", self.robot.joint_names
        )

    def tasks(self, params: dict[str, Any], held_out: bool = False) -> list[StepTask]:
        """One task per step of the objective's (or the held-out) amplitude."""
        gains = self.gains(params)
        e = self.eval
        return [StepTask(i, joint, target, gains, e.duration_s, e.final_error_rad, e.overshoot_pct, e.scene)
                for i, (joint, target) in enumerate(self.held_steps if held_out else self.steps)]

    def score(self, episodes: Sequence[Episode]) -> Score:
        """Mean cost over the steps (settling time, or the penalty of a step that misses a criterion)."""
        e = self.eval
        costs, rows = [], []
        for ep in sorted(episodes, key=lambda x: x.index):
            m = ep.result
            if m is None:
                cost = 10.0 * e.duration_s
            elif ep.status == "success":
                cost = float(m["settling_time_s"])
            else:
                miss = (max(0.0, m["final_error_rad"] / e.final_error_rad - 1.0)
                        + max(0.0, m["overshoot_pct"] / max(e.overshoot_pct, 1e-9) - 1.0)
                        + (1.0 if m["settling_time_s"] is None else 0.0))
                cost = e.duration_s * (1.0 + min(miss, 9.0))
            costs.append(cost)
            rows.append({"joint": ep.params["joint"], "target_deg": float(np.rad2deg(ep.params["target_rad"])),
                         "met": ep.status == "success", "reason": ep.reason, **(m or {})})
        met = sum(r["met"] for r in rows)
        settle = [r["settling_time_s"] for r in rows if r.get("settling_time_s") is not None]
        mean_settle = float(np.mean(settle)) if met == len(rows) else None
        line = (f"{met}/{len(rows)} steps meet the criteria"
                + (f", mean settling {mean_settle:.4f} s" if mean_settle is not None else "")
                + f", max overshoot {max((r.get('overshoot_pct') or 0.0) for r in rows):.2f} %")
        details = {"steps": len(rows), "met": met, "mean_settling_time_s": mean_settle,
                   "max_settling_time_s": max(settle) if settle else None, "per_step": rows}
        return Score(float(np.mean(costs)), line, details)

    def tuned_doc(self, params: dict[str, Any], out_dir: Path) -> dict[str, Any]:
        """The base gains file with ``params`` set."""
        return apply_params(self.base_doc, params)
