r"""Baseline IK methods the QP IK is compared with; all return :class:`~nextage_qp.ik.targets.IKResult`.

* :func:`pinv_ik` — the report's Algorithm 1: pseudo-inverse steps :math:`\Delta q = J^+ e` towards linearly
  spaced subgoals, one solve per arm (chest + that arm), the chest angle of the two solves averaged.
* :func:`dls_ik` — damped least squares over all joints, :math:`\Delta q = J^T (J J^T + \lambda^2 I)^{-1} e`.
* :func:`lm_ik` — Levenberg–Marquardt (lecture Algorithm 5): :math:`\Delta q = (J^T J + \lambda I)^{-1} J^T e`,
  accepted and :math:`\lambda \leftarrow \lambda/10` when the error drops, else rejected and
  :math:`\lambda \leftarrow 10\lambda`.

The error :math:`e` stacks, per target, the position error [m] and the world angular error [rad]
(:math:`\log(R_t R^T)` for a rotation, :math:`R a \times d` for an axis). Every iterate is clipped to
the joint limits, so no method returns q outside them.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from nextage_qp.ik.kinematic_model import Frame, chain_dofs, kinematic_model, resolve_frame
from nextage_qp.ik.targets import FrameTarget, IKResult, worst_errors
from nextage_qp.robots.model import Robot


@functools.lru_cache(maxsize=8)
def _model(robot: Robot) -> mujoco.MjModel:
    return kinematic_model(robot)


class _Problem:
    """Errors and world Jacobians of the targets on the kinematic model."""

    def __init__(self, robot: Robot, targets: Sequence[FrameTarget]) -> None:
        self.model = _model(robot)
        self.data = mujoco.MjData(self.model)
        self.targets = list(targets)
        self.frames: list[Frame] = [resolve_frame(robot, t.frame) for t in targets]
        self.lower, self.upper = np.array(robot.lower), np.array(robot.upper)
        self._jp, self._jr = np.zeros((3, self.model.nv)), np.zeros((3, self.model.nv))

    def update(self, q: np.ndarray) -> None:
        self.data.qpos[:] = q
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)

    def error(self, goals: Sequence[FrameTarget] | None = None) -> np.ndarray:
        """Stacked task error at the loaded q (towards ``goals``, default the targets)."""
        parts = []
        for target, frame in zip(goals or self.targets, self.frames, strict=True):
            pos, rot = frame.pose(self.data)
            if target.pos is not None:
                parts.append(target.pos - pos)
            if target.rot is not None:
                quat, err = np.empty(4), np.empty(3)
                mujoco.mju_mat2Quat(quat, (target.rot @ rot.T).reshape(-1))
                mujoco.mju_quat2Vel(err, quat, 1.0)
                parts.append(err)
            elif target.axis is not None and target.direction is not None:
                parts.append(np.cross(rot @ target.axis, target.direction))
        return np.concatenate(parts)

    def jacobian(self) -> np.ndarray:
        """Rows matching :meth:`error`, over all the robot's joints."""
        rows = []
        for target, frame in zip(self.targets, self.frames, strict=True):
            if frame.kind == "site":
                mujoco.mj_jacSite(self.model, self.data, self._jp, self._jr, frame.id)
            else:
                mujoco.mj_jacBody(self.model, self.data, self._jp, self._jr, frame.id)
            if target.pos is not None:
                rows.append(self._jp.copy())
            if target.has_orientation:
                rows.append(self._jr.copy())
        return np.vstack(rows)

    def worst(self) -> tuple[float, float]:
        return worst_errors(self.targets, [f.pose(self.data) for f in self.frames])

    def clip(self, q: np.ndarray) -> np.ndarray:
        return np.clip(q, self.lower, self.upper)


def _result(p: _Problem, q: np.ndarray, iters: int, pos_tol: float, rot_tol: float, start: float) -> IKResult:
    p.update(q)
    pos_err, rot_err = p.worst()
    ok = pos_err <= pos_tol and rot_err <= rot_tol
    status = "converged" if ok else "max_iters"
    return IKResult(q, ok, pos_err, rot_err, iters, status, time.perf_counter() - start)


def _interpolate(target: FrameTarget, pos: np.ndarray, rot: np.ndarray, s: float) -> FrameTarget:
    """The subgoal a fraction ``s`` of the way from (pos, rot) to the target (rotation by its log)."""
    goal_pos = None if target.pos is None else pos + s * (target.pos - pos)
    goal_rot = None
    if target.rot is not None:
        quat, vel = np.empty(4), np.empty(3)
        mujoco.mju_mat2Quat(quat, (rot.T @ target.rot).reshape(-1))
        mujoco.mju_quat2Vel(vel, quat, 1.0)
        step, mat = np.empty(4), np.empty(9)
        angle = float(np.linalg.norm(vel))
        mujoco.mju_axisAngle2Quat(step, vel / max(angle, 1e-12), s * angle)
        mujoco.mju_quat2Mat(mat, step)
        goal_rot = rot @ mat.reshape(3, 3)
    return FrameTarget(target.frame, goal_pos, goal_rot, target.axis, target.direction)


