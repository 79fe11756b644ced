"""The measured-state seam: what the controller sees of the joints and the objects.

:class:`~nextage_qp.loop.simulation.Simulation` passes the joint state the PD law uses and the free-object poses the
phases
read through one :class:`Sensors` object; :class:`PerfectSensors` (the default) reports the truth. Noise, delay,
dropouts or an estimator are another ``Sensors``, with no edit to the loop.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple, Protocol

import mujoco
import numpy as np

from nextage_qp.errors import SensorError
from nextage_qp.geometry import Pose
from nextage_qp.mobile.drive_models import Pose2

if TYPE_CHECKING:
    from nextage_qp.robots.model import Robot


class Wrench(NamedTuple):
    """A contact wrench in the world frame: force [N] and torque about the sensor's site [N m]."""

    force: np.ndarray
    torque: np.ndarray


class WrenchSensor:
    """A force/torque pair on a site: the wrench the world exerts on the site's body through contacts.

    MuJoCo's sensors give the force and torque between the body and its parent. At rest, the parent carries the
    body's weight and every contact on it, so the contact wrench is ``F = -F_sensor - m g`` and
    ``T = -T_sensor - (c - p) x m g`` (``c`` the body's centre of mass, ``p`` the site); motion adds the body's
    inertial force ``m a``, small in slow manipulation.
    """

    def __init__(self, model: mujoco.MjModel, force_sensor: int, torque_sensor: int) -> None:
        self.site = int(model.sensor_objid[force_sensor])
        self.name = model.site(self.site).name
        self.body = int(model.site_bodyid[self.site])
        self.mass = float(model.body_mass[self.body])
        self.force_adr, self.torque_adr = int(model.sensor_adr[force_sensor]), int(model.sensor_adr[torque_sensor])
        self._readings = np.r_[self.force_adr : self.force_adr + 3, self.torque_adr : self.torque_adr + 3]
        self.gravity = np.array(model.opt.gravity)
        self._weight = self.mass * self.gravity
        w = self._weight
        self._weight_cross = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])  # w x (.)

    def read(self, data: mujoco.MjData) -> Wrench:
        """The contact wrench now, in the world frame."""
        # Both readings rotated to the world in one product: rows (force, torque) of sensed @ R^T.
        world = data.sensordata.take(self._readings).reshape(2, 3) @ data.site_xmat[self.site].reshape(3, 3).T
        force = np.negative(world[0])
        force -= self._weight
        # -(lever x weight) = weight x lever
        torque = self._weight_cross @ (data.xipos[self.body] - data.site_xpos[self.site])
        torque -= world[1]
        return Wrench(force, torque)

    @staticmethod
    def of_model(model: mujoco.MjModel) -> list[WrenchSensor]:
        """Every site that carries both a force and a torque sensor."""
        by_site: dict[int, dict[int, int]] = {}
        for s in range(model.nsensor):
            if model.sensor_objtype[s] == mujoco.mjtObj.mjOBJ_SITE:
                by_site.setdefault(int(model.sensor_objid[s]), {})[int(model.sensor_type[s])] = s
        force, torque = int(mujoco.mjtSensor.mjSENS_FORCE), int(mujoco.mjtSensor.mjSENS_TORQUE)
        return [WrenchSensor(model, kinds[force], kinds[torque]) for kinds in by_site.values()
                if force in kinds and torque in kinds]


def unsensed(robot: Robot, frames: Sequence[str]) -> list[tuple[str, str]]:
    """Each of ``frames`` whose body carries no force/torque sensor (:class:`WrenchSensor`), with that body's name.

    A clamp's pads must feel its squeeze: the ``grasp`` refuses pads listed here, ``robot check`` names them.
    """
    sensed = {s.body for s in WrenchSensor.of_model(robot.model)}
    bodies = [(frame, robot.frame_body(frame)) for frame in frames]
    return [(frame, robot.model.body(body).name) for frame, body in bodies if body not in sensed]


@dataclass(frozen=True)
class Measurement:
    """What the controller knows after a tick.

    Time [s], joint positions [rad] and velocities [rad/s], the pose of every free object, the contact
    wrench at every force/torque site, and a mobile robot's base pose.
    """

    t: float
    q: np.ndarray
    qd: np.ndarray
    objects: Mapping[str, Pose] = field(default_factory=dict)
    wrenches: Mapping[str, Wrench] = field(default_factory=dict)
    base: Pose2 | None = None
    """A mobile robot's base pose from its wheel odometry (the controller's world); objects are given in it."""


class SensorWatch:
    """Fails the run when a force/torque sensor returns NaN or freezes (the same reading for ``frozen_s``).

    A working sensor never repeats a reading exactly: noise, and in simulation the arm's own micro-motion, change
    it at every tick.
    """

    def __init__(self, frozen_s: float = 0.2) -> None:
        self.frozen_s = frozen_s
        self._last: dict[str, tuple[np.ndarray, float]] = {}  # site -> (reading, since when)

    def check(self, t: float, wrenches: Mapping[str, Wrench]) -> None:
        """Raise :class:`~nextage_qp.errors.SensorError` for a NaN or frozen reading at ``t`` [s]."""
        for name, w in wrenches.items():
            reading = np.concatenate([w.force, w.torque])
            if not np.isfinite(reading.sum()):  # a NaN or inf anywhere
                raise SensorError(f"t={t:.3f} s: force/torque sensor {name} returned {reading[:3].tolist()} "
                                  f"(not finite); the sensor failed")
            last = self._last.get(name)
            if last is None or not (last[0] == reading).all():
                self._last[name] = (reading, t)
            elif t - last[1] >= self.frozen_s - 1e-9:
                raise SensorError(f"t={t:.3f} s: force/torque sensor {name} has read the same value "
                                  f"{np.round(reading[:3], 4).tolist()} N since t={last[1]:.3f} s; the sensor froze")

    def reset(self) -> None:
        """Forget the readings seen."""
        self._last.clear()


class Sensors(Protocol):
    """The seam between physics and controller (default: :class:`PerfectSensors`)."""

    @property
    def joints_exact(self) -> bool:
        """Whether :meth:`joints` reports the true joint state (else robot frames come from the measured joints)."""

    def joints(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured joint positions [rad] and velocities [rad/s] at time ``t`` [s] (every control tick)."""

    def objects(self, t: float, true: Mapping[str, Pose]) -> Mapping[str, Pose]:
        """Measured object poses at time ``t`` [s] (every control tick)."""

    def wrenches(self, t: float, true: Mapping[str, Wrench]) -> Mapping[str, Wrench]:
        """Measured contact wrenches at time ``t`` [s] (every control tick)."""

    def seen_at(self, name: str) -> float | None:
        """Time [s] the latest measurement of an object's pose describes; None when the poses are the truth."""


class PerfectSensors:
    """Sensors that report the simulator's state exactly."""

    joints_exact = True

    def joints(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        return q, qd

    def objects(self, t: float, true: Mapping[str, Pose]) -> Mapping[str, Pose]:  # noqa: D102
        return true

    def wrenches(self, t: float, true: Mapping[str, Wrench]) -> Mapping[str, Wrench]:  # noqa: D102
        return true

    def seen_at(self, name: str) -> float | None:  # noqa: D102
        return None
