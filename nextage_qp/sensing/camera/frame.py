"""What one depth frame gives the estimator (:class:`Frame`) and what it makes of each object (:class:`Detection`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Frame:
    """One depth frame: depth and expected depth [m] (H, W; NaN: no return), K (3x3), camera pose (world)."""

    depth: np.ndarray
    expected: np.ndarray
    K: np.ndarray
    cam_pos: np.ndarray
    cam_rot: np.ndarray  # columns: camera x (right), y (up), z (backwards), MuJoCo's convention
    cover: np.ndarray | None = None  # expected depth of the model as the estimator takes it (grown: SELF_PAD)
    whole: bool = True  # the whole image (False: a window around the tracked objects, NaN elsewhere)

    @property
    def model(self) -> np.ndarray:
        """Depth [m] of what the estimator takes for the model: ``cover``, else the expected depth."""
        return self.expected if self.cover is None else self.cover


@dataclass
class Detection:
    """An object's measurement (x, y, z, roll, pitch, yaw) or None, why, and the fit's numbers."""

    pose: np.ndarray | None
    status: str  # ok, out_of_view, occluded, missing, bad_fit
    rms: float = float("nan")
    points: int = 0
    occluded: float = 0.0
    support: float = 1.0  # share of its fitted surface in view and uncovered that the frame shows there (a fit's)
