"""Scene files and the overrides applied before compiling them: body poses, masses and contact friction.

Scenes are MJCF files in Menagerie's manner (``nextage.xml`` ⊂ ``scene.xml`` ⊂ a task scene). A task scene
is loaded as an :class:`mujoco.MjSpec`, changed by a :class:`SceneOverrides` and compiled, so no XML needs
editing to move an object, change its mass or make its contacts more or less slippery.

Friction in MuJoCo: a contact between two geoms takes the larger of their coefficients (unless an explicit
``<pair>`` sets its own). Scaling one geom's coefficient therefore does not scale the contacts it takes part
in; :func:`scale_friction` turns every contact of a body into an explicit pair whose sliding coefficients are
the effective ones times the factor.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, UnknownNameError


def package_root() -> Path:
    """Directory that holds ``scenes/`` and ``configs/`` (the checkout, or the installed package)."""
    here = Path(__file__).resolve().parent
    for candidate in (here, here.parent):
        if (candidate / "scenes" / "nextage.xml").is_file():
            return candidate
    raise ConfigError(f"cannot find the scenes/ directory next to {here} or {here.parent}")


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
    """

    poses: Mapping[str, BodyPose] = field(default_factory=dict)
    masses: Mapping[str, float] = field(default_factory=dict)
    friction_scale: Mapping[str, float] = field(default_factory=dict)


