"""Object poses from one depth frame.

The table is found by RANSAC, the points the robot's model does not explain are clustered, and each object's known
shape is fitted to its points (Gauss-Newton on the shape's signed distance, over x, y, z and yaw; an object the robot
holds also over roll and pitch, as it may turn in the grip).

The estimator sees what a real robot would: the depth image, the camera's intrinsics and its pose from forward
kinematics of the measured joints, and the depth the robot's own model expects there (itself and the known static
scene, no free objects). It never reads simulator state: it gets arrays only, and does not import MuJoCo itself.

Each object gets a :class:`Detection`: a pose, or the reason there is none (``out_of_view``, ``occluded``: the
model predicts the robot covers too much of it, ``missing``: no points where it should be, ``bad_fit``: its points do
not fit its shape, or leave it free to slide, e.g. a hand in front of it). Those are dropouts for the filter, not
measurements.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import replace

import numpy as np
from scipy import ndimage

from nextage_qp.geometry import nearest_equivalent
from nextage_qp.sensing.camera.fit import fit, planar_std, residuals, table_plane
from nextage_qp.sensing.camera.frame import Detection, Frame
from nextage_qp.sensing.camera.pixels import backproject, plane_height
from nextage_qp.sensing.camera.shapes import ShapeModel
from nextage_qp.sensing.camera.visible import GAP, occlusion, seen, supported

ABOVE = 0.004
"""Points this far above the table plane or more belong to objects [m]."""
MIN_PIXELS = 30
"""Smallest cluster (and fewest points of a fit) [px]."""
MAX_RMS = 0.004
"""Largest RMS distance [m] of an object's points to its fitted shape (beyond: a bad fit)."""
MAX_STD = 0.0025
"""Largest standard deviation [m] of a fit's horizontal position (:func:`~nextage_qp.sensing.camera.fit.planar_std`)
that
counts as a measurement: a partial view that leaves the object free to slide along a face is a bad fit."""
MAX_OCCLUDED = 0.7
"""Largest share of an object's predicted surface the robot may cover before the view is a dropout."""
PARTLY = 0.3
"""Share of an object's predicted surface covered by the robot from which a frame counts as occluded."""
MIN_SUPPORT = 0.9
"""Smallest share of a fit's uncovered camera-facing surface that the frame shows there
(:func:`~nextage_qp.sensing.camera.visible.supported`) for a whole view: below, the fit is to part of the object
(a sliver beside a hand the model does not quite cover) and is a partial view; good fits show nearly all of it."""
FREE_OFFSET = 0.01
"""Table points seen are moved this far towards the camera to make the free-space points [m]."""
MAX_POINTS = 400
"""Points used per fit of a tracked object, from its predicted pose (a random subset of more)."""
SEED_POINTS = 1200
"""Points used per fit of an object not tracked yet, from each of its yaw seeds: with few, noise (stereo) can make a
wrong seed's local minimum fit a little better."""
SINK = 0.01
"""How far [m] a fitted shape may reach below the table plane (its points' noise); deeper, it is no object."""
REST = 0.02
"""How far [m] above the table plane the bottom of an object not tracked yet may be: objects are first seen resting
(a floating fit is noise, e.g. stereo on the robot's own plain links)."""
MAX_THROUGH = 0.6
"""Largest share of a fitted shape's camera-facing surface seen through (silhouette pixels, noise)."""
WHOLE = 0.95
"""Share of an object's fitted camera-facing surface inside the image from which an object not tracked yet is taken
(a view cut by the image's edge can fit well at a wrong yaw)."""
OFF_TABLE = 0.005
"""A tracked object not held whose predicted bottom is this far [m] from the table plane is also fitted from resting
on it (the better fit wins): an object predicted high after a partial view (its top face taken for the bottom face of
one standing on it) is found again where it rests, one standing on another object keeps its own start."""
INLIER = 0.005
"""A point this near a fitted surface [m] is explained by it (choosing among candidate clusters)."""
SELF_PAD = 4
"""Pixels by which the model's silhouette (where the robot, or a static obstacle, stands above the table) grows when the
robot's depth cannot be measured (stereo on its plain links): what falls in it is the model, never an object."""


