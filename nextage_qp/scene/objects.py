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
the grasp) follows from the shape: a square box (half-extents within ``SQUARE_TOL``) :math:`\pi/2`, an oblong one
:math:`\pi`, an n-sided prism :math:`2\pi/n`, a cylinder, capsule or sphere any yaw (``0``), a compound none
(:math:`2\pi`) unless ``yaw_symmetry`` says otherwise.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, model_validator

from nextage_qp.io.schema import YamlModel

Shape = Literal["box", "cylinder", "capsule", "sphere", "prism"]
SIZES = {"box": 3, "cylinder": 2, "capsule": 2, "sphere": 1, "prism": 2}
"""Entries of ``size`` per shape."""
SQUARE_TOL = 0.001
"""Half-extents [m] within which a box's footprint counts as square (a quarter turn looks the same): a camera's fit
cannot tell its faces apart (it turns the estimate a quarter turn as readily as not), and a clamp closes on either
pair alike."""
Length = Annotated[float, Field(ge=0.001, le=1.0, allow_inf_nan=False)]
"""A size entry [m]: from 1 mm (thinner is no object a hand can push or clamp, and MuJoCo's contacts fail on it) to
1 m."""
Vec3 = tuple[float, float, float]
Unit = Annotated[float, Field(ge=0.0, le=1.0)]
RGBA = tuple[Unit, Unit, Unit, Unit]
"""A colour: red, green, blue and alpha, each in [0, 1]."""


class PartDecl(YamlModel):
    """One primitive: shape, size, and (in a compound) its offset in the object's frame."""

    shape: Shape = Field(description="The part's shape: box, cylinder, capsule, sphere or prism.")
    size: tuple[Length, ...] = Field(description="MuJoCo's geom size convention [m], as an object's size.")
    sides: int | None = Field(default=None, ge=3, le=24,
                              description="Sides of a prism, a regular polygon [count] (prism only).")
    pos: Vec3 = Field(default=(0.0, 0.0, 0.0), description="Offset in the object's frame [m] (compound parts).")
    axis: Literal["x", "y", "z"] = Field(default="z", description="Axis of a cylinder, capsule or prism.")
    rgba: RGBA | None = Field(
        default=None, description="Colour [1]: red, green, blue and alpha, each 0 to 1 (default: the object's).")

    @model_validator(mode="after")
    def _size_fits_shape(self) -> PartDecl:
        if len(self.size) != SIZES[self.shape]:
            raise ValueError(f"a {self.shape} takes {SIZES[self.shape]} size entries, got {len(self.size)}")
        if (self.sides is not None) != (self.shape == "prism"):
            raise ValueError("sides (>= 3) goes with shape: prism, and only with it")
        return self


class ObjectDecl(YamlModel):
    """An object declared in the task config (see the module docstring)."""

    shape: Literal["box", "cylinder", "capsule", "sphere", "prism", "compound"] = Field(
        default="box", description="Shape: box, cylinder, capsule, sphere, prism (a regular prism, see sides), "
                                   "or compound (a list of parts).")
    size: tuple[Length, ...] | None = Field(
        default=None, description="MuJoCo's geom size convention [m], each entry 1 mm to 1 m: box half-extents x, y, "
                                  "z; cylinder and capsule radius, half-height; prism circumradius, half-height; "
                                  "sphere radius (required unless the shape is compound).")
    sides: int | None = Field(default=None, ge=3, le=24,
                              description="Sides of a prism, a regular polygon [count] (prism only).")
    parts: tuple[PartDecl, ...] = Field(
        default=(), description="A compound's parts, each a primitive at an offset in the object's frame (compound "
                                "only); the mass is spread over them by volume.")
    mass: float = Field(default=0.1, ge=1e-4, le=50.0, allow_inf_nan=False,
                        description="Mass [kg], 0.1 g to 50 kg, spread over the parts by volume.")
    friction: float = Field(default=0.5, gt=0, le=5.0, allow_inf_nan=False,
                            description="Sliding friction coefficient [1] of its geoms (MuJoCo takes the larger of "
                                        "two touching geoms').")
    pos: tuple[float, float] | Vec3 | None = Field(default=None, description="Start position [m] (z: on the table).")
    yaw: float | None = Field(default=None, ge=-7.0, le=7.0, description="Start yaw [rad].")
    rgba: RGBA = Field(default=(0.95, 0.8, 0.1, 1.0),
                       description="Colour [1]: red, green, blue and alpha, each 0 to 1 (also its parts' default).")
    yaw_symmetry: float | None = Field(
        default=None, ge=0.0, le=7.0, description="Yaw after which the object looks the same [rad]; 0: any yaw "
                                                  "(default from the shape: square box (half-extents within 1 mm) "
                                                  "pi/2, oblong box pi, n-sided prism 2 pi/n, cylinder, capsule, "
                                                  "sphere 0, compound 2 pi).")
    marker: bool = Field(default=True, description="Add a target marker NAME_target for a new object.")
    fixed: bool = Field(default=False, description="A static obstacle (a shelf's board, a bin's wall): no joint, no "
                                                   "marker; it does not move, and its name is a collision group.")
    inertia_scale: float = Field(default=1.0, gt=0, le=100.0, allow_inf_nan=False,
                                 description="Factor [1] on the inertia of uniform density (a model's "
                                             "inertia_scaling); mass and centre of mass unchanged.")

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
            return math.pi / 2 if abs(self.size[0] - self.size[1]) <= SQUARE_TOL else math.pi
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


DOWN = {"z": (0.0, 0.0, -1.0), "x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0)}
"""The world's downward direction in a part's own frame, per ``axis`` (the rotations of ``object_build``)."""


def half_height(part: PartDecl) -> float:
    """How far the part reaches below its centre when the object stands upright [m]."""
    s, d = part.size, DOWN[part.axis]
    radial, axial = math.hypot(d[0], d[1]), abs(d[2])
    if part.shape == "box":
        return sum(abs(di) * si for di, si in zip(d, s, strict=True))
    if part.shape == "sphere":
        return s[0]
    if part.shape == "capsule":
        return s[1] * axial + s[0]
    if part.shape == "cylinder":
        return s[0] * radial + s[1] * axial
    assert part.sides is not None  # a prism: its lowest vertex
    ring = (2 * math.pi * k / part.sides for k in range(part.sides))
    return max(s[0] * (math.cos(a) * d[0] + math.sin(a) * d[1]) for a in ring) + s[1] * axial


def standing_height(decl: ObjectDecl) -> float:
    """Height of the object's origin over the surface it stands on [m]."""
    return max(half_height(p) - p.pos[2] for p in decl.primitives())
