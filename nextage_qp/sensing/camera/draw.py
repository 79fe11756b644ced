"""Fitted poses drawn over a camera image: each object's shape samples at its estimate, projected."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from nextage_qp.geometry import rot_z
from nextage_qp.sensing.camera.estimate import Frame
from nextage_qp.sensing.camera.pixels import project
from nextage_qp.sensing.camera.shapes import ShapeModel

COLOURS = ((255, 60, 60), (60, 200, 255), (255, 220, 40), (180, 90, 255))


def draw_poses(rgb: np.ndarray, frame: Frame, shapes: Mapping[str, ShapeModel],
               poses: Mapping[str, np.ndarray | None]) -> np.ndarray:
    """A copy of ``rgb`` with each object's surface samples at its pose (x, y, z, roll, pitch, yaw) as dots."""
    out = rgb.copy()
    h, w = out.shape[:2]
    for k, (name, pose) in enumerate(sorted(poses.items())):
        if pose is None:
            continue
        pts = shapes[name].samples[::4] @ rot_z(pose[5]).T + pose[:3]
        rows, cols, z = project(pts, frame.K, frame.cam_pos, frame.cam_rot)
        ok = (z > 0) & (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        out[rows[ok], cols[ok]] = COLOURS[k % len(COLOURS)]
    return out
