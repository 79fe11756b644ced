"""``drive``: take a mobile robot's base to a pose relative to a body, around obstacles, with the arms held.

The goal is where the robot's own frame (the robot file's mount frame; with ``frame: base``, the base's reference
point) should stand: ``offset`` (x, y [m]) and ``yaw`` [rad] in the frame of ``relative_to`` (a body, turned about z
only, or the world). The phase plans, from
where the odometry puts the base:

* a differential drive or a holonomic base: the shortest polyline that keeps the base's swept circle (how far the
  robot reaches from its reference point) ``clearance`` away from every ``avoid`` body's footprint, ending with a
  straight ``approach`` leg along the goal's heading; the differential drive turns in place at its corners;
* a bicycle (car-like) base: the shortest forward Dubins path to the goal with turns no tighter than its steering
  allows (``turn_margin`` wider), obstacles not considered.

Each tick the plan's timed pose (straight legs at ``speed``, turns at ``turn_rate``, ``accel`` ramps) is the target
of the base's frame in the whole-body IK (``cost`` per metre and radian, far above the base's motion cost), whose
rows keep it on its wheels (no sideways step, wheel speeds, curvature); the arms hold their joints. Done when the
plan has run out and the odometry puts the base within ``tolerance`` and ``yaw_tolerance`` of the goal, stopped.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.geometry import rot_z
from nextage_qp.ik import FrameTarget
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import View, reference
from nextage_qp.manipulation.phases.base import SETTLE_S, Phase, Spec, name_field
from nextage_qp.mobile.build import BASE_BODY
from nextage_qp.mobile.drive_models import Pose2, relative
from nextage_qp.mobile.drive_paths import Motion, around, dubins, polyline_motion


class DriveSpec(Spec):
    """Drive the base to a pose relative to a body, around the bodies it must avoid."""

    kind: Literal["drive"]
    relative_to: str = name_field("reference", default="world", description="Body whose frame the goal is in.")
    frame: Literal["robot", "base"] = Field(
        default="robot", description="Whose pose the goal is: the robot's own frame, or the base's reference point.")
    offset: tuple[float, float] = Field(description="Robot frame's x, y in that frame [m].")
    yaw: float = Field(default=0.0, ge=-7.0, le=7.0, description="Robot frame's yaw in that frame [rad].")
    approach: float = Field(default=0.6, ge=0.0, le=10.0,
                            description="Final straight leg along the goal's heading [m].")
    avoid: tuple[str, ...] = name_field("body", default=(), description="Bodies on the floor to keep clear of.")
    clearance: float = Field(default=0.1, ge=0.0, le=5.0,
                             description="Gap between the swept circle and the avoid bodies [m].")
    speed: float = Field(default=0.3, gt=0.0, le=5.0,
                         description="Speed on straight legs [m/s] (at most the base's limits.speed).")
    turn_rate: float = Field(default=0.6, gt=0.0, le=10.0,
                             description="Turn rate in turns [rad/s] (at most the base's limits.turn_rate).")
    accel: float = Field(default=0.3, gt=0.0, le=10.0,
                         description="Acceleration ramp of straight legs [m/s²] (turns: in proportion, accel / speed "
                                     "* turn_rate).")
    turn_margin: float = Field(default=1.15, ge=1.0, le=5.0,
                               description="Bicycle: turning radius as a multiple of its least [1].")
    tolerance: float = Field(default=0.02, gt=0.0, le=1.0,
                             description="Largest position error, by the odometry, at the end [m].")
    yaw_tolerance: float = Field(default=0.03, gt=0.0, le=1.0,
                                 description="Largest yaw error, by the odometry, at the end [rad].")
    cost: float = Field(default=20.0, gt=0.0, le=1e4, description="Weight of the base's pose target [1/m, 1/rad].")


class Drive(Phase):
    """See the module docstring."""

    spec: DriveSpec

    def start(self, view: View) -> None:  # noqa: D102
        c = self.spec
        base, pose = view.base(), view.base_pose()
        if base is None or pose is None:
            raise self.refusal(view, "the robot has no base (robot file: base:)")
        ref, ref_yaw = reference(view, c.relative_to)
        cos_r, sin_r = math.cos(ref_yaw), math.sin(ref_yaw)
        gx = ref[0] + cos_r * c.offset[0] - sin_r * c.offset[1]
        gy = ref[1] + sin_r * c.offset[0] + cos_r * c.offset[1]
        yaw = ref_yaw + c.yaw
        ax = base.spec.axle_x if c.frame == "robot" else 0.0  # the base's reference point: the robot frame's axle
        self.goal = Pose2(gx + math.cos(yaw) * ax, gy + math.sin(yaw) * ax, yaw)
        speed, turn = min(c.speed, base.limits.speed), min(c.turn_rate, base.limits.turn_rate)
        if base.type == "bicycle":
            assert base.bicycle is not None
            radius = c.turn_margin * base.bicycle.wheelbase / math.tan(base.limits.steer)
            legs = dubins(pose, self.goal, radius)
            self.info["turn_radius_m"] = round(radius, 3)
        else:
            # each obstacle kept clear of what reaches down below its top (arms pass over a crate)
            circles = [(x, y, r + view.base_radius(top + c.clearance) + c.clearance)
                       for x, y, r, top in (view.footprint(b) for b in c.avoid)]
            pre = np.array([self.goal.x - c.approach * math.cos(yaw), self.goal.y - c.approach * math.sin(yaw)])
            points = around(np.array([pose.x, pose.y]), pre, circles)
            if points is None:
                raise self.refusal(
                    view, f"no path keeps the base clear of {', '.join(c.avoid)} to the goal "
                    f"({self.goal.x:.2f}, {self.goal.y:.2f}): the start or the approach point is within an "
                    f"obstacle's clearance (circles {[tuple(round(v, 2) for v in k) for k in circles]})")
            if c.approach > 0:
                points.append(np.array([self.goal.x, self.goal.y]))
            legs = polyline_motion(pose, points, yaw)
            self.info["waypoints"] = len(points)
        self.motion = Motion(pose, legs, speed, turn, c.accel)
        self.start_t = view.t
        self.arms: np.ndarray | None = None
        self.info.update(path_m=round(sum(abs(leg.length) for leg in legs), 3),
                         planned_s=round(self.motion.duration, 2))

    def budget(self, view: View) -> float:
        """The planned motion's duration, the time it may then take to reach the goal, and coming to rest."""
        return self.motion.duration + self._late() + SETTLE_S

    def _late(self) -> float:
        """How long [s] after the planned motion ends the base may still be short of its goal."""
        return max(5.0, 0.5 * self.motion.duration)

    def update(self, view: View) -> Command:  # noqa: D102
        c = self.spec
        pose = view.base_pose()
        assert pose is not None
        if self.arms is None:  # the arms hold the joints they had when the drive began
            self.arms = view.joint_positions(view.joint_names())
        t = view.t - self.start_t
        ref = self.motion.at(t)
        error = relative(pose, self.goal)
        dist, turn = math.hypot(error.x, error.y), abs(error.yaw)
        self.info.update(error_m=round(dist, 4), yaw_error_rad=round(turn, 4))
        done = t >= self.motion.duration and dist <= c.tolerance and turn <= c.yaw_tolerance and view.settled()
        if t > self.motion.duration + self._late() and not done:
            raise self.failure(f"the base is {dist * 1e3:.0f} mm and "
                             f"{math.degrees(turn):.1f} deg from its goal {self.motion.duration:.1f} s after the "
                             "plan ended (odometry)")
        target = FrameTarget(BASE_BODY, pos=np.array([ref.x, ref.y, 0.0]), rot=rot_z(ref.yaw), position_cost=c.cost,
                             orientation_cost=c.cost)
        return Command((target,), posture=self.arms, base=not done, done=done)
