"""What a phase sees: a read-only :class:`View` of the run, the :class:`Grip` a clamp leaves, and moving setpoints.

Phases never touch the simulation, the IK or mink: they read the view and return a
:class:`~nextage_qp.loop.servo.Command`. :class:`~.sim_view.SimView` is the view of a running simulation; tests script
their own.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import mujoco
import numpy as np

from nextage_qp.errors import InfeasibleError, PhaseError
from nextage_qp.geometry import Pose, rot_z, yaw_of
from nextage_qp.ik import FrameTarget, RelativeTarget
from nextage_qp.mobile.base import MobileBase
from nextage_qp.mobile.drive_models import Pose2
from nextage_qp.planning.rrt import PathPlan
from nextage_qp.sensing.sensors import Wrench


@dataclass
class Setpoint:
    r"""A Cartesian point that walks towards a goal, one control tick at a time, at bounded speed and acceleration.

    Its speed :math:`s` [m/s] ramps up at ``accel`` [m/s²] and comes down in time to stop on the goal,
    :math:`s_{k+1} = \min(v_{max},\ s_k + a\,\Delta t,\ \sqrt{2 a (d - s_{k+1} \Delta t)})` with :math:`d`
    the distance left, so the commanded motion has no velocity steps for the joint references to chase.
    """

    pos: np.ndarray
    accel: float = 1.0
    speed: float = 0.0

    def advance(self, goal: np.ndarray, speed: float, dt: float) -> bool:
        """Move towards ``goal`` at up to ``speed`` [m/s]; True once on the goal (where the speed is 0)."""
        delta = goal - self.pos
        dist = float(np.linalg.norm(delta))
        a = self.accel
        brake = a * dt * (float(np.sqrt(1.0 + 2.0 * dist / (a * dt * dt))) - 1.0)  # v = sqrt(2 a (d - v dt))
        self.speed = min(speed, self.speed + a * dt, brake)
        if dist <= max(self.speed * dt, 2.0 * a * dt * dt):
            self.pos, self.speed = goal.copy(), 0.0
            return True
        self.pos = self.pos + delta * (self.speed * dt / dist)
        return False

    def jump(self, goal: np.ndarray) -> None:
        """Put the point on ``goal`` at once, at rest."""
        self.pos, self.speed = np.array(goal, dtype=float), 0.0


@dataclass(frozen=True)
class Grip:
    """An object clamped between pad frames: what ``grasp`` leaves for ``carry``, and ``release`` ends.

    Attributes:
        object: The clamped body.
        frames: The pad frames, +y side first.
        offsets: Pad frame -> its clamp point in the object's frame [m].
        rotations: Pad frame -> its rotation in the object's frame.
        relative: The first pad's commanded pose in the second pad's frame when the clamp closed.
        lateral: The clamp axis (from the second pad to the first) in the object's frame.
        force: Squeeze force [N] the pads keep (0: no force loop, the offsets stay as they are).
        force_gain: Gain of the force loop [m/s per N].
        place_joints: Joints with which the clamp reached the placement the grasp was chosen for (a start for
            the place phase's planning), or None.
    """

    object: str
    frames: tuple[str, ...]
    offsets: Mapping[str, np.ndarray]
    rotations: Mapping[str, np.ndarray]
    relative: RelativeTarget
    lateral: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    force: float = 0.0
    force_gain: float = 0.0
    place_joints: np.ndarray | None = None


ROUND_HEADINGS = np.pi / 4
"""Spacing [rad] of the headings tried for an object that looks the same at any yaw (yaw symmetry 0)."""


class RunState(Protocol):
    """The run as time passes: the clock, the clamp in force, and whether the robot has settled.

    Attributes:
        dt: Control period [s].
        grip: The current clamp, or None.
    """

    @property
    def t(self) -> float:
        """Simulated time [s]."""

    dt: float
    grip: Grip | None

    def settled(self) -> bool:
        """True when the reference has caught up with the commanded joints and the robot is nearly still."""

    def tracking_error(self) -> float:
        """Largest gap between the measured and the commanded joints [rad]."""


class Poses(Protocol):
    """Where things are: measured, commanded and at given joints, and how old an object's measurement is."""

    def body_pose(self, name: str) -> Pose:
        """Measured world pose of a free object; the fixed pose of any other body (target, obstacle)."""

    def frame_pose(self, name: str) -> Pose:
        """Measured world pose of a site or body of the robot."""

    def commanded_pose(self, name: str) -> Pose:
        """World pose of a site or body at the commanded joints."""

    def joint_positions(self, names: tuple[str, ...]) -> np.ndarray:
        """Measured positions [rad] of the named joints."""

    def pose_at(self, frame: str, q: np.ndarray) -> Pose:
        """World pose of a frame at joints ``q`` (e.g. a planned configuration)."""

    def unseen_s(self, obj: str) -> float:
        """Time [s] since the moment the latest measurement of an object's pose describes (0: poses are the truth)."""


class Geometry(Protocol):
    """The shapes of the scene: objects' extents, grips, resting heights, the table and obstacles."""

    def extent(self, obj: str, direction: np.ndarray) -> float:
        """Half-extent [m] of an object's collision geoms along a world direction (its pushing half-width)."""

    def grip_geometry(self, obj: str, lateral: np.ndarray, height: float | None = None) -> tuple[float, float]:
        """Where a clamp across ``lateral`` (a direction in the object's frame) holds an object [m].

        Returns (height of the clamp over the object's origin, half-width there); the height by default the middle
        of the widest part (the highest of several: a dumbbell's top plate).
        """

    def rest_height(self, obj: str, on: str | None = None) -> float:
        """Height [m] of an object's origin standing upright on the table, or on the object ``on`` (a stack)."""

    def table_top(self) -> float:
        """Height of the table's top face [m]."""

    def obstacle_top(self) -> float:
        """Height of the highest obstacle's top [m] (the table top when there is none)."""

    def yaw_symmetry(self, obj: str) -> float:
        """Yaw [rad] after which an object looks the same (2 pi for none)."""

    def weight(self, obj: str) -> float:
        """An object's weight [N]: its mass as the task declares it (its body and those below it) times gravity."""

    def footprint(self, name: str) -> tuple[float, float, float, float]:
        """A body's footprint on the floor as a circle about its origin: x, y, radius [m], and its top's height [m]."""


class Reach(Protocol):
    """What the arms reach: the joints, the IK's default posture, the clamping frames, planned joints."""

    def joint_names(self) -> tuple[str, ...]:
        """The robot's joints, in the order of the joint vectors :meth:`plan` returns."""

    def default_posture(self) -> np.ndarray:
        """The joints [rad] the IK's redundancy heads for when a command names no posture."""

    def looking_joints(self) -> np.ndarray:
        """Indices (into :meth:`joint_names`) of the joints a look-at task holds now: joint commands leave them."""

    def pad_frames(self) -> tuple[str, ...]:
        """The robot's clamping frames, one per arm, the first arm's (on the +y side) first."""

    def check_reach(self, frame: str, pos: np.ndarray, where: str) -> None:
        """Raise :class:`~nextage_qp.errors.InfeasibleError` when no joint configuration brings the frame to ``pos``."""

    def plan(self, targets: Sequence[FrameTarget], start: np.ndarray | None = None,
             allow: frozenset[str] = frozenset(), pos_tol: float | None = None,
             restarts: bool = True) -> np.ndarray | None:
        """Joints that put the frames on the targets together, or None when the arms cannot.

        An offline IK solve from ``start`` (default: the commanded joints), avoiding the IK's collision pairs with
        the objects where they are now (but for the ``allow`` groups, e.g. an object the frames hold); a target
        counts as reached within ``pos_tol`` (default ``sim_view.REACH_POS_TOL``) and ``sim_view.REACH_ROT_TOL``.
        ``restarts=False``: only the descent from ``start`` (no random restarts), so a solution found is one the
        joints reach continuously from there.
        """

    def plan_path(self, q_start: np.ndarray, q_goal: np.ndarray, *, near: Sequence[str] = (),
                  always: bool = False, escape: bool = False) -> PathPlan:
        """A collision-free joint path from ``q_start`` to ``q_goal`` [rad] through the world as it is believed now.

        The straight joint-space segment when nothing touches along it (unless ``always``), else a planned path that
        keeps the planner's clearance from obstacles and objects (``near``: bodies it may come close to but not
        touch, e.g. the object a push or grasp goes to). A held object (the view's grip) moves with its pads.
        ``escape``: ``q_start`` is where the robot stands, and a path may leave it first when it is in collision as
        the world is believed (:func:`~nextage_qp.planning.rrt.plan_path`).
        """

    def obstacle_groups(self) -> tuple[str, ...]:
        """The collision groups of the scene's obstacles: the obstacle, the clutter, the fixed objects it has."""

    def clearance_at(self, obj: str, pos: np.ndarray, yaw: float, beside: bool = False) -> tuple[float, np.ndarray]:
        """Smallest distance [m] from ``obj`` upright at ``pos`` (its origin) and ``yaw`` to the scene's obstacles.

        With it, the unit direction away from the nearest. Capped at 0.1 m (the direction zero there); the obstacles
        are :meth:`obstacle_groups`'. ``beside``: only those beside it, not one it stands on or under.
        """

    def room_at(self, q: np.ndarray, near: Sequence[str] = (), allow: Sequence[str] = ()) -> float:
        """How near [m] robot joints ``q`` [rad] (and a held object) come to anything (negative: how deep in it).

        Up to the planner's lookahead; ``near`` and ``allow`` as for :meth:`path_blocked`.
        """

    def path_blocked(self, path: Sequence[np.ndarray], clearance: float | None = None,
                     near: Sequence[str] = (), allow: Sequence[str] = ()) -> str | None:
        """What the first state along a joint path [rad] that breaks the planner's clearance touches, or None.

        ``clearance`` [m]: another than the planning config's; ``near``: bodies it may come close to, not touch;
        ``allow``: bodies it may touch.

        Checked densely, a held object (the view's grip) moving with its pads.
        """


class Forces(Protocol):
    """What the wrists feel."""

    def wrench(self, site: str) -> Wrench:
        """Measured contact wrench on a site's body, world frame: force [N] and torque about the site [N m]."""


class Base(Protocol):
    """A mobile robot's base: what it is, where its odometry says it is, how far the robot on it reaches."""

    def base(self) -> MobileBase | None:
        """The robot's wheeled base (its type, limits and geometry), or None for a fixed robot."""

    def base_pose(self) -> Pose2 | None:
        """Where the base's odometry says it is (the controller's world), or None for a fixed robot."""

    def base_radius(self, below: float = np.inf) -> float:
        """How far [m] the robot on its base reaches from the base's reference point, as it stands now.

        Only its parts that reach down below the height ``below`` [m] count.
        """


class View(RunState, Poses, Geometry, Reach, Forces, Base, Protocol):
    """The read-only run state a phase works from: every concern above (a helper asks for the few it uses)."""


def refusal(view: RunState) -> type[PhaseError] | type[InfeasibleError]:
    """The error for a phase that finds its task impossible: a refusal (exit 2) while nothing has moved yet."""
    return InfeasibleError if view.t == 0.0 else PhaseError


def reference(view: Poses, relative_to: str) -> tuple[np.ndarray, float]:
    """Position [m] and yaw [rad] of a reference body, or the world origin."""
    if relative_to == "world":
        return np.zeros(3), 0.0
    pos, rot = view.body_pose(relative_to)
    return pos, yaw_of(rot)


def resolve_point(view: View, spec: Any) -> tuple[np.ndarray, float]:
    """World position [m] and yaw [rad] of a body-relative point spec, from the live reference pose.

    The position is ``ref.pos + R @ offset`` with ``R`` the reference's yaw (``axes: yaw``) or the identity
    (``axes: world``); the yaw is the reference's (or, with ``heading: radial``, the direction away from the
    chest axis) plus the spec's ``yaw``.
    """
    ref_pos, ref_yaw = reference(view, spec.relative_to)
    rot = rot_z(ref_yaw) if spec.axes == "yaw" else np.eye(3)
    pos = ref_pos + rot @ np.asarray(spec.offset)
    base = float(np.arctan2(pos[1], pos[0])) if getattr(spec, "heading", "reference") == "radial" else ref_yaw
    return pos, base + (spec.yaw if spec.yaw is not None else 0.0)


def frame_target(view: View, spec: Any, pos: np.ndarray) -> FrameTarget:
    """An IK target for ``spec.frame`` at ``pos`` with the orientation the spec asks for (yaw, quat or axis)."""
    if spec.yaw is not None:
        _, ref_yaw = reference(view, spec.relative_to)
        return FrameTarget(spec.frame, pos=pos, rot=rot_z(ref_yaw + spec.yaw))
    if spec.quat is not None:
        mat = np.empty(9)
        mujoco.mju_quat2Mat(mat, np.asarray(spec.quat, dtype=float))
        return FrameTarget(spec.frame, pos=pos, rot=mat.reshape(3, 3))
    if spec.axis is not None and spec.direction is not None:
        return FrameTarget(spec.frame, pos=pos, axis=np.asarray(spec.axis), direction=np.asarray(spec.direction))
    return FrameTarget(spec.frame, pos=pos)
