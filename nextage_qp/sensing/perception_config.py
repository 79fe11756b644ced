"""The ``perception:`` block of a task config: where the object poses the phases see come from.

.. code-block:: yaml

    perception:
      source: camera         # truth | simulated (faults.object_pose's model) | camera (rendered images)
      camera: head_rgbd      # a camera of the robot file
      depth: rendered        # rendered (an RGB-D sensor) | stereo (block matching on the two RGB cameras below)
      stereo: [head_left, head_right]
      look_at: true          # the head keeps the task's object and target in view (a low-weight IK task)
      hand_cameras: null     # cameras on the hands that see what the head cannot (null: the robot file's wrist ones)
      held_every: 3          # while every object is held aloft, a frame every 3rd camera period
      rest_every: 3          # while every object rests untouched, far from the robot, a frame every 3rd period
      obstacles: camera      # declared (the scene's) | camera (the clutter as the camera's occupancy map shows it)
      dump: runs/frame       # write one frame's RGB, depth, clusters and fitted pose as PNGs
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from nextage_qp.io.schema import YamlModel


class PerceptionConfig(YamlModel):
    """See the module docstring."""

    source: Literal["truth", "simulated", "camera"] | None = Field(
        default=None, description="truth; simulated: faults.object_pose's noise, latency and dropouts; camera: poses "
        "estimated from the robot camera's images. Default: simulated with faults.object_pose, else truth.")
    camera: str = Field(default="head_rgbd", min_length=1, description="The robot file's camera that gives depth.")
    depth: Literal["rendered", "stereo"] = Field(
        default="rendered", description="rendered: the camera's depth with its noise model; stereo: block matching on "
        "the two RGB cameras of `stereo` (nextage_qp.sensing.camera.stereo; the world's surfaces get a random-dot "
        "texture).")
    stereo: tuple[str, str] = Field(default=("head_left", "head_right"),
                                    description="Left and right RGB cameras of a rectified pair (depth: stereo).")
    look_at: bool = Field(default=True, description="The head keeps the object and target in view (camera only).")
    look_cost: float = Field(default=0.05, ge=0, le=10.0, description="Weight of the look-at task [1/rad].")
    noise_pos_m: float | None = Field(
        default=None, gt=0, le=0.1, allow_inf_nan=False, description="Position noise the filter assumes of a clear "
        "view's fit [m]. Default: 1 mm with rendered depth (its fits scatter about 0.8 mm RMS in 3-D; an assumed noise "
        "far above that averages a pushed object's drift away), 2 mm with stereo depth.")
    noise_rot_rad: float = Field(default=0.02, gt=0, le=0.5, description="Rotation noise the filter assumes [rad].")
    cover_spread: float | None = Field(
        default=None, ge=0, le=100, allow_inf_nan=False, description="Factor [1]: the noise the filter assumes of a "
        "fit grows by 1 + cover_spread * the share of the object it does not see (the robot covers it, the frame lacks "
        "it). Default: 8 with stereo depth (block matching smears depth across the robot's edges), 0 with rendered "
        "depth.")
    window: bool | None = Field(
        default=None, description="Render (and, with stereo, match) a tracked object's frames only in a window around "
        "it (its bounding box grown by 5 cm), the whole frame every 15th and while one is untracked: fewer pixels to "
        "render and estimate. Default: on, off with an obstacle map (map, obstacles: camera), which takes whole "
        "frames.")
    hand_cameras: tuple[str, ...] | None = Field(
        default=None, description="Cameras on the hands (robot-file names) that look at an object the head's frame "
        "does not fit cleanly (hidden by a hand, covered, a partial fit), rendered only then and only where their "
        "view holds the object (nextage_qp.sensing.camera.hands). Default: every robot-file camera on an arm's wrist "
        "or tool body with rendered depth, none with stereo depth; []: none.")
    held_every: int = Field(
        default=3, ge=1, le=100, description="While the robot holds every tracked object (clamped, not pushed) 3 cm "
        "or more over the table, the head takes a frame every this many camera periods [count]: a held object's "
        "estimate follows the hands between frames (nextage_qp.estimation.held); 1: every period.")
    rest_every: int = Field(
        default=3, ge=1, le=100, description="While every tracked object rests on the table, its last two fits at most "
        "5 mm apart, with no geom of the robot (its bounding sphere) within 5 cm of it, the head takes a frame every "
        "this many camera periods [count]: nothing moves it between frames (nextage_qp.sensing.camera.source); never "
        "with an obstacle map; 1: every period.")
    map: bool = Field(default=False, description="Build an occupancy map of the obstacles from the camera's whole "
                      "frames (source: camera) and report it, scored against the scene "
                      "(nextage_qp.sensing.camera.seen); the phases plan with the declared obstacles.")
    obstacles: Literal["declared", "camera"] = Field(
        default="declared", description="Where the controller's obstacles come from. declared: the scene's (every "
        "clutter piece known exactly); camera: the generated clutter only as the camera's occupancy map shows it "
        "(source: camera, rendered depth; implies map): its clusters become boxes that the planner's validity check "
        "and the IK's collision rows of the clutter group use in place of the clutter, and free spots are chosen "
        "among them when a phase first names the target (nextage_qp.scene.seen_obstacles).")
    unknown: Literal["occupied", "free"] = Field(
        default="occupied", description="With obstacles: camera, what the space over the table the camera has never "
        "seen is for the controller: occupied (boxes of it join the obstacles; the shadows of the robot's links and of "
        "the tracked objects aside) or free.")
    scan: bool | None = Field(
        default=None, description="Before the first phase, the head looks over the mapped space (a grid of points "
        "over the work region, each held until the camera has looked at it) so that the map has seen it before any "
        "motion is planned (unset: on with obstacles: camera; needs look_at).")
    dump: str | None = Field(default=None, description="Folder for one frame's RGB, depth, clusters and fit (PNGs).")
    dump_at_s: float = Field(default=1.0, ge=0, description="Time of the dumped frame [s].")