class Estimator:
    """Poses of known shapes from depth frames (see the module docstring).

    Args:
        shapes: Object name -> its shape model.
        seed: Seed of RANSAC and of the point subsets.
        self_pad: 0, or ``SELF_PAD``: the model's silhouette grown by this many pixels is the model, whatever its depth.
    """

    def __init__(self, shapes: Mapping[str, ShapeModel], seed: int = 0, self_pad: int = 0) -> None:
        self.shapes, self.self_pad = dict(shapes), self_pad
        self.rng = np.random.default_rng(seed)
        self.plane: tuple[np.ndarray, float] | None = None
        self.clusters = np.zeros((0, 0), dtype=int)  # labels of the last frame (0: none), for dumps
        self.free = np.zeros((0, 3))  # free-space points of the last frame
        self.cover: np.ndarray | None = None  # the last frame's model grown by ``self_pad`` (its depth [m])

    def segment(self, f: Frame) -> list[np.ndarray]:
        """World points of each cluster the model does not explain (largest first); sets ``cover`` (None unpadded)."""
        self.cover = None
        finite = np.isfinite(f.depth)
        found = np.flatnonzero(finite)  # pixels with depth, row-major
        sub = self.rng.integers(0, len(found), min(len(found), 1500)) if len(found) else np.zeros(0, int)
        rows, cols = np.divmod(found[sub], f.depth.shape[1])
        if f.whole or self.plane is None:  # a window's largest level plane may be a hand's or an object's top
            points = backproject(f.depth, f.K, f.cam_pos, f.cam_rot, rows, cols)
            self.plane = table_plane(points, self.rng) or self.plane
        with np.errstate(invalid="ignore"):
            unexplained = finite & ~(f.expected - f.depth < GAP)
            if self.self_pad and self.plane is not None:  # the model's padded silhouette: the model
                body = plane_height(f.expected, f.K, f.cam_pos, f.cam_rot, *self.plane) > ABOVE
                grown = ndimage.minimum_filter(np.where(body, f.expected, np.inf), 2 * self.self_pad + 1,
                                               mode="constant", cval=np.inf)  # its nearest depth within the pad
                unexplained &= ~np.isfinite(grown)  # the silhouette dilated
                self.cover = np.fmin(f.expected, grown)  # the model grown: what covers an object, as above
        height = (plane_height(f.depth, f.K, f.cam_pos, f.cam_rot, *self.plane) if self.plane is not None
                  else np.full(f.depth.shape, np.nan))  # NaN without depth (or plane): neither on the table nor above
        with np.errstate(invalid="ignore"):
            table, above = np.abs(height) < ABOVE, height > ABOVE
        on = np.flatnonzero(table)
        if len(on) > 4000:
            on = on[self.rng.integers(0, len(on), 4000)]
        tr, tc = np.divmod(on, f.depth.shape[1])
        near = backproject(f.depth, f.K, f.cam_pos, f.cam_rot, tr, tc)
        towards = f.cam_pos - near
        self.free = near + FREE_OFFSET * towards / np.linalg.norm(towards, axis=1, keepdims=True)
        labels, n = ndimage.label(unexplained & above, structure=np.ones((3, 3)))
        self.clusters = labels
        sizes = np.bincount(labels.ravel(), minlength=n + 1)[1:].astype(float)  # as ndimage.sum_labels gives them
        boxes = ndimage.find_objects(labels)  # each cluster's bounding rows and columns
        out = []
        for k in np.argsort(-sizes):
            if sizes[k] < MIN_PIXELS:
                break
            rs, cs = boxes[k]
            r, c = np.nonzero(labels[rs, cs] == k + 1)  # within its box: the same pixels, in the same order
            out.append(backproject(f.depth, f.K, f.cam_pos, f.cam_rot, r + rs.start, c + cs.start))
        return out

    def _table_z(self, xy: np.ndarray) -> float:
        """Height [m] of the table plane under the point ``xy``."""
        assert self.plane is not None
        n, d = self.plane
        return float((d - n[:2] @ xy) / n[2])

    def estimate(self, f: Frame, priors: Mapping[str, np.ndarray | None],
                 held: Collection[str] = ()) -> dict[str, Detection]:
        """A :class:`Detection` per object of ``priors`` (name -> predicted pose vector, or None: not yet seen).

        Objects in ``held`` (the robot holds them: they may turn in its grip) are fitted over roll and pitch too;
        every other object is fitted upright (it rests on the table).

        A tracked object with no points at all near its prediction, or predicted out of view, is searched for among
        the clusters no other object explains, as an object not seen yet is (**re-acquisition**): a prediction that
        drifted away, e.g. coasting on a velocity that wrong measurements gave it, is found again where the object
        rests, at the equivalent yaw (modulo its symmetry) nearest the prediction. The filter gates such a jump, and
        restarts there when the next frame confirms it. An object with points near its prediction that do not fit
        (a partial view) is a dropout there, never a fit of another cluster.
        """
        clusters = self.segment(f)
        if self.cover is not None:  # an object's view is as covered as the grown model, which hides its points
            f = replace(f, cover=self.cover)
        cloud = np.concatenate(clusters) if clusters else np.zeros((0, 3))
        out: dict[str, Detection] = {}
        lost: list[str] = []
        for name in sorted(priors, key=lambda k: priors[k] is None):  # tracked objects first
            shape, prior = self.shapes[name], priors[name]
            if prior is not None:
                tilt = name in held
                share = occlusion(f, shape, prior, tilt)
                if share is None:
                    out[name] = Detection(None, "out_of_view")
                    lost.append(name)
                    continue
                if share > MAX_OCCLUDED:
                    out[name] = Detection(None, "occluded", occluded=share)
                    continue
                near = cloud[np.linalg.norm(cloud - prior[:3], axis=1) < shape.search_radius]
                out[name] = self._search(f, shape, [(near, [prior[5]], prior)], share, tilt)
                if out[name].status == "missing" and len(near) < MIN_PIXELS:
                    lost.append(name)
                continue
            out[name] = self._search(f, shape, self._seeded(shape, clusters), 0.0)
            if out[name].pose is not None:  # its cluster is taken (tracked objects came first)
                clusters = self._untaken(clusters, shape, out[name])
        if lost:  # after every other object has taken its points (objects not tracked yet took theirs above)
            for other, found in out.items():
                if found.pose is not None and priors[other] is not None:
                    clusters = self._untaken(clusters, self.shapes[other], found)
        for name in lost:
            shape, prior = self.shapes[name], priors[name]
            again = self._search(f, shape, self._seeded(shape, clusters), 0.0)
            if again.pose is not None:
                if prior is not None:  # the equivalent yaw nearest the prediction, as a tracked fit's
                    again.pose[5] = nearest_equivalent(again.pose[5], prior[5], shape.symmetry)
                out[name] = again
                clusters = self._untaken(clusters, shape, again)
        return out

    @staticmethod
    def _seeded(shape: ShapeModel, clusters: list[np.ndarray]) -> list[tuple[np.ndarray, list[float], None]]:
        """Candidates of an object not tracked (any longer): every cluster, from six yaw seeds."""
        seeds = list(np.arange(6) * (shape.symmetry or 2 * np.pi) / 6)
        return [(c, seeds, None) for c in clusters]

    @staticmethod
    def _untaken(clusters: list[np.ndarray], shape: ShapeModel, found: Detection) -> list[np.ndarray]:
        """The clusters the object ``found`` (a pose) does not explain."""
        assert found.pose is not None
        return [c for c in clusters if np.median(np.abs(residuals(shape, c, found.pose[[0, 1, 2, 5]]))) > 0.01]

    def _search(self, f: Frame, shape: ShapeModel,
                candidates: Sequence[tuple[np.ndarray, list[float], np.ndarray | None]], share: float,
                tilt: bool = False) -> Detection:
        """The best fit of ``shape`` among candidate (points, yaw seeds, prior) triples; ``missing`` when none fits.

        ``tilt``: fit roll and pitch too, from the prior's (a candidate with a prior only).
        """
        best: Detection = Detection(None, "missing", occluded=share)
        best_explained, best_fit = 0.0, (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(4))  # points, free, pose
        for pts, yaws, pr in candidates:
            if len(pts) < MIN_PIXELS:
                continue
            centre = pts.mean(axis=0)
            z0 = self._table_z(centre[:2]) - shape.bottom if self.plane is not None and pr is None else (
                pr[2] if pr is not None else centre[2])
            turned = (pr[3], pr[4]) if tilt and pr is not None else ()  # roll and pitch, when fitted
            starts = [np.array([*(pr[:2] if pr is not None else centre[:2]), z0, *turned, y]) for y in yaws]
            if pr is not None and not tilt and self.plane is not None:  # a prediction off the table: from on it too
                rest = self._table_z(pr[:2]) - shape.bottom
                if abs(z0 - rest) > OFF_TABLE:
                    starts += [np.r_[x0[:2], rest, x0[3:]] for x0 in starts]
            free = self.free[np.linalg.norm(self.free[:, :2] - starts[0][:2], axis=1) < shape.radius + 0.03]
            free = free[:200]
            support = len(pts)  # the cluster's points before subsampling
            limit = MAX_POINTS if pr is not None else SEED_POINTS
            if len(pts) > limit:
                pts = pts[self.rng.permutation(len(pts))[:limit]]
            x, rms = min((fit(shape, pts, x0, free) for x0 in starts), key=lambda fitted: fitted[1])
            above = x[2] + shape.bottom - self._table_z(x[:2]) if self.plane is not None else 0.0  # its bottom
            if above < -SINK or (pr is None and above > REST):
                continue  # no object is inside the table, and one not tracked yet rests on it
            through, in_view = seen(f, shape, x)
            if through > MAX_THROUGH:
                continue  # the camera sees beyond where the shape would be: it is not there
            if pr is None and in_view < WHOLE:
                continue  # an object is first taken from a view of all of it (cut by the image's edge: a guess)
            # Across clusters, the fit that explains the most points (a cluster's share within INLIER of the
            # surface, times its size), then the smaller RMS: a small patch of noise (stereo on a plain surface)
            # can fit one face of a shape closely.
            explained = support * float(np.mean(np.abs(residuals(shape, pts, x)) < INLIER))
            if best.pose is None or (rms <= MAX_RMS, explained, -rms) > (best.rms <= MAX_RMS, best_explained,
                                                                         -best.rms):
                yaw = x[-1] if pr is None else nearest_equivalent(x[-1], pr[5], shape.symmetry)
                pose = np.array([*x[:3], *(x[3:5] if len(x) == 6 else (0.0, 0.0)), yaw])
                best = Detection(pose, "ok", rms, len(pts), share)
                best_explained, best_fit = explained, (pts, free, pose if len(x) == 6 else pose[[0, 1, 2, 5]])
        if best.pose is not None and (best.rms > MAX_RMS or planar_std(
                shape, best_fit[0], best_fit[2], best.rms, best_fit[1]) > MAX_STD):
            best = Detection(None, "bad_fit", best.rms, best.points, share)
        if best.pose is not None:
            best.support = supported(f, shape, best.pose)
        return best
