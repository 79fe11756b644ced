"""Differential IK of both wrists and the shared chest as one QP, built on mink.

Each step assembles mink's objective (frame, axis-align, posture and extra tasks; the same :math:`(H, c)` as
:func:`mink.build_ik`, built in reused arrays by :mod:`nextage_qp.ik.objective`) and adds what mink lacks: the
joint limits as a solver box (``lb``/``ub``, :mod:`nextage_qp.ik.limits`) and collision rows only for pairs that
can bind (:mod:`nextage_qp.ik.collision`). :meth:`QPIK.solve` integrates the
steps to a tolerance with a backtracking guard that never accepts a q closing a pair below its minimum distance.
"""

from __future__ import annotations

from collections.abc import Sequence

import mink
import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, UnknownNameError
from nextage_qp.ik.backend import QPSolver
from nextage_qp.ik.collision import ActiveCollisionLimit, apart_at
from nextage_qp.ik.config import IKConfig
from nextage_qp.ik.kinematic_model import (
    PLANAR_JOINTS,
    Frame,
    ObjectPoses,
    kinematic_model,
    mocap_ids,
    resolve_frame,
    set_object_poses,
)
from nextage_qp.ik.limits import JointBoxLimit
from nextage_qp.ik.memo import SolveMemo
from nextage_qp.ik.objective import Objective
from nextage_qp.ik.search import Descent
from nextage_qp.ik.solve import OfflineSolver
from nextage_qp.ik.starts import Starts
from nextage_qp.ik.targets import FrameTarget, IKInfeasibleError, IKResult, RelativeTarget
from nextage_qp.ik.tasks import TaskCache
from nextage_qp.mobile.rows import BaseRows
from nextage_qp.robots.model import Robot, per_joint


