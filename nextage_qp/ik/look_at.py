r"""A look-at task: a camera's optical axis towards a point, moving only the head's joints.

With :math:`u` the unit vector from the camera to the point and :math:`R` the camera's rotation (MuJoCo's
convention: it looks along :math:`-z`), the error is the first two components of :math:`u_c = R^T u` (zero when
the point is on the optical axis). Its Jacobian, from the camera's world-aligned Jacobians :math:`J_p, J_r` at
distance :math:`d`, is :math:`R^T\left(-(I - u u^T) J_p / d + [u]_\times J_r\right)`, with every column outside the
head's joints zeroed: the task can never move the arms or the torso, whatever its weight.
"""

from __future__ import annotations

from collections.abc import Sequence

import mink
import mujoco
import numpy as np


class LookAtTask(mink.Task):
    """Point the camera ``camera`` at :attr:`point`, with the joints ``dofs`` only.

    Args:
        model: The IK's model.
        camera: A camera of the model (the robot file's cameras are added to it).
        dofs: Velocity indices of the joints that may move (the head's).
        cost: Weight of the task [1/rad].
    """

    def __init__(self, model: mujoco.MjModel, camera: str, dofs: Sequence[int] | np.ndarray, cost: float) -> None:
        super().__init__(cost=np.full(2, cost), gain=0.5)
        cam = _camera(model, camera)
        self.body = int(model.cam_bodyid[cam])
        self.local_pos = np.array(model.cam_pos[cam])
        local = np.zeros(9)
        mujoco.mju_quat2Mat(local, model.cam_quat[cam])
        self.local_rot = local.reshape(3, 3)
        self.dofs = np.asarray(dofs, dtype=int)
        self.point: np.ndarray | None = None
        self._jp, self._jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))

    def pose(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """The camera's world position and rotation (from its body's pose)."""
        body_rot = data.xmat[self.body].reshape(3, 3)
        return data.xpos[self.body] + body_rot @ self.local_pos, body_rot @ self.local_rot

    def _u(self, data: mujoco.MjData) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
        assert self.point is not None
        pos, rot = self.pose(data)
        rel = self.point - pos
        d = max(float(np.linalg.norm(rel)), 1e-6)
        return rel / d, d, rot, pos

    def off_axis(self, data: mujoco.MjData) -> float:
        """Angle [rad] between the camera's optical axis and the direction to :attr:`point`."""
        u, _, rot, _ = self._u(data)
        return float(np.arccos(np.clip(-rot[:, 2] @ u, -1.0, 1.0)))

    def compute_error(self, configuration: mink.Configuration) -> np.ndarray:  # noqa: D102
        if self.point is None:
            return np.zeros(2)
        u, _, rot, _ = self._u(configuration.data)
        return (rot.T @ u)[:2]

    def compute_jacobian(self, configuration: mink.Configuration) -> np.ndarray:  # noqa: D102
        model, data = configuration.model, configuration.data
        out = np.zeros((2, model.nv))
        if self.point is None:
            return out
        u, d, rot, pos = self._u(data)
        mujoco.mj_jac(model, data, self._jp, self._jr, pos, self.body)
        skew = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
        full = rot.T @ (-(np.eye(3) - np.outer(u, u)) @ self._jp / d + skew @ self._jr)
        out[:, self.dofs] = full[:2, self.dofs]
        return out

    def head_step(self, configuration: mink.Configuration, vmax: np.ndarray) -> np.ndarray:
        """A joint step [rad] of the head alone towards the point (for ticks without an IK solve)."""
        if self.point is None:
            return np.zeros(configuration.model.nv)
        e, J = self.compute_error(configuration), self.compute_jacobian(configuration)[:, self.dofs]
        step = -np.linalg.solve(J.T @ J + 1e-3 * np.eye(len(self.dofs)), J.T @ (self.gain * e))
        out = np.zeros(configuration.model.nv)
        out[self.dofs] = np.clip(step, -vmax[self.dofs], vmax[self.dofs])
        return out


def _camera(model: mujoco.MjModel, name: str) -> int:
    cam = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name))
    if cam < 0:
        cams = [model.camera(i).name for i in range(model.ncam)]
        raise ValueError(f"no camera {name!r} in the IK model; cameras: {', '.join(cams) or '(none)'}")
    return cam


def head_dofs(model: mujoco.MjModel, data: mujoco.MjData, camera: str, wrists: Sequence[tuple[str, int]]) -> np.ndarray:
    """Velocity indices that move the camera ``camera`` and none of the ``wrists`` ((kind, id): site or body)."""
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    body = int(model.cam_bodyid[_camera(model, camera)])
    mujoco.mj_jacBody(model, data, jp, jr, body)
    moves_camera = np.abs(np.vstack([jp, jr])).max(axis=0) > 1e-9
    moves_arm = np.zeros(model.nv, dtype=bool)
    for kind, fid in wrists:
        (mujoco.mj_jacSite if kind == "site" else mujoco.mj_jacBody)(model, data, jp, jr, fid)
        moves_arm |= np.abs(np.vstack([jp, jr])).max(axis=0) > 1e-9
    return np.flatnonzero(moves_camera & ~moves_arm)


def watch(ik, camera: str, cost: float) -> LookAtTask:
    """A look-at task for the robot camera ``camera`` in the IK ``ik``'s model.

    It moves only the joints that move the camera and neither arm's wrist (the head's).
    """
    wrists = [(f.kind, f.id) for f in (ik.frame(arm.wrist) for arm in ik.robot.arms)]
    return LookAtTask(ik.model, camera, head_dofs(ik.model, ik.configuration.data, camera, wrists), cost)
