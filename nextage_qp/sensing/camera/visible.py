"""What a depth frame shows of a shape at a pose: the share it sees through, the share the robot covers.

Arrays only, as :mod:`nextage_qp.sensing.camera.estimate`, which uses these to accept or reject a fit and to call a view
occluded from the robot's model alone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from nextage_qp.geometry import rot_z
from nextage_qp.sensing.camera.fit import pose_rot
from nextage_qp.sensing.camera.pixels import project
from nextage_qp.sensing.camera.shapes import ShapeModel

if TYPE_CHECKING:
    from nextage_qp.sensing.camera.frame import Frame

GAP = 0.01
"""A pixel nearer than the model expects by this much [m] shows something the model does not know (an object)."""
AGREE = 0.01
"""A pixel whose depth is within this of a fitted surface [m] shows that surface (:func:`supported`)."""
_AROUND = np.mgrid[-1:2, -1:2].reshape(2, 1, 9)
"""Row and column offsets of a pixel's 3 x 3 neighbourhood."""
THROUGH = 0.03
"""Depth [m] beyond a fitted surface at which the camera sees through where the shape would be."""


def facing(f: Frame, shape: ShapeModel, pos: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, ...]:
    """Pixel rows, cols, depth of the shape's camera-facing samples at ``pos``, ``rot``, which are in view, and cosines.

    The cosine of a sample's normal to the line of sight is the area it shows the camera per unit of surface.
    """
    cam = (f.cam_pos - pos) @ rot  # the camera in the shape's frame
    lean = shape.lean - shape.normals @ cam  # each normal along the line of sight to its sample
    front = lean < 0  # faces the camera
    local = shape.samples[front]
    rows, cols, z = project(local @ rot.T + pos, f.K, f.cam_pos, f.cam_rot)
    h, w = f.depth.shape
    cos = -lean[front] / np.linalg.norm(local - cam, axis=1)
    return rows, cols, z, (z > 0) & (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w), cos


def seen(f: Frame, shape: ShapeModel, x: np.ndarray) -> tuple[float, float]:
    """Shares of the shape's camera-facing surface at a fit's pose ``x``: seen through, and inside the image.

    Seen through: the frame has depth behind it. A shape where the image shows something farther away (by more than
    ``THROUGH`` [m]) cannot be there; nearer (the robot in front) or no depth say nothing (1 with none in view).
    """
    rows, cols, z, inside, _ = facing(f, shape, x[:3], pose_rot(x))
    if not inside.any():
        return 1.0, 0.0
    with np.errstate(invalid="ignore"):
        beyond = f.depth[rows[inside], cols[inside]] > z[inside] + THROUGH
    return float(beyond.mean()), float(inside.mean())


def occlusion(f: Frame, shape: ShapeModel, prior: np.ndarray, tilt: bool = False) -> float | None:
    """Share of the shape's surface facing the camera at ``prior`` that the robot covers (None: out of view).

    From the model alone: the expected depth (robot and static scene; :attr:`Frame.model`, as grown where the
    estimator grows it) in front of the shape's samples. ``tilt``: at the prior's roll and pitch too (else upright).
    """
    rows, cols, z, inside, _ = facing(f, shape, prior[:3], pose_rot(prior) if tilt else rot_z(prior[5]))
    if inside.mean() < 0.5:
        return None
    with np.errstate(invalid="ignore"):
        covered = f.model[rows[inside], cols[inside]] < z[inside] - GAP
    return float(covered.mean())


def supported(f: Frame, shape: ShapeModel, x: np.ndarray) -> float:
    """Share of the shape's camera-facing surface at a fit's pose ``x`` that the frame shows where the fit puts it.

    Over the samples inside the image that the robot's model does not cover and that nothing hides (the pixel's
    depth is not nearer than the surface: the object's own parts, a hand), each weighed by the area it shows the
    camera (the cosine of its normal to the line of sight): those whose pixel's depth is within ``AGREE`` of the
    fitted surface at the sample's pixel or one of its eight neighbours (a sample on the silhouette may fall a pixel
    off it), against those where the camera sees beyond it. A fit to the whole visible object shows nearly
    all of it; a fit to a sliver beside a hand the model does not quite cover places the rest of its surface where
    the camera sees the table behind (0 with no such sample).
    """
    rows, cols, z, inside, cos = facing(f, shape, x[:3], pose_rot(x))
    rows, cols, z, cos = rows[inside], cols[inside], z[inside], cos[inside]
    h, w = f.depth.shape
    depth = f.depth[rows, cols]
    near = f.depth[np.clip(rows[:, None] + _AROUND[0], 0, h - 1), np.clip(cols[:, None] + _AROUND[1], 0, w - 1)]
    with np.errstate(invalid="ignore"):
        agree = (np.abs(near - z[:, None]) < AGREE).any(axis=1)  # a pixel off at the silhouette: its neighbours
        weigh = np.where((agree | (depth > z)) & ~(f.model[rows, cols] < z - GAP), cos, 0.0)
    total = weigh.sum()
    return float(weigh[agree].sum() / total) if total > 0 else 0.0
