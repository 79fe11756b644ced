"""Depth from the robot's two RGB cameras by semi-global block matching (OpenCV's ``StereoSGBM``).

The pair must be rectified as mounted: both cameras with the same image size and field of view, looking the same
way, the right one offset along the left one's image x axis (the Nextage's head cameras are). Depth is the distance
along the left camera's optical axis, ``z = f B / d`` for disparity ``d`` [px], focal length ``f`` [px] and baseline
``B`` [m]; pixels without a unique match (occluded in the right view, or too plain to match) have none (NaN).

Block matching needs texture: MuJoCo's surfaces are uniformly coloured, so a stereo config's world gets a random-dot
texture on every surface that is not the robot's (:func:`nextage_qp.scene.texture.speckle`), the pattern an active
stereo sensor's projector (or textured real objects) would give it.
"""

from __future__ import annotations

import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.robots.cameras import CameraFile
from nextage_qp.sensing.camera.pixels import project

EXTRA = "install the vision extra (pip install 'nextage-qp[vision]': opencv-python-headless)"
"""What a stereo config needs that the base install lacks."""
NEAREST = 0.3
"""Nearest depth matched [m]: sets the disparity search range."""
BLOCK = 5
"""Matching block size [px] (odd)."""
MARGIN = 0.05
"""Margin [m] around a tracked object's bounding box (in its own frame, at its predicted pose) that its window shows."""
PAD = 16
"""Pixels around a window (the matcher's aggregation paths start at its edges) [px]."""
WHOLE_EVERY = 15
"""Every this many frames the whole image is matched (also while an object is untracked, or was lost last frame)."""
WHOLE_SHARE = 0.6
"""A window covering this share of the image or more is matched whole."""
PARALLEL = 1e-3
"""Largest misalignment of the two cameras' axes [rad] and of the baseline off the left image's x axis (share)."""


def _cv2():
    try:
        import cv2
    except ImportError:
        raise ConfigError(f"perception.depth: stereo needs OpenCV; {EXTRA}") from None
    return cv2


def check_pair(left: CameraFile, right: CameraFile, rot_left: np.ndarray, rot_right: np.ndarray,
               baseline: np.ndarray, names: tuple[str, str]) -> float:
    """The baseline [m] of a rectified pair; ``baseline``: right camera's position minus the left's (world).

    ``rot_*``: the cameras' world rotations (columns x right, y up, z backwards).

    Raises:
        ConfigError: The cameras differ in size or field of view, look different ways, or the right camera is not
            to the right of the left one along its image x axis.
    """
    where = f"perception.stereo [{names[0]}, {names[1]}]"
    if (left.width, left.height, left.fovx) != (right.width, right.height, right.fovx):
        raise ConfigError(f"{where}: the two cameras need the same width, height and fovx, got {left.width}x"
                          f"{left.height} {left.fovx} deg and {right.width}x{right.height} {right.fovx} deg")
    turn = float(np.arccos(np.clip((np.trace(rot_left.T @ rot_right) - 1.0) / 2.0, -1.0, 1.0)))
    local = rot_left.T @ baseline
    b = float(np.linalg.norm(local))
    if turn > PARALLEL or b == 0.0 or local[0] <= 0 or np.hypot(local[1], local[2]) > PARALLEL * b:
        raise ConfigError(f"{where}: the pair must be rectified as mounted (parallel axes, the right camera along "
                          f"the left one's image x axis); got axes {np.degrees(turn):.2f} deg apart and the right "
                          f"camera at {np.round(local, 4).tolist()} m in the left one's frame (x right, y up); name "
                          f"the cameras left first, or mount them parallel")
    return b


class StereoMatcher:
    """Depth images [m] from rectified left/right RGB images (see the module docstring).

    Args:
        K: The left camera's 3x3 intrinsics [px].
        baseline: Distance between the cameras [m].

    Raises:
        ConfigError: OpenCV is not installed.
    """

    def __init__(self, K: np.ndarray, baseline: float) -> None:
        cv2 = _cv2()
        self.cv2, self.f, self.baseline = cv2, float(K[0, 0]), float(baseline)
        span = 16 * int(np.ceil(self.f * self.baseline / NEAREST / 16))  # disparities searched: a multiple of 16
        self.sgbm = cv2.StereoSGBM_create(
            minDisparity=0, numDisparities=span, blockSize=BLOCK, P1=8 * BLOCK * BLOCK, P2=32 * BLOCK * BLOCK,
            uniquenessRatio=15, speckleWindowSize=100, speckleRange=2, disp12MaxDiff=1,
            mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)

    def cut(self, win: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
        """Rows and columns of both images that matching the window ``win`` needs.

        ``win``: rows ``r0:r1`` and columns ``c0:c1`` of the left image (:func:`window`). The cut has its rows, and the
        columns from ``c0`` less the disparity range, so that every pixel of the window is searched over the whole
        range, as in the whole image.
        """
        r0, r1, c0, c1 = win
        return r0, r1, max(0, c0 - self.sgbm.getNumDisparities()), c1

    def depth(self, left: np.ndarray, right: np.ndarray, win: tuple[int, int, int, int] | None = None,
              size: tuple[int, int] | None = None) -> np.ndarray:
        """Depth [m] along the left camera's axis (H, W) float32, NaN where no disparity was found.

        With ``win``: ``left`` and ``right`` are the images' :meth:`cut` for it, ``size`` the whole image's (H, W);
        the depth is that of the window's pixels, NaN elsewhere.
        """
        cv2 = self.cv2
        gray = [cv2.cvtColor(np.ascontiguousarray(im), cv2.COLOR_RGB2GRAY) for im in (left, right)]
        disparity = self.sgbm.compute(*gray).astype(np.float32) / 16.0  # OpenCV's fixed point: 4 fractional bits
        if win is None or size is None:  # the whole image
            win, size = (0, left.shape[0], 0, left.shape[1]), left.shape[:2]
        r0, r1, c0, c1 = win
        start = self.cut(win)[2]
        depth = np.full(size, np.nan, dtype=np.float32)
        with np.errstate(divide="ignore"):
            d = disparity[:, c0 - start:]
            depth[r0:r1, c0:c1] = np.where(d > 0.5, self.f * self.baseline / d, np.nan)
        return depth


def window(corners: np.ndarray, K: np.ndarray, pos: np.ndarray, rot: np.ndarray,
           size: tuple[int, int], pad: int = PAD) -> tuple[int, int, int, int] | None:
    """Rows ``r0:r1`` and columns ``c0:c1`` of an image of ``size`` (H, W) that show every world point of ``corners``.

    ``K``, ``pos``, ``rot``: the camera's intrinsics and pose. The points' bounds are padded by ``pad`` pixels and
    clipped to the image. None (the whole image): no points, a point (nearly) behind the camera, or a window of
    :data:`WHOLE_SHARE` of the image or more.
    """
    if len(corners) == 0:
        return None
    rows, cols, z = project(np.asarray(corners, dtype=float).reshape(-1, 3), K, pos, rot)
    if np.any(z <= 0.05):
        return None
    h, w = size
    r0, r1 = max(0, int(rows.min()) - pad), min(h, int(rows.max()) + pad + 1)
    c0, c1 = max(0, int(cols.min()) - pad), min(w, int(cols.max()) + pad + 1)
    if r1 <= r0 or c1 <= c0 or (r1 - r0) * (c1 - c0) >= WHOLE_SHARE * h * w:
        return None
    return r0, r1, c0, c1
