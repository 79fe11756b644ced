"""A wheeled base under a robot, added to a scene with MjSpec (the robot file's ``base:`` section).

The base is a body ``mobile_base`` on a free joint (``mobile_base_free``) whose origin is the middle of the driven
axle on the floor, x forward. The robot is attached to it so that the robot's own frame lands where the robot file's
mount puts it. Its weight rests on the wheels and casters, which touch the floor through MuJoCo's contacts:

* ``diff_drive``: two driven wheels (``mobile_base_wheel_right`` / ``_left``, hinge joints about the axle, velocity
  actuators with the wheel torque limit) and two frictionless caster spheres, in front of and behind the axle;
* ``bicycle``: the driven rear wheels as above, and two steered front wheels ``wheelbase`` ahead (a steering hinge
  with a position servo ``mobile_base_steer_right`` / ``_left``, Ackermann angles, and a free-rolling wheel);
* ``holonomic``: no wheels; planar joints ``mobile_base_x``, ``_y``, ``_yaw`` with velocity actuators (an
  omnidirectional platform) instead of the free joint.

Contacts between the floor and the robot's own root body (its feet, which the base now carries) are excluded.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from nextage_qp.mobile.base_file import BaseFile

BASE_BODY = "mobile_base"
"""Name of the base's body."""
BASE_JOINT = "mobile_base_free"
"""Name of the base's free joint (diff_drive, bicycle)."""
PLANAR_JOINTS = ("mobile_base_x", "mobile_base_y", "mobile_base_yaw")
"""The holonomic base's joints, and the IK model's base joints of every base type."""
WHEELS = ("mobile_base_wheel_right", "mobile_base_wheel_left")
"""The driven wheels' joints and actuators (right first)."""
STEERS = ("mobile_base_steer_right", "mobile_base_steer_left")
"""The bicycle's steering joints and their servos."""
FRONT_WHEELS = ("mobile_base_front_right", "mobile_base_front_left")
"""The bicycle's free-rolling front wheels' joints."""
WHEEL_HALF_WIDTH = 0.025
"""Half the width of a wheel [m]."""
CASTER_RADIUS = 0.025
"""Radius of a caster sphere [m]."""
STEER_KP = 400.0
"""Stiffness of the steering servos [N m / rad]."""


def add_base(spec: mujoco.MjSpec, base: BaseFile, pos: tuple[float, float, float], yaw: float) -> tuple[
        mujoco.MjsBody, mujoco.MjsFrame]:
    """Add the base to ``spec``'s world; returns its body and the frame the robot is attached to.

    ``pos``, ``yaw``: where the robot's own frame stands in the world (the robot file's mount).
    """
    x, y, heading = start_pose(base, pos, yaw)
    if base.type == "holonomic":  # its joints are the world's x, y and yaw: the body sits at the origin
        body = spec.worldbody.add_body(name=BASE_BODY)
    else:
        body = spec.worldbody.add_body(name=BASE_BODY, pos=[x, y, 0.0],
                                       quat=[math.cos(heading / 2), 0.0, 0.0, math.sin(heading / 2)])
    r, half_track = base.wheel_radius, 0.5 * base.track
    body.add_geom(name="mobile_base_chassis", type=mujoco.mjtGeom.mjGEOM_BOX, pos=[0.0, 0.0, r],
                  size=[0.5 * r, max(half_track - 2 * WHEEL_HALF_WIDTH, 0.01), base.chassis.half_height],
                  contype=0, conaffinity=0, group=2, rgba=[0.25, 0.27, 0.3, 1.0], mass=base.chassis.mass)
    if base.type == "holonomic":
        for name, axis, kind in zip(PLANAR_JOINTS, ([1, 0, 0], [0, 1, 0], [0, 0, 1]),
                                    (mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_SLIDE,
                                     mujoco.mjtJoint.mjJNT_HINGE), strict=True):
            body.add_joint(name=name, type=kind, axis=axis, damping=5.0)
    else:
        body.add_freejoint(name=BASE_JOINT)
        for name, side in zip(WHEELS, (-1.0, 1.0), strict=True):
            _wheel(body, name, [0.0, side * half_track, r], r)
        if base.type == "diff_drive":
            reach = max(2.5 * r, 0.25)
            for x in (reach, -reach):
                body.add_geom(name=f"{BASE_BODY}_caster_{'front' if x > 0 else 'back'}",
                              type=mujoco.mjtGeom.mjGEOM_SPHERE,
                              pos=[x, 0.0, CASTER_RADIUS], size=[CASTER_RADIUS, 0, 0], condim=1, priority=1,
                              rgba=[0.1, 0.1, 0.1, 1.0], mass=0.2)
        else:
            assert base.wheelbase is not None  # checked by the schema
            for steer, wheel, side in zip(STEERS, FRONT_WHEELS, (-1.0, 1.0), strict=True):
                knuckle = body.add_body(name=steer, pos=[base.wheelbase, side * half_track, r])
                knuckle.add_joint(name=steer, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1], damping=2.0,
                                  range=[-base.limits.steer, base.limits.steer], armature=0.01)
                knuckle.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.02, 0, 0], contype=0, conaffinity=0,
                                 group=2, mass=0.3)
                _wheel(knuckle, wheel, [0.0, 0.0, 0.0], r, driven=False)
    frame = body.add_frame(pos=[-base.axle_x, 0.0, pos[2] + base.lift])
    return body, frame


