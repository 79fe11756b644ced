"""A task config's positions in the robot's workspace: one config, any robot whose reach allows the task.

With ``scene.frame: workspace`` a config's positions are relative to the work region the robot file declares
(``workspace:``): x-y from the region's centre, z above the table top. The scene's table stands where the robot file
puts it. :func:`to_world` turns such a scene into world positions before the scene is compiled; a robot file without
a workspace is refused with what to add.
"""

from __future__ import annotations

import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.manipulation.config import FreeSpot, PoseOverride, SceneConfig
from nextage_qp.robots.robot_file import WorkspaceFile

TABLE = "table"
"""The scene body that is the table (the bundled scenes' name)."""


def to_world(scene: SceneConfig, workspace: WorkspaceFile | None, robot: str, source: str) -> SceneConfig:
    """``scene`` with its positions in the world frame (unchanged when it is written in the world frame already).

    Raises:
        ConfigError: The scene is written in the workspace frame and the robot file declares no workspace.
    """
    if scene.frame == "world":
        return scene
    if workspace is None:
        raise ConfigError(f"{source}: scene.frame: workspace, but robot {robot!r} declares no workspace; add "
                          "workspace: {centre: [x, y], size: [hx, hy], top: z} to its robot file (docs/robots.md), or "
                          "write the scene in world coordinates (scene.frame: world)", source=source, key="scene.frame")
    cx, cy = workspace.centre
    origin = np.array([cx, cy, workspace.top])

    def point(p: tuple[float, ...]) -> tuple[float, ...]:
        return tuple(float(v) for v in np.asarray(p, dtype=float) + origin[: len(p)])

    def spot(s: FreeSpot | None) -> FreeSpot | None:
        if s is None:
            return None
        (x0, y0), (x1, y1) = s.region
        near = None if s.near is None else (s.near[0] + cx, s.near[1] + cy)
        return s.model_copy(update={"region": ((x0 + cx, y0 + cy), (x1 + cx, y1 + cy)), "near": near})

    poses = {name: pose.model_copy(update={"pos": None if pose.pos is None else point(pose.pos),
                                           "free_spot": spot(pose.free_spot)})
             for name, pose in scene.poses.items()}
    if workspace.table is not None and (TABLE not in poses or poses[TABLE].pos is None):
        poses[TABLE] = PoseOverride(pos=workspace.table, yaw=poses[TABLE].yaw if TABLE in poses else None)
    objects = {name: decl.model_copy(update={"pos": None if decl.pos is None else point(decl.pos)})
               for name, decl in scene.objects.items()}
    clutter = scene.clutter
    if clutter is not None:
        (x0, y0), (x1, y1) = clutter.region
        clutter = clutter.model_copy(update={"region": ((x0 + cx, y0 + cy), (x1 + cx, y1 + cy))})
    return scene.model_copy(update={"frame": "world", "poses": poses, "objects": objects, "clutter": clutter})
