"""Differential IK of both wrists and the shared chest as one QP, built on mink.

Each step assembles mink's objective (frame, axis-align, posture and extra tasks; the same :math:`(H, c)` as
:func:`mink.build_ik`, built in reused arrays by :mod:`nextage_qp.ik.objective`) and adds what mink lacks: the
joint limits as a solver box (``lb``/``ub``, :mod:`nextage_qp.ik.limits`) and collision rows only for pairs that
can bind (:mod:`nextage_qp.ik.collision`). :meth:`QPIK.solve` integrates the
steps to a tolerance with a backtracking guard that never accepts a q closing a pair below its minimum distance.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence

import mink
import mujoco
import numpy as np

from nextage_qp.errors import UnknownNameError
from nextage_qp.ik.backend import QPSolver
from nextage_qp.ik.collision import ActiveCollisionLimit
from nextage_qp.ik.config import IKConfig
from nextage_qp.ik.limits import JointBoxLimit
from nextage_qp.ik.memo import SolveMemo
from nextage_qp.ik.model import (
    Frame,
    ObjectPoses,
    chain_dofs,
    kinematic_model,
    mocap_ids,
    resolve_frame,
    set_object_poses,
)
from nextage_qp.ik.objective import Objective
from nextage_qp.ik.safe_step import advance
from nextage_qp.ik.targets import FrameTarget, IKInfeasibleError, IKResult, RelativeTarget, worst_errors
from nextage_qp.ik.tasks import TaskCache
from nextage_qp.robot import Robot, per_joint

RELAXED_MARGIN = 2.0
"""The relaxation gate of :meth:`QPIK.solve` gives up on a target the search without collision rows misses by more
than this many times the accepted errors."""


class QPIK:
    """QP differential IK over the 15 robot joints (mink tasks, box limits, active collision rows).

    Args:
        robot: The robot and its scene (objects become mocap bodies of the IK model).
        config: Costs, limits and solver.
        model: The robot's kinematic model (:func:`kinematic_model`) when another IK of the same robot has it
            already (e.g. a planner beside the servo's IK); compiled otherwise.
        memo: Remember this many :meth:`solve` results by their inputs (:class:`~nextage_qp.ik.memo.SolveMemo`),
            so a planner that asks the same question again gets the stored answer; 0: none.

    Raises:
        UnknownNameError: A geom group, joint or keyframe named in the config is not in the robot.
    """

    def __init__(self, robot: Robot, config: IKConfig, *, model: mujoco.MjModel | None = None,
                 memo: int = 0) -> None:
        self.robot, self.config = robot, config
        self.memo = SolveMemo(memo) if memo > 0 else None
        self.model = kinematic_model(robot) if model is None else model
        self._mocap = mocap_ids(self.model)
        self.configuration = mink.Configuration(self.model, robot.keyframe_q("home"))
        if isinstance(config.posture_target, str):
            q_posture = robot.keyframe_q(config.posture_target)
        else:
            q_posture = robot.q_from_names(config.posture_target, base=robot.keyframe_q("home"))
        self.posture = mink.PostureTask(self.model, cost=config.posture_cost)
        self.posture.set_target(q_posture)
        self._posture_goal: np.ndarray | None = None  # the array last given to the posture task by step()
        self.default_posture = q_posture
        default = float(IKConfig.model_fields["velocity_limit"].default)
        vmax = per_joint(config.velocity_limit, default, robot.joint_names)
        margin = np.minimum(config.limit_margin, 0.45 * (robot.upper - robot.lower))
        self.box = JointBoxLimit(robot.lower + margin, robot.upper - margin, vmax, config.limit_gain)
        self.groups = groups = robot.collision_geoms(config.group_specs())
        self._allow_masks: dict[frozenset[str], np.ndarray] = {}
        pairs = []
        for i, pair in enumerate(config.collision_pairs):
            for name in (pair.a, pair.b):
                if name not in groups:
                    raise UnknownNameError(f"geom group (collision_pairs[{i}])", name, groups)
            pairs.append((groups[pair.a], groups[pair.b], pair.min_distance, pair.detection_distance))
        self.collision = ActiveCollisionLimit(self.model, pairs, config.collision_gain, self.box) if pairs else None
        self._frames: dict[str, Frame] = {}
        self.tasks = TaskCache(config.lm_damping, config.position_cost, config.orientation_cost, self.frame)
        self.objective = Objective(self.model)
        self.qp = QPSolver(config.solver, self.model.nv)

    def _allowed(self, groups: frozenset[str]) -> np.ndarray:
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

    def set_object_poses(self, poses: ObjectPoses) -> None:
        """Place objects (cube, dumbbell, ...) for collision avoidance: name -> (pos [m], quat wxyz)."""
        set_object_poses(self.model, self.configuration.data, poses, self._mocap)
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
    ) -> np.ndarray:
        """One IK step: the joint velocity v [rad/s] (15,) minimising the task costs for a step of ``dt`` [s].

        ``allow`` names collision groups whose pairs are not avoided on this step (e.g. the object a push is
        in contact with); ``posture`` replaces the configured posture target on this step (e.g. a configuration a
        planner found for where the motion is going, so the redundancy heads there; an array not changed in place
        afterwards: passing the same array again keeps the target as set); ``extra``: more mink tasks (e.g. a look-at).

        Raises:
            IKInfeasibleError: The QP has no solution; the message names the active limits.
            UnknownNameError: ``allow`` names a group the robot does not have.
        """
        if self.collision is not None:
            self.collision.allow(self._allowed(allow))
        goal = self.default_posture if posture is None else posture
        if goal is not self._posture_goal:  # the same array as last time: the task holds it already
            self.posture.set_target(goal)
            self._posture_goal = goal
        if object_poses:
            set_object_poses(self.model, self.configuration.data, object_poses, self._mocap)
        self.configuration.update(np.asarray(q, dtype=float))
        return self._step(targets, dt, [*self.tasks.relative(relative), *extra])

    def _step(self, targets: Sequence[FrameTarget], dt: float, extra_tasks: Sequence[mink.Task]) -> np.ndarray:
        """:meth:`step` at the configuration already loaded in :attr:`configuration`."""
        tasks = [*self.tasks.frames(targets, self.configuration.data), self.posture, *extra_tasks]
        q = self.configuration.data.qpos
        lb, ub = self.box.bounds(q, dt)
        # mink's objective; the box goes to the solver as bounds and the collision rows are added here (computed
        # with the same box, so it is evaluated once).
        H, c = self.objective.build(self.configuration, tasks, self.config.damping)
        G = h = None
        if self.collision is not None:
            rows = self.collision.compute_qp_inequalities(self.configuration, dt)
            if not rows.inactive:
                G, h = rows.G, rows.h
        x = self.qp.solve(H, c, lb, ub, G, h)
        if x is None:  # also where the box itself is empty (q outside its limits): lb > ub
            raise IKInfeasibleError(self._explain(q, lb, ub))
        return np.asarray(x) / dt

    def _explain(self, q: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> str:
        """Describe the limits active at an infeasible step."""
        parts = self.box.violated(q, lb, ub, self.robot.joint_names)
        parts += self.collision.violated(self.model) if self.collision is not None else []
        what = "; ".join(parts) or "no single limit violated (conflicting limits or extra tasks)"
        return f"IK QP infeasible ({self.config.solver}): active limits: {what}"

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
    ) -> IKResult:
        """Iterate IK steps of ``config.dt`` from ``q0`` until every target is within tolerance.

        A descent that stalls in a local minimum (or hits the iteration cap) is restarted up to
        ``config.restarts`` times from random in-limit configurations (seeded, so deterministic). An
        unreachable target ends with ``converged=False`` (status ``max_iters`` or ``stalled``) and the best q
        found; no exception. A step that would bring a watched collision pair below its minimum distance is
        halved until it does not.

        **Relaxation gate** (with ``accept`` and collision pairs). When the first descent misses, the same search
        (same start, same restarts) runs first on the relaxed problem without collision rows, whose steps cost a
        fraction as much (no distance queries, no collision-safe halving). Collision rows only shrink the set of
        reachable configurations, so a target the relaxed search misses by more than ``RELAXED_MARGIN`` times the
        accepted errors is out of reach with them too: the collision-aware restarts are skipped and the best of the
        first descent is returned. (The margin because both searches are local: on the sweeps, a relaxed miss below
        the accepted error itself was sometimes beaten by the collision-aware restarts, never one above it.)

        Args:
            targets: Frame targets, solved together in one QP per step.
            q0: Start configuration [rad] (15,).
            max_iters: Iteration cap per descent (default ``config.max_iters``).
            extra_tasks: Further mink tasks added to every step.
            object_poses: Object name -> (pos, quat wxyz) for collision avoidance.
            allow: Collision groups whose pairs are not avoided (e.g. an object the frames hold).
            good_enough: Position [m] and orientation [rad] errors at which a stalled descent is kept without
                restarts (a caller that accepts millimetres need not pay for restarts chasing microns).
            accept: Position [m] and orientation [rad] errors the caller accepts as reached; turns on the
                relaxation gate (above).

        Raises:
            IKInfeasibleError: A step's QP is infeasible (e.g. ``q0`` far outside the joint limits).
        """
        start = time.perf_counter()
        cfg = self.config
        if self.collision is not None:
            self.collision.allow(self._allowed(allow))
        if object_poses:
            set_object_poses(self.model, self.configuration.data, object_poses, self._mocap)
        key = None
        if self.memo is not None and not extra_tasks:  # a mink task's inputs are not all visible: not remembered
            data = self.configuration.data
            key = self.memo.key(targets, q0, (data.mocap_pos, data.mocap_quat, *(good_enough or (None,)),
                                              *(accept or (None,))),
                                (str(max_iters), *sorted(allow)))
            found = self.memo.get(key)
            if found is not None:
                self.configuration.update(found.q)
                return found._replace(time_s=time.perf_counter() - start)
        frames = [self.frame(t.frame) for t in targets]
        total, best = 0, None
        # Restarts re-draw only the joints that move a target frame; the others keep their q0 values.
        starts = _Starts(np.array(q0, dtype=float), np.any([chain_dofs(self.model, f) for f in frames], axis=0),
                         self.box.lower, self.box.upper, cfg.restarts + 1, cfg.seed)
        cap = max_iters or cfg.max_iters
        for attempt, q in enumerate(starts):
            score, q_best, pos_err, rot_err, iters, status = self._descend(targets, frames, q, cap, extra_tasks)
            total += iters
            if best is None or score < best[0]:
                best = (score, q_best, pos_err, rot_err, status)
            if status == "converged":
                break
            if good_enough is not None and best[2] <= good_enough[0] and best[3] <= good_enough[1]:
                break
            if attempt == 0 and starts.count > 1 and self.collision is not None and accept is not None:
                reached, iters = self._relaxed_reach(targets, frames, starts, cap, extra_tasks,
                                                     (RELAXED_MARGIN * accept[0], RELAXED_MARGIN * accept[1]))
                total += iters
                if not reached:
                    break
        assert best is not None
        _, q_best, pos_err, rot_err, status = best
        self.configuration.update(q_best)
        result = IKResult(q_best, status == "converged", pos_err, rot_err, total, status, time.perf_counter() - start)
        if key is not None and self.memo is not None:
            self.memo.put(key, result)
        return result

    def _relaxed_reach(
        self,
        targets: Sequence[FrameTarget],
        frames: Sequence[Frame],
        starts: _Starts,
        cap: int,
        extra_tasks: Sequence[mink.Task],
        within: tuple[float, float],
    ) -> tuple[bool, int]:
        """Whether the search from ``starts`` without collision rows comes ``within`` the targets: (reached, iters).

        ``within``: position [m] and orientation [rad] errors.
        """
        collision, self.collision, total = self.collision, None, 0
        try:
            for q in starts:
                _, _, pos_err, rot_err, iters, status = self._descend(targets, frames, q, cap, extra_tasks)
                total += iters
                if status == "converged" or (pos_err <= within[0] and rot_err <= within[1]):
                    return True, total
            return False, total
        finally:
            self.collision = collision

    def _descend(
        self,
        targets: Sequence[FrameTarget],
        frames: Sequence[Frame],
        q0: np.ndarray,
        cap: int,
        extra_tasks: Sequence[mink.Task],
    ) -> tuple[float, np.ndarray, float, float, int, str]:
        """One descent from ``q0``: (score, best q, position error, orientation error, iterations, status)."""
        cfg, q = self.config, q0.copy()
        self.configuration.update(q)
        best = (np.inf, q.copy(), np.inf, np.inf)
        since_best, iters = 0, 0
        while True:
            pos_err, rot_err = worst_errors(targets, [f.pose(self.configuration.data) for f in frames])
            score = pos_err / cfg.pos_tol + rot_err / cfg.rot_tol
            if score < best[0]:
                since_best = 0 if score < 0.99 * best[0] else since_best
                best = (score, q.copy(), pos_err, rot_err)
            if pos_err <= cfg.pos_tol and rot_err <= cfg.rot_tol:
                return (*best, iters, "converged")
            if iters >= cap:
                return (*best, iters, "max_iters")
            if since_best >= cfg.stall_iters:
                return (*best, iters, "stalled")
            dq = self._step(targets, cfg.dt, extra_tasks) * cfg.dt
            q_prev, q = q, self._advance(q, dq)
            iters, since_best = iters + 1, since_best + 1
            if q is q_prev:
                # Every halving of the step ran into a collision pair: the next steps would start from the same q
                # and be the same, with no progress, until the cap or the stall test ends the descent. End it now
                # with the same outcome and iteration count.
                ahead = min(cap - iters, cfg.stall_iters - since_best)
                if ahead > 0:
                    iters, since_best = iters + ahead, since_best + ahead
                return (*best, iters, "max_iters" if iters >= cap else "stalled")

    def _advance(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Q + dq inside the joint limits, collision-safe (:func:`~nextage_qp.ik.safe_step.advance`)."""
        if self.collision is None:
            q_new = np.clip(q + dq, self.box.lower, self.box.upper)
            self.configuration.update(q_new)
            return q_new
        return advance(self.collision, self.configuration, q, dq, self.box.lower, self.box.upper)


class _Starts:
    """Start configurations of the descents: ``q0``, then ``count - 1`` seeded random restarts, drawn when used.

    Restarts re-draw only the ``moving`` joints (within ``lower``/``upper``); the others keep their ``q0`` values.
    """

    def __init__(self, q0: np.ndarray, moving: np.ndarray, lower: np.ndarray, upper: np.ndarray, count: int,
                 seed: int) -> None:
        self.q0, self.moving, self.lower, self.upper, self.count = q0, moving, lower, upper, count
        self._rng = np.random.default_rng(seed)
        self._drawn: list[np.ndarray] = [q0]

    def __getitem__(self, k: int) -> np.ndarray:
        if not 0 <= k < self.count:
            raise IndexError(k)
        while len(self._drawn) <= k:
            self._drawn.append(np.where(self.moving, self._rng.uniform(self.lower, self.upper), self.q0))
        return self._drawn[k]

    def __iter__(self) -> Iterator[np.ndarray]:
        return (self[k] for k in range(self.count))
