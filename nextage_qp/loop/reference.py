r"""Jerk-limited joint references (Ruckig): streamed online, and offline segments chained through waypoints.

Ruckig computes time-optimal trajectories whose velocity, acceleration and jerk stay inside per-joint
bounds, :math:`|\dot q| \le v_{max}` [rad/s], :math:`|\ddot q| \le a_{max}` [rad/s²],
:math:`|\dddot q| \le j_{max}` [rad/s³]. Two uses:

* :class:`JointTrajectory` (alias :data:`ReferenceGenerator`) streams a reference online: the target may
  change every control tick and each :meth:`~JointTrajectory.update` advances the reference by ``dt``.
* :func:`chain_waypoints` plans an offline trajectory through waypoints, one
  state-to-state segment per pair, each time-optimal within the same limits (the community edition's intermediate
  waypoints need Ruckig's cloud service).

Every Ruckig result is checked; invalid input raises :class:`~nextage_qp.errors.TrajectoryError` naming the joints.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import ruckig
from pydantic import Field, field_validator

from nextage_qp.errors import TrajectoryError
from nextage_qp.io.schema import YamlModel
from nextage_qp.robots.model import PerJoint, per_joint

_OK = (ruckig.Result.Working, ruckig.Result.Finished)
MIN_LIMIT = 0.01  # smallest bound: below it a reference takes longer than Ruckig computes (ErrorTrajectoryDuration)
NUDGE = 1e-12  # [rad] a target moves for Ruckig to solve a step it failed on numerically (JointTrajectory._nudged)


class TrajectoryLimits(YamlModel):
    """Kinematic bounds of the joint references, scalar (every joint) or per joint.

    A per-joint value is a list in the robot's joint order or a mapping ``{joint: value}`` (joints left out take
    the default of the field); the names and the list's length are checked against the robot (:meth:`arrays`).

    Attributes:
        max_velocity: [rad/s]; the URDF's joint velocity limit is 1.0. Every bound is at least ``MIN_LIMIT``.
        max_acceleration: [rad/s²].
        max_jerk: [rad/s³].
    """

    max_velocity: PerJoint = Field(
        default=1.0, description="Joint velocity bound [rad/s]: one value, a list in joint order, or joint -> value "
                                 "(others 1.0); at least 0.01, and capped by the robot file's velocity_limits.")
    max_acceleration: PerJoint = Field(
        default=4.0, description="Joint acceleration bound [rad/s²]: one value, a list in joint order, or joint -> "
                                 "value (others 4.0); at least 0.01.")
    max_jerk: PerJoint = Field(
        default=40.0, description="Joint jerk bound [rad/s³]: one value, a list in joint order, or joint -> value "
                                  "(others 40.0); at least 0.01.")

    @field_validator("max_velocity", "max_acceleration", "max_jerk")
    @classmethod
    def _check(cls, value: PerJoint) -> PerJoint:
        values = value.values() if isinstance(value, dict) else np.atleast_1d(value)
        if any(not (np.isfinite(v) and v >= MIN_LIMIT) for v in values):
            raise ValueError(f"every limit must be finite and >= {MIN_LIMIT:g}, got {value}")
        return value

    def arrays(self, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-joint (velocity, acceleration, jerk) bounds over ``names``.

        Joints a mapping leaves out get the field's default.

        Raises:
            ConfigError: A list of the wrong length or a mapping with a joint not in ``names``.
        """
        defaults = type(self).model_fields
        v, a, j = (per_joint(getattr(self, f), float(defaults[f].default), names, f"trajectory.{f}")
                   for f in ("max_velocity", "max_acceleration", "max_jerk"))
        return v, a, j


