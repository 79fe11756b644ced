"""Transit through free space on planned joints.

Waypoints for one or more frames are each solved by the offline IK from the previous waypoint's solution, and
driven as joint goals. Streaming Cartesian setpoints through the differential IK can stall in a local minimum
against a collision constraint (a hand folded near the torso, a forearm over an object). Planning each waypoint
with the multi-start IK first tells whether the route is reachable at all, and driving the joints there (Ruckig
shapes the motion) cannot stall on the way. Consecutive waypoints are solved from one another, so the joints
move between neighbouring configurations.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from nextage_qp.ik import FrameTarget
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import Setpoint, View

REACHED = 0.005
"""A waypoint counts as reached when every frame is this close to where the planned joints put it [m] and the robot
has settled."""


class PlannedRoute:
    """Waypoints (each a tuple of frame targets reached together) driven through planned joints.

    Args:
        waypoints: The route; the frames of each waypoint are solved together.
        straight: Per waypoint, whether the leg to it is a straight Cartesian line (frames' setpoints streamed
            through the IK, with its collision avoidance, and the planned joints as the posture to head for)
            instead of a joint-space move; for short legs near objects, such as going down beside one.
        speed: Cartesian speed of straight legs [m/s].
        pos_tol: Position error [m] within which the planner counts a waypoint as reached (default: the view's).
        continuous: The planner's random restarts (a reconfiguration of the arms) for the first waypoint only; each
            later one is reached by descending from the previous one's joints, so the arms do not swing between
            neighbouring waypoints (and a route out of reach is given up at the cost of one descent per waypoint).
    """

    def __init__(self, waypoints: Sequence[Sequence[FrameTarget]], straight: Sequence[bool] | None = None,
                 speed: float = 0.05, pos_tol: float | None = None, continuous: bool = False) -> None:
        self.waypoints = [tuple(w) for w in waypoints]
        self.straight = list(straight) if straight is not None else [False] * len(self.waypoints)
        self.speed, self.pos_tol, self.continuous = speed, pos_tol, continuous
        self.joints: list[np.ndarray] = []
        self.planned: list[list[np.ndarray]] = []  # per waypoint, each frame's position at the planned joints
        self.leg = 0
        self._points: list[Setpoint] | None = None

    def plan(self, view: View, restarts: bool = True) -> bool:
        """Solve every waypoint, each from the previous solution; False when one is out of reach.

        ``restarts=False``: each waypoint only by the descent from the previous one (see :meth:`View.plan`); a
        ``continuous`` route restarts for its first waypoint only.
        """
        self.joints, self.planned, start = [], [], None
        for k, targets in enumerate(self.waypoints):
            q = view.plan(targets, start, pos_tol=self.pos_tol, restarts=restarts and (k == 0 or not self.continuous))
            if q is None:
                return False
            self.joints.append(q)
            self.planned.append([view.pose_at(t.frame, q).pos for t in targets])
            start = q
        self.leg = 0
        return True

    @property
    def done(self) -> bool:
        """True once the last waypoint has been reached."""
        return self.leg >= len(self.waypoints)

    def step(self, view: View) -> Command:
        """This tick's command towards the current waypoint; moves on once its frames are there and settled."""
        leg = min(self.leg, len(self.joints) - 1)
        q, targets = self.joints[leg], self.waypoints[leg]
        if self.straight[leg]:
            if self._points is None:
                self._points = [Setpoint(view.commanded_pose(t.frame).pos) for t in targets]
            for point, t in zip(self._points, targets, strict=True):
                point.advance(np.asarray(t.pos), self.speed, view.dt)
            command = Command(tuple(dataclasses.replace(t, pos=p.pos) for t, p in zip(targets, self._points,
                                                                                        strict=True)), posture=q)
        else:
            command = Command(joints=dict(zip(view.joint_names(), q, strict=True)))
        if not self.done:
            near = all(float(np.linalg.norm(view.frame_pose(t.frame).pos - p)) < REACHED
                       for t, p in zip(targets, self.planned[leg], strict=True))
            if near and view.settled():
                self.leg += 1
                self._points = None
        return command
