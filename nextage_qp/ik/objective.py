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
    _native = None

_FRAME = {
    "site": (mujoco.mjtObj.mjOBJ_SITE, mujoco.mj_jacSite, "site_xpos", "site_xmat"),
    "body": (mujoco.mjtObj.mjOBJ_BODY, mujoco.mj_jacBody, "xpos", "xmat"),
    "geom": (mujoco.mjtObj.mjOBJ_GEOM, mujoco.mj_jacGeom, "geom_xpos", "geom_xmat"),
}


class _FrameRows:
    """The weighted rows of one :class:`mink.FrameTask`, written in place."""

    def __init__(self, model: mujoco.MjModel, task: mink.FrameTask) -> None:
        obj, self.jac_fn, pos_attr, mat_attr = _FRAME[task.frame_type]
        self.task, self.model = task, model
        name = task.frame_name
        self.id = name if isinstance(name, int) else mujoco.mj_name2id(model, obj, name)
        if not 0 <= self.id < getattr(model, {"site": "nsite", "body": "nbody", "geom": "ngeom"}[task.frame_type]):
            raise mink.InvalidFrame(task.frame_name, task.frame_type, model)
        self.pos_attr, self.mat_attr = pos_attr, mat_attr
        self.jac = np.empty((6, model.nv))

    def fill(self, data: mujoco.MjData, w: np.ndarray, e: np.ndarray) -> float:
        """Write :math:`W` (6, nv) and :math:`e` (6,) of the task at ``data``; returns :math:`\\mu`."""
        task, i, jac = self.task, self.id, self.jac
        target = task.transform_target_to_world
        if target is None:
            raise mink.TargetNotSet(type(task).__name__)
        xpos, xmat = getattr(data, self.pos_attr)[i], getattr(data, self.mat_attr)[i]
        frame = _native.xmat_xpos_to_wxyz_xyz(xmat, xpos)
        goal = target.wxyz_xyz
        error = _native.se3_rminus(goal, frame)
        self.jac_fn(self.model, data, jac[:3], jac[3:], i)
        # -J_log(T*^-1 T) A_fw (the world-aligned MuJoCo Jacobian turned into the frame's own), weighted by C.
        left = _native.se3_jlog(_native.se3_inverse_multiply(goal, frame)) @ _native.se3_rotation_adjoint_from_xmat(
            xmat)
        cost = task.cost
        left *= -cost[:, None]
        np.matmul(left, jac, out=w)
        np.multiply(cost, error, out=e)
        e *= -task.gain
        return float(task.lm_damping * (e @ e))


class Objective:
    """Builds :math:`(H, c)` of the IK QP for a list of mink tasks (the same objective as :func:`mink.build_ik`).

    Args:
        model: The IK's kinematic model.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model, nv = model, model.nv
        self.H, self.c = np.empty((nv, nv)), np.empty(nv)
        self._rows = np.empty((12, nv))
        self._errors = np.empty(12)
        self._frames: dict[int, _FrameRows] = {}
        self._posture_error = np.empty(nv)
        self._diag = self.H.reshape(-1)[:: nv + 1]  # a view of H's diagonal

    def _frame(self, task: mink.FrameTask) -> _FrameRows:
        rows = self._frames.get(id(task))
        if rows is None or rows.task is not task:
            rows = self._frames[id(task)] = _FrameRows(self.model, task)
        return rows

    def build(self, configuration: mink.Configuration, tasks: Sequence[mink.Task],
              damping: float) -> tuple[np.ndarray, np.ndarray]:
        """:math:`(H, c)` at the configuration (arrays owned by this object, overwritten by the next call)."""
        data, nv = configuration.data, self.model.nv
        frames = [t for t in tasks if type(t) is mink.FrameTask] if _native is not None else []
        if len(frames) * 6 > len(self._rows):
            self._rows, self._errors = np.empty((6 * len(frames), nv)), np.empty(6 * len(frames))
        mu, n = damping, 6 * len(frames)
        w, e = self._rows[:n], self._errors[:n]
        for k, task in enumerate(frames):
            mu += self._frame(task).fill(data, w[6 * k : 6 * k + 6], e[6 * k : 6 * k + 6])
        H, c = self.H, self.c
        np.matmul(w.T, w, out=H)
        np.matmul(e, w, out=c)
        np.negative(c, out=c)
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
