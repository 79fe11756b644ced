"""Pictures of a manipulation run: debug markers, headless video, the live viewer and a summary plot.

Markers (as the report's coloured spheres): green = object target, blue = the IK's commanded tool
frames, red = the measured tool frames, yellow = where each tool started.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.nextage import TOOL_SITES

if TYPE_CHECKING:
    from nextage_qp.manipulation.runner import Runner

GREEN, BLUE, RED, YELLOW = (0.1, 0.9, 0.2, 0.8), (0.2, 0.4, 1.0, 0.8), (1.0, 0.2, 0.1, 0.8), (1.0, 0.9, 0.1, 0.8)


def _tool_frames(runner: Runner) -> list[str]:
    return [f for f in TOOL_SITES if f in runner.robot.site_names]


Marker = tuple[np.ndarray, tuple[float, float, float, float], float]
"""A marker sphere: position, RGBA colour, radius."""


def marker_points(runner: Runner, starts: dict[str, np.ndarray]) -> list[Marker]:
    """The target, commanded, measured and start tool positions as marker spheres."""
    view = runner.view
    points: list[Marker] = [(np.asarray(view.body_pose(runner.cfg.target).pos, dtype=float), GREEN, 0.015)]
    for frame in _tool_frames(runner):
        points += [(np.asarray(view.commanded_pose(frame).pos, dtype=float), BLUE, 0.008),
                   (np.asarray(view.frame_pose(frame).pos, dtype=float), RED, 0.006), (starts[frame], YELLOW, 0.006)]
    return points


def draw_markers(scene: mujoco.MjvScene, points: list[Marker]) -> None:
    """Append marker spheres to ``scene`` (as many as it has room for)."""
    for pos, rgba, size in points:
        if scene.ngeom >= scene.maxgeom:
            return
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE, np.array([size, 0, 0]),
                            np.asarray(pos, dtype=float), np.eye(3).reshape(-1), np.asarray(rgba, dtype=np.float32))
        scene.ngeom += 1


def add_markers(scene: mujoco.MjvScene, runner: Runner, starts: dict[str, np.ndarray]) -> None:
    """Append marker spheres for the target, commanded, measured and start tool positions to ``scene``."""
    draw_markers(scene, marker_points(runner, starts))


FAST_FLAGS = (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION, mujoco.mjtRndFlag.mjRND_SKYBOX)
"""Render features the video leaves out: in software GL they cost several times the rest of a frame."""


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
    try:
        while (state := frames.get()) is not None:
            data.qpos[:], data.mocap_pos[:], data.mocap_quat[:], points = state
            mujoco.mj_kinematics(model, data)
            mujoco.mj_camlight(model, data)
            renderer.update_scene(data, camera=camera)
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
                 camera: str = "workspace") -> None:
        import multiprocessing
        import pickle

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
        self.starts = {f: runner.view.frame_pose(f).pos for f in _tool_frames(runner)}

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


def _display_check() -> None:
    """Raise a one-line ConfigError when no window can open (before GLFW prints its own text or exits)."""
    import os

    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ConfigError("--viewer: no display (DISPLAY is not set); run under a display or "
                          "'xvfb-run -a nextage-qp run ...', or write a video with --video instead")
    try:
        import glfw
    except ImportError as exc:
        raise ConfigError(f"--viewer: GLFW is not available ({exc}); install the 'glfw' package") from None
    glfw.ERROR_REPORTING = "ignore"  # its failures become the one line below, not warnings on stderr
    if not glfw.init():
        raise ConfigError(f"--viewer: cannot open the display {os.environ.get('DISPLAY', '')!r}; "
                          "check that the X server runs, or use --video")


def workspace_view(runner: Runner, camera: str = "workspace") -> tuple[np.ndarray, float, float, float]:
    """Free-camera ``(lookat, distance, azimuth_deg, elevation_deg)`` looking as the scene's ``camera`` does.

    It is aimed at the point of the camera's optical axis nearest the object, so that the table, the object, the
    target and the hands are in view and the user can orbit about the object.
    """
    m, d = runner.robot.model, runner.sim.data
    cam = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, camera)
    obj = np.asarray(runner.view.body_pose(runner.cfg.object).pos, dtype=float)
    if cam < 0:  # a scene without that camera: look at the object from the front, above
        return obj, 1.6, 180.0, -30.0
    pos, forward = d.cam_xpos[cam].copy(), -d.cam_xmat[cam].reshape(3, 3)[:, 2]
    distance = float(max(np.dot(obj - pos, forward), 0.3))
    azimuth = float(np.degrees(np.arctan2(forward[1], forward[0])))
    elevation = float(np.degrees(np.arcsin(np.clip(forward[2], -1.0, 1.0))))
    return pos + distance * forward, distance, azimuth, elevation


class LiveViewer:
    """The passive MuJoCo viewer with the debug markers, paced to real time and framed on the workspace.

    Every ~1/60 s of simulated time it syncs the window and, if the simulation runs ahead of the wall clock,
    waits, so the motion plays at real time. Closing the window lets the run finish at full speed. ``close``
    ends the viewer's thread before the process exits (GLFW torn down under a live window segfaults).
    """

    def __init__(self, runner: Runner, speed: float = 1.0) -> None:
        import threading

        import mujoco.viewer

        _display_check()
        before = set(threading.enumerate())
        try:
            self.handle = mujoco.viewer.launch_passive(runner.robot.model, runner.sim.data)
        except Exception as exc:
            raise ConfigError(f"--viewer: cannot open a window ({exc}); use --video on a headless machine") from None
        self.threads = [t for t in threading.enumerate() if t not in before]
        lookat, distance, azimuth, elevation = workspace_view(runner)
        with self.handle.lock():
            self.handle.cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            self.handle.cam.lookat[:] = lookat
            self.handle.cam.distance, self.handle.cam.azimuth, self.handle.cam.elevation = distance, azimuth, elevation
        self.starts = {f: runner.view.frame_pose(f).pos for f in _tool_frames(runner)}
        self.speed, self.next_t = speed, 0.0
        self.t0: tuple[float, float] | None = None  # (simulated, wall) time of the first frame

    def on_tick(self, runner: Runner, phase: Any) -> None:
        """Tick callback: sync the window, redraw the markers, wait for the wall clock."""
        import time

        if runner.sim.time < self.next_t or not self.handle.is_running():
            return
        self.next_t = runner.sim.time + 1.0 / 60.0
        with self.handle.lock():
            self.handle.user_scn.ngeom = 0
            add_markers(self.handle.user_scn, runner, self.starts)
        self.handle.sync()
        now = time.perf_counter()
        if self.t0 is None:
            self.t0 = (runner.sim.time, now)
        ahead = (runner.sim.time - self.t0[0]) / self.speed - (now - self.t0[1])
        if ahead > 0:
            time.sleep(ahead)

    def close(self) -> None:
        """Close the window and wait for the viewer's thread to finish."""
        self.handle.close()
        for thread in self.threads:
            thread.join(timeout=10.0)


