"""A run's video, rendered headless and encoded in a process of its own (``run --video``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco

from nextage_qp.errors import ConfigError
from nextage_qp.mobile.build import BASE_BODY
from nextage_qp.viz.run import FAST_FLAGS, draw_markers, marker_points, marker_starts

if TYPE_CHECKING:
    from nextage_qp.manipulation.runner import Runner


FOLLOW = "follow:"
"""Prefix of a camera name that follows a body: ``follow:BODY``."""


def video_process(path: str, fps: int, size: tuple[int, int], camera: str, frames: Any, status: Any) -> None:
    """Render the states received on ``frames`` and encode them into ``path`` (``None`` ends the video).

    The first item on ``frames`` is the pickled model; each later item is ``(qpos, mocap_pos, mocap_quat,
    markers)``. Reports ``("ready", None)`` once the GL context and the file are open, then ``("done", n_frames)``,
    or ``("error", message)`` at any point.
    """
    import pickle

    model = pickle.loads(frames.get())
    model.vis.quality.offsamples = 0  # multisampling doubles a software-GL frame's cost
    try:
        renderer = mujoco.Renderer(model, *size)
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
            data.qpos[:], data.mocap_pos[:], data.mocap_quat[:], points = state
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)  # a tracking camera follows the body's subtree centre of mass
            mujoco.mj_camlight(model, data)
            renderer.update_scene(data, camera=view)
            for flag in FAST_FLAGS:
                renderer.scene.flags[flag] = False
            draw_markers(renderer.scene, points)
            writer.append_data(renderer.render())
            count += 1
        writer.close()
        status.send(("done", count))
    except Exception as exc:
        status.send(("error", f"{type(exc).__name__}: {exc}"))


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
        path.parent.mkdir(parents=True, exist_ok=True)
        ctx = multiprocessing.get_context("spawn")
        self.frames = ctx.Queue(self.QUEUE)
        self.status, child = ctx.Pipe(duplex=False)
        self.process = ctx.Process(target=video_process, daemon=True, name="nextage-qp-video",
                                   args=(str(path), fps, size, camera, self.frames, child))
        self.process.start()
        self.frames.put(pickle.dumps(runner.robot.model))  # through the queue's feeder thread: never blocks here
        kind, message = self._wait(120.0)
        if kind != "ready":
            self.frames.cancel_join_thread()  # the model may still sit in the pipe: do not wait at exit
            self.process.join(timeout=5.0)
            raise ConfigError(message)
        self.period, self.next_t = 1.0 / fps, 0.0
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
        kind, value = self.status.recv()
        return str(kind), value

    def on_tick(self, runner: Runner, phase: Any) -> None:
        """Tick callback: send a frame's state when one is due."""
        if runner.sim.time + 1e-9 < self.next_t:
            return
        self.next_t += self.period
        d = runner.sim.data
        self.frames.put((d.qpos.copy(), d.mocap_pos.copy(), d.mocap_quat.copy(), marker_points(runner, self.starts)))

    def close(self) -> int:
        """Finish the file; returns the number of frames written, raises OSError if the video could not be made."""
        self.frames.put(None)
        kind, value = self._wait(600.0)
        self.process.join(timeout=10.0)
        if kind != "done":
            self.frames.cancel_join_thread()
            raise OSError(value)
        return int(value)
