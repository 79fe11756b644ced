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


def unit2(v: np.ndarray) -> np.ndarray:
    """Planar vector ``v`` normalised (``[1, 0]`` for a zero vector)."""
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else np.array([1.0, 0.0])


def rotate2(d: np.ndarray, angle: float) -> np.ndarray:
    """Planar vector ``d`` rotated by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])


def turn2(d: np.ndarray, goal: np.ndarray, max_angle: float) -> np.ndarray:
    """Planar unit vector ``d`` turned towards ``goal`` by at most ``max_angle`` [rad]."""
    angle = float(np.arctan2(d[0] * goal[1] - d[1] * goal[0], d @ goal))
    return rotate2(d, float(np.clip(angle, -max_angle, max_angle)))
