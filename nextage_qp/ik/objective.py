r"""The QP objective of an IK step, assembled into preallocated arrays: mink's formulation with fewer Python layers.

Every task of the IK has mink's weighted least-squares form: a cost-weighted Jacobian :math:`W_i = C_i J_i`,
a weighted error :math:`e_i = -C_i\,\alpha_i\,\epsilon_i` (gain :math:`\alpha_i`, error :math:`\epsilon_i`) and a
Levenberg-Marquardt term :math:`\mu_i = \lambda_i \|e_i\|^2`. The objective of :func:`mink.build_ik` is

.. math::

    H = \sum_i W_i^T W_i + \Big(\delta + \sum_i \mu_i\Big) I, \qquad c = -\sum_i W_i^T e_i

with Tikhonov damping :math:`\delta`. :class:`Objective` computes exactly this. The terms that every tick has
take a short path: a :class:`mink.FrameTask` writes its rows into a reused buffer with mink's own compiled SE(3)
operations (the error :math:`\epsilon = T^* \ominus T`, the Jacobian :math:`-J_{log}(T^{*-1} T)\,{}_B J`), and
a :class:`mink.PostureTask` (Jacobian :math:`I`) adds :math:`C^2` to the diagonal of :math:`H` instead of
stacking an identity. Every other task (relative frames, axis alignment, a user's own) goes through its
``compute_qp_residual`` (or ``compute_qp_objective``) as in mink.
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
    """Where a :class:`mink.FrameTask`'s frame lives in the model: its id, Jacobian function and pose arrays."""

    def __init__(self, model: mujoco.MjModel, task: mink.FrameTask) -> None:
        obj, self.jac_fn, self.pos_attr, self.mat_attr = _FRAME[task.frame_type]
        self.task = task
        name = task.frame_name
        self.id = name if isinstance(name, int) else mujoco.mj_name2id(model, obj, name)
        if not 0 <= self.id < getattr(model, {"site": "nsite", "body": "nbody", "geom": "ngeom"}[task.frame_type]):
            raise mink.InvalidFrame(task.frame_name, task.frame_type, model)


class Objective:
    """Builds :math:`(H, c)` of the IK QP for a list of mink tasks (the same objective as :func:`mink.build_ik`).

    Frame tasks are done together: per frame the compiled SE(3) operations write its error, its
    :math:`J_{log} A_{fw}` and its MuJoCo Jacobian into stacked arrays, then one batched product gives every
    frame's weighted rows.

    Args:
        model: The IK's kinematic model.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model, nv = model, model.nv
        self.H, self.c = np.empty((nv, nv)), np.empty(nv)
        self._diag = self.H.reshape(-1)[:: nv + 1]  # a view of H's diagonal
        self._frames: dict[int, _Frame] = {}
        self._posture_error = np.empty(nv)
        self._alloc(2)

    def _alloc(self, n: int) -> None:
        nv = self.model.nv
        self._left, self._jac, self._rows = np.empty((n, 6, 6)), np.empty((n, 6, nv)), np.empty((n, 6, nv))
        self._error, self._cost, self._scale = np.empty((n, 6)), np.empty((n, 6)), np.empty((n, 1))
        # Views made once per frame slot: its Jacobian's two halves and its J_log A.
        self._slots = [(j[:3], j[3:], left) for j, left in zip(self._jac, self._left, strict=True)]

    def _frame(self, task: mink.FrameTask) -> _Frame:
        frame = self._frames.get(id(task))
        if frame is None or frame.task is not task:
            frame = self._frames[id(task)] = _Frame(self.model, task)
        return frame

    def _frame_rows(self, data: mujoco.MjData,
                    frames: Sequence[mink.FrameTask]) -> tuple[np.ndarray, np.ndarray, float]:
        """Stacked weighted rows :math:`W` (6m, nv), errors :math:`e` (6m,) and summed LM term of m frame tasks."""
        m = len(frames)
        if m > len(self._left):
            self._alloc(m)
        left, jac, error, cost, scale = self._left[:m], self._jac[:m], self._error[:m], self._cost[:m], self._scale[:m]
        lm = np.empty(m)
        for k, task in enumerate(frames):
            f, target = self._frame(task), task.transform_target_to_world
            if target is None:
                raise mink.TargetNotSet(type(task).__name__)
            jacp, jacr, left_k = self._slots[k]
            xpos, xmat = getattr(data, f.pos_attr)[f.id], getattr(data, f.mat_attr)[f.id]
            pose, goal = _native.xmat_xpos_to_wxyz_xyz(xmat, xpos), target.wxyz_xyz
            error[k] = _native.se3_rminus(goal, pose)
            f.jac_fn(self.model, data, jacp, jacr, f.id)
            # J_log(T*^-1 T) A_fw: A_fw turns MuJoCo's world-aligned Jacobian into the frame's own.
            np.matmul(_native.se3_jlog(_native.se3_inverse_multiply(goal, pose)),
                      _native.se3_rotation_adjoint_from_xmat(xmat), out=left_k)
            cost[k], scale[k], lm[k] = task.cost, task.gain, task.lm_damping
        rows = self._rows[:m]
        np.matmul(left, jac, out=rows)
        np.negative(cost, out=cost)  # -C from here on
        rows *= cost[:, :, None]  # W = -C J_log A J
        error *= cost
        error *= scale  # e = -alpha C eps
        return rows.reshape(6 * m, -1), error.reshape(-1), float(lm @ np.vecdot(error, error))

    def build(self, configuration: mink.Configuration, tasks: Sequence[mink.Task],
              damping: float) -> tuple[np.ndarray, np.ndarray]:
        """:math:`(H, c)` at the configuration (arrays owned by this object, overwritten by the next call)."""
        data, H, c = configuration.data, self.H, self.c
        frames = [t for t in tasks if type(t) is mink.FrameTask] if _native is not None else []
        if frames:
            w, e, mu = self._frame_rows(data, frames)
            np.matmul(w.T, w, out=H)
            np.matmul(e, w, out=c)
            np.negative(c, out=c)
        else:
            H.fill(0.0)
            c.fill(0.0)
            mu = 0.0
        mu += damping
        for task in tasks:
            if frames and type(task) is mink.FrameTask:
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
