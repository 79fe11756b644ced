"""``perception.source: camera``: object measurements from the robot camera's depth frames.

The depth is the camera's own (``perception.depth: rendered``, an RGB-D sensor) or block matching on two RGB
cameras (``stereo``, :mod:`nextage_qp.sensing.camera.stereo`), in the left camera's view.

:class:`CameraMeasurer` renders a frame of the world (:class:`~nextage_qp.sensing.camera.render.RobotCamera`), computes
the camera's pose from the *measured* joints, and hands images, intrinsics and pose to the
:class:`~nextage_qp.sensing.camera.estimate.Estimator`; the poses it returns go through the same latency queue and
Kalman filter as the simulated camera's (:class:`~nextage_qp.sensing.faulty.FaultySensors`). It counts, per object,
frames seen, detections, predicted occlusions and the time per frame spent rendering and estimating. For the
detection rate it classes each frame by where the object truly is (given for that count alone, after the estimate):
*unoccluded* when at least half of its camera-facing surface is inside the image and the robot's model covers at
most ``PARTLY`` of it, whatever the estimator believed (an object still outside the view as the head turns to it is
no missed detection; one the estimator thinks hidden, but in plain view, is).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.geometry import Pose, pose_vector
from nextage_qp.sensing.camera.estimate import MIN_SUPPORT, PARTLY, SELF_PAD, Estimator, Frame
from nextage_qp.sensing.camera.fit import pose_rot
from nextage_qp.sensing.camera.frame import Detection
from nextage_qp.sensing.camera.hands import UNSEEN, HandCameras, clear, hand_camera_names
from nextage_qp.sensing.camera.render import RobotCamera, render_problem
from nextage_qp.sensing.camera.seen import ObstacleMapper
from nextage_qp.sensing.camera.shapes import ShapeModel
from nextage_qp.sensing.camera.stereo import MARGIN, PAD, WHOLE_EVERY, StereoMatcher, check_pair, window
from nextage_qp.sensing.camera.visible import occlusion
from nextage_qp.sensing.perception_config import PerceptionConfig

FIT_NOISE = {"rendered": 0.001, "stereo": 0.002}
"""Default ``perception.noise_pos_m`` per depth source [m]: the position noise the filter assumes of a clear view's fit.
A rendered depth frame's fit of a resting or pushed object scatters about 0.8 mm RMS in 3-D (docs/perception.md); an
assumed noise well above that makes the filter average a pushed object's slow sideways drift into a lag."""
COVER_SPREAD = {"rendered": 0.0, "stereo": 8.0}
"""Default ``perception.cover_spread`` per depth source: the filter's assumed noise grows by 1 + spread x the share
of the object a fit does not see. Stereo fits degrade fast as the hand covers an object (block matching smears the
hand's depth into the object's); rendered depth degrades slowly, which the partial views' gate absorbs
(docs/perception.md)."""

EDGE = 4
"""Pixels around a rendered window beyond its objects' boxes (the estimator's neighbourhoods at its border)."""
REST = 0.01
"""An object's predicted bottom within this of the table plane [m] rests on it (``perception.rest_every``)."""
STILL = 0.005
"""An object whose last two fits lie at most this far apart [m] is still (``perception.rest_every``)."""
NEAR = 0.05
"""No geom of the robot (its bounding sphere) within this of an object [m] leaves it untouched until the next frame
(``perception.rest_every``)."""
ALOFT = 0.03
"""A held object's predicted bottom this high [m] over the table plane or more is in the air (``perception.held_every``
applies); lower, it may be meeting the table or what stands on it."""

STATUSES = ("ok", "out_of_view", "occluded", "missing", "bad_fit")
IN_VIEW = ("ok", "missing", "bad_fit")
"""The outcomes of a frame in which an object was in view and not hidden behind the robot (a detection is due)."""