def pinv_ik(
    robot: Robot,
    targets: Sequence[FrameTarget],
    q0: np.ndarray,
    *,
    subgoals: int = 20,
    max_iters: int = 200,
    pos_tol: float = 1e-4,
    rot_tol: float = 1e-3,
) -> IKResult:
    """The report's Algorithm 1: pseudo-inverse over ``subgoals`` interpolated goals, arms solved separately.

    Each target is solved over the joints that move its frame (for an arm's frame: the arm and the torso joints
    above it), one :math:`J^+ e` step per subgoal and then refinement steps on the final goal; a joint that
    several targets share (a torso joint) gets the mean of the separate solves.
    """
    start = time.perf_counter()
    q0 = np.asarray(q0, dtype=float)
    solutions, iters = [], 0
    for target in targets:
        p = _Problem(robot, [target])
        dofs = np.flatnonzero(chain_dofs(p.model, p.frames[0]))
        q = q0.copy()
        p.update(q)
        pos, rot = (a.copy() for a in p.frames[0].pose(p.data))
        for k in range(1, subgoals + max_iters + 1):
            goal = _interpolate(target, pos, rot, min(k / subgoals, 1.0))
            if k > subgoals and _done(p, pos_tol, rot_tol):
                break
            q[dofs] += np.linalg.pinv(p.jacobian()[:, dofs]) @ p.error([goal])
            q = p.clip(q)
            p.update(q)
            iters += 1
        solutions.append((dofs, q))
    q, total, count = q0.copy(), np.zeros(robot.nq), np.zeros(robot.nq)
    for dofs, sol in solutions:
        total[dofs] += sol[dofs]
        count[dofs] += 1
    solved = count > 0
    q[solved] = total[solved] / count[solved]
    return _result(_Problem(robot, targets), q, iters, pos_tol, rot_tol, start)


def _done(p: _Problem, pos_tol: float, rot_tol: float) -> bool:
    pos_err, rot_err = p.worst()
    return pos_err <= pos_tol and rot_err <= rot_tol


def _iterate(
    robot: Robot,
    targets: Sequence[FrameTarget],
    q0: np.ndarray,
    step: Callable[[_Problem, np.ndarray], np.ndarray],
    max_iters: int,
    pos_tol: float,
    rot_tol: float,
) -> IKResult:
    """Apply ``step(problem, q) -> q`` (which leaves the problem updated at the q it returns) until done."""
    start = time.perf_counter()
    p, q = _Problem(robot, targets), np.array(q0, dtype=float)
    p.update(q)
    iters = 0
    while iters < max_iters and not _done(p, pos_tol, rot_tol):
        q = step(p, q)
        iters += 1
    return _result(p, q, iters, pos_tol, rot_tol, start)


def dls_ik(
    robot: Robot,
    targets: Sequence[FrameTarget],
    q0: np.ndarray,
    *,
    damping: float = 0.05,
    max_iters: int = 200,
    pos_tol: float = 1e-4,
    rot_tol: float = 1e-3,
) -> IKResult:
    r"""Damped least squares over all the robot's joints with damping :math:`\lambda` [m or rad]."""

    def step(p: _Problem, q: np.ndarray) -> np.ndarray:
        jac, err = p.jacobian(), p.error()
        q = p.clip(q + jac.T @ np.linalg.solve(jac @ jac.T + damping**2 * np.eye(len(err)), err))
        p.update(q)
        return q

    return _iterate(robot, targets, q0, step, max_iters, pos_tol, rot_tol)


def lm_ik(
    robot: Robot,
    targets: Sequence[FrameTarget],
    q0: np.ndarray,
    *,
    lam: float = 1e-2,
    max_iters: int = 200,
    pos_tol: float = 1e-4,
    rot_tol: float = 1e-3,
) -> IKResult:
    r"""Levenberg–Marquardt with adaptive :math:`\lambda` (lecture Algorithm 5)."""
    err: np.ndarray | None = None  # error at the current q, carried between steps

    def step(p: _Problem, q: np.ndarray) -> np.ndarray:
        nonlocal lam, err
        if err is None:
            err = p.error()
        jac = p.jacobian()
        dq = np.linalg.solve(jac.T @ jac + lam * np.eye(len(q)), jac.T @ err)
        q_new = p.clip(q + dq)
        p.update(q_new)
        err_new = p.error()
        if err_new @ err_new < err @ err:
            lam, err = max(lam / 10.0, 1e-9), err_new
            return q_new
        p.update(q)
        lam = min(lam * 10.0, 1e6)
        return q

    return _iterate(robot, targets, q0, step, max_iters, pos_tol, rot_tol)
