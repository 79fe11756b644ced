"""Clutter as data: random boxes and cylinders on the table (``scene.clutter``), placed from a seed.

:func:`add_clutter` stands ``count`` static bodies ``clutter_0``, ``clutter_1`` ... on the table inside ``region``,
each at least ``keep_out`` from every declared object and target and from the straight corridor between each free
object and its ``NAME_target`` marker, and apart from each other. They form the collision group ``clutter``
(usable in ``ik.collision_pairs``; the planner avoids them as obstacles). The same seed places the same clutter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import mujoco
import numpy as np
from pydantic import Field, model_validator

from nextage_qp.errors import ConfigError
from nextage_qp.io.schema import YamlModel

PREFIX = "clutter_"
"""Generated bodies' (and geoms') name prefix; the collision group is ``clutter``."""
GAP = 0.01
"""Least gap [m] between two pieces of clutter."""
TRIES = 2000
"""Random placements tried per piece before the region counts as too full."""
RGBA = (0.55, 0.5, 0.45, 1.0)
"""Colour of the clutter."""


class ClutterDecl(YamlModel):
    """Random obstacles on the table: how many, their shapes and sizes, where, and what they keep clear of."""

    count: int = Field(default=0, ge=0, le=40, description="Pieces of clutter [count].")
    seed: int | None = Field(default=None, ge=0, le=2**32 - 1,
                             description="Seed of their shapes, sizes and places [-] (unset: the run's seed, so a "
                                         "sweep draws new clutter every episode).")
    shapes: tuple[Literal["box", "cylinder"], ...] = Field(
        default=("box", "cylinder"), min_length=1, description="Shapes drawn from, with equal chance.")
    size: tuple[float, float] = Field(
        default=(0.02, 0.05), description="Footprint half-size of a box or radius of a cylinder [m], drawn "
                                          "uniformly from [min, max].")
    height: tuple[float, float] = Field(default=(0.05, 0.2), description="Height [m], drawn from [min, max].")
    region: tuple[tuple[float, float], tuple[float, float]] = Field(
        default=((0.25, -0.4), (0.75, 0.4)), description="Rectangle [m] of the table, [[x0, y0], [x1, y1]] in the "
                                                         "world, that holds every piece's footprint.")
    keep_out: float = Field(default=0.05, ge=0, le=0.5, description="Least distance [m] of a piece's footprint "
                                                                    "from every object, target and push corridor.")
    corridor: bool = Field(default=True, description="Keep out of the straight corridor between each free object "
                                                     "and its NAME_target marker too (a push's path).")

    @model_validator(mode="after")
    def _ranges(self) -> ClutterDecl:
        for key, (lo, hi), top in (("size", self.size, 0.3), ("height", self.height, 1.0)):
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi <= top):
                raise ValueError(f"{key}: [{lo}, {hi}] must be finite, 0 < min <= max <= {top}")
        (x0, y0), (x1, y1) = self.region
        if not all(math.isfinite(v) for v in (x0, y0, x1, y1)) or not (x0 < x1 and y0 < y1):
            raise ValueError(f"region: [[{x0}, {y0}], [{x1}, {y1}]] must be finite with x0 < x1 and y0 < y1")
        return self


def _footprints(spec: mujoco.MjSpec, keep_clear: Sequence[str] = (), placed_later: Sequence[str] = ()
                ) -> tuple[list[tuple[np.ndarray, float]], list[tuple[np.ndarray, np.ndarray]]]:
    """Free objects, markers and the ``keep_clear`` bodies as (centre, radius), and the (object, target) corridors.

    Markers in ``placed_later`` (a free spot, chosen among the clutter) count for neither.
    """
    free = mujoco.mjtJoint.mjJNT_FREE
    circles: list[tuple[np.ndarray, float]] = []
    centres: dict[str, tuple[np.ndarray, float]] = {}
    for body in spec.worldbody.bodies:
        if not body.name:
            continue
        is_free = any(j.type == free for j in body.joints)
        if not is_free and not body.name.endswith("_target") and body.name not in keep_clear:
            continue
        if body.name in placed_later:
            continue
        radius = 0.0
        for g in [g for g in body.geoms if not (g.type == mujoco.mjtGeom.mjGEOM_BOX and g.size[2] < 0.005)]:  # pads
            xy = float(np.hypot(g.pos[0], g.pos[1]))
            size = g.size
            extent = float(np.hypot(size[0], size[1])) if g.type == mujoco.mjtGeom.mjGEOM_BOX else float(size[0])
            radius = max(radius, xy + extent)
        c = (np.array(body.pos[:2], dtype=float), max(radius, 0.02))
        circles.append(c)
        centres[body.name] = c
    corridors = [(centres[n][0], centres[f"{n}_target"][0]) for n in centres
                 if f"{n}_target" in centres and not n.endswith("_target")]
    return circles, corridors


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = float(np.clip((p - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def add_clutter(spec: mujoco.MjSpec, clutter: ClutterDecl, table_top: float, source: str = "scene",
                avoid: Sequence[tuple[float, float, float]] = (), keep_clear: Sequence[str] = (),
                placed_later: Sequence[str] = ()) -> list[str]:
    """Stand the clutter on the table of a composed scene spec, in place; returns the bodies' names.

    ``avoid``: further circles (x, y, radius [m]) to keep ``keep_out`` from (the robot's start posture);
    ``keep_clear``: static bodies kept clear of like the objects (declared fixed objects); ``placed_later``: targets
    placed after the clutter, where their objects fit among it (a free spot): not kept clear of.

    Raises:
        ConfigError: The region cannot hold ``count`` pieces clear of the objects, targets and corridors.
    """
    if clutter.count == 0:
        return []
    rng = np.random.default_rng(clutter.seed or 0)
    circles, corridors = _footprints(spec, keep_clear, placed_later)
    circles += [(np.array([x, y]), r) for x, y, r in avoid]
    (x0, y0), (x1, y1) = clutter.region
    placed: list[tuple[np.ndarray, float]] = []
    names = []
    for i in range(clutter.count):
        for _ in range(TRIES):
            shape = clutter.shapes[int(rng.integers(len(clutter.shapes)))]
            half = float(rng.uniform(*clutter.size))
            height = float(rng.uniform(*clutter.height))
            yaw = float(rng.uniform(-math.pi, math.pi))
            radius = half * math.sqrt(2.0) if shape == "box" else half
            if x1 - x0 < 2 * radius or y1 - y0 < 2 * radius:
                continue
            centre = np.array([rng.uniform(x0 + radius, x1 - radius), rng.uniform(y0 + radius, y1 - radius)])
            if any(np.linalg.norm(centre - c) < radius + r + clutter.keep_out for c, r in circles):
                continue
            if clutter.corridor and any(_segment_distance(centre, a, b) < radius + clutter.keep_out + w
                                        for (a, b), w in zip(corridors, (_corridor_width(circles, a) for a, _ in
                                                                          corridors), strict=True)):
                continue
            if any(np.linalg.norm(centre - c) < radius + r + GAP for c, r in placed):
                continue
            break
        else:
            raise ConfigError(f"{source}: scene.clutter: placed {i} of {clutter.count} pieces; region "
                              f"{[list(clutter.region[0]), list(clutter.region[1])]} holds no more clear of the "
                              f"objects, targets and corridors (keep_out {clutter.keep_out:g} m): enlarge the region, "
                              "or lower count, size or keep_out")
        name = f"{PREFIX}{i}"
        body = spec.worldbody.add_body(name=name, pos=[float(centre[0]), float(centre[1]), table_top + height / 2],
                                       quat=[math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
        geom = body.add_geom(name=name, rgba=list(RGBA))
        if shape == "box":
            geom.type = mujoco.mjtGeom.mjGEOM_BOX
            geom.size = [half, half, height / 2]
        else:
            geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
            geom.size = [half, height / 2, 0.0]
        placed.append((centre, radius))
        names.append(name)
    return names


def _corridor_width(circles: list[tuple[np.ndarray, float]], start: np.ndarray) -> float:
    """Half-width of a push corridor: the radius of the object at its start."""
    return next((r for c, r in circles if np.allclose(c, start)), 0.0)
