"""The wheeled base of a compiled model: its indices, its commands and its true state.

:class:`MobileBase` turns a body twist into actuator commands through the base's inverse kinematics (a
differential drive's wheel speeds; a bicycle's rear wheel speeds and Ackermann front angles; a holonomic base's
joint velocities) and reads the truth the run reports against (what the controller believes:
:mod:`nextage_qp.mobile.odometry`).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.io.per_joint import descends
from nextage_qp.mobile.base_file import BaseFile
from nextage_qp.mobile.build import (
    BASE_BODY,
    BASE_JOINT,
    PLANAR_JOINTS,
    STEERS,
    WHEELS,
    ackermann,
    planar_pose,
    start_pose,
)
from nextage_qp.mobile.drive_models import Bicycle, DiffDrive, Pose2, Twist

HOLD_GAIN = 10.0
"""Gain [1/s] with which a standing base's driven joints return to the angles they hold."""


class MobileBase:
    """A robot's base in one compiled model.

    Args:
        model: The compiled scene with the base (:func:`~nextage_qp.mobile.build.add_base`).
        spec: The robot file's ``base:`` section.
        mount: Where the robot's own frame starts: (x, y, z) [m] and yaw [rad].
        source: The robot file (for messages).

    Raises:
        ConfigError: The model lacks the base's body, joints or actuators.
    """

    def __init__(self, model: mujoco.MjModel, spec: BaseFile, mount: tuple[tuple[float, float, float], float],
                 source: str) -> None:
        self.spec, self.type, self.limits = spec, spec.type, spec.limits
        self.drive = DiffDrive(spec.wheel_radius, 0.5 * spec.track)
        self.bicycle = Bicycle(spec.wheelbase, 0.0) if spec.wheelbase is not None else None
        self.start = Pose2(*start_pose(spec, *mount))
        self.body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, BASE_BODY)
        if self.body < 0:
            raise ConfigError(f"{source}: base: the model has no body {BASE_BODY!r}")

        def joint(name: str) -> int:
            jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if jid < 0:
                raise ConfigError(f"{source}: base: the model has no joint {name!r}")
            return jid

        def actuator(name: str) -> int:
            aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
            if aid < 0:
                raise ConfigError(f"{source}: base: the model has no actuator {name!r}")
            return aid

        if self.type == "holonomic":
            ids = [joint(n) for n in PLANAR_JOINTS]
            self.planar_qpos = np.array([model.jnt_qposadr[j] for j in ids])
            self.planar_dof = np.array([model.jnt_dofadr[j] for j in ids])
            self.actuators = np.array([actuator(n) for n in PLANAR_JOINTS])
            self.wheel_qpos = self.wheel_dof = np.zeros(0, dtype=int)
        else:
            free = joint(BASE_JOINT)
            self.free_qpos, self.free_dof = int(model.jnt_qposadr[free]), int(model.jnt_dofadr[free])
            wheels = [joint(n) for n in WHEELS]
            self.wheel_qpos = np.array([model.jnt_qposadr[j] for j in wheels])
            self.wheel_dof = np.array([model.jnt_dofadr[j] for j in wheels])
            self.actuators = np.array([actuator(n) for n in WHEELS])
            self.steer_actuators = np.array([actuator(n) for n in STEERS]) if self.type == "bicycle" else None
        self.command_twist = Twist(0.0, 0.0, 0.0)
        """The body twist last commanded."""
        self._hold: np.ndarray | None = None  # the driven joints' angles a standing base holds
        subtree = [b for b in range(model.nbody) if descends(model, b, self.body)]
        colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        self._geoms = np.flatnonzero(np.isin(model.geom_bodyid, subtree) & colliding)
        # each geom's bounding box (local frame: centre, half-sizes) as its 8 corners
        box = model.geom_aabb[self._geoms].reshape(-1, 2, 3)
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
        self._corners = box[:, None, 0, :] + signs[None] * box[:, None, 1, :]  # (geoms, 8, 3)

    def radius(self, data: mujoco.MjData, below: float = np.inf) -> float:
        """How far [m] the robot and its base reach from the reference point in the floor's plane, as they stand.

        The circle it sweeps turning in place; only what reaches down below the height ``below`` [m] counts.
        """
        rot = data.geom_xmat[self._geoms].reshape(-1, 3, 3)
        corners = np.einsum("gij,gkj->gki", rot, self._corners) + data.geom_xpos[self._geoms][:, None, :]
        low = corners[:, :, 2].min(axis=1) < below
        planar = corners[low, :, :2] - data.xpos[self.body][:2]
        return float(np.max(np.hypot(planar[..., 0], planar[..., 1]), initial=0.0))

    def reset(self, data: mujoco.MjData) -> None:
        """Put a holonomic base at its start pose (a free base starts there from the model) and stop it."""
        if self.type == "holonomic":
            data.qpos[self.planar_qpos] = self.start
        self._hold = None
        self.command(data, Twist(0.0, 0.0, 0.0))

    def place(self, data: mujoco.MjData, pose: tuple[float, float, float] | np.ndarray) -> None:
        """Put the base at a planar pose (x, y [m], yaw [rad]) in ``data`` (kinematics must be run afterwards)."""
        x, y, yaw = (float(v) for v in pose)
        if self.type == "holonomic":
            data.qpos[self.planar_qpos] = x, y, yaw
            return
        data.qpos[self.free_qpos : self.free_qpos + 2] = x, y
        data.qpos[self.free_qpos + 3 : self.free_qpos + 7] = math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)

    def pose(self, data: mujoco.MjData) -> Pose2:
        """The true planar pose of the base's reference point (the driven axle's middle)."""
        if self.type == "holonomic":
            return Pose2(*(float(v) for v in data.qpos[self.planar_qpos]))
        q = data.qpos
        return Pose2(*planar_pose(q[self.free_qpos : self.free_qpos + 3], q[self.free_qpos + 3 : self.free_qpos + 7]))

    def twist(self, data: mujoco.MjData) -> Twist:
        """The true body twist of the reference point: forward, lateral [m/s] and turn rate [rad/s]."""
        yaw = self.pose(data).yaw
        if self.type == "holonomic":
            xd, yd, wd = (float(v) for v in data.qvel[self.planar_dof])
        else:  # a free joint's qvel: world linear velocity of the body's origin, then angular (local frame)
            dof = self.free_dof
            xd, yd = float(data.qvel[dof]), float(data.qvel[dof + 1])
            local = data.qvel[dof + 3 : dof + 6]
            rot = data.xmat[self.body].reshape(3, 3)
            wd = float((rot @ local)[2])
        c, s = math.cos(yaw), math.sin(yaw)
        return Twist(c * xd + s * yd, -s * xd + c * yd, wd)

    def wheel_angles(self, data: mujoco.MjData) -> np.ndarray:
        """The driven wheels' encoder angles [rad] (right, left)."""
        return data.qpos[self.wheel_qpos].copy()

    def command(self, data: mujoco.MjData, twist: Twist) -> Twist:
        r"""Send a body twist to the actuators through the inverse kinematics; returns the twist sent.

        The twist is scaled down uniformly until every wheel speed and the steering angle are within the limits
        (so the path's curvature is kept); a bicycle's lateral velocity is dropped (it has none at its rear axle),
        and so is a differential drive's. A zero twist brakes: the driven joints hold the angles they had when it
        began (velocity commands :math:`-k_{hold}(\varphi - \varphi_{hold})`), so forces on the robot (an arm
        pushing, its own reaction) do not make a parked base creep.
        """
        lim = self.limits
        vx, vy, w = float(twist.vx), float(twist.vy), float(twist.omega)
        if vx == 0.0 and vy == 0.0 and w == 0.0:
            joints = self.planar_qpos if self.type == "holonomic" else self.wheel_qpos
            if self._hold is None:
                self._hold = data.qpos[joints].copy()
            data.ctrl[self.actuators] = -HOLD_GAIN * (data.qpos[joints] - self._hold)
            self.command_twist = Twist(0.0, 0.0, 0.0)
            return self.command_twist
        self._hold = None
        if self.type == "holonomic":
            scale = min(1.0, lim.speed / max(math.hypot(vx, vy), 1e-12), lim.turn_rate / max(abs(w), 1e-12))
            vx, vy, w = vx * scale, vy * scale, w * scale
            yaw = self.pose(data).yaw
            c, s = math.cos(yaw), math.sin(yaw)
            data.ctrl[self.actuators] = (c * vx - s * vy, s * vx + c * vy, w)
            self.command_twist = Twist(vx, vy, w)
            return self.command_twist
        vy = 0.0
        if self.type == "bicycle":
            assert self.bicycle is not None and self.steer_actuators is not None
            k = math.tan(lim.steer) / self.bicycle.wheelbase  # largest curvature
            if abs(w) > k * abs(vx):  # beyond the steering: keep the speed, turn as tightly as it can
                w = math.copysign(k * abs(vx), w)
            steer = self.bicycle.inverse(vx, w) if vx != 0.0 else 0.0
            data.ctrl[self.steer_actuators] = ackermann(steer, self.bicycle.wheelbase, self.drive.half_track)
        right, left = self.drive.inverse(vx, w)
        scale = min(1.0, lim.wheel_speed / max(abs(right), abs(left), 1e-12))
        data.ctrl[self.actuators] = (right * scale, left * scale)
        self.command_twist = Twist(vx * scale, 0.0, w * scale)
        return self.command_twist