def start_pose(base: BaseFile, pos: tuple[float, float, float], yaw: float) -> tuple[float, float, float]:
    """World (x, y, yaw) of the base's reference point for a robot mounted at ``pos``, ``yaw``."""
    return pos[0] + math.cos(yaw) * base.axle_x, pos[1] + math.sin(yaw) * base.axle_x, yaw


def _wheel(parent: mujoco.MjsBody, name: str, pos: list[float], radius: float, *, driven: bool = True) -> None:
    wheel = parent.add_body(name=name, pos=pos)
    wheel.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0], damping=0.0 if driven else 0.01,
                    armature=0.01)
    # an ellipsoid tyre (radius r in the wheel's plane, the half-width across it) touches the floor at one point, as
    # a real tyre's contact patch does: a cylinder's two rims would scrub in every turn
    wheel.add_geom(name=f"{name}_tyre", type=mujoco.mjtGeom.mjGEOM_ELLIPSOID,
                   size=[radius, WHEEL_HALF_WIDTH, radius], friction=[1.2, 0.01, 0.001], condim=3, priority=1,
                   rgba=[0.08, 0.08, 0.08, 1.0], mass=1.5)


def add_base_actuators(spec: mujoco.MjSpec, base: BaseFile) -> None:
    """The base's actuators, after the robot's (whose actuators stay contiguous)."""
    lim = base.limits
    if base.type == "holonomic":
        for name, top, force in zip(PLANAR_JOINTS, (lim.speed, lim.speed, lim.turn_rate), (2000.0, 2000.0, 800.0),
                                    strict=True):
            act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_velocity(kv=4000.0 if name != PLANAR_JOINTS[2] else 1500.0)
            act.ctrlrange, act.ctrllimited = [-top, top], 1
            act.forcerange, act.forcelimited = [-force, force], 1
        return
    for name in WHEELS:
        act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_velocity(kv=8.0 * lim.wheel_torque / max(lim.wheel_speed, 1.0))
        act.ctrlrange, act.ctrllimited = [-lim.wheel_speed, lim.wheel_speed], 1
        act.forcerange, act.forcelimited = [-lim.wheel_torque, lim.wheel_torque], 1
    if base.type == "bicycle":
        for name in STEERS:
            act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_position(kp=STEER_KP, kv=20.0)
            act.ctrlrange, act.ctrllimited = [-lim.steer, lim.steer], 1


def ackermann(steer: float, wheelbase: float, half_track: float) -> tuple[float, float]:
    """Right and left front-wheel angles [rad] for the bicycle's steering angle ``steer`` [rad] (Ackermann)."""
    if abs(steer) < 1e-9:
        return 0.0, 0.0
    radius = wheelbase / math.tan(steer)  # signed turning radius of the rear axle's middle
    return math.atan(wheelbase / (radius + half_track)), math.atan(wheelbase / (radius - half_track))


def base_kinematic_joints(spec: mujoco.MjSpec) -> None:
    """Replace the base's free joint by the planar joints :data:`PLANAR_JOINTS` (the IK's copy)."""
    body = spec.body(BASE_BODY)
    if body is None:
        return
    for joint in list(body.joints):
        if joint.type == mujoco.mjtJoint.mjJNT_FREE:
            spec.delete(joint)
            body.pos, body.quat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]  # the joints are the world's x, y, yaw
            for name, axis, kind in zip(PLANAR_JOINTS, ([1, 0, 0], [0, 1, 0], [0, 0, 1]),
                                        (mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_SLIDE,
                                         mujoco.mjtJoint.mjJNT_HINGE), strict=True):
                body.add_joint(name=name, type=kind, axis=axis)


def planar_pose(pos: np.ndarray, quat: np.ndarray) -> tuple[float, float, float]:
    """(x, y, yaw) of a body from its world position and quaternion (w, x, y, z)."""
    w, x, y, z = (float(v) for v in quat)
    return float(pos[0]), float(pos[1]), math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