def _yaw_quat(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


TOUCH_SUFFIX = "__touch"
"""Name suffix of the contact sensor :func:`compile_scene` adds to a body it is asked to watch."""


def touch_sensor(body: str) -> str:
    """Name of the contact sensor that watches ``body``: its data are (contacts found, nearest distance [m])."""
    return body + TOUCH_SUFFIX


def compile_scene(scene: str | Path, overrides: SceneOverrides | None = None,
                  touch: tuple[str, ...] = ()) -> mujoco.MjModel:
    """Compile a scene MJCF with optional pose, mass and friction overrides.

    Every body of ``touch`` that the scene has gets a contact sensor (:func:`touch_sensor`): MuJoCo then reports
    at every physics step whether anything touches it, with no Python in the physics loop.

    Raises:
        ConfigError: The scene is missing or an override names a body that is not in it.
    """
    spec = scene_spec(scene, overrides)
    names = {b.name for b in spec.bodies}
    for body in touch:
        if body in names:
            # found + dist of the nearest contact (reduce: mindist), one slot
            found_dist = (1 << int(mujoco.mjtConDataField.mjCONDATA_FOUND)) | (
                1 << int(mujoco.mjtConDataField.mjCONDATA_DIST))
            spec.add_sensor(name=touch_sensor(body), type=mujoco.mjtSensor.mjSENS_CONTACT,
                            objtype=mujoco.mjtObj.mjOBJ_BODY, objname=body, intprm=[found_dist, 1, 1])
    try:
        return spec.compile()
    except ValueError as exc:
        raise ConfigError(f"scene {str(scene)!r} does not compile: {' '.join(str(exc).split())}") from None


def scene_spec(scene: str | Path, overrides: SceneOverrides | None = None) -> mujoco.MjSpec:
    """The scene's MjSpec with the overrides applied (not compiled).

    Raises:
        ConfigError: The scene is missing, an override names a body that is not in it, or a value is not
            physical (a mass or friction factor that is not > 0).
    """
    path = scene_path(scene)
    if path.is_dir():
        raise ConfigError(f"scene {str(scene)!r} is a directory; give an MJCF file or a bundled scene name")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:  # MuJoCo's parser: not XML, not MJCF, a missing include
        raise ConfigError(f"scene {str(path)!r} is not a valid MJCF file: {' '.join(str(exc).split())}") from None
    overrides = overrides or SceneOverrides()
    free = mujoco.mjtJoint.mjJNT_FREE

    def rigid_subtree(body: mujoco.MjsBody) -> bool:  # no joint but a free one in the body and below it
        return all(j.type == free for j in body.joints) and all(rigid_subtree(c) for c in body.bodies)

    # Poses: the scene's own bodies (objects, targets, obstacles), not the robot's links. Masses and friction:
    # the free objects only.
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
    return spec


def _collides(m: mujoco.MjModel, g: int, h: int) -> bool:
    """Whether MuJoCo's broad phase would consider geoms ``g`` and ``h`` (contype/conaffinity, parent filter)."""
    if not ((m.geom_contype[g] & m.geom_conaffinity[h]) or (m.geom_contype[h] & m.geom_conaffinity[g])):
        return False
    wg, wh = int(m.body_weldid[m.geom_bodyid[g]]), int(m.body_weldid[m.geom_bodyid[h]])
    if wg == wh:
        return False
    if m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT:
        return True
    pg, ph = int(m.body_weldid[m.body_parentid[wg]]), int(m.body_weldid[m.body_parentid[wh]])
    return not ((wg and ph == wg) or (wh and pg == wh))


def _mixed(m: mujoco.MjModel, g: int, h: int) -> dict[str, object]:
    """Contact parameters MuJoCo would mix for a dynamic contact of ``g`` and ``h`` (explicit pair fields)."""
    pg, ph = int(m.geom_priority[g]), int(m.geom_priority[h])
    if pg != ph:
        top = g if pg > ph else h
        fr = m.geom_friction[top]
        return {"condim": int(m.geom_condim[top]), "friction": [fr[0], fr[0], fr[1], fr[2], fr[2]],
                "solref": m.geom_solref[top].copy(), "solimp": m.geom_solimp[top].copy(),
                "margin": float(max(m.geom_margin[g], m.geom_margin[h])),
                "gap": float(max(m.geom_gap[g], m.geom_gap[h]))}
    fr = np.maximum(m.geom_friction[g], m.geom_friction[h])
    sg, sh = float(m.geom_solmix[g]), float(m.geom_solmix[h])
    mix = 0.5 if sg + sh < mujoco.mjMINVAL else sg / (sg + sh)
    return {"condim": int(max(m.geom_condim[g], m.geom_condim[h])), "friction": [fr[0], fr[0], fr[1], fr[2], fr[2]],
            "solref": mix * m.geom_solref[g] + (1 - mix) * m.geom_solref[h],
            "solimp": mix * m.geom_solimp[g] + (1 - mix) * m.geom_solimp[h],
            "margin": float(max(m.geom_margin[g], m.geom_margin[h])), "gap": float(max(m.geom_gap[g], m.geom_gap[h]))}


def scale_friction(spec: mujoco.MjSpec, factors: Mapping[str, float]) -> None:
    r"""Scale the sliding friction of every contact of the named bodies, in place.

    For body :math:`B` with factor :math:`s`, an explicit ``<pair>`` that involves :math:`B` gets its two
    sliding coefficients multiplied by :math:`s`; every other contact :math:`B` could make (by contype /
    conaffinity, not excluded, not parent-filtered) becomes an explicit pair with MuJoCo's mixed parameters and
    sliding friction :math:`s \cdot \max(\mu_B, \mu_{other})`, and the body pair is excluded from dynamic
    collision so that no contact is counted twice. Torsional and rolling friction are unchanged.
    """
    for k, geom in enumerate(spec.geoms):
        if not geom.name:
            geom.name = f"_geom{k}"
    model = spec.compile()
    geom_name = [model.geom(i).name for i in range(model.ngeom)]
    excluded = {frozenset((int(model.exclude_signature[i]) >> 16, int(model.exclude_signature[i]) & 0xFFFF))
                for i in range(model.nexclude)}
    paired: set[frozenset[int]] = set()
    for pair in spec.pairs:
        gids = frozenset((model.geom(pair.geomname1).id, model.geom(pair.geomname2).id))
        paired.add(gids)
        bodies = {model.body(int(model.geom_bodyid[g])).name for g in gids}
        factor = float(np.prod([factors[b] for b in bodies if b in factors]))
        if factor != 1.0:
            pair.friction = np.concatenate([np.asarray(pair.friction[:2]) * factor, pair.friction[2:]])
    for name, factor in factors.items():
        body = model.body(name).id
        own = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body]
        partners: set[int] = set()
        for g in own:
            for h in range(model.ngeom):
                hb = int(model.geom_bodyid[h])
                if frozenset((g, h)) in paired or frozenset((body, hb)) in excluded or not _collides(model, g, h):
                    continue
                params = _mixed(model, g, h)
                fr = np.asarray(params.pop("friction"), dtype=float)
                fr[:2] *= factor * factors.get(model.body(hb).name, 1.0)
                spec.add_pair(geomname1=geom_name[g], geomname2=geom_name[h], friction=fr, **params)
                paired.add(frozenset((g, h)))
                partners.add(hb)
        for hb in sorted(partners):
            spec.add_exclude(bodyname1=name, bodyname2=model.body(hb).name)
