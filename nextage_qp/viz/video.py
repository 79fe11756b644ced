"""A run's video, rendered headless and encoded in a process of its own (``run --video``).

A run whose object poses come from a robot camera (``perception.source: camera``) shows that camera's view in the
top right corner, with each object's latest fitted pose drawn over it (:class:`HeadView`).
"""

from __future__ import annotations

import queue
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.mobile.build import BASE_BODY
from nextage_qp.viz.run import FAST_FLAGS, draw_markers, marker_points, marker_starts

if TYPE_CHECKING:
    from nextage_qp.manipulation.runner import Runner


FOLLOW = "follow:"
"""Prefix of a camera name that follows a body: ``follow:BODY``."""


@dataclass(frozen=True)
class HeadView:
    """A robot camera's view for a video's corner: its name, image size, intrinsics and the objects' shape models."""

    camera: str
    width: int
    height: int
    K: Any
    shapes: dict[str, Any]

    @staticmethod
    def of(measurer: Any) -> HeadView:
        """The view of a :class:`~nextage_qp.sensing.camera.source.CameraMeasurer`'s camera."""
        cam = measurer.camera
        return HeadView(cam.name, cam.spec.width, cam.spec.height, cam.K, dict(measurer.estimator.shapes))

    def view(self, renderer: mujoco.Renderer, data: mujoco.MjData, poses: dict[str, Any]) -> Any:
        """The camera's image of ``data`` (as the robot's camera renders it) with ``poses`` drawn over it."""
        from nextage_qp.sensing.camera.draw import draw_poses
        from nextage_qp.sensing.camera.estimate import Frame
        from nextage_qp.sensing.camera.render import render_camera, shown_option

        cam = mujoco.mj_name2id(renderer.model, mujoco.mjtObj.mjOBJ_CAMERA, self.camera)
        image = render_camera(renderer, data, cam, shown_option())
        none = np.empty((0, 0))  # the drawing needs the camera only, no depth
        frame = Frame(none, none, self.K, data.cam_xpos[cam].copy(), data.cam_xmat[cam].reshape(3, 3).copy())
        return draw_poses(image, frame, self.shapes, poses)

    @staticmethod
    def paste(image: Any, corner: Any) -> Any:
        """``image`` with ``corner`` (at most half its width, scaled down by whole steps) in its top right corner."""
        step = 1
        while corner.shape[1] // step > image.shape[1] // 2 or corner.shape[0] // step > image.shape[0] // 2:
            step += 1
        small = corner[::step, ::step]
        out = image.copy()
        out[: small.shape[0], out.shape[1] - small.shape[1] :] = small
        return out


def video_process(path: str, fps: int, size: tuple[int, int], camera: str, frames: Any, status: Any) -> None:
    """Render the states received on ``frames`` and encode them into ``path`` (``None`` ends the video).

    The first item on ``frames`` is the pickled ``(model, inset)``, ``inset`` None or a robot camera's
    :class:`HeadView`; each later item is ``(qpos, mocap_pos, mocap_quat, markers, poses)``, ``poses`` the camera's
    latest fitted pose per object. Reports ``("ready", None)`` once the GL context and the file are open, then
    ``("done", n_frames)``, or ``("error", message)`` at any point.
    """
    import pickle

    model, inset = pickle.loads(frames.get())
    model.vis.quality.offsamples = 0  # multisampling doubles a software-GL frame's cost
    try:
        renderer = mujoco.Renderer(model, *size)
        head = None if inset is None else mujoco.Renderer(model, inset.height, inset.width)
    except Exception as exc:  # no GL context: name the fix
        status.send(("error", f"--video: cannot open an offscreen GL context ({exc}); set MUJOCO_GL=egl"))
        return
    try:
        import imageio.v2 as imageio

        writer = imageio.get_writer(path, fps=fps, macro_block_size=1)
    except Exception as exc:
        status.send(("error", f"--video {path}: cannot write: {exc}"))
        return
    status.send(("ready", None))
    data, count = mujoco.MjData(model), 0
    view: str | mujoco.MjvCamera = camera
    if camera.startswith(FOLLOW):  # a camera that follows a body (a mobile robot's base) from behind and above
        view = mujoco.MjvCamera()
        view.type, view.trackbodyid = mujoco.mjtCamera.mjCAMERA_TRACKING, model.body(camera[len(FOLLOW):]).id
        view.distance, view.elevation, view.azimuth = 3.5, -30.0, 150.0
    try:
        while (state := frames.get()) is not None:
            data.qpos[:], data.mocap_pos[:], data.mocap_quat[:], points, poses = state
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)  # a tracking camera follows the body's subtree centre of mass
            mujoco.mj_camlight(model, data)
            renderer.update_scene(data, camera=view)
            for flag in FAST_FLAGS:
                renderer.scene.flags[flag] = False
            draw_markers(renderer.scene, points)
            image = renderer.render()
            if head is not None and inset is not None:
                image = inset.paste(image, inset.view(head, data, poses))
            writer.append_data(image)
            count += 1
        writer.close()
        status.send(("done", count))
    except Exception as exc:  # the first line only: ffmpeg's command and output follow it
        status.send(("error", f"{type(exc).__name__}: {(str(exc).strip().splitlines() or [''])[0]}"))


