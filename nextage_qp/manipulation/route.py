"""Transit through free space on planned joints.

Waypoints for one or more frames are each solved by the offline IK from the previous waypoint's solution, and
driven as joint goals. Streaming Cartesian setpoints through the differential IK can stall in a local minimum
against a collision constraint (a hand folded near the torso, a forearm over an object). Planning each waypoint
with the multi-start IK first tells whether the route is reachable at all, and driving the joints there (Ruckig
shapes the motion) cannot stall on the way. Consecutive waypoints are solved from one another, so the joints
move between neighbouring configurations.

Each joint-space leg is checked before it runs (:meth:`View.plan_path`): where the straight segment between two
waypoints' joints would touch an obstacle, an object or the robot itself, the leg follows a planned collision-free
path instead (``plan: auto``); ``always`` plans every leg, ``never`` drives the straight segments unchecked.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Literal, get_args

import numpy as np

from nextage_qp.errors import PhaseError
from nextage_qp.geometry import path_length
from nextage_qp.ik import FrameTarget
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import Setpoint, View

PlanMode = Literal["auto", "always", "never"]
"""``plan``: a leg planned where its straight segment is blocked, every leg planned, or none."""
PLAN_MODES: tuple[str, ...] = get_args(PlanMode)
"""The values of :data:`PlanMode`."""
VIA_TOL = 0.01
"""A planned path's intermediate waypoint counts as reached when every joint is this close [rad] and settled."""

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
        plan: How joint-space legs are checked and planned (:data:`PLAN_MODES`).
        near: Bodies the route may come near but not touch (the object it goes to).

    Attributes:
        blocked: Why the last :meth:`plan` found no path for a leg (None when it found one for every leg).
    """

    def __init__(self, waypoints: Sequence[Sequence[FrameTarget]], straight: Sequence[bool] | None = None,
                 speed: float = 0.05, pos_tol: float | None = None, continuous: bool = False, plan: PlanMode = "auto",
                 near: Sequence[str] = ()) -> None:
        self.waypoints = [tuple(w) for w in waypoints]
        self.straight = list(straight) if straight is not None else [False] * len(self.waypoints)
        self.speed, self.pos_tol, self.continuous = speed, pos_tol, continuous
        self.mode, self.near = plan, tuple(near)
        self.joints: list[np.ndarray] = []
        self.vias: list[list[np.ndarray]] = []  # per waypoint, the joints driven in turn (the last: its joints)
        self.via = 0
        self.blocked: str | None = None
        self.planned: list[list[np.ndarray]] = []  # per waypoint, each frame's position at the planned joints
        self.leg = 0
        self._points: list[Setpoint] | None = None
        self._first_planned = True

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
        self.leg, self.via, self.blocked = 0, 0, None
        self.vias = [[q] for q in self.joints]
        self._first_planned = self.mode == "never"
        if self.mode == "never":
            return True
        for k in range(1, len(self.joints)):  # the first leg starts where the robot will be: planned as it begins
            if not self.straight[k] and not self._plan_leg(view, k, self.joints[k - 1]):
                return False
        return True

    def _plan_leg(self, view: View, k: int, start: np.ndarray, escape: bool = False) -> bool:
        """Check (and, where blocked, plan) joint-space leg ``k`` from ``start``; False with :attr:`blocked` set.

        ``escape``: ``start`` is where the robot stands; in collision as the world is believed, the path leaves it
        first (:func:`~nextage_qp.planning.rrt.escape`).
        """
        path = view.plan_path(start, self.joints[k], near=self.near, always=self.mode == "always", escape=escape)
        if not path.found:
            self.blocked = f"leg {k + 1} of {len(self.joints)}: {path.reason()}"
            return False
        self.vias[k] = [np.asarray(p) for p in path.path[1:]]
        return True

    def length(self, start: np.ndarray) -> float:
        """The route's length [m] for its first frame, from ``start`` through the waypoints as planned (0 before
        :meth:`plan` succeeds): straight lines between them, however the joints go.
        """  # noqa: D205
        return path_length([start, *(p[0] for p in self.planned)])

    @property
    def done(self) -> bool:
        """True once the last waypoint has been reached."""
        return self.leg >= len(self.waypoints)

    def step(self, view: View) -> Command:
        """This tick's command towards the current waypoint; moves on once its frames are there and settled."""
        leg = min(self.leg, len(self.joints) - 1)
        q, targets = self.joints[leg], self.waypoints[leg]
        if not self._first_planned:
            self._first_planned = True
            if not self.straight[0] and not self._plan_leg(view, 0, view.joint_positions(view.joint_names()),
                                                           escape=True):
                raise PhaseError(f"no collision-free path to the route's first waypoint: {self.blocked}")
        if self.straight[leg]:
            if self._points is None:
                self._points = [Setpoint(view.commanded_pose(t.frame).pos) for t in targets]
            for point, t in zip(self._points, targets, strict=True):
                point.advance(np.asarray(t.pos), self.speed, view.dt)
            command = Command(tuple(dataclasses.replace(t, pos=p.pos) for t, p in zip(targets, self._points,
                                                                                        strict=True)), posture=q)
        else:
            vias = self.vias[leg] if leg < len(self.vias) else [q]
            via = vias[min(self.via, len(vias) - 1)]
            command = Command(joints=dict(zip(view.joint_names(), via, strict=True)))
            if self.via < len(vias) - 1:  # an intermediate waypoint of a planned path: on once reached and still
                off = np.abs(view.joint_positions(view.joint_names()) - via)
                off[view.looking_joints()] = 0.0  # a look-at task holds the head, whatever the path planned
                if float(np.max(off)) < VIA_TOL and view.settled():
                    self.via += 1
                return command
        if not self.done:
            near = all(float(np.linalg.norm(view.frame_pose(t.frame).pos - p)) < REACHED
                       for t, p in zip(targets, self.planned[leg], strict=True))
            if near and view.settled():
                self.leg += 1
                self.via = 0
                self._points = None
        return command
