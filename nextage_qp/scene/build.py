"""Objects declared in a task config (:mod:`nextage_qp.scene.objects`) built into a scene with MjSpec."""

from __future__ import annotations

import math
from collections.abc import Mapping

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, one_line
from nextage_qp.scene.objects import ObjectDecl, PartDecl, standing_height, volume

MARKER_RGBA = (0.2, 0.8, 0.3, 0.25)
"""Colour of an added target marker (a ghost of the object)."""
_AXIS_QUAT = {"z": [1.0, 0.0, 0.0, 0.0], "x": [math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0],
              "y": [math.sqrt(0.5), -math.sqrt(0.5), 0.0, 0.0]}
_TYPES = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
          "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE, "sphere": mujoco.mjtGeom.mjGEOM_SPHERE}


def _prism_mesh(spec: mujoco.MjSpec, name: str, part: PartDecl) -> str:
    assert part.sides is not None
    r, h, n = part.size[0], part.size[1], part.sides
    ring = [(r * math.cos(2 * math.pi * k / n), r * math.sin(2 * math.pi * k / n)) for k in range(n)]
    verts = [c for x, y in ring for z in (-h, h) for c in (x, y, z)]
    spec.add_mesh(name=name, uservert=verts)
    return name


def _add_parts(spec: mujoco.MjSpec, body: mujoco.MjsBody, name: str, decl: ObjectDecl, visual: bool) -> None:
    parts = decl.primitives()
    total = sum(volume(p) for p in parts)
    for i, part in enumerate(parts):
        geom = body.add_geom(pos=list(part.pos), quat=_AXIS_QUAT[part.axis], rgba=list(part.rgba or decl.rgba))
        geom.name = f"{name}_{i}" if not visual else ""
        if part.shape == "prism":
            geom.type = mujoco.mjtGeom.mjGEOM_MESH
            geom.meshname = _prism_mesh(spec, f"{name}_prism_{i}{'_v' if visual else ''}", part)
        else:
            geom.type = _TYPES[part.shape]
            geom.size = [*part.size, 0.0, 0.0][:3]
        if visual:
            geom.contype = geom.conaffinity = 0
            geom.group = 1
            geom.rgba = list(MARKER_RGBA)
            geom.mass = 0.0
        else:
            geom.friction = [decl.friction, 0.005, 0.0001]
            geom.mass = decl.mass * volume(part) / total


def _set_inertial(body: mujoco.MjsBody, decl: ObjectDecl) -> None:
    """The body's mass, centre of mass and inertia, as MuJoCo computes them from the declared parts."""
    scratch = mujoco.MjSpec()
    probe = scratch.worldbody.add_body(name="probe")
    probe.add_freejoint()
    _add_parts(scratch, probe, "probe", decl, visual=False)
    m = scratch.compile()
    body.explicitinertial = True
    body.mass = float(m.body_mass[1])
    body.ipos = m.body_ipos[1].copy()
    body.iquat = m.body_iquat[1].copy()
    body.inertia = m.body_inertia[1] * decl.inertia_scale
    body.fullinertia = [np.nan] * 6  # the diagonal inertia above, not a full one the scene file gave


def _repoint_pairs(spec: mujoco.MjSpec, old: set[str], new: list[str]) -> None:
    """The scene's contact pairs (their friction, say) that named a replaced geom now name each new one."""
    seen = set()
    for pair in [p for p in spec.pairs if p.geomname1 in old or p.geomname2 in old]:
        first = pair.geomname1 in old
        other = pair.geomname2 if first else pair.geomname1
        for geom in new if other not in seen else ():  # one pair per geom and partner (the partner's first)
            clone = spec.add_pair(geomname1=geom if first else other, geomname2=other if first else geom)
            for key in ("condim", "friction", "gap", "margin", "solimp", "solref", "solreffriction"):
                setattr(clone, key, getattr(pair, key))
        seen.add(other)
        spec.delete(pair)


def _flat(geom: mujoco.MjsGeom) -> bool:
    return geom.type == mujoco.mjtGeom.mjGEOM_BOX and geom.size[2] <= 0.001


