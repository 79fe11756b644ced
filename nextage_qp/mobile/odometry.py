"""What the controller believes of its base: wheel odometry, the transform to its world, and a run's report.

:class:`Odometry` integrates the driven wheels' encoder angles with the forward kinematics on exact arcs;
:func:`to_odometry` expresses a true world pose where the odometry's world has it (a robot's own sensors report
objects relative to itself); :class:`BaseTrack` does both every tick and logs the truth beside them, from which
:func:`base_report` makes the run's figures.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import mujoco
import numpy as np

from nextage_qp.geometry import Pose, rot_z
from nextage_qp.mobile.base import MobileBase
from nextage_qp.mobile.drive_models import Pose2, Twist, integrate


class Odometry:
    r"""Dead reckoning from the driven wheels' encoders (a holonomic base: its joints' encoders).

    Each update integrates the wheels' angle changes since the last one as one exact arc of the forward
    kinematics: :math:`\Delta s = r(\Delta\varphi_R + \Delta\varphi_L)/2`,
    :math:`\Delta\psi = r(\Delta\varphi_R - \Delta\varphi_L)/(2l)` (a bicycle's rear axle alike).
    """

    def __init__(self, base: MobileBase) -> None:
        self.base = base
        self.pose = base.start
        self._last: np.ndarray | None = None

    def reset(self, data: mujoco.MjData, pose: Pose2 | None = None) -> None:
        """Start from ``pose`` (default: the base's start pose) at the wheels' angles now."""
        self.pose = self.base.start if pose is None else pose
        self._last = self.base.wheel_angles(data) if self.base.type != "holonomic" else None

    def update(self, data: mujoco.MjData) -> Pose2:
        """Integrate the encoders' motion since the last update; returns the pose."""
        base = self.base
        if base.type == "holonomic":
            self.pose = Pose2(*(float(v) for v in data.qpos[base.planar_qpos]))
            return self.pose
        now = base.wheel_angles(data)
        if self._last is None:
            self._last = now
            return self.pose
        d_right, d_left = (float(v) for v in now - self._last)
        self._last = now
        step = base.drive.forward(d_right, d_left)  # over a unit time: the arc's length and turn
        self.pose = integrate(self.pose, step, 1.0)
        return self.pose


def drift(true: Pose2, believed: Pose2) -> tuple[np.ndarray, np.ndarray]:
    """The planar transform (rotation 3x3, translation) from the true world to the odometry's world.

    A point fixed to the base is at ``p_true`` in the world and at ``R p_true + t`` where the odometry puts it.
    """
    rot = rot_z(believed.yaw - true.yaw)
    pos = np.array([believed.x, believed.y, 0.0]) - rot @ np.array([true.x, true.y, 0.0])
    return rot, pos


def to_odometry(pose: Pose, true: Pose2, believed: Pose2) -> Pose:
    """A true world pose expressed in the odometry's world.

    As a robot's own sensor reports it: relative to itself, composed with where its odometry says it is.
    """
    rot, pos = drift(true, believed)
    return Pose(rot @ pose.pos + pos, rot @ pose.rot)


class BaseTrack:
    """A simulation's view of its robot's base: the base, its odometry, and a log of every tick.

    Attributes:
        base: The base.
        odometry: Its wheel odometry.
        log: Per tick: t [s], true x, y, yaw, odometry x, y, yaw, true forward and lateral speed [m/s], commanded
            forward speed [m/s].
    """

    def __init__(self, base: MobileBase) -> None:
        self.base, self.odometry = base, Odometry(base)
        self.log: list[tuple[float, ...]] = []

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """The base at its start, stopped; odometry from there; an empty log."""
        self.base.reset(data)
        mujoco.mj_forward(model, data)
        self.odometry.reset(data)
        self.log.clear()

    def command(self, data: mujoco.MjData, twist: Twist) -> Twist:
        """Command the base's body twist (held over the next ticks); returns what its limits let through."""
        return self.base.command(data, twist)

    def observe(self, data: mujoco.MjData, t: float, objects: Mapping[str, Pose]) -> tuple[Pose2, dict[str, Pose]]:
        """After a tick: the odometry's pose, and ``objects`` (true world poses) in the odometry's world."""
        believed, true = self.odometry.update(data), self.base.pose(data)
        tw = self.base.twist(data)
        self.log.append((t, *true, *believed, tw.vx, tw.vy, self.base.command_twist.vx))
        return believed, {name: to_odometry(pose, true, believed) for name, pose in objects.items()}


LATERAL_LIMIT = 0.01
"""Lateral speed [m/s] of a base's reference point above which a tick counts as sliding sideways."""


def base_report(log: list[tuple[float, ...]], base: MobileBase) -> dict[str, object]:
    """What a run's base did, from the simulation's per-tick log (:attr:`BaseTrack.log`).

    Distance driven (true), final true and odometry poses, the odometry's drift (position [m], heading [rad]),
    the largest true lateral speed of the reference point [m/s], and wheel slip: the ticks whose lateral speed
    exceeds ``LATERAL_LIMIT`` and the largest gap between the odometry's and the true forward speed [m/s].
    """
    if len(log) < 2:
        return {}
    a = np.array(log)
    t, true, odo, forward, lateral = a[:, 0], a[:, 1:4], a[:, 4:7], a[:, 7], a[:, 8]
    dt = np.diff(t)
    odo_speed = np.hypot(*np.diff(odo[:, :2], axis=0).T) / np.where(dt > 0, dt, np.inf)
    slipping = np.abs(lateral) > LATERAL_LIMIT
    return {
        "type": base.type,
        "distance_m": round(float(np.sum(np.hypot(*np.diff(true[:, :2], axis=0).T))), 4),
        "final_pose": [round(float(v), 5) for v in true[-1]],
        "final_odometry_pose": [round(float(v), 5) for v in odo[-1]],
        "odometry_drift_m": round(float(np.hypot(*(odo[-1, :2] - true[-1, :2]))), 5),
        "odometry_drift_rad": round(abs(math.remainder(float(odo[-1, 2] - true[-1, 2]), 2 * math.pi)), 5),
        "max_lateral_speed_m_s": round(float(np.max(np.abs(lateral))), 5),
        "sliding_ticks": int(np.count_nonzero(slipping)),
        "max_wheel_slip_m_s": round(float(np.max(np.abs(odo_speed - np.abs(forward[1:])), initial=0.0)), 5),
    }