class QPIK:
    """QP differential IK over the robot's joints (mink tasks, box limits, active collision rows).

    Args:
        robot: The robot and its scene (objects become mocap bodies of the IK model).
        config: Costs, limits and solver.
        model: The robot's kinematic model (:func:`kinematic_model`) when another IK of the same robot has it
            already (e.g. a planner beside the servo's IK); compiled otherwise.
        memo: Remember this many :meth:`solve` results by their inputs (:class:`~nextage_qp.ik.memo.SolveMemo`),
            so a planner that asks the same question again gets the stored answer, and as many descents without
            collision rows (a solve's restarts draw the same starts for the same targets); 0: none.

    Raises:
        UnknownNameError: A geom group, joint or keyframe named in the config is not in the robot.
    """

    def __init__(self, robot: Robot, config: IKConfig, *, model: mujoco.MjModel | None = None,
                 memo: int = 0) -> None:
        self.robot, self.config = robot, config
        self.model = kinematic_model(robot) if model is None else model
        self.mocap = mocap_ids(self.model)
        """Mocap index of each object of the IK model (objects are mocap bodies here), by name."""
        # A mobile robot's IK variables start with its base's planar joints (world x, y, yaw): their values are
        # the base pose the controller believes (base_pose, from odometry), their steps the base's motion.
        self.nb = len(PLANAR_JOINTS) if robot.base is not None else 0
        self.base = BaseRows(robot.base) if robot.base is not None else None
        self.base_pose = np.array(robot.base.start, dtype=float) if robot.base is not None else np.zeros(0)
        """The base's pose (x, y [m], yaw [rad]) in the IK's world, set by the caller (a mobile robot's only)."""
        self.base_velocity = np.zeros(self.nb)
        """The base's world velocity (x-dot, y-dot [m/s], yaw rate [rad/s]) of the last :meth:`step`."""
        self.configuration = mink.Configuration(self.model, self.full(robot.keyframe_q("home")))
        if isinstance(config.posture_target, str):
            q_posture = robot.keyframe_q(config.posture_target)
        else:
            q_posture = robot.q_from_names(config.posture_target, base=robot.keyframe_q("home"))
        cost = config.posture_cost if not self.nb else np.r_[np.zeros(self.nb), np.full(robot.nq, config.posture_cost)]
        self.posture = mink.PostureTask(self.model, cost=cost)  # the base has no posture
        self.posture.set_target(self.full(q_posture))
        self._posture_goal: np.ndarray | None = None  # the array last given to the posture task by step()
        self.default_posture = q_posture
        default = float(IKConfig.model_fields["velocity_limit"].default)
        vmax = per_joint(config.velocity_limit, default, robot.joint_names, "ik.velocity_limit")
        margin = np.minimum(config.limit_margin, 0.45 * (robot.upper - robot.lower))
        lower, upper = robot.lower + margin, robot.upper - margin
        if robot.base is not None:  # no bounds on where the base goes; its speed bounded per world axis
            lim = robot.base.limits
            lower, upper = np.r_[np.full(self.nb, -np.inf), lower], np.r_[np.full(self.nb, np.inf), upper]
            vmax = np.r_[lim.speed, lim.speed, lim.turn_rate, vmax]
        self.box = JointBoxLimit(lower, upper, vmax, config.limit_gain)
        self.groups = groups = robot.collision_geoms(config.group_specs())
        self._allow_masks: dict[frozenset[str], np.ndarray] = {}
        pairs: list[tuple[Sequence[int], Sequence[int], float, float]] = []
        home = self.full(robot.keyframe_q("home"))
        for i, pair in enumerate(config.collision_pairs):
            for name in (pair.a, pair.b):
                if name not in groups:
                    raise UnknownNameError(f"geom group (collision_pairs[{i}])", name, groups)
            # the pairs of geoms not touching at home (a group with itself: its own links kept apart)
            apart = apart_at(self.model, home, groups[pair.a], groups[pair.b], pair.min_distance)
            if not apart and pair.a == pair.b:
                raise ConfigError(f"ik.collision_pairs[{i}]: {pair.a!r} with itself keeps nothing apart: no two of "
                                  f"its geoms on different bodies are {pair.min_distance:g} m apart at home; pair it "
                                  "with another group, or name a group of several links (an arm)",
                                  key=f"ik.collision_pairs[{i}]")
            pairs += [([g1], [g2], pair.min_distance, pair.detection_distance) for g1, g2 in apart]
        self.collision = ActiveCollisionLimit(self.model, pairs, config.collision_gain, self.box) if pairs else None
        self._frames: dict[str, Frame] = {}
        self.tasks = TaskCache(config.lm_damping, config.position_cost, config.orientation_cost, self.frame)
        self.objective = Objective(self.model)
        self.qp = QPSolver(config.solver, self.model.nv)
        self.offline = OfflineSolver(self, memo)
        """The offline solve over this IK's steps (:meth:`solve`)."""

    def allowed(self, groups: frozenset[str]) -> np.ndarray:
        """Boolean geom mask of the named collision groups (cached per set of names)."""
        mask = self._allow_masks.get(groups)
        if mask is None:
            mask = np.zeros(self.model.ngeom, dtype=bool)
            for name in groups:
                if name not in self.groups:
                    raise UnknownNameError("collision group (allow)", name, self.groups)
                mask[list(self.groups[name])] = True
            self._allow_masks[groups] = mask
        return mask

    def solve(
        self,
        targets: Sequence[FrameTarget],
        q0: np.ndarray,
        *,
        max_iters: int | None = None,
        extra_tasks: Sequence[mink.Task] = (),
        object_poses: ObjectPoses | None = None,
        allow: frozenset[str] = frozenset(),
        good_enough: tuple[float, float] | None = None,
        accept: tuple[float, float] | None = None,
        restarts: int | None = None,
    ) -> IKResult:
        """Joints that put the frames on ``targets`` (:meth:`~nextage_qp.ik.solve.OfflineSolver.solve`)."""
        return self.offline.solve(targets, q0, max_iters=max_iters, extra_tasks=extra_tasks, object_poses=object_poses,
                                  allow=allow, good_enough=good_enough, accept=accept, restarts=restarts)

    def starts(self, frames: Sequence[Frame], q0: np.ndarray, restarts: int | None = None) -> Starts:
        """The starts of a solve for ``frames`` from ``q0`` (:meth:`OfflineSolver.starts`)."""
        return self.offline.starts(frames, q0, restarts)

    @property
    def memo(self) -> SolveMemo[IKResult] | None:
        """The remembered solve results (None without a memo)."""
        return self.offline.memo

    @property
    def relaxed_memo(self) -> SolveMemo[Descent] | None:
        """The remembered descents without collision rows (None without a memo)."""
        return self.offline.relaxed_memo

    def world_changed(self) -> None:
        """The model's obstacle geometry changed in place (the camera's boxes): measure every collision pair anew and
        forget the remembered solves (those without collision rows stand).
        """  # noqa: D205
        if self.collision is not None:
            self.collision.forget()
        if self.offline.memo is not None:
            self.offline.memo.clear()

    def set_object_poses(self, poses: ObjectPoses) -> None:
        """Place objects (cube, dumbbell, ...) for collision avoidance: name -> (pos [m], quat wxyz)."""
        set_object_poses(self.model, self.configuration.data, poses, self.mocap)
        self.configuration.update()

    def frame(self, name: str) -> Frame:
        """Resolve (and cache) a body or site name; raises UnknownFrameError listing valid names."""
        if name not in self._frames:
            self._frames[name] = resolve_frame(self.robot, name)
        return self._frames[name]

    def step(
        self,
        q: np.ndarray,
        targets: Sequence[FrameTarget],
        dt: float,
        *,
        relative: Sequence[RelativeTarget] = (),
        object_poses: ObjectPoses | None = None,
        allow: frozenset[str] = frozenset(),
        posture: np.ndarray | None = None,
        extra: Sequence[mink.Task] = (),
        base: bool = False,
    ) -> np.ndarray:
        """One IK step: the joint velocity v [rad/s] minimising the task costs for a step of ``dt`` [s].

        ``allow`` names collision groups whose pairs are not avoided on this step (e.g. the object a push is
        in contact with); ``posture`` replaces the configured posture target on this step (e.g. a configuration a
        planner found for where the motion is going, so the redundancy heads there; an array not changed in place
        afterwards: passing the same array again keeps the target as set); ``extra``: more mink tasks (e.g. a look-at).
        ``base``: a mobile robot's base may move on this step, within its rows (:class:`~nextage_qp.mobile.rows.
        BaseRows`); its velocity is then :attr:`base_velocity`. Otherwise it stays where :attr:`base_pose` is.

        Raises:
            IKInfeasibleError: The QP has no solution; the message names the active limits.
            UnknownNameError: ``allow`` names a group the robot does not have.
        """
        if self.collision is not None:
            self.collision.allow(self.allowed(allow))
        goal = self.default_posture if posture is None else posture
        if goal is not self._posture_goal:  # the same array as last time: the task holds it already
            self.posture.set_target(self.full(goal))
            self._posture_goal = goal
        if object_poses:
            set_object_poses(self.model, self.configuration.data, object_poses, self.mocap)
        self.load(q)
        v = self.velocity(targets, dt, [*self.tasks.relative(relative), *extra], base=base)
        if not self.nb:
            return v
        self.base_velocity = v[: self.nb]
        return v[self.nb :]

    def load(self, q: np.ndarray) -> None:
        """Put the IK's configuration at robot joints ``q`` [rad] (and a mobile robot's base at :attr:`base_pose`)."""
        self.configuration.update(self.full(np.asarray(q, dtype=float)))

    def full(self, q: np.ndarray) -> np.ndarray:
        """The IK's variables for robot joints ``q``: a mobile robot's base pose first (``q`` itself otherwise)."""
        return q if not self.nb else np.r_[self.base_pose, q]

    def velocity(self, targets: Sequence[FrameTarget], dt: float, extra_tasks: Sequence[mink.Task], *,
                 base: bool = False, rows: bool = True) -> np.ndarray:
        """:meth:`step` at the configuration already loaded in :attr:`configuration`: every IK variable's velocity.

        ``rows=False``: without the collision rows (the offline solve's relaxed descents).
        """
        collision = self.collision if rows else None
        tasks = [*self.tasks.frames(targets, self.configuration.data), self.posture, *extra_tasks]
        q = self.configuration.data.qpos
        lb, ub = self.box.bounds(q, dt)
        # mink's objective; the box goes to the solver as bounds and the collision rows are added here (computed
        # with the same box, so it is evaluated once).
        H, c = self.objective.build(self.configuration, tasks, self.config.damping)
        G = h = A = b = None
        if collision is not None:
            active = collision.compute_qp_inequalities(self.configuration, dt)
            if not active.inactive:
                G, h = active.G, active.h
        if self.nb:
            if base and self.base is not None:  # the base moves within its rows, at a cost ("drive far, reach near")
                H[range(self.nb), range(self.nb)] += self.config.base_cost**2
                A, b, base_g, base_h = self.base.rows(float(q[2]), dt, self.model.nv)
                G, h = (base_g, base_h) if G is None else (np.vstack([G, base_g]), np.r_[h, base_h])
            else:
                lb[: self.nb], ub[: self.nb] = 0.0, 0.0
        x = self.qp.solve(H, c, lb, ub, G, h, A, b)
        if x is None:  # also where the box itself is empty (q outside its limits): lb > ub
            raise IKInfeasibleError(self._explain(q, lb, ub, collision))
        return np.asarray(x) / dt

    def _explain(self, q: np.ndarray, lb: np.ndarray, ub: np.ndarray, collision: ActiveCollisionLimit | None) -> str:
        """Describe the limits active at an infeasible step."""
        parts = self.box.violated(q, lb, ub, (*PLANAR_JOINTS[: self.nb], *self.robot.joint_names))
        parts += collision.violated(self.model) if collision is not None else []
        what = "; ".join(parts) or "no single limit violated (conflicting limits or extra tasks)"
        return f"IK QP infeasible ({self.config.solver}): active limits: {what}"