def plot_run(runner: Runner, path: Path) -> None:
    """PNG with the object's distance to its target over time (phases shaded) and a top view of the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rec = runner.sim.recorder.arrays()
    t = rec["t"]
    obj = rec[f"object_{runner.cfg.object}"][:, :3]
    tgt = runner.view.body_pose(runner.cfg.target).pos
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    ax1.semilogy(t, np.maximum(np.linalg.norm(obj - tgt, axis=1), 1e-5), label="3-D")
    ax1.semilogy(t, np.maximum(np.linalg.norm((obj - tgt)[:, :2], axis=1), 1e-5), label="x-y")
    ax1.axhline(runner.cfg.success.planar_error, color="k", ls="--", lw=0.8, label="success threshold (x-y)")
    for i, ph in enumerate(runner.records):
        if ph.status != "skipped":
            ax1.axvspan(ph.start_s, ph.start_s + ph.duration_s, color=f"C{i % 8}", alpha=0.08)
            ax1.text(ph.start_s, ax1.get_ylim()[1] if i else 0.5, ph.name, fontsize=7, rotation=90, va="top")
    ax1.set(xlabel="time [s]", ylabel="object distance to target [m]", title=f"{runner.cfg.task}")
    ax1.legend(fontsize=8, loc="lower left")
    ax1.grid(alpha=0.3, which="both")
    ax2.plot(obj[:, 0], obj[:, 1], color="k", lw=2, label=runner.cfg.object)
    for frame in _tool_frames(runner):
        key = f"frame_{frame}"
        if key in rec:
            ax2.plot(rec[key][:, 0], rec[key][:, 1], lw=1, label=frame)
    ax2.plot(*tgt[:2], "g*", ms=14, label="target")
    groups = runner.robot.collision_geoms()
    for g in groups.get("obstacle", ()):
        corners = _box_footprint(runner, g)
        ax2.fill(corners[:, 0], corners[:, 1], color="r", alpha=0.5, label="obstacle")
    ax2.set(xlabel="x [m]", ylabel="y [m]", title="top view", aspect="equal")
    ax2.legend(fontsize=7)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _box_footprint(runner: Runner, geom: int) -> np.ndarray:
    d, m = runner.sim.data, runner.robot.model
    rot, c, s = d.geom_xmat[geom].reshape(3, 3), m.geom_size[geom][0], m.geom_size[geom][1]
    local = np.array([[c, s, 0], [-c, s, 0], [-c, -s, 0], [c, -s, 0], [c, s, 0]])
    return d.geom_xpos[geom] + local @ rot.T
