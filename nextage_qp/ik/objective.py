r"""The QP objective of an IK step, assembled into preallocated arrays: mink's formulation with fewer Python layers.

Every task of the IK has mink's weighted least-squares form: a cost-weighted Jacobian :math:`W_i = C_i J_i`,
a weighted error :math:`e_i = -C_i\,\alpha_i\,\epsilon_i` (gain :math:`\alpha_i`, error :math:`\epsilon_i`) and a
Levenberg-Marquardt term :math:`\mu_i = \lambda_i \|e_i\|^2`. The objective of :func:`mink.build_ik` is

.. math::

    H = \sum_i W_i^T W_i + \Big(\delta + \sum_i \mu_i\Big) I, \qquad c = -\sum_i W_i^T e_i

with Tikhonov damping :math:`\delta`. :class:`Objective` computes exactly this. The terms that every tick has
take a short path: a :class:`mink.FrameTask` and a :class:`mink.RelativeFrameTask` write their rows into reused
buffers with mink's own compiled SE(3) operations, exactly as mink's tasks compute them (frame: the error
:math:`\epsilon = T^* \ominus T`, the Jacobian :math:`-J_{log}(T^{*-1} T)\,{}_B J`; relative: the error
:math:`\epsilon = T_{rf} \ominus T^*` of the frame in the root's frame, the Jacobian
:math:`J_{log}(T^{*-1} T_{rf})\,({}_f J_f - \mathrm{Ad}(T_{rf}^{-1})\,{}_r J_r)`; axis-align: the error
:math:`a - R^T t`, the Jacobian :math:`-[R^T t]_\times\,{}_B J_\omega`, in three of its six rows), and a
:class:`mink.PostureTask`
(Jacobian :math:`I`) adds :math:`C^2` to the diagonal of :math:`H` instead of stacking an identity. Every other
task (a look-at, a user's own) goes through its ``compute_qp_residual`` (or ``compute_qp_objective``) as in
mink.
"""

from __future__ import annotations

from collections.abc import Sequence

import mink
import mujoco
import numpy as np

try:  # mink's compiled SE(3) operations (the same ones mink's FrameTask calls)
    from mink.lie import _lie_ops_c as _native
except ImportError:  # pragma: no cover - a mink build without them: every task takes mink's own path
    _native = None  # type: ignore[assignment]

_FRAME = {
    "site": (mujoco.mjtObj.mjOBJ_SITE, mujoco.mj_jacSite, "site_xpos", "site_xmat"),
    "body": (mujoco.mjtObj.mjOBJ_BODY, mujoco.mj_jacBody, "xpos", "xmat"),
    "geom": (mujoco.mjtObj.mjOBJ_GEOM, mujoco.mj_jacGeom, "geom_xpos", "geom_xmat"),
}


