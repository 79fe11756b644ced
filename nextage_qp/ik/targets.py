"""IK targets, the result record shared by every IK method, and how target errors are measured."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from nextage_qp.errors import ConfigError, IKError


class IKInfeasibleError(IKError):
    """The QP of one IK step has no solution; the message names the limits that were active."""


@dataclass(frozen=True)
class FrameTarget:
    """Where one frame (body or site) should go.

    Attributes:
        frame: Body or site name of the model, e.g. an arm's wrist frame.
        pos: Target position [m] in the world, or None for no position target.
        rot: Target rotation (3 x 3, columns = frame axes in the world), or None.
        axis: Tool axis in the frame's own coordinates that must point along ``direction`` (instead of ``rot``).
        direction: World direction the ``axis`` must point along.
        position_cost: Per-target position weight [1/m]; None uses the config's.
        orientation_cost: Per-target orientation weight [1/rad]; None uses the config's.
    """

    frame: str
    pos: np.ndarray | None = None
    rot: np.ndarray | None = None
    axis: np.ndarray | None = None
    direction: np.ndarray | None = None
    position_cost: float | None = None
    orientation_cost: float | None = None

    def __post_init__(self) -> None:
        where = f"target {self.frame!r}"
        if self.pos is not None:
            object.__setattr__(self, "pos", _vector(self.pos, f"{where}: pos"))
        if self.rot is not None:
            rot = np.asarray(self.rot, dtype=float)
            if rot.shape != (3, 3) or not _is_rotation(rot):
                raise ConfigError(f"{where}: rot must be a 3x3 rotation matrix, got {rot.tolist()}")
            object.__setattr__(self, "rot", rot)
        if (self.axis is None) != (self.direction is None):
            raise ConfigError(f"{where}: axis and direction must be given together")
        if self.axis is not None and self.direction is not None:
            if self.rot is not None:
                raise ConfigError(f"{where}: give either rot or axis+direction, not both")
            object.__setattr__(self, "axis", _unit(self.axis, f"{where}: axis"))
            object.__setattr__(self, "direction", _unit(self.direction, f"{where}: direction"))
        if self.pos is None and self.rot is None and self.axis is None:
            raise ConfigError(f"{where}: needs pos, rot or axis+direction")
        for name in ("position_cost", "orientation_cost"):
            cost = getattr(self, name)
            if cost is not None and not cost >= 0.0:
                raise ConfigError(f"{where}: {name} must be >= 0, got {cost}")

    @property
    def has_orientation(self) -> bool:
        """True when the target constrains orientation (full rotation or one axis)."""
        return self.rot is not None or self.axis is not None


_EYE = np.eye(3)


def _is_rotation(rot: np.ndarray) -> bool:
    """True for a finite 3x3 rotation matrix (orthonormal to 1e-6, determinant +1); cheap, called every tick."""
    ortho = np.abs(rot.T @ rot - _EYE).max()
    if not ortho <= 1e-6:  # also False for NaN
        return False
    a, b, c = rot[0].tolist(), rot[1].tolist(), rot[2].tolist()
    det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
    return det > 0


def _vector(value: np.ndarray, where: str) -> np.ndarray:
    vec = np.asarray(value, dtype=float).reshape(-1)
    if vec.shape != (3,) or not math.isfinite(vec[0] + vec[1] + vec[2]):  # NaN or inf anywhere
        raise ConfigError(f"{where} must be 3 finite numbers, got {np.asarray(value).tolist()}")
    return vec


def _unit(value: np.ndarray, where: str) -> np.ndarray:
    vec = _vector(value, where)
    norm = float(np.linalg.norm(vec))
    if norm < 1e-9:
        raise ConfigError(f"{where} must be non-zero")
    return vec / norm


@dataclass(frozen=True)
class RelativeTarget:
    """Where one frame should be in another frame's coordinates (e.g. one clamp pad relative to the other).

    Attributes:
        frame: The frame whose pose is constrained.
        root: The frame it is expressed in.
        pos: ``frame``'s origin in ``root`` coordinates [m].
        rot: ``frame``'s rotation in ``root`` coordinates (3 x 3).
        cost: Weight of the position [1/m] and orientation [1/rad] errors.
    """

    frame: str
    root: str
    pos: np.ndarray
    rot: np.ndarray
    cost: float = 1.0

    @classmethod
    def between(
        cls, frame: str, root: str, poses: Mapping[str, tuple[np.ndarray, np.ndarray]], cost: float
    ) -> RelativeTarget:
        """The relative pose of ``frame`` in ``root`` given both frames' world poses."""
        (p, r), (p0, r0) = poses[frame], poses[root]
        return cls(frame, root, r0.T @ (p - p0), r0.T @ r, cost)


class IKResult(NamedTuple):
    """Outcome of one IK solve (every method returns this record).

    Attributes:
        q: Best joint vector found [rad], the robot's joints in
            :attr:`~nextage_qp.robots.model.Robot.joint_names` order.
        converged: True when every target is within the position and orientation tolerances.
        pos_err_m: Largest position error over the targets at ``q`` [m].
        rot_err_rad: Largest orientation error over the targets at ``q`` [rad].
        iters: Iterations (IK steps) used.
        status: ``converged``, ``max_iters`` or ``stalled``.
        time_s: Wall time of the solve [s].
    """

    q: np.ndarray
    converged: bool
    pos_err_m: float
    rot_err_rad: float
    iters: int
    status: str
    time_s: float


def target_errors(target: FrameTarget, pos: np.ndarray, rot: np.ndarray) -> tuple[float, float]:
    r"""Position error [m] and orientation error [rad] of a frame at pose (pos, rot) against a target.

    The orientation error is the angle of :math:`R_t^T R` for a full rotation target, and the angle
    :math:`\arccos(\hat d \cdot R a)` between the tool axis and the direction for an axis target.
    """
    pos_err = 0.0 if target.pos is None else math.dist(pos, target.pos)
    if target.rot is not None:
        cos = (float(np.vecdot(target.rot.reshape(9), rot.reshape(9))) - 1.0) / 2.0  # trace(R_t^T R)
    elif target.axis is not None and target.direction is not None:
        cos = float(target.direction @ (rot @ target.axis))
    else:
        return pos_err, 0.0
    return pos_err, math.acos(min(1.0, max(-1.0, cos)))


def worst_errors(targets: Sequence[FrameTarget], poses: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[float, float]:
    """Largest position [m] and orientation [rad] errors over several targets and their current poses."""
    errs = [target_errors(t, p, r) for t, (p, r) in zip(targets, poses, strict=True)]
    return max(e[0] for e in errs), max(e[1] for e in errs)
