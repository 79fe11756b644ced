"""Per-joint settings: one value for every joint, a list in joint order, or a mapping of joint names."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, UnknownJointError

PerJoint = float | tuple[float, ...] | dict[str, float]
"""A per-joint setting: one value for every joint, a list in joint order, or ``{joint: value}``."""


def within_range(q: np.ndarray, lower: np.ndarray, upper: np.ndarray, names: Sequence[str], where: str) -> np.ndarray:
    """``q`` itself when every joint is finite and within ``[lower, upper]`` (to 1e-6 rad).

    Raises:
        ConfigError: One line naming the first joint outside its range (or not finite), its value and the range.
    """
    bad = np.flatnonzero(~((q >= lower - 1e-6) & (q <= upper + 1e-6)))  # NaN fails both
    if bad.size:
        i = int(bad[0])
        raise ConfigError(f"{where}: joint {names[i]} at {q[i]:.4g} rad is outside its range [{lower[i]:.4g}, "
                          f"{upper[i]:.4g}] (a robot file's angles are in radians unless it says angle: degree)")
    return q


def per_joint(value: PerJoint, default: float, names: Sequence[str], where: str = "") -> np.ndarray:
    """The per-joint array of a setting; joints a mapping leaves out get ``default`` (one meaning everywhere).

    Raises:
        ConfigError: A list of the wrong length or a mapping with an unknown joint.
    """
    if isinstance(value, dict):
        out = np.full(len(names), float(default))
        for joint, v in value.items():
            if joint not in names:
                raise UnknownJointError(joint, names)
            out[list(names).index(joint)] = v
        return out
    arr = np.broadcast_to(np.asarray(value, dtype=float), (len(names),)) if np.ndim(value) == 0 else np.asarray(value)
    if arr.shape != (len(names),):
        raise ConfigError(f"{where + ': ' if where else ''}a per-joint list needs {len(names)} values (one per joint: "
                          f"{', '.join(names[:3])}, ...), got {len(arr)}")
    return np.array(arr, dtype=float)


def descends(m: mujoco.MjModel, body: int, root: int) -> bool:
    """Whether ``body`` is ``root`` or lies in its subtree (every body descends from the world, 0)."""
    while body > 0:
        if body == root:
            return True
        body = int(m.body_parentid[body])
    return root == 0
