r"""Forward kinematics and Jacobians of any frame, over MuJoCo and over the report's transform chain.

Two independent implementations:

* :class:`Kinematics` evaluates MuJoCo (``mj_kinematics`` / ``mj_jac``) on a private ``MjData``, so it never
  disturbs a running simulation.
* :func:`chain_fk` multiplies one homogeneous transform per joint along a kinematic chain built from a
  topology map written from a joint table (the Nextage's: :data:`nextage_qp.kinematics.nextage_chain.TOPOLOGY`), as in
  the report:

  .. math::

      {}^{p}T_{c}(q) = \begin{bmatrix} R(\hat a, q) & o \\ 0 & 1 \end{bmatrix},\quad
      R(\hat a, q) = I + \sin q\,[\hat a]_\times + (1-\cos q)\,[\hat a]_\times^2

  (Rodrigues' axis-angle rotation, report Eq. 1-2), with joint origin :math:`o` [m] and unit axis
  :math:`\hat a`; a frame's world pose is the product from the base down to the frame.
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco
import numpy as np

from nextage_qp.errors import InfeasibleError, UnknownFrameError
from nextage_qp.geometry import Pose
from nextage_qp.robots.model import Robot


class Kinematics:
    """FK and Jacobians of a robot's bodies and sites for a given joint vector.

    Args:
        robot: The robot (any scene).
    """

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.data = mujoco.MjData(robot.model)
        self._jacp = np.zeros((3, robot.model.nv))
        self._jacr = np.zeros((3, robot.model.nv))
        self._q: np.ndarray | None = None  # the joints the data's kinematics were last computed for

    def _update(self, q: np.ndarray) -> None:
        if self._q is not None and np.array_equal(q, self._q):  # several frames of one joint vector: once
            return
        self.data.qpos[self.robot.qpos_idx] = q
        mujoco.mj_kinematics(self.robot.model, self.data)
        self._q = q.copy()

    def fk(self, frame: str, q: np.ndarray) -> Pose:
        """World pose of a body or site at joint vector ``q`` [rad] (the robot's joints).

        Raises:
            UnknownFrameError: ``frame`` is neither a site nor a body.
        """
        kind, fid = self.robot.frame(frame)
        self._update(np.asarray(q, dtype=float))
        if kind == "site":
            return Pose(self.data.site_xpos[fid].copy(), self.data.site_xmat[fid].reshape(3, 3).copy())
        return Pose(self.data.xpos[fid].copy(), self.data.xmat[fid].reshape(3, 3).copy())

    def reach(self, frame: str, q: np.ndarray) -> tuple[np.ndarray, float, str | None]:
        """A sphere the frame's origin never leaves, whatever the joints: centre, radius [m], the joint at the centre.

        The centre is the anchor of the first joint (from the root) that moves the frame; each hinge or ball joint
        keeps the distance from its anchor to the next one's, each slide joint adds its travel (an unlimited slide or a
        free joint: an infinite radius). A frame no joint moves: its origin and radius 0 (joint None).
        """
        kind, fid = self.robot.frame(frame)
        self._update(np.asarray(q, dtype=float))
        m, d = self.robot.model, self.data
        body = fid if kind == "body" else int(m.site_bodyid[fid])
        point = (d.site_xpos if kind == "site" else d.xpos)[fid].copy()
        joints: list[int] = []
        while body > 0:
            joints[:0] = range(int(m.body_jntadr[body]), int(m.body_jntadr[body] + m.body_jntnum[body]))
            body = int(m.body_parentid[body])
        if not joints:
            return point, 0.0, None
        radius, at = 0.0, d.xanchor[joints[0]]
        for j in joints:
            kind_j = m.jnt_type[j]
            if kind_j == mujoco.mjtJoint.mjJNT_FREE or (kind_j == mujoco.mjtJoint.mjJNT_SLIDE and not m.jnt_limited[j]):
                return point, float("inf"), m.joint(j).name
            radius += float(np.linalg.norm(d.xanchor[j] - at))
            radius += float(np.ptp(m.jnt_range[j])) if kind_j == mujoco.mjtJoint.mjJNT_SLIDE else 0.0
            at = d.xanchor[j]
        return d.xanchor[joints[0]].copy(), radius + float(np.linalg.norm(point - at)), m.joint(joints[0]).name

    def check_reach(self, frame: str, pos: np.ndarray, q: np.ndarray, where: str) -> None:
        """Refuse a target position no joint configuration can bring the frame's origin to (:meth:`reach`).

        Raises:
            InfeasibleError: One line: how far the target is from the sphere's centre, and the radius.
        """
        centre, radius, joint = self.reach(frame, q)
        dist = float(np.linalg.norm(np.asarray(pos, dtype=float) - centre))
        if dist <= radius + 1e-3:
            return
        at = ", ".join(f"{x:.3f}" for x in centre)
        if joint is None:
            raise InfeasibleError(f"{where}: {frame} is moved by no joint of the robot; it stays at ({at}), "
                                  f"{dist:.3f} m from the target")
        raise InfeasibleError(f"{where}: out of reach: {dist:.3f} m from {joint} at ({at}), and {frame} reaches at "
                              f"most {radius:.3f} m from there")

    def jacobian(self, frame: str, q: np.ndarray) -> np.ndarray:
        """The 6 x n world-frame Jacobian ``[J_v; J_w]`` of a frame's origin over the robot's n joints.

        Rows 0-2 map joint velocities [rad/s] to the origin's linear velocity [m/s], rows 3-5 to the
        frame's angular velocity [rad/s], both in world coordinates.
        """
        kind, fid = self.robot.frame(frame)
        self._update(np.asarray(q, dtype=float))
        mujoco.mj_comPos(self.robot.model, self.data)
        if kind == "site":
            mujoco.mj_jacSite(self.robot.model, self.data, self._jacp, self._jacr, fid)
        else:
            mujoco.mj_jacBody(self.robot.model, self.data, self._jacp, self._jacr, fid)
        dofs = self.robot.dof_idx
        return np.vstack([self._jacp[:, dofs], self._jacr[:, dofs]])


def axis_angle_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation matrix for a unit ``axis`` and ``angle`` [rad] (report Eq. 1)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def joint_transform(origin: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Homogeneous transform parent link -> child link of a revolute joint (report Eq. 2)."""
    t = np.eye(4)
    t[:3, :3] = axis_angle_rotation(axis, angle)
    t[:3, 3] = origin
    return t


def chain_fk(
    link: str,
    q: Mapping[str, float],
    topology: Mapping[str, tuple[str | None, tuple[float, ...], tuple[float, ...]]],
) -> np.ndarray:
    """World transform (4 x 4) of a joint's child link frame by chaining per-joint transforms.

    Args:
        link: A joint name (``J``) or its link (``J_Link``).
        q: Joint angles [rad] by joint name (a joint left out is at 0).
        topology: joint -> (parent joint, origin, axis).

    Raises:
        UnknownFrameError: ``link`` is not in the topology.
    """
    joint = link.removesuffix("_Link")
    if joint not in topology:
        raise UnknownFrameError(link, [f"{j}_Link" for j in topology])
    angles = q
    chain: list[str] = []
    node: str | None = joint
    while node is not None:
        chain.append(node)
        node = topology[node][0]
    t = np.eye(4)
    for name in reversed(chain):
        _, origin, axis = topology[name]
        t = t @ joint_transform(np.asarray(origin), np.asarray(axis, dtype=float), float(angles.get(name, 0.0)))
    return t
