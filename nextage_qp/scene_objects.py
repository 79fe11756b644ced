r"""Objects declared as data in a task config (``scene.objects``) and added to the scene with MjSpec.

.. code-block:: yaml

    scene:
      objects:
        cube: {shape: box, size: [0.02, 0.04, 0.03], mass: 0.2}        # replaces the scene's cube
        puck: {shape: cylinder, size: [0.03, 0.02], pos: [0.4, 0.1]}    # a new object, and its marker puck_target
        nut: {shape: prism, sides: 6, size: [0.03, 0.015]}
        bar: {shape: compound, parts: [{shape: box, size: [0.1, 0.01, 0.01]},
                                       {shape: cylinder, size: [0.02, 0.03], pos: [0.1, 0, 0]}]}

``size`` follows MuJoCo's geom convention: box half-extents ``[x, y, z]``; cylinder and capsule ``[radius,
half-height]``; prism (a regular ``sides``-gon) ``[circumradius, half-height]``; sphere ``[radius]``. A declared
object stands on the surface under it (its lowest point on the table top), so a new size needs no new height; its
mass is spread over its parts by volume. An object the scene already has keeps its name, its free joint and its
target marker; its geometry is replaced. The yaw after which it looks the same (used by the yaw criteria and
the grasp) follows from the shape: a square box :math:`\pi/2`, an oblong one :math:`\pi`, an n-sided prism
:math:`2\pi/n`, a cylinder, capsule or sphere any yaw (``0``), a compound none (:math:`2\pi`) unless
``yaw_symmetry`` says otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Literal

import mujoco
import numpy as np
from pydantic import BaseModel, Field, model_validator

from nextage_qp.errors import ConfigError
from nextage_qp.yaml_file import STRICT

Shape = Literal["box", "cylinder", "capsule", "sphere", "prism"]
SIZES = {"box": 3, "cylinder": 2, "capsule": 2, "sphere": 1, "prism": 2}
"""Entries of ``size`` per shape."""
Length = Annotated[float, Field(gt=0, le=1.0, allow_inf_nan=False)]
Vec3 = tuple[float, float, float]


class PartDecl(BaseModel):
    """One primitive: shape, size, and (in a compound) its offset in the object's frame."""

    model_config = STRICT

    shape: Shape
    size: tuple[Length, ...] = Field(description="MuJoCo's geom size convention [m] (see the module docstring).")
    sides: int | None = Field(default=None, ge=3, le=24, description="Sides of a prism.")
    pos: Vec3 = Field(default=(0.0, 0.0, 0.0), description="Offset in the object's frame [m] (compound parts).")
    axis: Literal["x", "y", "z"] = Field(default="z", description="Axis of a cylinder, capsule or prism.")

    @model_validator(mode="after")
    def _size_fits_shape(self) -> PartDecl:
        if len(self.size) != SIZES[self.shape]:
            raise ValueError(f"a {self.shape} takes {SIZES[self.shape]} size entries, got {len(self.size)}")
        if (self.sides is not None) != (self.shape == "prism"):
            raise ValueError("sides (>= 3) goes with shape: prism, and only with it")
        return self


