"""Offline jerk-limited trajectories: state-to-state Ruckig segments chained through waypoints.

Ruckig's community edition computes intermediate waypoints only through a cloud service, so a path through
waypoints is one state-to-state segment per pair, each time-optimal within the same limits.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import ruckig

from nextage_qp.errors import TrajectoryError
from nextage_qp.trajectory import TrajectoryLimits, check_result, fill_limits, joint_error


class Samples(NamedTuple):
    """A trajectory sampled at a fixed period: time [s] (k,), q [rad], qd [rad/s], qdd [rad/s²] (k, n)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


def plan_segment(
    q0: np.ndarray,
    q1: np.ndarray,
    limits: TrajectoryLimits,
    *,
    qd0: np.ndarray | None = None,
    qd1: np.ndarray | None = None,
    joint_names: Sequence[str] = (),
) -> ruckig.Trajectory:
    """Time-optimal state-to-state segment from ``(q0, qd0)`` to ``(q1, qd1)`` (zero accelerations).

    Raises:
        TrajectoryError: Ruckig rejected the input (naming the joint) or could not plan it.
    """
    joint_names = tuple(joint_names) or tuple(f"joint {i}" for i in range(len(q0)))
    n = len(joint_names)
    inp = ruckig.InputParameter(n)
    fill_limits(inp, limits, joint_names)
    inp.current_position, inp.target_position = np.asarray(q0, float).tolist(), np.asarray(q1, float).tolist()
    inp.current_velocity = [0.0] * n if qd0 is None else np.asarray(qd0, float).tolist()
    inp.target_velocity = [0.0] * n if qd1 is None else np.asarray(qd1, float).tolist()
    traj = ruckig.Trajectory(n)
    try:
        check_result(ruckig.Ruckig(n).calculate(inp, traj), "segment")
    except ruckig.RuckigError as exc:
        raise joint_error(exc, "segment", joint_names) from None
    return traj


def chain_waypoints(
    waypoints: Sequence[np.ndarray],
    limits: TrajectoryLimits,
    *,
    dt: float,
    velocities: Sequence[np.ndarray] | None = None,
    joint_names: Sequence[str] = (),
) -> Samples:
    """Plan through ``waypoints`` (the first is the start), one segment per pair, sampled every ``dt`` [s].

    Args:
        waypoints: Joint positions [rad], at least two.
        limits: Bounds applied on every segment.
        dt: Sampling period [s].
        velocities: Optional velocity [rad/s] at each waypoint (default: stop at each one).
        joint_names: Names used in error messages (default: ``joint 0`` ...).

    Raises:
        TrajectoryError: Fewer than two waypoints, or a segment could not be planned (the message
            names the segment and joint).
    """
    if len(waypoints) < 2:
        raise TrajectoryError(f"need at least two waypoints (start and goal), got {len(waypoints)}")
    if velocities is not None and len(velocities) != len(waypoints):
        raise TrajectoryError(f"got {len(velocities)} waypoint velocities for {len(waypoints)} waypoints")
    segments: list[ruckig.Trajectory] = []
    for k in range(len(waypoints) - 1):
        vel = (None, None) if velocities is None else (velocities[k], velocities[k + 1])
        try:
            segments.append(
                plan_segment(waypoints[k], waypoints[k + 1], limits, qd0=vel[0], qd1=vel[1], joint_names=joint_names)
            )
        except TrajectoryError as exc:
            raise TrajectoryError(f"waypoint {k} -> {k + 1}: {exc}") from None
    ends = np.cumsum([seg.duration for seg in segments])
    t = np.append(np.arange(0.0, ends[-1], dt), ends[-1])
    which = np.minimum(np.searchsorted(ends, t, side="right"), len(segments) - 1)
    starts = np.concatenate([[0.0], ends[:-1]])
    rows = [np.concatenate(segments[s].at_time(ti - starts[s])) for ti, s in zip(t, which, strict=True)]
    data = np.asarray(rows)
    n = len(waypoints[0])
    return Samples(t, data[:, :n], data[:, n : 2 * n], data[:, 2 * n :])
