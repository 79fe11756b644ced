"""The live viewer: refuses cleanly without a display; under a virtual display (Xvfb) it opens, frames the
workspace, paces the run to real time and exits 0 (skipped where ``xvfb-run`` is not installed)."""

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from nextage_qp.cli import main
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner
from nextage_qp.viz.viewer import workspace_view


def test_without_a_display_one_line_and_exit_2(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["run", "push_cube", "--viewer", "--json"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--viewer" in err and "xvfb-run" in err, err


@pytest.mark.parametrize("config", ["push_cube", "dock_dumbbell"])
def test_view_frames_the_object(config):
    runner = Runner(load_config(config, []), config)
    lookat, distance, _azimuth, elevation = workspace_view(runner)
    obj = runner.view.body_pose(runner.cfg.object).pos
    # the view centre is within a hand's width of the object, seen from 1-2.5 m, from above
    assert np.linalg.norm(lookat - obj) < 0.25 and 1.0 < distance < 2.5 and -60 < elevation < -10


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run (Debian package xvfb) not installed")
def test_viewer_under_xvfb_paces_to_real_time_and_exits_0(tmp_path):
    env = {**os.environ, "MUJOCO_GL": "egl"}
    env.pop("DISPLAY", None)
    proc = subprocess.run(["xvfb-run", "-a", sys.executable, "-m", "nextage_qp.cli", "run", "push_cube", "--viewer",
                           "--json"], capture_output=True, text=True, env=env, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    # nothing on stderr but the plain progress lines (stderr is not a terminal): no GLFW text, no traceback
    assert all(line.startswith("run push_cube: phase") for line in proc.stderr.splitlines()), proc.stderr[-2000:]
    result = json.loads(proc.stdout)
    assert result["success"], result["failed_criteria"]
    # paced: the run took at least (almost) as long on the wall clock as in simulated time
    assert result["wall_time_s"] >= 0.9 * result["sim_time_s"], (result["wall_time_s"], result["sim_time_s"])


def test_video_writes_one_frame_per_period(tmp_path):
    from nextage_qp.viz.video import VideoRecorder

    runner = Runner(load_config("push_cube", []), "push_cube")
    video = VideoRecorder(runner, tmp_path / "v.mp4", fps=25, size=(120, 160))
    for k in range(101):  # 0.2 s of simulated time at 2 ms per tick: frames due at 0, 0.04, ..., 0.2
        runner.sim._step = 2 * k  # sim_dt is 1 ms
        video.on_tick(runner, None)
    assert video.close() == 6
    import imageio.v3 as iio

    assert sum(1 for _ in iio.imiter(tmp_path / "v.mp4")) == 6


def test_video_without_a_gl_backend_is_one_error_before_the_run(tmp_path, monkeypatch):
    from nextage_qp.errors import ConfigError
    from nextage_qp.viz.video import VideoRecorder

    runner = Runner(load_config("push_cube", []), "push_cube")
    monkeypatch.setenv("MUJOCO_GL", "no_such_backend")
    with pytest.raises(ConfigError, match="--video"):
        VideoRecorder(runner, tmp_path / "v.mp4")


@pytest.mark.skipif(__import__("nextage_qp.sensing.camera.render", fromlist=["render_problem"]).render_problem() is not None,
                    reason="offscreen rendering unavailable")
def test_video_of_a_camera_run_shows_the_head_view_with_the_fitted_pose(tmp_path):
    import imageio.v3 as iio

    from nextage_qp.sensing.camera.draw import COLOURS
    from nextage_qp.viz.video import VideoRecorder

    runner = Runner(load_config("push_cube", ["perception.source=camera"]), "push_cube")
    measurer = runner.sensors.measurer
    pos, rot = measurer.camera.pose(runner.robot.get_q(runner.sim.data))
    ahead = pos - 0.8 * rot[:, 2]  # 0.8 m along the camera's axis (it looks along its -z)
    measurer.poses = {"cube": np.array([*ahead, 0.0, 0.0, 0.0])}  # as if the camera had fitted the cube there
    video = VideoRecorder(runner, tmp_path / "v.mp4", fps=25, size=(240, 320))
    video.on_tick(runner, None)
    assert video.close() == 1
    frame = next(iter(iio.imiter(tmp_path / "v.mp4"))).astype(int)
    corner, rest = frame[:120, 160:], frame[120:, :160]
    near = lambda img: (np.abs(img - np.array(COLOURS[0])).sum(axis=2) < 90).sum()  # noqa: E731 (codec blur)
    assert near(corner) >= 5 and near(rest) == 0  # the pose is drawn in the corner's head view only
