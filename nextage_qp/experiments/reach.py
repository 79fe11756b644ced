"""Reach: move a frame to a Cartesian target through the servo tick (QP IK -> Ruckig -> PD -> MuJoCo)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.ik import QPIK, FrameTarget, IKConfig
from nextage_qp.loop.pd import Gains
from nextage_qp.loop.reference import TrajectoryLimits
from nextage_qp.loop.servo import Command, Servo
from nextage_qp.loop.simulation import Simulation, Timing
from nextage_qp.robots.model import Robot


class ReachResult(NamedTuple):
    """Outcome of a reach.

    Attributes:
        final_error_m: ‖p_frame − p_target‖ at the end [m].
        time_to_1mm_s: First time after which the distance stays below 1 mm [s] (None if never).
        max_abs_torque_nm: Peak |torque| over all joints [N·m].
        saturated_steps: Physics steps with at least one torque clamped to its actuator range.
        ik_converged_q: The commanded joint vector at the end [rad].
    """

    final_error_m: float
    time_to_1mm_s: float | None
    max_abs_torque_nm: float
    saturated_steps: int
    ik_converged_q: np.ndarray


def run_reach(
    robot: Robot,
    frame: str,
    pos: np.ndarray,
    *,
    gains: Gains,
    limits: TrajectoryLimits | None = None,
    axis: np.ndarray | None = None,
    direction: np.ndarray | None = None,
    duration: float = 3.0,
    timing: Timing | None = None,
) -> tuple[ReachResult, Simulation]:
    r"""Reach ``pos`` [m] with ``frame`` from the home pose, streaming IK through Ruckig to the PD loop.

    Every control tick the QP IK gives a joint velocity :math:`v` [rad/s] at the commanded configuration
    and the command integrates it, :math:`q_{cmd} \leftarrow q_{cmd} + v\,\Delta t_{ctrl}`; Ruckig turns
    :math:`q_{cmd}` into a jerk-limited reference that the PD law tracks at every physics step.

    Raises:
        UnknownFrameError: ``frame`` is not a site or body.
        ConfigError: Bad duration, or only one of ``axis`` / ``direction`` given.
    """
    if not duration > 0:
        raise ConfigError(f"--duration must be > 0 s, got {duration}")
    if (axis is None) != (direction is None):
        raise ConfigError("--axis and --direction go together: the frame's axis is turned along the direction")
    robot.frame(frame)
    sim = Simulation(robot, gains, limits, timing=timing, frames=(frame,))
    q0 = robot.keyframe_q("home")
    sim.reset(q0)
    servo = Servo(QPIK(robot, IKConfig()), sim, q0)
    target = FrameTarget(frame=frame, pos=np.asarray(pos, dtype=float), axis=axis, direction=direction)
    command = Command((target,))
    while sim.time < duration - 1e-9:
        servo.step(command)
        sim.tick()
    a = sim.recorder.arrays()
    dist = np.linalg.norm(a[f"frame_{frame}"][:, :3] - target.pos, axis=1)
    outside = np.flatnonzero(dist >= 1e-3)
    if not outside.size:
        t1: float | None = 0.0
    elif outside[-1] == len(dist) - 1:
        t1 = None
    else:
        t1 = float(a["t"][outside[-1] + 1])
    result = ReachResult(
        final_error_m=float(dist[-1]),
        time_to_1mm_s=t1,
        max_abs_torque_nm=float(np.abs(a["tau"]).max()),
        saturated_steps=int(sim.pd.any_saturated_ticks),
        ik_converged_q=np.array(servo.q_cmd),
    )
    sim.recorder.meta |= {"frame": frame, "target_pos_m": list(map(float, pos)), "final_error_m": result.final_error_m}
    return result, sim
