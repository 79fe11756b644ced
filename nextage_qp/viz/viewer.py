"""The live MuJoCo viewer of a run (``run --viewer``): markers, framing, real-time pacing, clean exit."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.viz.run import add_markers, marker_starts

if TYPE_CHECKING:
    from nextage_qp.manipulation.runner import Runner


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

    def __init__(self, runner: Runner) -> None:
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
        self.starts = marker_starts(runner)
        self.next_t = 0.0
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
        ahead = (runner.sim.time - self.t0[0]) - (now - self.t0[1])
        if ahead > 0:
            time.sleep(ahead)

    def close(self) -> None:
        """Close the window and wait for the viewer's thread to finish."""
        self.handle.close()
        for thread in self.threads:
            thread.join(timeout=10.0)