class VideoRecorder:
    """Renders the run headless at ``fps`` into an MP4 (set ``MUJOCO_GL=egl`` on a machine without display).

    Rendering and encoding run in a process of their own, fed the joint state and the marker positions of each
    frame, so that on a machine with two cores they overlap the simulation instead of adding to it (a software-GL
    frame costs about as much as 0.7 s of simulated time in the control loop).
    """

    QUEUE = 64
    """Frames in flight: when rendering falls behind, the run waits for it rather than holding every frame."""

    def __init__(self, runner: Runner, path: Path, *, fps: int = 25, size: tuple[int, int] = (480, 640),
                 camera: str | None = None) -> None:
        import multiprocessing
        import pickle

        if camera is None:  # the workspace's camera; a mobile robot is followed
            camera = f"{FOLLOW}{BASE_BODY}" if runner.robot.base is not None else "workspace"
        try:  # an existing file the encoder could not replace (read-only, immutable, not ours): say so before the run
            path.open("r+b").close() if path.exists() else path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"--video {path}: cannot write the file ({exc.strerror or exc}: read-only or no "
                              "permission); give another path") from None
        ctx = multiprocessing.get_context("spawn")
        self.frames = ctx.Queue(self.QUEUE)
        self.status, child = ctx.Pipe(duplex=False)
        self.process = ctx.Process(target=video_process, daemon=True, name="nextage-qp-video",
                                   args=(str(path), fps, size, camera, self.frames, child))
        self.process.start()
        self.measurer = getattr(runner.sensors, "measurer", None)  # a robot camera's (perception.source: camera)
        inset = None if self.measurer is None else HeadView.of(self.measurer)
        self.frames.put(pickle.dumps((runner.robot.model, inset)))  # the queue's feeder thread: never blocks here
        kind, message = self._wait(120.0)
        if kind != "ready":
            self.frames.cancel_join_thread()  # the model may still sit in the pipe: do not wait at exit
            self.process.join(timeout=5.0)
            raise ConfigError(message)
        self.period, self.next_t = 1.0 / fps, 0.0
        self.error: str | None = None
        self.starts = marker_starts(runner)

    def _wait(self, timeout: float) -> tuple[str, Any]:
        """The video process's next report, or an error if it died or did not answer within ``timeout`` s."""
        import time

        end = time.monotonic() + timeout
        while not self.status.poll(0.2):
            if not self.process.is_alive() and not self.status.poll(0.2):
                return "error", f"--video: the renderer process exited with code {self.process.exitcode}"
            if time.monotonic() > end:
                self.process.kill()
                return "error", f"--video: the renderer did not answer within {timeout:.0f} s"
        try:
            kind, value = self.status.recv()
        except EOFError:  # the process died without a report
            return "error", f"--video: the renderer process exited with code {self.process.exitcode}"
        return str(kind), value

    def on_tick(self, runner: Runner, phase: Any) -> None:
        """Tick callback: send a frame's state when one is due."""
        if runner.sim.time + 1e-9 < self.next_t:
            return
        self.next_t += self.period
        d = runner.sim.data
        poses = dict(self.measurer.poses) if self.measurer is not None else {}
        state = (d.qpos.copy(), d.mocap_pos.copy(), d.mocap_quat.copy(), marker_points(runner, self.starts), poses)
        while self.error is None:  # a full queue waits for the renderer, unless it has stopped with an error
            try:
                self.frames.put(state, timeout=1.0)
                return
            except queue.Full:
                if self.status.poll() or not self.process.is_alive():
                    self.error = str(self._wait(1.0)[1])
                    self.frames.cancel_join_thread()  # frames left in the pipe are never read: do not wait at exit

    def close(self) -> int:
        """Finish the file; returns the number of frames written, raises OSError if the video could not be made."""
        if self.error is not None:  # the renderer stopped during the run (its queue may be full: do not wait)
            self.process.kill()
            raise OSError(self.error)
        self.frames.put(None)
        kind, value = self._wait(600.0)
        self.process.join(timeout=10.0)
        if kind != "done":
            self.frames.cancel_join_thread()
            raise OSError(value)
        return int(value)
