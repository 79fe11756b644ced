r"""Wheeled-base kinematics: the differential drive and the kinematic bicycle, and exact motion on SE(2).

A planar pose is :math:`(x, y, \psi)` in the world; a body twist :math:`(v_x, v_y, \omega)` is the base's velocity
in its own frame (forward, left) [m/s] and its turn rate [rad/s].

**Differential drive** (wheel radius :math:`r`, wheels at :math:`\pm l` from the centre line, right wheel speed
:math:`\dot\varphi_R`, left :math:`\dot\varphi_L` [rad/s], positive rolling forward):

.. math:: v_x = \tfrac{r}{2}(\dot\varphi_R + \dot\varphi_L), \qquad v_y = 0, \qquad
          \omega = \tfrac{r}{2l}(\dot\varphi_R - \dot\varphi_L)

and back, :math:`\dot\varphi_{R,L} = (v_x \pm l\,\omega) / r`.

**Kinematic bicycle** (front steering angle :math:`\delta`, speed :math:`v` of the reference point, which lies
:math:`l_r` ahead of the rear axle and :math:`l_f` behind the front one):

.. math:: \beta = \arctan\frac{l_r \tan\delta}{l_f + l_r}, \qquad v_x = v\cos\beta, \quad v_y = v\sin\beta,
          \quad \omega = \frac{v}{l_r}\sin\beta

(with the reference point on the rear axle, :math:`l_r = 0`: :math:`\beta = 0`, :math:`\omega = v\tan\delta / L`).

**Exact integration.** A body twist held for :math:`\Delta t` moves the base along a circular arc (the exponential
of SE(2)): :math:`\Delta\psi = \omega\Delta t` and, in the start frame,

.. math:: \begin{pmatrix}\Delta x\\ \Delta y\end{pmatrix} = \frac{1}{\omega}
          \begin{pmatrix}\sin\Delta\psi & \cos\Delta\psi - 1\\ 1 - \cos\Delta\psi & \sin\Delta\psi\end{pmatrix}
          \begin{pmatrix}v_x\\ v_y\end{pmatrix}

(a series near :math:`\omega = 0`), so a robot that cannot slide sideways never drifts sideways in its odometry.
"""

from __future__ import annotations

import math
from typing import NamedTuple


class Twist(NamedTuple):
    """A planar body twist: forward and left velocity [m/s], turn rate [rad/s]."""

    vx: float
    vy: float
    omega: float


class Pose2(NamedTuple):
    """A planar pose in the world: position [m] and heading [rad]."""

    x: float
    y: float
    yaw: float


class DiffDrive(NamedTuple):
    """A differential-drive base.

    Attributes:
        wheel_radius: :math:`r` [m].
        half_track: :math:`l`, each wheel's distance from the centre line [m] (half the track).
    """

    wheel_radius: float
    half_track: float

    def forward(self, right: float, left: float) -> Twist:
        """Body twist from the wheel speeds [rad/s]."""
        r, half = self.wheel_radius, self.half_track
        return Twist(0.5 * r * (right + left), 0.0, 0.5 * r * (right - left) / half)

    def inverse(self, vx: float, omega: float) -> tuple[float, float]:
        """Wheel speeds (right, left) [rad/s] for a forward velocity [m/s] and a turn rate [rad/s]."""
        r, half = self.wheel_radius, self.half_track
        return (vx + half * omega) / r, (vx - half * omega) / r


class Bicycle(NamedTuple):
    """A kinematic bicycle (a car-like base with front steering).

    Attributes:
        front: :math:`l_f`, from the reference point to the front axle [m].
        rear: :math:`l_r`, from the rear axle to the reference point [m] (0: the reference point on the rear axle).
    """

    front: float
    rear: float

    @property
    def wheelbase(self) -> float:
        """:math:`L = l_f + l_r` [m]."""
        return self.front + self.rear

    def slip(self, steer: float) -> float:
        r""":math:`\beta` [rad] at the steering angle ``steer`` [rad]."""
        return math.atan(self.rear * math.tan(steer) / self.wheelbase)

    def forward(self, speed: float, steer: float) -> Twist:
        """Body twist of the reference point from its speed [m/s] and the steering angle [rad]."""
        if self.rear == 0.0:
            return Twist(speed, 0.0, speed * math.tan(steer) / self.wheelbase)
        beta = self.slip(steer)
        return Twist(speed * math.cos(beta), speed * math.sin(beta), speed * math.sin(beta) / self.rear)

    def inverse(self, speed: float, omega: float) -> float:
        r"""Steering angle [rad] that turns at ``omega`` [rad/s] at ``speed`` [m/s] (0 at rest).

        Raises:
            ValueError: No steering angle gives that turn rate at that speed (:math:`|\omega l_r / v| > 1`).
        """
        if speed == 0.0:
            return 0.0
        if self.rear == 0.0:
            return math.atan(omega * self.wheelbase / speed)
        sin_beta = omega * self.rear / speed
        if abs(sin_beta) > 1.0:
            raise ValueError(f"turn rate {omega:g} rad/s is beyond any steering angle at {speed:g} m/s")
        return math.atan(math.tan(math.asin(sin_beta)) * self.wheelbase / self.rear)


def integrate(pose: Pose2, twist: Twist, dt: float) -> Pose2:
    """The pose after holding a body ``twist`` for ``dt`` [s]: the exact arc (SE(2) exponential)."""
    theta = twist.omega * dt
    if abs(theta) > 1e-6:
        s, c = math.sin(theta) / theta, (1.0 - math.cos(theta)) / theta
    else:  # series, exact to rounding for |theta| <= 1e-6
        t2 = theta * theta
        s, c = 1.0 - t2 / 6.0, theta * (0.5 - t2 / 24.0)
    dx = (s * twist.vx - c * twist.vy) * dt
    dy = (c * twist.vx + s * twist.vy) * dt
    cos_y, sin_y = math.cos(pose.yaw), math.sin(pose.yaw)
    return Pose2(pose.x + cos_y * dx - sin_y * dy, pose.y + sin_y * dx + cos_y * dy, pose.yaw + theta)


def body_twist(pose: Pose2, world_velocity: tuple[float, float, float]) -> Twist:
    """The body twist of a base at ``pose`` moving at world velocity (x-dot, y-dot [m/s], yaw rate [rad/s])."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    xd, yd, wd = world_velocity
    return Twist(c * xd + s * yd, -s * xd + c * yd, wd)


def relative(a: Pose2, b: Pose2) -> Pose2:
    """Pose ``b`` expressed in the frame of ``a``."""
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    dx, dy = b.x - a.x, b.y - a.y
    return Pose2(c * dx + s * dy, -s * dx + c * dy, math.remainder(b.yaw - a.yaw, 2.0 * math.pi))