class RefState(NamedTuple):
    """A joint reference: position [rad], velocity [rad/s], acceleration [rad/s²], each (n,)."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


def cap_velocity(limits: TrajectoryLimits, names: Sequence[str], cap: np.ndarray) -> TrajectoryLimits:
    """``limits`` with each joint's velocity bound capped at ``cap`` [rad/s] (inf: no cap), e.g. a robot file's."""
    cap = np.asarray(cap, dtype=float)
    if not np.isfinite(cap).any():
        return limits
    v = np.minimum(limits.arrays(names)[0], cap)
    return limits.model_copy(update={"max_velocity": dict(zip(names, v.tolist(), strict=True))})


def fill_limits(inp: ruckig.InputParameter, limits: TrajectoryLimits, names: Sequence[str]) -> None:
    """Write the per-joint limits of ``names`` into a Ruckig input."""
    v, a, j = limits.arrays(names)
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = v.tolist(), a.tolist(), j.tolist()


def check_result(result: ruckig.Result, what: str) -> None:
    """Raise :class:`TrajectoryError` unless Ruckig is working or finished."""
    if result not in _OK:
        raise TrajectoryError(f"{what}: Ruckig returned {result.name}")


def joint_error(exc: Exception, what: str, names: Sequence[str]) -> TrajectoryError:
    """Rewrite Ruckig's ``... of DoF 3 ...`` message with the joint's name."""
    msg = re.sub(r"\[ruckig\]\s*", "", str(exc)).strip()
    msg = re.sub(r"DoF (\d+)", lambda m: f"joint {names[int(m.group(1))]}", msg)
    return TrajectoryError(f"{what}: {msg}")


class JointTrajectory:
    """Online jerk-limited reference generator for the robot's joints (Ruckig, re-targeted every tick).

    Args:
        limits: Velocity, acceleration and jerk bounds.
        dt: Control period [s]; each :meth:`update` advances the reference by ``dt``.
        lower: Optional joint lower limits [rad]; a target outside ``[lower, upper]`` is an error.
        upper: Optional joint upper limits [rad].
        joint_names: The joints, in order (names used in error messages).
    """

    def __init__(
        self,
        limits: TrajectoryLimits,
        *,
        dt: float,
        lower: np.ndarray | None = None,
        upper: np.ndarray | None = None,
        joint_names: Sequence[str],
    ) -> None:
        if not dt > 0:
            raise TrajectoryError(f"control period dt must be > 0 s, got {dt}")
        self.names = tuple(joint_names)
        self.n = len(self.names)
        self.dt = dt
        self.limits = limits
        self.lower, self.upper = lower, upper
        self._otg = ruckig.Ruckig(self.n, dt)
        self._inp = ruckig.InputParameter(self.n)
        self._out = ruckig.OutputParameter(self.n)
        fill_limits(self._inp, limits, self.names)
        self._result = ruckig.Result.Finished
        self.reset(np.zeros(self.n))

    def reset(self, q: np.ndarray, qd: np.ndarray | None = None) -> None:
        """Restart from state ``(q, qd)`` (zero acceleration) with the target equal to ``q``."""
        q = np.asarray(q, dtype=float)
        qd = np.zeros(self.n) if qd is None else np.asarray(qd, dtype=float)
        self._inp.current_position, self._inp.current_velocity = q.tolist(), qd.tolist()
        self._inp.current_acceleration = [0.0] * self.n
        self._inp.target_position, self._inp.target_velocity = q.tolist(), [0.0] * self.n
        self._inp.target_acceleration = [0.0] * self.n
        self._otg.reset()
        self._state = RefState(q.copy(), qd.copy(), np.zeros(self.n))
        self._t0 = 0.0
        self._result = ruckig.Result.Finished if not np.any(qd) else ruckig.Result.Working

    def set_target(self, q_target: np.ndarray, qd_target: np.ndarray | None = None) -> None:
        """Set the state to reach: position [rad] and, optionally, velocity [rad/s] (default 0).

        Raises:
            TrajectoryError: The target is not finite or lies outside the joint limits given.
        """
        q_target = np.asarray(q_target, dtype=float)
        if q_target.shape != (self.n,) or not np.isfinite(q_target.sum()):  # NaN or inf anywhere
            raise TrajectoryError(f"target must be {self.n} finite joint positions, got {q_target}")
        if self.lower is not None and self.upper is not None and not (
            (q_target >= self.lower - 1e-9) & (q_target <= self.upper + 1e-9)
        ).all():
            bad = np.flatnonzero((q_target < self.lower - 1e-9) | (q_target > self.upper + 1e-9))
            if bad.size:
                detail = ", ".join(
                    f"{self.names[i]}={q_target[i]:.4f} not in [{self.lower[i]:.4f}, {self.upper[i]:.4f}]"
                    for i in bad
                )
                raise TrajectoryError(f"target outside the joint limits: {detail}")
        self._inp.target_position = q_target.tolist()
        self._inp.target_velocity = [0.0] * self.n if qd_target is None else np.asarray(qd_target, float).tolist()

    def update(self) -> RefState:
        """Advance the reference by ``dt`` towards the current target and return it.

        Raises:
            TrajectoryError: Ruckig rejected the input (the message names the joint) or failed.
        """
        prev = self._state
        result = self._update(ruckig.Synchronization.Time)
        new = self._output()
        if not np.isfinite(new[0].sum() + new[1].sum() + new[2].sum()):  # NaN or inf anywhere
            # Ruckig can return a non-finite step for a rare synchronised profile; redo the step from the last
            # good state without synchronisation (each joint's own profile honours every limit).
            self._inp.current_position, self._inp.current_velocity = prev.q.tolist(), prev.qd.tolist()
            self._inp.current_acceleration = prev.qdd.tolist()
            result = self._update(ruckig.Synchronization.No)
            new = self._output()
            if not all(np.isfinite(a).all() for a in new):
                bad = int(np.flatnonzero(~(np.isfinite(new[0]) & np.isfinite(new[1]) & np.isfinite(new[2])))[0])
                raise TrajectoryError(
                    f"reference update: Ruckig returned a non-finite state for joint {self.names[bad]}"
                )
        self._result = result
        self._t0 = self._out.time - self.dt
        self._out.pass_to_input(self._inp)
        self._state = RefState(*new)
        return self._state

    def _output(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration of Ruckig's last step."""
        out = self._out
        return np.array(out.new_position), np.array(out.new_velocity), np.array(out.new_acceleration)

    def _update(self, first: ruckig.Synchronization) -> ruckig.Result:
        """One Ruckig step with synchronisation ``first``, retried unsynchronised when it fails numerically.

        Time synchronisation of all joints can fail numerically for some states ("t sync"); each joint's own
        time-optimal profile still honours every limit. The input is left time-synchronised.
        """
        modes = (first,) if first == ruckig.Synchronization.No else (first, ruckig.Synchronization.No)
        try:
            for i, mode in enumerate(modes):
                if mode != ruckig.Synchronization.Time:  # the input is left time-synchronised between calls
                    self._inp.synchronization = mode
                try:
                    result = self._otg.update(self._inp, self._out)
                    break
                except ruckig.RuckigError as exc:
                    if i == len(modes) - 1:
                        result = self._nudged(exc)

        finally:
            if modes[-1] != ruckig.Synchronization.Time:
                self._inp.synchronization = ruckig.Synchronization.Time
        check_result(result, "reference update")
        return result

    def _nudged(self, exc: ruckig.RuckigError) -> ruckig.Result:
        """The step with the target ``NUDGE`` off (Ruckig fails rare states, "error in step 1"; raises if again)."""
        target, self._inp.target_position = self._inp.target_position, [q + NUDGE for q in self._inp.target_position]
        try:
            return self._otg.update(self._inp, self._out)
        except ruckig.RuckigError:
            raise joint_error(exc, "reference update", self.names) from None
        finally:
            self._inp.target_position = target

    def interpolate(self, tau: float) -> RefState:
        """The reference ``tau`` [s] after the start of the last :meth:`update` (0 <= tau <= dt)."""
        q, qd, qdd = self._out.trajectory.at_time(self._t0 + tau)
        return RefState(np.asarray(q), np.asarray(qd), np.asarray(qdd))

    @property
    def state(self) -> RefState:
        """The reference after the last :meth:`update` (or :meth:`reset`)."""
        return self._state

    @property
    def target(self) -> np.ndarray:
        """The current target position [rad]."""
        return np.array(self._inp.target_position)

    @property
    def done(self) -> bool:
        """True when the last update reached the end of the trajectory to the current target."""
        return self._result == ruckig.Result.Finished and self.is_at_target

    @property
    def is_at_target(self) -> bool:
        """True when the reference state equals the target state (within 1e-9)."""
        return bool(
            np.allclose(self._state.q, self._inp.target_position, atol=1e-9, rtol=0)
            and np.allclose(self._state.qd, self._inp.target_velocity, atol=1e-9, rtol=0)
        )


ReferenceGenerator = JointTrajectory
"""Alias: the online reference generator."""


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