def table_top(spec: mujoco.MjSpec) -> float | None:
    """Height [m] of the top of the scene's table (its colliding boxes), or None without a table."""
    body = next((b for b in spec.worldbody.bodies if b.name == "table"), None)
    if body is None:
        return None
    tops = [body.pos[2] + g.pos[2] + g.size[2] for g in body.geoms
            if g.type == mujoco.mjtGeom.mjGEOM_BOX and (g.contype or g.conaffinity)]
    return max(tops) if tops else None


def declare_objects(spec: mujoco.MjSpec, objects: Mapping[str, ObjectDecl], source: str = "scene") -> list[str]:
    """Add or replace the declared objects (and markers ``NAME_target`` for new ones) in a scene spec, in place.

    Call before the scene's pose, mass and friction overrides, and :func:`rest_on_table` after them. Returns the
    markers it added.

    Raises:
        ConfigError: A name is taken by something that is not a free object of the scene.
    """
    free = mujoco.mjtJoint.mjJNT_FREE
    markers = []
    for name, decl in objects.items():
        body = next((b for b in spec.worldbody.bodies if b.name == name), None)
        if body is not None and not any(j.type == free for j in body.joints):
            raise ConfigError(f"scene.objects.{name}: {name!r} is a fixed body of the scene {source}, not an "
                              "object; choose another name", key=f"scene.objects.{name}")
        if body is not None and decl.fixed:
            raise ConfigError(f"scene.objects.{name}: {name!r} is a free object of the scene {source}; a fixed "
                              "object takes a new name", key=f"scene.objects.{name}")
        if body is None:
            try:
                body = spec.worldbody.add_body(name=name, pos=[0.5, 0.0, 1.0])
                if not decl.fixed:
                    body.add_freejoint(name=f"{name}_joint")
            except ValueError as exc:  # MuJoCo: "repeated name 'world' in body"; a robot's link, the world
                raise ConfigError(f"scene.objects.{name}: {name!r} is taken in the scene {source} "
                                  f"({one_line(exc)}); choose another name", key=f"scene.objects.{name}") from None
        marker = next((b for b in spec.worldbody.bodies if b.name == f"{name}_target"), None)
        if marker is None and decl.marker and not decl.fixed:
            marker = spec.worldbody.add_body(name=f"{name}_target", pos=[0.5, 0.0, 1.0])
            markers.append(marker.name)
        if marker is not None and not any(g.contype or g.conaffinity for g in marker.geoms):  # takes the new shape
            for geom in [g for g in marker.geoms if not _flat(g)]:  # (a flat pad under it stays)
                spec.delete(geom)
            _add_parts(spec, marker, f"{name}_target", decl, visual=True)
        old = {g.name for g in body.geoms}
        for geom in list(body.geoms):
            spec.delete(geom)
        _add_parts(spec, body, name, decl, visual=False)
        _repoint_pairs(spec, old, [g.name for g in body.geoms])
        if not decl.fixed:
            _set_inertial(body, decl)
        if decl.pos is not None:
            body.pos = [decl.pos[0], decl.pos[1], decl.pos[2] if len(decl.pos) == 3 else body.pos[2]]
        if decl.yaw is not None:
            body.quat = [math.cos(decl.yaw / 2), 0.0, 0.0, math.sin(decl.yaw / 2)]
        numeric = f"{name}_yaw_symmetry"
        for old in [n for n in spec.numerics if n.name == numeric]:
            spec.delete(old)
        spec.add_numeric(name=numeric, data=[decl.symmetry()])
    return markers


def rest_on_table(spec: mujoco.MjSpec, objects: Mapping[str, ObjectDecl], markers: list[str]) -> None:
    """Stand each declared object (and each added marker) on the table top, unless its ``pos`` gives a height."""
    top = table_top(spec)
    if top is None:
        return
    for name, decl in objects.items():
        if decl.pos is None or len(decl.pos) == 2:
            body = spec.body(name)
            body.pos = [body.pos[0], body.pos[1], top + standing_height(decl)]
        if f"{name}_target" in markers:
            marker = spec.body(f"{name}_target")
            marker.pos = [marker.pos[0], marker.pos[1], top + standing_height(decl)]