class CameraMeasurer:
    """Measurements of every free object from one robot camera (see the module docstring).

    Args:
        cfg: The config's perception block.
        robot: The :class:`~nextage_qp.robots.model.Robot` (its description's cameras, its objects' shape models).
        data: The simulation's data: the world the camera renders (and nothing else reads).
        joints: The measured joint positions at a time [s].
        seed: The run's seed.
        source: Where the config came from (for messages).
        places: Rectangles of the table [m] the task puts objects in, which the obstacle map covers too
            (:class:`~nextage_qp.sensing.camera.seen.ObstacleMapper`).
    """

    def __init__(self, cfg: PerceptionConfig, robot: Any, data: mujoco.MjData, joints: Callable[[float], np.ndarray],
                 seed: int, source: str = "<config>",
                 places: Sequence[tuple[tuple[float, float], tuple[float, float]]] = ()) -> None:
        cams = dict(robot.description.cameras) if robot.description is not None else {}
        stereo = cfg.depth == "stereo"
        for key, name in ((("stereo", n) for n in cfg.stereo) if stereo else [("camera", cfg.camera)]):
            if name not in cams:
                raise ConfigError(f"{source}: perception.{key}: {name!r} is not a camera of robot {robot.name!r}; "
                                  f"valid: {', '.join(sorted(cams)) or '(the robot file has none)'}")
        problem = render_problem()
        if problem is not None:
            raise ConfigError(f"{source}: perception.source: camera: {problem}")
        name = cfg.stereo[0] if stereo else cfg.camera  # the camera whose view the depth is in
        self.cfg, self.spec, self.data, self.joints = cfg, cams[name], data, joints
        model = robot.model
        self.camera = RobotCamera(model, name, self.spec, robot, seed)
        self.right: RobotCamera | None = None
        self.matcher: StereoMatcher | None = None
        if stereo:
            self.right, self.matcher = stereo_pair(model, robot, cams, cfg.stereo, self.camera, seed, source)
        self.symmetry = {n: robot.yaw_symmetry(n) for n in robot.object_names}
        shapes = {n: ShapeModel.of_body(model, n, self.symmetry[n]) for n in robot.object_names}
        self.estimator = Estimator(shapes, seed, SELF_PAD if stereo else 0)  # stereo cannot measure the plain links
        radii = {n: s.reach for n, s in shapes.items()}  # each shape's farthest point from its origin [m]
        self.windowed = 0  # frames rendered (or matched) in a window around the tracked objects
        mapped = cfg.map or cfg.obstacles == "camera"  # the map takes whole frames
        self.windows = cfg.window if cfg.window is not None else not mapped  # perception.window's default
        self.lost = True  # an object was out of view or missing in the last frame
        kinds = (*STATUSES, "partly_occluded", "part_fitted", "unoccluded", "unoccluded_ok")
        self.counts = {n: dict.fromkeys(kinds, 0) for n in robot.object_names}
        self.ms: dict[str, list[float]] = {"render": [], "estimate": []}
        self.dumped = cfg.dump is None
        self.dump_error: str | None = None
        self.last: tuple[float, np.ndarray] | None = None
        self.poses: dict[str, np.ndarray | None] = {}
        """Each object's pose vector fitted in the latest frame (None: not seen in it); for videos."""
        self.views: dict[str, list[tuple[float, bool]]] = {n: [] for n in robot.object_names}
        """Per object, each frame's time [s] and whether it was unoccluded in it (as counted: see the module doc)."""
        self.partial: set[str] = set()
        """The objects of the latest frame fitted from a partial view (the robot's model covers more than ``PARTLY``
        of them, or the frame shows less than ``MIN_SUPPORT`` of the fitted surface where the fit puts it): the filter
        lets such a view confirm an object's pose, not move it (``PoseKalman.update``)."""
        self.spread: dict[str, float] = {}
        """The latest frame's fits' noise relative to a clear view's (``perception.cover_spread``)."""
        self.cover_spread = COVER_SPREAD[cfg.depth] if cfg.cover_spread is None else cfg.cover_spread
        self.noise_pos = FIT_NOISE[cfg.depth] if cfg.noise_pos_m is None else cfg.noise_pos_m
        """The position noise [m] the filter assumes of a clear view's fit (``perception.noise_pos_m``)."""
        self.mapper = ObstacleMapper(robot, radii, places) if mapped else None
        names = hand_camera_names(robot, cfg.hand_cameras, source) if cfg.hand_cameras is not None or not stereo else ()
        self.hands = HandCameras(names, robot, shapes, seed) if names else None
        self.periods = 0  # frame periods
        self.by_hand = False  # the last period's every object came from a hand camera's clean view
        self.hand_only = 0  # periods whose objects the hand cameras alone saw (no head frame)
        self.skipped = False  # the last period took no frame (``held_every``, ``rest_every``): no dropout
        self.held_skipped = 0  # periods without a frame as every object was held
        self.rest_skipped = 0  # periods without a frame as every object was at rest away from the robot
        self.moved: dict[str, float | None] = {}  # per object, how far its last two fits lie apart [m]
        from nextage_qp.robots.model import robot_bodies

        self._robot_geoms = np.isin(model.geom_bodyid, list(robot_bodies(robot)))
        self.world = (model, data)  # for the map's score alone

    @property
    def rate_hz(self) -> float:
        """Frame rate [Hz]."""
        return self.spec.rate_hz

    @property
    def latency_s(self) -> float:
        """Age of a measurement when it reaches the filter [s]."""
        return self.spec.latency_s

    def __call__(self, t: float, priors: Mapping[str, np.ndarray | None], held: Collection[str] = (),
                 truth: Mapping[str, Pose] | None = None) -> dict[str, np.ndarray | None]:
        """Measured pose vectors (x, y, z, roll, pitch, yaw) at ``t`` [s], None where the object was not seen.

        ``held``: objects the robot holds (fitted with their roll and pitch, see :meth:`Estimator.estimate`).
        ``truth``: the objects' true poses, for the detection count alone (see the module doc); without them a frame is
        unoccluded where the estimator's prediction was in view and uncovered.
        """
        self.periods += 1
        self.skipped = self.periods % self.cfg.held_every != 0 and self._aloft(priors, held)
        if self.skipped:  # every object held aloft: its estimate follows the hands until the next frame
            self.held_skipped += 1
            return {}
        q = self.joints(t)
        self.skipped = self.periods % self.cfg.rest_every != 0 and self._untouched(q, priors, held)
        if self.skipped:  # every object at rest with the robot away from it: nothing moves it until the next frame
            self.rest_skipped += 1
            return {}
        hands: dict[str, Detection] | None = None  # the hand cameras' clean views, once asked
        if (self.hands is not None and self.by_hand and self.periods % WHOLE_EVERY and priors
                and all(p is not None for p in priors.values())):
            hands = self.hands.measure(self.data, q, priors, dict.fromkeys(priors, UNSEEN), held,
                                       self.estimator.plane)
            if len(hands) == len(priors):  # every object in a hand camera's clean view: no head frame this period
                self.hand_only += 1
                self.partial, self.spread = set(), dict.fromkeys(hands, 1.0)
                self.poses = {name: det.pose for name, det in hands.items()}
                self.lost = False
                return dict(self.poses)
        detections, frame, win = self._head(t, q, priors, held, truth)
        if self.hands is not None:  # a hand camera's clean view of what the head missed stands in for the head's
            if hands is None:
                hands = self.hands.measure(self.data, q, priors, detections, held, self.estimator.plane)
            hands = {name: det for name, det in hands.items() if not clear(detections[name])}
            for name, det in hands.items():
                detections[name] = det
                self.partial.discard(name)
                self.spread[name] = 1.0
        self.by_hand = hands is not None and 0 < len(hands) == len(priors)
        for name, det in detections.items():  # how far each fit moved since the last (None: not fitted in both)
            last = self.poses.get(name)
            self.moved[name] = (float(np.linalg.norm(det.pose[:3] - last[:3]))
                                if det.pose is not None and last is not None else None)
        self.poses = {name: det.pose for name, det in detections.items()}
        if self.mapper is not None and win is None and self.matcher is None:  # a whole frame: the map takes it
            self.mapper.update(frame, self.camera.own(), self.estimator.plane, self.poses, truth=self.world,
                               priors=priors)
        self.lost = any(det.status in ("out_of_view", "missing") for det in detections.values())
        return dict(self.poses)

    def _untouched(self, q: np.ndarray, priors: Mapping[str, np.ndarray | None], held: Collection[str]) -> bool:
        """Whether every object is tracked, resting on the table, still, and away from the robot at joints ``q``.

        Resting: its predicted bottom within ``REST`` of the table plane; still: its last two fits ``STILL`` apart at
        most; away: every geom of the robot's model at ``q`` (its bounding sphere) at least ``NEAR`` from the object's
        shape at its prior (``perception.rest_every``). Never with an obstacle map (its frames are the map's).
        """
        plane = self.estimator.plane
        if self.mapper is not None or self.lost or plane is None or not priors or held:
            return False
        normal, offset = plane
        for name, prior in priors.items():
            moved = self.moved.get(name)
            if prior is None or moved is None or moved > STILL:
                return False
            if abs(float(normal @ prior[:3]) - offset + self.estimator.shapes[name].bottom) > REST:
                return False
        self.camera.pose(q)  # the robot's geoms at q: only once every object rests still
        kin, mine = self.camera.kin, self._robot_geoms
        for name, prior in priors.items():
            assert prior is not None
            gap = (self.estimator.shapes[name].sdf_at(kin.geom_xpos[mine], prior[:3], pose_rot(prior))
                   - self.camera.model.geom_rbound[mine])
            if float(gap.min()) < NEAR:
                return False
        return True

    def _aloft(self, priors: Mapping[str, np.ndarray | None], held: Collection[str]) -> bool:
        """Whether every object is tracked, held, and predicted at least ``ALOFT`` over the table plane.

        Set down, or lowered onto the table, a held object meets the world and may turn in the grip: it gets every
        frame.
        """
        plane = self.estimator.plane
        if self.lost or plane is None or not priors or not set(priors) <= set(held):
            return False
        normal, offset = plane
        for name, prior in priors.items():
            if prior is None or float(normal @ prior[:3]) - offset + self.estimator.shapes[name].bottom < ALOFT:
                return False
        return True

    def _head(self, t: float, q: np.ndarray, priors: Mapping[str, np.ndarray | None], held: Collection[str],
              truth: Mapping[str, Pose] | None) -> tuple[dict[str, Detection], Frame, tuple[int, int, int, int] | None]:
        """The head camera's frame at ``t`` [s] (joints ``q``): its detections (counted), the frame and its window."""
        t0 = time.perf_counter()
        pos, rot = self.camera.pose(q)
        win = self.window(priors, pos, rot) if self.windows else None
        self.windowed += win is not None
        if self.matcher is not None and self.right is not None:
            cut = self.matcher.cut(win) if win is not None else None
            depth = self.matcher.depth(self.camera.rgb(self.data, cut), self.right.rgb(self.data, cut), win,
                                       (self.spec.height, self.spec.width))
        else:
            depth = self.camera.depth(self.data, win)
        expected = self.camera.expected(win if self.matcher is None else None)  # stereo's: whole, as measured
        t1 = time.perf_counter()
        # The table plane is found in whole frames (a window's largest level plane may be a hand's top); a stereo
        # window is as it was measured (docs/perception.md), found in every frame.
        frame = Frame(depth, expected, self.camera.K, pos, rot, whole=win is None or self.matcher is not None)
        self.last = (t, depth)  # the latest depth image [m] and its time [s] (for recordings)
        detections = self.estimator.estimate(frame, priors, held)
        self.ms["render"].append((t1 - t0) * 1e3)
        self.ms["estimate"].append((time.perf_counter() - t1) * 1e3)
        self.partial, self.spread = set(), {}
        for name, det in detections.items():
            counts = self.counts[name]
            counts[det.status] += 1
            fitted = det.status == "ok"
            covered, part = fitted and det.occluded > PARTLY, fitted and det.support < MIN_SUPPORT
            counts["partly_occluded"] += int(covered)
            counts["part_fitted"] += int(part)
            if covered or part:
                self.partial.add(name)
            if fitted:  # the share of the object the fit does not see: covered by the robot, or missing from the frame
                self.spread[name] = 1.0 + self.cover_spread * (1.0 - (1.0 - det.occluded) * det.support)
            if truth is not None and name in truth:  # after the estimate: the estimator never sees it
                share = occlusion(frame, self.estimator.shapes[name], pose_vector(truth[name]), tilt=True)
                sighted = share is not None and share <= PARTLY
            else:
                sighted = det.status in IN_VIEW and det.occluded <= PARTLY
            counts["unoccluded"] += int(sighted)
            self.views[name].append((t, sighted))
            counts["unoccluded_ok"] += int(sighted and det.status == "ok")
        if not self.dumped and t + 1e-9 >= self.cfg.dump_at_s:
            self.dumped = True
            try:
                self.dump(Path(str(self.cfg.dump)), frame, detections)
            except OSError as exc:  # a lost frame dump is not a failed run: reported with the camera's figures
                self.dump_error = f"perception.dump {self.cfg.dump}: cannot write: {exc.strerror or exc}"
        return detections, frame, win

    def window(self, priors: Mapping[str, np.ndarray | None], pos: np.ndarray,
               rot: np.ndarray) -> tuple[int, int, int, int] | None:
        """The window rendered (and matched): around each tracked object, the region the estimator searches.

        Each object's bounding box (in its own frame, at its prior) grown by ``MARGIN``, and ``EDGE`` pixels (``PAD``
        with stereo, whose matching paths start at the window's edges); the rest of the frame is no return.

        The whole image (None) every ``WHOLE_EVERY`` frames, while an object is not tracked, and after a frame that
        lost one (re-acquisition searches the whole view).
        """
        if self.lost or len(self.ms["render"]) % WHOLE_EVERY == 0 or any(p is None for p in priors.values()):
            return None
        corners = [self.estimator.shapes[n].box_corners(p[:3], pose_rot(p), MARGIN)
                   for n, p in priors.items() if p is not None]
        points = np.concatenate(corners) if corners else np.empty((0, 3))
        return window(points, self.camera.K, pos, rot, (self.spec.height, self.spec.width),
                      PAD if self.matcher is not None else EDGE)

    def dump(self, folder: Path, frame: Frame, detections: Mapping[str, Any]) -> None:
        """Write the frame's RGB, depth, clusters and fitted poses (drawn over the RGB) as PNGs into ``folder``."""
        import imageio.v3 as iio

        from nextage_qp.sensing.camera.draw import draw_poses

        folder.mkdir(parents=True, exist_ok=True)
        rgb = self.camera.rgb(self.data)
        z = np.nan_to_num(frame.depth, nan=0.0)
        iio.imwrite(folder / "rgb.png", rgb)
        iio.imwrite(folder / "depth.png", (255 * np.clip(z / max(float(z.max()), 1e-6), 0, 1)).astype(np.uint8))
        labels = self.estimator.clusters
        palette = np.random.default_rng(1).integers(60, 255, (int(labels.max()) + 1, 3)).astype(np.uint8)
        palette[0] = 0
        iio.imwrite(folder / "clusters.png", palette[labels])
        shapes = {n: self.estimator.shapes[n] for n in detections}
        iio.imwrite(folder / "fit.png", draw_poses(rgb, frame, shapes, {n: d.pose for n, d in detections.items()}))

    def report(self) -> dict[str, Any]:
        """Frames, per object its frames by outcome, its detection rate, and the median ms per frame.

        ``partly_occluded``: detected though the robot covered more than ``PARTLY`` of it; ``part_fitted``: detected
        by a fit the frame shows less than ``MIN_SUPPORT`` of (both partial views); ``unoccluded``: frames in
        which it was in view and the robot covered at most ``PARTLY`` of it (at its true pose, see the module doc;
        ``unoccluded_ok``: detected in them). ``detected_of_unoccluded`` is the detection rate over those;
        ``detected_of_in_view`` over every frame in which the estimator predicted it in view and covered at most
        ``MAX_OCCLUDED`` (partly occluded ones too).
        """
        objects = {}
        for name, c in self.counts.items():
            seen, clear = sum(c[s] for s in IN_VIEW), c["unoccluded"]
            objects[name] = {**c, "detected_of_in_view": c["ok"] / seen if seen else None,
                             "detected_of_unoccluded": c["unoccluded_ok"] / clear if clear else None}
        if not self.dumped and not self.dump_error:  # the run ended before the time of the frame asked for
            last = f"{self.last[0]:g} s" if self.last is not None else "its start"
            self.dump_error = (f"perception.dump_at_s {self.cfg.dump_at_s:g} s: the camera's last frame was at "
                               f"{last}; nothing written to {self.cfg.dump} (set a time within the run)")
        med = {f"{k}_ms_median": float(np.median(v)) if v else None for k, v in self.ms.items()}
        return {"camera": self.camera.name, "depth": self.cfg.depth, "frames": len(self.ms["render"]), **med,
                "windowed_frames": self.windowed, "held_skipped": self.held_skipped,
                "rest_skipped": self.rest_skipped,
                **({"map": self.mapper.report(*self.world)} if self.mapper is not None else {}),
                **({"hand_cameras": {**self.hands.report(), "head_skipped": self.hand_only}}
                   if self.hands is not None else {}),
                "objects": objects, **({"dump_error": self.dump_error} if self.dump_error else {})}

    def close(self) -> None:
        """Free the renderers."""
        self.camera.close()
        if self.hands is not None:
            self.hands.close()
        if self.right is not None:
            self.right.close()


def stereo_pair(model: mujoco.MjModel, robot: Any, cams: Mapping[str, Any], names: tuple[str, str],
                left: RobotCamera, seed: int, source: str) -> tuple[RobotCamera, StereoMatcher]:
    """The right camera of a stereo pair and the matcher, after checking the pair is rectified as mounted.

    Raises:
        ConfigError: The cameras are on different bodies, or not a rectified pair (:func:`check_pair`).
    """
    specs = [cams[n] for n in names]
    if specs[0].body != specs[1].body:
        raise ConfigError(f"{source}: perception.stereo: {names[0]!r} and {names[1]!r} must be on one body, got "
                          f"{specs[0].body!r} and {specs[1].body!r}")
    try:
        baseline = check_pair(specs[0], specs[1], specs[0].rot(), specs[1].rot(),
                              np.subtract(specs[1].pos, specs[0].pos), names)
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None
    return RobotCamera(model, names[1], specs[1], robot, seed), StereoMatcher(left.K, baseline)
