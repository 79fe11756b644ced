"""Poses and planar rotations shared by every layer."""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np


class Pose(NamedTuple):
    """A frame or body pose in the world: position [m] and rotation matrix (columns = the frame's axes)."""

    pos: np.ndarray
    rot: np.ndarray

    @property
    def quat(self) -> np.ndarray:
        """Unit quaternion (w, x, y, z) of the rotation."""
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, np.asarray(self.rot, dtype=float).reshape(-1))
        return quat


def rot_z(yaw: float) -> np.ndarray:
    """Rotation matrix of ``yaw`` [rad] about the world z axis."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def yaw_of(rot: np.ndarray) -> float:
    """Heading [rad] of a rotation: the angle of its x axis projected on the world x-y plane."""
    return float(np.arctan2(rot[1, 0], rot[0, 0]))


def wrap(angle: float, period: float = 2.0 * np.pi) -> float:
    """``angle`` wrapped into ``[-period/2, period/2)`` [rad]."""
    return float((angle + 0.5 * period) % period - 0.5 * period)