class _Frame:
    """Where a frame lives in the model: its id, Jacobian function and pose arrays."""

    def __init__(self, model: mujoco.MjModel, name: str | int, kind: str) -> None:
        obj, self.jac_fn, self.pos_attr, self.mat_attr = _FRAME[kind]
        self.id = name if isinstance(name, int) else mujoco.mj_name2id(model, obj, name)
        if not 0 <= self.id < getattr(model, {"site": "nsite", "body": "nbody", "geom": "ngeom"}[kind]):
            raise mink.InvalidFrame(name, kind, model)

    def pose(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """The frame's pose as wxyz_xyz (7,) and its row-major rotation matrix (9,)."""
        xmat = getattr(data, self.mat_attr)[self.id]
        return _native.xmat_xpos_to_wxyz_xyz(xmat, getattr(data, self.pos_attr)[self.id]), xmat

    def local_jacobian(self, model: mujoco.MjModel, data: mujoco.MjData, jac: np.ndarray, xmat: np.ndarray,
                       out: np.ndarray) -> np.ndarray:
        """The frame's Jacobian in its own axes (mink's ``get_frame_jacobian``), via ``jac`` (6, nv) as scratch."""
        self.jac_fn(model, data, jac[:3], jac[3:], self.id)
        return np.matmul(_native.se3_rotation_adjoint_from_xmat(xmat), jac, out=out)


_FAST = (mink.FrameTask, mink.RelativeFrameTask, mink.AxisAlignTask)


class Objective:
    """Builds :math:`(H, c)` of the IK QP for a list of mink tasks (the same objective as :func:`mink.build_ik`).

    Frame and relative-frame tasks are done together: each writes its error and weighted Jacobian rows into
    stacked arrays (the compiled SE(3) operations and MuJoCo's Jacobians), then one product gives :math:`H`.

    Args:
        model: The IK's kinematic model.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model, nv = model, model.nv
        self.H, self.c = np.empty((nv, nv)), np.empty(nv)
        self._diag = self.H.reshape(-1)[:: nv + 1]  # a view of H's diagonal
        self._frames: dict[tuple[str | int, str], _Frame] = {}
        self._posture_error = np.empty(nv)
        self._scratch, self._local = np.empty((6, nv)), np.empty((6, nv))
        self._alloc(2)

    def _alloc(self, n: int) -> None:
        nv = self.model.nv
        self._rows = np.empty((n, 6, nv))
        self._error, self._cost, self._scale = np.empty((n, 6)), np.empty((n, 6)), np.empty((n, 1))
        self._slots = list(self._rows)  # views made once

    def _frame(self, name: str | int, kind: str) -> _Frame:
        frame = self._frames.get((name, kind))
        if frame is None:
            frame = self._frames[(name, kind)] = _Frame(self.model, name, kind)
        return frame

    def _stacked_rows(self, data: mujoco.MjData,
                      tasks: Sequence[mink.Task]) -> tuple[np.ndarray, np.ndarray, float]:
        """Stacked weighted rows :math:`W` (6m, nv), errors :math:`e` (6m,) and LM term of m (relative) frame tasks."""
        m, model, scratch = len(tasks), self.model, self._scratch
        if m > len(self._slots):
            self._alloc(m)
        error, cost, scale = self._error[:m], self._cost[:m], self._scale[:m]
        lm = np.empty(m)
        last = None  # the frame whose local Jacobian self._local holds (a frame task's, for its axis task next)
        for k, task in enumerate(tasks):
            rows = self._slots[k]
            if isinstance(task, mink.FrameTask):
                target = task.transform_target_to_world
                if target is None:
                    raise mink.TargetNotSet(type(task).__name__)
                f = self._frame(task.frame_name, task.frame_type)
                pose, xmat = f.pose(data)
                goal = target.wxyz_xyz
                error[k] = _native.se3_rminus(goal, pose)
                local = f.local_jacobian(model, data, scratch, xmat, self._local)
                last = f
                np.matmul(_native.se3_jlog(_native.se3_inverse_multiply(goal, pose)), local, out=rows)
                np.negative(rows, out=rows)  # J = -J_log(T*^-1 T) B_J
            elif isinstance(task, mink.AxisAlignTask):  # rows 0-2: -[d]x J_w with d = R^T t; rows 3-5 zero
                if task.target_dir is None:
                    raise mink.TargetNotSet(type(task).__name__)
                f = self._frame(task.frame_name, task.frame_type)
                xmat = getattr(data, f.mat_attr)[f.id]
                d = xmat.reshape(3, 3).T @ task.target_dir
                local = self._local if last is f else f.local_jacobian(model, data, scratch, xmat, self._local)
                last = f
                skew = np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])
                np.matmul(skew, local[3:], out=rows[:3])
                np.negative(rows[:3], out=rows[:3])
                rows[3:] = 0.0
                error[k, :3], error[k, 3:] = task.axis - d, 0.0
                cost[k, :3], cost[k, 3:], scale[k], lm[k] = task.cost, 0.0, task.gain, task.lm_damping
                continue
            else:
                assert isinstance(task, mink.RelativeFrameTask)
                last = None
                target = task.transform_target_to_root
                if target is None:
                    raise mink.TargetNotSet(type(task).__name__)
                f, r = self._frame(task.frame_name, task.frame_type), self._frame(task.root_name, task.root_type)
                (frame_pose, frame_mat), (root_pose, root_mat) = f.pose(data), r.pose(data)
                relative, goal = _native.se3_inverse_multiply(root_pose, frame_pose), target.wxyz_xyz
                error[k] = _native.se3_rminus(relative, goal)
                root_local = r.local_jacobian(model, data, scratch, root_mat, self._local)
                local = _native.se3_adjoint(_native.se3_inverse(relative)) @ root_local
                np.subtract(f.local_jacobian(model, data, scratch, frame_mat, self._local), local, out=local)
                np.matmul(_native.se3_jlog(_native.se3_inverse_multiply(goal, relative)), local, out=rows)
            cost[k], scale[k], lm[k] = task.cost, task.gain, task.lm_damping
        rows = self._rows[:m]
        rows *= cost[:, :, None]  # W = C J
        np.negative(cost, out=cost)
        error *= cost
        error *= scale  # e = -alpha C eps
        return rows.reshape(6 * m, -1), error.reshape(-1), float(lm @ np.vecdot(error, error))

    def build(self, configuration: mink.Configuration, tasks: Sequence[mink.Task],
              damping: float) -> tuple[np.ndarray, np.ndarray]:
        """:math:`(H, c)` at the configuration (arrays owned by this object, overwritten by the next call)."""
        data, H, c = configuration.data, self.H, self.c
        stacked = [t for t in tasks if type(t) in _FAST] if _native is not None else []
        if stacked:
            w, e, mu = self._stacked_rows(data, stacked)
            np.matmul(w.T, w, out=H)
            np.matmul(e, w, out=c)
            np.negative(c, out=c)
        else:
            H.fill(0.0)
            c.fill(0.0)
            mu = 0.0
        mu += damping
        for task in tasks:
            if stacked and type(task) in _FAST:
                continue
            if type(task) is mink.PostureTask and task._v_ids is None and task.target_q is not None:
                # W = C (diagonal): W^T W = C^2 on the diagonal, -W^T e = C^2 alpha (q - q*).
                err = self._posture_error
                mujoco.mj_differentiatePos(self.model, err, 1.0, task.target_q, configuration.q)
                cost2 = task.cost * task.cost
                self._diag += cost2
                c += cost2 * task.gain * err
                if task.lm_damping:
                    we = task.cost * task.gain * err
                    mu += task.lm_damping * float(we @ we)
                continue
            residual = task.compute_qp_residual(configuration)
            if residual is None:
                h_task, c_task = task.compute_qp_objective(configuration)
                H += h_task
                c += c_task
            else:
                wt, et, mu_t = residual
                H += wt.T @ wt
                c -= et @ wt
                mu += mu_t
        self._diag += mu
        return H, c
