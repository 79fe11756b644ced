"""Step response: one joint steps to an absolute target under PD control, every other joint holds home."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.io.per_joint import descends
from nextage_qp.loop.pd import Gains
from nextage_qp.loop.simulation import Simulation
from nextage_qp.robots.model import Robot


class StepMetrics(NamedTuple):
    """Classic step-response figures of one joint.

    Attributes:
        final_error_rad: |target − q(T)| at the end of the run [rad].
        overshoot_pct: Largest excursion beyond the target, in % of the step.
        rise_time_s: Time from 10 % to 90 % of the step [s] (None if 90 % is never reached).
        settling_time_s: Time after which |target − q| stays within 2 % of the step [s] (None if never).
        max_abs_torque_nm: Peak |torque| of the stepping joint [N·m].
        saturated_steps: Physics steps on which that joint's torque was clamped to the actuator range.
    """

    final_error_rad: float
    overshoot_pct: float
    rise_time_s: float | None
    settling_time_s: float | None
    max_abs_torque_nm: float
    saturated_steps: int


def step_metrics(
    t: np.ndarray, q: np.ndarray, tau: np.ndarray, q0: float, target: float, tau_max: float
) -> StepMetrics:
    """Figures of a step from ``q0`` to ``target`` [rad] given the joint's time series ``t``, ``q``, ``tau``."""
    step = target - q0
    progress = (q - q0) / step  # 0 at the start, 1 at the target
    err = np.abs(target - q)
    r10, r90 = np.flatnonzero(progress >= 0.1), np.flatnonzero(progress >= 0.9)
    rise = float(t[r90[0]] - t[r10[0]]) if r90.size else None
    outside = np.flatnonzero(err > 0.02 * abs(step))
    if not outside.size:
        settle: float | None = 0.0
    elif outside[-1] == len(t) - 1:
        settle = None
    else:
        settle = float(t[outside[-1] + 1] - t[0])
    return StepMetrics(
        final_error_rad=float(err[-1]),
        overshoot_pct=float(max(0.0, (progress.max() - 1.0) * 100.0)),
        rise_time_s=rise,
        settling_time_s=settle,
        max_abs_torque_nm=float(np.abs(tau).max()),
        saturated_steps=int(np.sum(np.abs(tau) >= tau_max - 1e-9)),
    )


def blocking_contacts(robot: Robot, sim: Simulation, joint: str) -> list[str]:
    """Contacts, in the final state, between the bodies ``joint`` moves and the rest of the scene.

    Each is ``"A against B"`` (geom names, or their bodies' where a geom has none), ``A`` on the moving side.
    """
    m, d = robot.model, sim.data
    root = int(m.jnt_bodyid[robot.joint_ids[robot.joint_index(joint)]])
    moving = {b for b in range(m.nbody) if descends(m, b, root)}

    def name(geom: int) -> str:
        return m.geom(geom).name or m.body(int(m.geom_bodyid[geom])).name

    found: list[str] = []
    for c in d.contact[: d.ncon]:
        g1, g2 = int(c.geom1), int(c.geom2)
        side1, side2 = int(m.geom_bodyid[g1]) in moving, int(m.geom_bodyid[g2]) in moving
        if side1 != side2:
            a, b = (g1, g2) if side1 else (g2, g1)
            pair = f"{name(a)} against {name(b)}"
            if pair not in found:
                found.append(pair)
    return found


def run_step(
    robot: Robot, joint: str, target: float, gains: Gains, *, duration: float = 3.0, shaped: bool = False
) -> tuple[StepMetrics, Simulation]:
    """Simulate a step of ``joint`` from the home pose to ``target`` [rad]; returns the figures and the run.

    With ``shaped=False`` (the report's test) the reference jumps at t = 0; with ``shaped=True`` it
    follows a jerk-limited Ruckig trajectory.

    Raises:
        UnknownJointError: ``joint`` is not a robot joint.
        ConfigError: The target is outside the joint's range or equals the home position.
    """
    j = robot.joint_index(joint)
    q0 = robot.keyframe_q("home")
    lo, hi = float(robot.lower[j]), float(robot.upper[j])
    if not lo <= target <= hi:
        raise ConfigError(
            f"--target-deg {np.rad2deg(target):.2f}: outside {joint}'s range "
            f"[{np.rad2deg(lo):.2f}, {np.rad2deg(hi):.2f}] deg"
        )
    if abs(target - q0[j]) < 1e-6:
        raise ConfigError(f"--target-deg {np.rad2deg(target):.2f}: equals {joint}'s home position; nothing to step")
    if not duration > 0:
        raise ConfigError(f"--duration must be > 0 s, got {duration}")
    sim = Simulation(robot, gains)
    sim.reset(q0)
    q_des = q0.copy()
    q_des[j] = target
    sim.set_target(q_des, shaped=shaped)
    sim.run(duration)
    a = sim.recorder.arrays()
    metrics = step_metrics(a["t"], a["q"][:, j], a["tau"][:, j], float(q0[j]), target, float(robot.torque_limit[j]))
    return metrics, sim
