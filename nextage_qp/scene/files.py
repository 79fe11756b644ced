"""Scene files and the overrides applied before compiling them: body poses, masses and contact friction.

Scenes are MJCF files without a robot (``scene.xml`` ⊂ a task scene: floor, lights, table, objects, targets,
obstacles); a robot is attached to them (:func:`nextage_qp.robots.compose.compose`). A task scene is loaded as an
:class:`mujoco.MjSpec`, changed by a :class:`SceneOverrides` and compiled, so no XML needs editing to move an
object, change its mass or make its contacts more or less slippery.

Friction overrides scale every contact of a body (:func:`nextage_qp.scene.friction.scale_friction`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, UnknownNameError, one_line
from nextage_qp.scene.friction import scale_friction


def package_root() -> Path:
    """Directory that holds ``scenes/`` and ``configs/`` (the checkout, or the installed package)."""
    package = Path(__file__).resolve().parent.parent
    for candidate in (package, package.parent):
        if (candidate / "scenes" / "scene.xml").is_file():
            return candidate
    raise ConfigError(f"cannot find the scenes/ directory next to {package} or {package.parent}")


def scene_path(scene: str | Path) -> Path:
    """Resolve a scene given as a path or as a short name (``push_cube`` -> ``scenes/push_cube.xml``).

    Raises:
        ConfigError: The scene does not exist; the message lists the bundled scenes.
    """
    path = Path(scene)
    if path.is_file():
        return path
    bundled = package_root() / "scenes"
    for cand in (bundled / path, bundled / f"{path}.xml"):
        if cand.is_file():
            return cand
    names = sorted(p.stem for p in bundled.glob("*.xml") if p.stem != "table")
    raise ConfigError(f"scene {str(scene)!r} not found; bundled scenes: {', '.join(names)} (or a path to an MJCF file)")


@dataclass(frozen=True)
class BodyPose:
    """Override of a body's pose in a scene (objects, targets, obstacle).

    Attributes:
        pos: Position [m] in the world frame, or None to keep the XML value.
        yaw: Rotation about the world z axis [rad], or None to keep the XML orientation.
    """

    pos: tuple[float, float, float] | None = None
    yaw: float | None = None


@dataclass(frozen=True)
class SceneOverrides:
    """Changes applied to a scene before it is compiled, so no XML needs editing.

    Attributes:
        poses: Body name -> new pose (e.g. ``{"cube": BodyPose(pos=(0.35, 0.02, 0.91))}``). For a free
            body this is its start pose; for a static or visual body (target, obstacle) its fixed pose.
        masses: Body name -> new mass [kg]; the inertia is scaled by the same factor.
        friction_scale: Body name -> factor on the sliding friction of every contact the body takes part in.
        objects: Object name -> declaration (:class:`~nextage_qp.scene.objects.ObjectDecl`): added or reshaped.
        clutter: Random obstacles on the table (:class:`~nextage_qp.scene.clutter.ClutterDecl`), or None.
        clutter_avoid: Circles (x, y, radius [m]) the clutter keeps ``keep_out`` from: the robot's start posture.
        placed_later: Targets placed once the scene is compiled, where their objects fit among the clutter (a free
            spot): the clutter does not keep clear of them.
        speckle: Every surface that is not the robot's gets a random-dot texture (what stereo block matching needs:
            :func:`nextage_qp.scene.texture.speckle`); the physics is unchanged.
        seen_pool: Add the pool of box geoms that hold the obstacles a camera sees
            (:func:`nextage_qp.scene.seen_obstacles.add_pool`); the physics never meets them.
    """

    poses: Mapping[str, BodyPose] = field(default_factory=dict)
    masses: Mapping[str, float] = field(default_factory=dict)
    friction_scale: Mapping[str, float] = field(default_factory=dict)
    objects: Mapping[str, Any] = field(default_factory=dict)
    speckle: bool = False
    clutter: Any = None
    clutter_avoid: tuple[tuple[float, float, float], ...] = ()
    placed_later: tuple[str, ...] = ()
    seen_pool: bool = False


def _yaw_quat(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


TOUCH_SUFFIX = "__touch"
"""Name suffix of the contact sensor :func:`compile_scene` adds to a body it is asked to watch."""


def touch_sensor(body: str) -> str:
    """Name of the contact sensor that watches ``body``: its data are (contacts found, nearest distance [m])."""
    return body + TOUCH_SUFFIX


def load_scene(scene: str | Path) -> mujoco.MjSpec:
    """A scene file as a spec (bundled name or path).

    Raises:
        ConfigError: The scene is missing, a directory or not valid MJCF.
    """
    path = scene_path(scene)
    if path.is_dir():
        raise ConfigError(f"scene {str(scene)!r} is a directory; give an MJCF file or a bundled scene name")
    try:
        return mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:  # MuJoCo's parser: not XML, not MJCF, a missing include
        raise ConfigError(f"scene {str(path)!r} is not a valid MJCF file: {one_line(exc)}") from None


def apply_overrides(spec: mujoco.MjSpec, overrides: SceneOverrides, source: str = "scene") -> None:
    """Apply pose, mass and friction overrides to a (composed) scene spec.

    Poses apply to the scene's own bodies (objects, targets, obstacles: rigid bodies at the world's top level),
    masses and friction to its free objects.

    Raises:
        ConfigError: An override names a body the scene does not have, or a value is not physical (a mass or
            friction factor that is not > 0).
    """
    free = mujoco.mjtJoint.mjJNT_FREE

    def rigid_subtree(body: mujoco.MjsBody) -> bool:  # no joint but a free one in the body and below it
        return all(j.type == free for j in body.joints) and all(rigid_subtree(c) for c in body.bodies)

    placeable = [b.name for b in spec.worldbody.bodies if b.name and rigid_subtree(b)]
    objects = [b.name for b in spec.bodies if b.name and any(j.type == free for j in b.joints)]

    def body_of(name: str, kind: str, valid: list[str]) -> mujoco.MjsBody:
        if name not in valid:
            raise UnknownNameError(kind, name, valid)
        return spec.body(name)

    for name, pose in overrides.poses.items():
        body = body_of(name, "scene body (object, target or obstacle)", placeable)
        if pose.pos is not None:
            body.pos = np.asarray(pose.pos, dtype=float)
        if pose.yaw is not None:
            body.quat = _yaw_quat(pose.yaw)
    for name, mass in overrides.masses.items():
        body = body_of(name, "object", objects)
        if not (mass > 0 and np.isfinite(mass)):
            raise ConfigError(f"mass of {name!r} must be a finite mass > 0 kg, got {mass}")
        old = float(np.atleast_1d(body.mass)[0])
        if not old > 0:
            raise ConfigError(f"mass of {name!r}: the scene gives it no mass to scale (set it in the MJCF)")
        scale = mass / old
        body.mass = mass
        body.inertia = np.asarray(body.inertia) * scale
    for name, factor in overrides.friction_scale.items():
        body_of(name, "object", objects)
        if not (factor > 0 and np.isfinite(factor)):
            raise ConfigError(f"friction_scale of {name!r} must be a finite factor > 0, got {factor}")
    scaled = {n: f for n, f in overrides.friction_scale.items() if f != 1.0}
    if scaled:
        scale_friction(spec, scaled)


def add_touch_sensors(spec: mujoco.MjSpec, bodies: tuple[str, ...]) -> None:
    """A contact sensor (:func:`touch_sensor`) on each of ``bodies`` that the spec has.

    MuJoCo then reports at every physics step whether anything touches the body, with no Python in the physics loop.
    """
    names = {b.name for b in spec.bodies}
    # found + dist of the nearest contact (reduce: mindist), one slot
    found_dist = (1 << int(mujoco.mjtConDataField.mjCONDATA_FOUND)) | (1 << int(mujoco.mjtConDataField.mjCONDATA_DIST))
    for body in bodies:
        if body in names:
            spec.add_sensor(
                name=touch_sensor(body),
                type=mujoco.mjtSensor.mjSENS_CONTACT,
                objtype=mujoco.mjtObj.mjOBJ_BODY,
                objname=body,
                intprm=[found_dist, 1, 1],
            )