class ObjectDecl(BaseModel):
    """An object declared in the task config (see the module docstring)."""

    model_config = STRICT

    shape: Shape | Literal["compound"] = "box"
    size: tuple[Length, ...] | None = None
    sides: int | None = Field(default=None, ge=3, le=24)
    parts: tuple[PartDecl, ...] = ()
    mass: float = Field(default=0.1, gt=0, le=50.0, allow_inf_nan=False, description="[kg]")
    friction: float = Field(default=0.5, gt=0, le=5.0, allow_inf_nan=False, description="Sliding friction.")
    pos: tuple[float, float] | Vec3 | None = Field(default=None, description="Start position [m] (z: on the table).")
    yaw: float | None = Field(default=None, ge=-7.0, le=7.0, description="Start yaw [rad].")
    rgba: tuple[float, float, float, float] = (0.95, 0.8, 0.1, 1.0)
    yaw_symmetry: float | None = Field(default=None, ge=0.0, le=7.0, description="[rad]; 0: any yaw.")

    @model_validator(mode="after")
    def _shape_or_parts(self) -> ObjectDecl:
        if self.shape == "compound":
            if not self.parts or self.size is not None or self.sides is not None:
                raise ValueError("a compound takes parts (and no size or sides of its own)")
        else:
            if self.parts:
                raise ValueError(f"parts go with shape: compound, not {self.shape}")
            if self.size is None:
                raise ValueError(f"a {self.shape} needs size ({SIZES[self.shape]} entries)")
            PartDecl(shape=self.shape, size=self.size, sides=self.sides)  # the same checks as a part
        return self

    def primitives(self) -> tuple[PartDecl, ...]:
        """The object's parts (a single-shape object is one part at its origin)."""
        if self.shape == "compound":
            return self.parts
        assert self.size is not None
        return (PartDecl(shape=self.shape, size=self.size, sides=self.sides),)

    def symmetry(self) -> float:
        """The yaw [rad] after which the object looks the same (0: any yaw)."""
        if self.yaw_symmetry is not None:
            return self.yaw_symmetry
        if self.shape == "box":
            assert self.size is not None
            return math.pi / 2 if math.isclose(self.size[0], self.size[1], rel_tol=1e-9) else math.pi
        if self.shape == "prism":
            assert self.sides is not None
            return 2 * math.pi / self.sides
        return 0.0 if self.shape in ("cylinder", "capsule", "sphere") else 2 * math.pi


def volume(part: PartDecl) -> float:
    """Volume of a part [m^3]."""
    s = part.size
    if part.shape == "box":
        return 8.0 * s[0] * s[1] * s[2]
    if part.shape == "cylinder":
        return 2.0 * math.pi * s[0] ** 2 * s[1]
    if part.shape == "capsule":
        return 2.0 * math.pi * s[0] ** 2 * s[1] + 4.0 / 3.0 * math.pi * s[0] ** 3
    if part.shape == "sphere":
        return 4.0 / 3.0 * math.pi * s[0] ** 3
    assert part.sides is not None
    return part.sides / 2.0 * s[0] ** 2 * math.sin(2 * math.pi / part.sides) * 2.0 * s[1]


def half_height(part: PartDecl) -> float:
    """How far the part reaches below its centre when the object stands upright [m]."""
    s = part.size
    if part.shape == "box":
        return s[2]
    if part.shape == "sphere":
        return s[0]
    if part.axis == "z":
        return s[1] + (s[0] if part.shape == "capsule" else 0.0)
    return s[0]  # lying on its side: the radius (a prism's circumradius)


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
        geom = body.add_geom(pos=list(part.pos), quat=_AXIS_QUAT[part.axis], rgba=list(decl.rgba))
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
            geom.rgba = [*decl.rgba[:3], 0.25]
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
    body.inertia = m.body_inertia[1].copy()
    body.fullinertia = [np.nan] * 6  # the diagonal inertia above, not a full one the scene file gave


def _table_top(spec: mujoco.MjSpec) -> float | None:
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
            raise ConfigError(f"{source}: scene.objects.{name}: {name!r} is a fixed body of the scene, not an object; "
                              "choose another name")
        if body is None:
            body = spec.worldbody.add_body(name=name, pos=[0.5, 0.0, 1.0])
            body.add_freejoint(name=f"{name}_joint")
            if not any(b.name == f"{name}_target" for b in spec.bodies):
                marker = spec.worldbody.add_body(name=f"{name}_target", pos=[0.5, 0.0, 1.0])
                _add_parts(spec, marker, f"{name}_target", decl, visual=True)
                markers.append(marker.name)
        for geom in list(body.geoms):
            spec.delete(geom)
        _add_parts(spec, body, name, decl, visual=False)
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
    top = _table_top(spec)
    if top is None:
        return
    for name, decl in objects.items():
        if decl.pos is None or len(decl.pos) == 2:
            body = spec.body(name)
            body.pos = [body.pos[0], body.pos[1], top + standing_height(decl)]
        if f"{name}_target" in markers:
            marker = spec.body(f"{name}_target")
            marker.pos = [marker.pos[0], marker.pos[1], top + standing_height(decl)]


def standing_height(decl: ObjectDecl) -> float:
    """Height of the object's origin over the surface it stands on [m]."""
    return max(half_height(p) - p.pos[2] for p in decl.primitives())
