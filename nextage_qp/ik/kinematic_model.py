"""The IK's kinematic model: the scene with its free objects turned into mocap bodies.

Objects of a task scene (cube, dumbbell) have free joints, which must not be IK variables. The kinematic
model is compiled from the same composed spec with every free joint removed and its body made a mocap body (and
any joint the robot file leaves out removed), so ``nq == nv`` = the robot's joints, in
:attr:`~nextage_qp.robots.model.Robot.joint_names` order, and objects are placed through ``data.mocap_pos`` /
``data.mocap_quat``. Geom and body ids equal those of the full model.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, UnknownNameError
from nextage_qp.mobile.build import PLANAR_JOINTS, base_kinematic_joints
from nextage_qp.robots.model import Robot
from nextage_qp.scene.compile import compile_spec
from nextage_qp.scene.seen_obstacles import blind

__all__ = ["PLANAR_JOINTS", "Frame", "ObjectPoses", "chain_dofs", "ik_joint_names", "kinematic_model",
           "lever_bounds", "mocap_ids", "moved_by_a_joint", "resolve_frame", "set_object_poses"]

ObjectPoses = Mapping[str, tuple[np.ndarray, np.ndarray]]
"""Object name -> (position [m], unit quaternion w, x, y, z) in the world."""


def ik_joint_names(robot: Robot) -> tuple[str, ...]:
    """The joints of the IK's kinematic model: a mobile robot's planar base joints first, then the robot's."""
    return (*PLANAR_JOINTS, *robot.joint_names) if robot.base is not None else robot.joint_names


def kinematic_model(robot: Robot) -> mujoco.MjModel:
    """Compile the robot's scene, with its overrides, without free joints (objects become mocap bodies).

    A mobile robot's base keeps three planar joints (world x, y and yaw: :data:`PLANAR_JOINTS`) in place of its
    free joint, and loses its wheels' joints; the base's pose is the IK's to set, from odometry.

    Raises:
        ConfigError: The scene cannot be recompiled, or the result is not exactly the robot's joints (and a
            mobile base's planar joints before them).
    """
    free = robot.model.jnt_type == mujoco.mjtJoint.mjJNT_FREE
    extra = len(robot.model.jnt_type) - int(free.sum()) != robot.nq
    wanted = ik_joint_names(robot)
    if not free.any() and not extra:
        model = robot.model
    else:
        if robot.spec is None:
            raise ConfigError(f"{robot.scene}: the IK needs the scene's spec to make its kinematic copy")
        spec = robot.spec()
        if robot.base is not None:
            base_kinematic_joints(spec)
        keep = set(wanted)
        for joint in list(spec.joints):
            if joint.type == mujoco.mjtJoint.mjJNT_FREE:
                body = joint.parent
                spec.delete(joint)
                body.mocap = True
            elif joint.name not in keep:  # a joint the robot file leaves out (a gripper's, a wheel): held at its rest
                spec.delete(joint)
        joints = {j.name for j in spec.joints}
        for actuator in list(spec.actuators):  # those of the joints left out go too
            if actuator.trntype == mujoco.mjtTrn.mjTRN_JOINT and actuator.target not in joints:
                spec.delete(actuator)
        model = compile_spec(spec, f"{robot.scene} (the IK's kinematic copy)")
        if robot.blinded:  # a controller that knows the obstacles from its camera alone
            blind(model)
        if model.ngeom != robot.model.ngeom or model.nbody != robot.model.nbody:
            raise ConfigError(f"{robot.scene}: kinematic model does not match the robot's model")
    names = tuple(model.joint(i).name for i in range(model.njnt))
    if names != wanted or model.nv != len(wanted):
        raise ConfigError(f"{robot.scene}: IK model must have exactly the joints {wanted}, got {names}")
    return model


