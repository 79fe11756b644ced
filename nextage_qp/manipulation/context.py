"""What a phase sees each control tick: live body poses, commanded and measured frame poses, setpoints."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from nextage_qp.errors import UnknownNameError
from nextage_qp.ik import QPIK, FrameTarget
from nextage_qp.manipulation.config import TargetSpec, Waypoint
from nextage_qp.robot import Robot
from nextage_qp.sim import Simulation


def rot_z(yaw: float) -> np.ndarray:
    """Rotation matrix of ``yaw`` [rad] about the world z axis."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def yaw_of(rot: np.ndarray) -> float:
    """Heading [rad] of a rotation: the angle of its x axis projected on the world x-y plane."""
    return float(np.arctan2(rot[1, 0], rot[0, 0]))


@dataclass
class Setpoint:
    """A Cartesian point that walks towards a goal at a bounded speed, one control tick at a time."""

    pos: np.ndarray

    def advance(self, goal: np.ndarray, speed: float, dt: float) -> bool:
        """Move at most ``speed * dt`` [m] towards ``goal``; True once on the goal."""
        delta = goal - self.pos
        dist = float(np.linalg.norm(delta))
        step = speed * dt
        if dist <= step:
            self.pos = goal.copy()
            return True
        self.pos = self.pos + delta * (step / dist)
        return False


@dataclass
class RunContext:
    """Shared state of a run: the simulation, the IK and the IK's own joint state ``q_cmd``.

    Attributes:
        q_cmd: Joint vector the IK integrates [rad]; Ruckig follows it, the PD tracks Ruckig.
        extra_tasks: mink tasks that stay active across phases (e.g. the clamp's relative-pose task).
        holding: Object currently clamped (for drop detection), or None.
        grasp_offsets: Pad frame -> its clamp point in the held object's frame [m].
        grasp_rot: Pad frame -> its rotation in the held object's frame.
    """

    robot: Robot
    sim: Simulation
    ik: QPIK
    q_cmd: np.ndarray
    extra_tasks: list = field(default_factory=list)
    holding: str | None = None
    grasp_offsets: dict[str, np.ndarray] = field(default_factory=dict)
    grasp_rot: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def dt(self) -> float:
        """Control period [s]."""
        return self.sim.ctrl_dt

    def body_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Live world position [m] and rotation of a body in the simulation."""
        bid = mujoco.mj_name2id(self.robot.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if bid < 0:
            raise UnknownNameError("body", name, self.robot.body_names)
        d = self.sim.data
        return d.xpos[bid].copy(), d.xmat[bid].reshape(3, 3).copy()

    def frame_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Measured world pose of a site or body in the simulation."""
        kind, fid = self.robot.frame(name)
        d = self.sim.data
        if kind == "site":
            return d.site_xpos[fid].copy(), d.site_xmat[fid].reshape(3, 3).copy()
        return d.xpos[fid].copy(), d.xmat[fid].reshape(3, 3).copy()

    def commanded_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Pose of a frame at the IK's joint state ``q_cmd`` (where the robot is being sent)."""
        pos, rot = self.ik.frame(name).pose(self.ik.configuration.data)
        return pos.copy(), rot.copy()

    def reference(self, relative_to: str) -> tuple[np.ndarray, float]:
        """Position [m] and yaw [rad] of a reference body, or the world origin."""
        if relative_to == "world":
            return np.zeros(3), 0.0
        pos, rot = self.body_pose(relative_to)
        return pos, yaw_of(rot)

    def resolve_point(self, spec: TargetSpec | Waypoint) -> tuple[np.ndarray, float]:
        """World position [m] and yaw [rad] of a body-relative point spec, from the live reference pose."""
        ref_pos, ref_yaw = self.reference(spec.relative_to)
        rot = rot_z(ref_yaw) if spec.axes == "yaw" else np.eye(3)
        pos = ref_pos + rot @ np.asarray(spec.offset)
        base = float(np.arctan2(pos[1], pos[0])) if getattr(spec, "heading", "reference") == "radial" else ref_yaw
        return pos, base + (spec.yaw if spec.yaw is not None else 0.0)

    def frame_target(self, spec: TargetSpec, pos: np.ndarray) -> FrameTarget:
        """An IK target at ``pos`` with the orientation the spec asks for."""
        if spec.yaw is not None:
            _, ref_yaw = self.reference(spec.relative_to)
            return FrameTarget(spec.frame, pos=pos, rot=rot_z(ref_yaw + spec.yaw))
        if spec.quat is not None:
            mat = np.empty(9)
            mujoco.mju_quat2Mat(mat, np.asarray(spec.quat, dtype=float))
            return FrameTarget(spec.frame, pos=pos, rot=mat.reshape(3, 3))
        if spec.axis is not None and spec.direction is not None:
            return FrameTarget(spec.frame, pos=pos, axis=np.asarray(spec.axis), direction=np.asarray(spec.direction))
        return FrameTarget(spec.frame, pos=pos)
