"""Pictures of a manipulation run: debug markers and a summary plot (video: video.py, live viewer: viewer.py).

Markers (as the report's coloured spheres): green = object target, blue = the IK's commanded tool
frames, red = the measured tool frames, yellow = where each tool started.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from nextage_qp.robots.model import tool_frames as robot_tool_frames

if TYPE_CHECKING:
    from nextage_qp.manipulation.runner import Runner

GREEN, BLUE, RED, YELLOW = (0.1, 0.9, 0.2, 0.8), (0.2, 0.4, 1.0, 0.8), (1.0, 0.2, 0.1, 0.8), (1.0, 0.9, 0.1, 0.8)


def tool_frames(runner: Runner) -> list[str]:
    """The tool sites of the run's robot (markers are drawn for these)."""
    return list(robot_tool_frames(runner.robot))


def marker_starts(runner: Runner) -> dict[str, np.ndarray]:
    """Where each tool frame is now: the yellow markers' positions for the rest of the run."""
    return {f: runner.view.frame_pose(f).pos for f in tool_frames(runner)}


Marker = tuple[np.ndarray, tuple[float, float, float, float], float]
"""A marker sphere: position, RGBA colour, radius."""


def marker_points(runner: Runner, starts: dict[str, np.ndarray]) -> list[Marker]:
    """The target, commanded, measured and start tool positions as marker spheres."""
    view = runner.view
    points: list[Marker] = [(np.asarray(view.body_pose(runner.cfg.target).pos, dtype=float), GREEN, 0.015)]
    for frame in tool_frames(runner):
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


def plot_run(runner: Runner, path: Path) -> None:
    """PNG with the object's distance to its target over time (phases shaded) and a top view of the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rec = runner.sim.recorder.arrays()
    t = rec["t"]
    key = f"object_{runner.cfg.object}"
    base = np.array(runner.sim.base.log) if runner.sim.base is not None and runner.sim.base.log else None
    if key not in rec and base is not None:  # the object is the robot's base
        t, obj = base[:, 0], np.c_[base[:, 1:3], np.zeros(len(base))]
    else:
        obj = rec[key][:, :3]
    tgt = runner.view.body_pose(runner.cfg.target).pos
    track = runner.sensors.history.get(runner.cfg.object) if runner.sensors is not None else None
    fig, axes = plt.subplots(1, 3 if track else 2, figsize=(18 if track else 12, 4.5))
    ax1, ax2 = axes[:2]
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
    for frame in tool_frames(runner):
        key = f"frame_{frame}"
        if key in rec:
            ax2.plot(rec[key][:, 0], rec[key][:, 1], lw=1, label=frame)
    ax2.plot(*tgt[:2], "g*", ms=14, label="target")
    if base is not None:  # where the base went, and where odometry says it went
        ax2.plot(base[:, 1], base[:, 2], color="0.35", lw=2.5, alpha=0.6, label="base (true)")
        ax2.plot(base[:, 4], base[:, 5], color="m", lw=1, ls="--", label="base (odometry)")
    groups = runner.robot.collision_geoms()
    for g in groups.get("obstacle", ()):
        corners = _box_footprint(runner, g)
        ax2.fill(corners[:, 0], corners[:, 1], color="r", alpha=0.5, label="obstacle")
    ax2.set(xlabel="x [m]", ylabel="y [m]", title="top view", aspect="equal")
    ax2.legend(fontsize=7)
    ax2.grid(alpha=0.3)
    if track:
        _plot_estimate(axes[2], t, obj, track, runner.cfg.object)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _plot_estimate(ax: Any, t: np.ndarray, truth: np.ndarray, track: list[Any], name: str) -> None:
    """Truth, raw measurements (as they arrived) and the estimate the phases saw, x and y against time."""
    te = np.array([row[0] for row in track])
    est = np.array([row[1][:3] for row in track])
    meas = [(row[0], row[2][:3]) for row in track if row[2] is not None]
    for axis, label in ((0, "x"), (1, "y")):
        color = f"C{axis}"
        ax.plot(t, truth[:, axis], color=color, lw=1.5, label=f"{label} truth")
        ax.plot(te, est[:, axis], color=color, lw=1, ls="--", label=f"{label} estimate")
        if meas:
            ax.plot([m[0] for m in meas], [m[1][axis] for m in meas], ".", color=color, ms=2, label=f"{label} measured")
    ax.set(xlabel="time [s]", ylabel=f"{name} position [m]", title="perception: truth, measurements, estimate")
    ax.legend(fontsize=7, ncol=3)
    ax.grid(alpha=0.3)


def _box_footprint(runner: Runner, geom: int) -> np.ndarray:
    d, m = runner.sim.data, runner.robot.model
    rot, c, s = d.geom_xmat[geom].reshape(3, 3), m.geom_size[geom][0], m.geom_size[geom][1]
    local = np.array([[c, s, 0], [-c, s, 0], [-c, -s, 0], [c, -s, 0], [c, s, 0]])
    return d.geom_xpos[geom] + local @ rot.T
