"""Hand cameras: a robot camera on a wrist looks at an object the head camera cannot see clearly.

A pushing hand hides the object from the head; a camera on that hand looks over its tool face at the object it
pushes. :class:`HandCameras` renders a hand camera only when it is wanted: for an object the head's frame did not
fit cleanly (hidden, covered by the robot, a bad or partial fit), and only the hand cameras whose view holds the
object's predicted centre. Each hand camera fits the object's known shape as the head's estimator does
(:class:`~nextage_qp.sensing.camera.estimate.Estimator`), on the table plane the head found, in the same frame
period; a fit to an object wholly in its view (a view cut by the image's edge leaves it free to slide along the cut)
then stands in for the head's. While the hand cameras see every object so, the head renders only every
``WHOLE_EVERY``-th frame (:class:`~nextage_qp.sensing.camera.source.CameraMeasurer`). The obstacle map takes the
head's whole frames alone.
"""

from __future__ import annotations

import time
from collections.abc import Collection, Mapping, Sequence
from typing import Any

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.sensing.camera.estimate import MIN_SUPPORT, PARTLY, WHOLE, Estimator
from nextage_qp.sensing.camera.frame import Detection, Frame
from nextage_qp.sensing.camera.pixels import project
from nextage_qp.sensing.camera.render import RobotCamera
from nextage_qp.sensing.camera.shapes import ShapeModel
from nextage_qp.sensing.camera.visible import seen

NEAREST = 0.03
"""A hand camera is asked about an object whose predicted centre is at least this far in front of it [m]."""
FARTHEST = 0.6
"""... and at most this far [m]: farther, the head's view is as good."""
UNSEEN = Detection(None, "occluded", occluded=1.0)
"""What stands for the head's detection of an object in a period without a head frame."""
HAND_COVER = 0.5
"""Share of an object's camera-facing surface the robot may cover in a hand camera's clean view: a hand camera looks
past the tool at an object touching it, whose face on the tool it cannot see (a head's clean view: ``PARTLY``)."""


def clear(det: Detection, cover: float = PARTLY) -> bool:
    """Whether a detection is a clean view: fitted, covered by the robot at most ``cover``, well supported."""
    return det.status == "ok" and det.occluded <= cover and det.support >= MIN_SUPPORT


def hand_camera_names(robot: Any, asked: Sequence[str] | None, source: str) -> tuple[str, ...]:
    """The hand cameras of ``perception.hand_cameras``: ``asked``, or (None) every robot-file camera on a wrist.

    A camera is on a wrist when its body is the body of an arm's wrist or tool frame.

    Raises:
        ConfigError: An asked camera the robot file lacks.
    """
    cams = dict(robot.description.cameras) if robot.description is not None else {}
    if asked is not None:
        for name in asked:
            if name not in cams:
                raise ConfigError(f"{source}: perception.hand_cameras: {name!r} is not a camera of robot "
                                  f"{robot.name!r}; valid: {', '.join(sorted(cams)) or '(the robot file has none)'}")
        return tuple(asked)
    model = robot.model
    wrists = {model.body(robot.frame_body(f)).name for arm in robot.arms for f in (arm.wrist, arm.tool)}
    return tuple(name for name, cam in cams.items() if cam.body in wrists)


class HandCameras:
    """The hand cameras of a run (see the module docstring).

    Args:
        names: The cameras (robot-file names).
        robot: The :class:`~nextage_qp.robots.model.Robot`.
        shapes: Object name -> its shape model (the head estimator's).
        seed: The run's seed.
    """

    def __init__(self, names: Sequence[str], robot: Any, shapes: Mapping[str, ShapeModel], seed: int) -> None:
        specs = robot.description.cameras
        self.cameras = [RobotCamera(robot.model, n, specs[n], robot, seed + 1 + i) for i, n in enumerate(names)]
        self.estimators = [Estimator(shapes, seed + 101 + i) for i in range(len(names))]
        self.frames = dict.fromkeys(names, 0)  # frames rendered per camera
        self.used = dict.fromkeys(names, 0)  # frames whose measurement stood in for the head's
        self.ms: list[float] = []  # per frame rendered: render and estimate [ms]

    def wanted(self, q: np.ndarray,
               centres: Mapping[str, np.ndarray]) -> list[tuple[int, list[str], np.ndarray, np.ndarray]]:
        """Per hand camera whose view holds a predicted centre of ``centres``: index, objects, pose (pos, rot).

        The pose is the camera's at the joints ``q``, which :meth:`measure` renders from.
        """
        out = []
        for i, cam in enumerate(self.cameras):
            pos, rot = cam.pose(q)
            names = []
            for name, c in centres.items():
                rows, cols, z = project(c[None, :], cam.K, pos, rot)
                h, w = cam.spec.height, cam.spec.width
                if NEAREST <= z[0] <= FARTHEST and 0 <= rows[0] < h and 0 <= cols[0] < w:
                    names.append(name)
            if names:
                out.append((i, names, pos, rot))
        return out

    def measure(self, data: mujoco.MjData, q: np.ndarray, priors: Mapping[str, np.ndarray | None],
                head: Mapping[str, Detection], held: Collection[str],
                plane: tuple[np.ndarray, float] | None) -> dict[str, Detection]:
        """Clean detections from the hand cameras of the objects the head's ``head`` detections missed.

        ``priors``: the filter's predictions (only tracked objects are looked for); ``plane``: the table plane the
        head found (a close view of an object's top may show more of it than of the table).
        """
        centres = {n: p[:3] for n, p in priors.items() if p is not None and n in head and not clear(head[n])}
        if not centres or plane is None:
            return {}
        out: dict[str, Detection] = {}
        by: dict[str, str] = {}  # the camera each detection of ``out`` came from
        for i, names, pos, rot in self.wanted(q, centres):
            t0 = time.perf_counter()
            cam, est = self.cameras[i], self.estimators[i]
            frame = Frame(cam.depth(data), cam.expected(), cam.K, pos, rot, whole=False)
            est.plane = plane
            dets = est.estimate(frame, {n: priors[n] for n in names}, held)
            self.ms.append((time.perf_counter() - t0) * 1e3)
            self.frames[cam.name] += 1
            for name, det in dets.items():
                whole = (det.pose is not None and clear(det, HAND_COVER)
                         and seen(frame, est.shapes[name], det.pose)[1] >= WHOLE)
                if whole and (name not in out or det.rms < out[name].rms):
                    out[name], by[name] = det, cam.name
        for name in by.values():
            self.used[name] += 1
        return out

    def report(self) -> dict[str, Any]:
        """Per hand camera its frames and the frames whose measurement was used; the median ms per frame."""
        return {"frames": dict(self.frames), "used": dict(self.used),
                "ms_median": float(np.median(self.ms)) if self.ms else None}

    def close(self) -> None:
        """Free the renderers."""
        for cam in self.cameras:
            cam.close()