class Frame(NamedTuple):
    """A resolved frame: ``kind`` is ``"site"`` or ``"body"``, ``id`` its id in the model."""

    name: str
    kind: str
    id: int

    def xpos(self, data: mujoco.MjData) -> np.ndarray:
        """World position [m] of the frame in ``data`` (a view)."""
        return data.site_xpos[self.id] if self.kind == "site" else data.xpos[self.id]

    def xmat(self, data: mujoco.MjData) -> np.ndarray:
        """Row-major world rotation matrix (9,) of the frame in ``data`` (a view)."""
        return data.site_xmat[self.id] if self.kind == "site" else data.xmat[self.id]

    def pose(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """World position [m] and rotation matrix of the frame in ``data`` (after kinematics)."""
        if self.kind == "site":
            return data.site_xpos[self.id], data.site_xmat[self.id].reshape(3, 3)
        return data.xpos[self.id], data.xmat[self.id].reshape(3, 3)


def resolve_frame(robot: Robot, name: str) -> Frame:
    """Resolve a body or site name (sites win); raises UnknownFrameError listing the valid names."""
    kind, fid = robot.frame(name)
    return Frame(name, kind, fid)


def chain_dofs(model: mujoco.MjModel, frame: Frame) -> np.ndarray:
    """Boolean mask (nv,) of the dofs that move ``frame``: those of its body and every ancestor."""
    mask = np.zeros(model.nv, dtype=bool)
    body = frame.id if frame.kind == "body" else int(model.site_bodyid[frame.id])
    while body > 0:
        adr, num = int(model.body_dofadr[body]), int(model.body_dofnum[body])
        mask[adr : adr + num] = True
        body = int(model.body_parentid[body])
    return mask


def mocap_ids(model: mujoco.MjModel) -> dict[str, int]:
    """Mocap body name -> mocap id."""
    return {model.body(b).name: int(model.body_mocapid[b]) for b in range(model.nbody) if model.body_mocapid[b] >= 0}


def set_object_poses(model: mujoco.MjModel, data: mujoco.MjData, poses: ObjectPoses,
                     mocap: Mapping[str, int] | None = None) -> None:
    """Place mocap objects (by body name) in ``data``; kinematics must be run afterwards.

    ``mocap`` is :func:`mocap_ids` of the model, for a caller that places objects often.

    Raises:
        UnknownNameError: A name is not a mocap object of the model; the message lists those that are.
        ConfigError: A position or quaternion has the wrong shape.
    """
    mocap = mocap_ids(model) if mocap is None else mocap
    for name, (pos, quat) in poses.items():
        if name not in mocap:
            raise UnknownNameError("object", name, mocap)
        p, qt = np.asarray(pos, dtype=float), np.asarray(quat, dtype=float)
        norm = math.sqrt(float(qt @ qt)) if qt.shape == (4,) else 0.0
        if p.shape != (3,) or not norm > 0:
            raise ConfigError(f"object {name!r}: pose must be pos (3,) and non-zero quat wxyz (4,)")
        i = mocap[name]
        data.mocap_pos[i] = p
        data.mocap_quat[i] = qt / norm


def moved_by_a_joint(model: mujoco.MjModel, body: int) -> bool:
    """Whether any joint on the chain from the world to ``body`` moves it (its points have a Jacobian)."""
    while body > 0:
        if model.body_dofnum[body] > 0:
            return True
        body = int(model.body_parentid[body])
    return False


def lever_bounds(model: mujoco.MjModel) -> np.ndarray:
    """Lever arms (ngeom, nv) [m] that hold in every configuration.

    Each entry bounds the distance from a hinge dof's anchor to any point of a geom it moves (the sum of
    the offsets along the chain, and of the travel of the slide joints between); 1 for a slide dof (it moves every
    point by its own travel), 0 where the dof does not move the geom, inf for a ball or free joint's.
    """
    lever = np.zeros((model.ngeom, model.nv))
    norm = np.linalg.norm  # per vector, as along the chain: each offset's norm computed once
    slide = (model.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE).tolist()
    travel = [(float(np.abs(r).max()) if lim else np.inf) if sl else 0.0  # how far a slide joint moves its body
              for r, lim, sl in zip(model.jnt_range, model.jnt_limited.tolist(), slide, strict=True)]
    body_len = [float(norm(p)) + sum(travel[j] for j in range(a, a + n))
                for p, a, n in zip(model.body_pos, model.body_jntadr.tolist(), model.body_jntnum.tolist(), strict=True)]
    joint_len = [float(norm(p)) for p in model.jnt_pos]
    hinge = (model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE).tolist()
    parent, dofadr, dofnum, dof_jnt = (a.tolist() for a in (model.body_parentid, model.body_dofadr,
                                                            model.body_dofnum, model.dof_jntid))
    for g, (pos, rbound, body) in enumerate(zip(model.geom_pos, model.geom_rbound.tolist(),
                                                model.geom_bodyid.tolist(), strict=True)):
        length = float(norm(pos) + rbound)
        row = lever[g]
        while body > 0:
            for dof in range(dofadr[body], dofadr[body] + dofnum[body]):
                jnt = dof_jnt[dof]
                row[dof] = length + joint_len[jnt] if hinge[jnt] else 1.0 if slide[jnt] else np.inf
            length += body_len[body]
            body = parent[body]
    return lever
