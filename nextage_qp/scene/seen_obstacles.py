"""Obstacles the controller knows only from its cameras (``perception.obstacles: camera``): a pool of box geoms.

The composed scene gets :data:`POOL` box geoms (each alone in a body ``seen_k`` under the body :data:`BODY`; a body
of one geom has no bounding-volume tree to go stale when it moves), parked far below the floor and colliding with
nothing, so the physics never meets them. The controller (its IK, planner and geometry queries) works on copies of
the model made by :func:`blind`: in those every generated clutter geom (``clutter_*``) is parked below the floor and
collides with nothing, so nothing the controller computes depends on the clutter's pose or shape, and the pool's geoms
collide as the clutter's would, forming the ``clutter`` collision group in its place. :class:`SeenBoxes` holds the
boxes the camera's occupancy map gives and writes them into the pool of every such copy (:meth:`SeenBoxes.sync`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

POOL = 48
"""Box geoms in the pool: the most obstacle boxes the controller keeps (the largest, when the map has more)."""
BODY = "seen_obstacles"
"""The pool's body (a child of the world, at its origin)."""
PREFIX = "seen_"
"""The pool geoms' name prefix."""
PARK = np.array([0.0, 0.0, -10.0])
"""Where an unused pool geom, or a blinded clutter geom, is [m] (relative to its body: far below the floor)."""
IDLE = 0.005
"""Half-size of an unused pool geom [m]."""
MAX_HALF = 0.6
"""Largest half-size of a box [m]; a pool geom's bounding radius is fixed at that box's (an upper bound for any)."""
CLUTTER = "clutter_"
"""The generated clutter's body prefix (:mod:`nextage_qp.scene.clutter`)."""


def add_pool(spec: mujoco.MjSpec, count: int = POOL) -> None:
    """Add the pool of ``count`` parked, non-colliding, transparent box geoms to a composed scene spec, in place."""
    pool = spec.worldbody.add_body(name=BODY)
    for k in range(count):
        body = pool.add_body(name=f"{PREFIX}{k}", pos=list(PARK))
        body.add_geom(name=f"{PREFIX}{k}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[IDLE] * 3, contype=0,
                      conaffinity=0, rgba=[0.0, 0.0, 0.0, 0.0], mass=0.0, density=0.0)


def pool_geoms(model: mujoco.MjModel) -> np.ndarray:
    """The pool's geom ids, one per body, in the bodies' order (empty when the scene has none)."""
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, BODY)
    if bid < 0:
        return np.zeros(0, dtype=int)
    bodies = np.flatnonzero(model.body_parentid == bid)
    return np.array([int(model.body_geomadr[b]) for b in bodies], dtype=int)


def clutter_geoms(model: mujoco.MjModel) -> np.ndarray:
    """The generated clutter's geom ids."""
    bodies = [b for b in range(model.nbody) if model.body(b).name.startswith(CLUTTER)]
    return np.flatnonzero(np.isin(model.geom_bodyid, bodies))


def blind(model: mujoco.MjModel) -> None:
    """Make ``model`` (a controller's copy) blind to the clutter and aware of the pool, in place (see the module doc).

    The pool's geoms take the contact bits the clutter had (1, 1 where there was none).
    """
    clutter, pool = clutter_geoms(model), pool_geoms(model)
    contype = int(model.geom_contype[clutter].max()) if len(clutter) else 1
    conaffinity = int(model.geom_conaffinity[clutter].max()) if len(clutter) else 1
    model.geom_contype[clutter] = 0
    model.geom_conaffinity[clutter] = 0
    model.geom_pos[clutter] = PARK
    model.geom_size[clutter] = IDLE
    model.geom_rbound[clutter] = IDLE * np.sqrt(3.0)
    model.geom_aabb[clutter] = [0.0, 0.0, 0.0, IDLE, IDLE, IDLE]
    model.body_contype[model.geom_bodyid[clutter]] = 0
    model.body_conaffinity[model.geom_bodyid[clutter]] = 0
    model.geom_contype[pool] = contype or 1
    model.geom_conaffinity[pool] = conaffinity or 1
    model.body_contype[model.geom_bodyid[pool]] = contype or 1  # the broadphase filters bodies by these
    model.body_conaffinity[model.geom_bodyid[pool]] = conaffinity or 1
    model.geom_rbound[pool] = MAX_HALF * np.sqrt(3.0)


class SeenBoxes:
    """The camera's obstacle boxes (centre [m], half-sizes [m], yaw about the vertical [rad]) for blinded models.

    Each :meth:`set` that changes the boxes starts a new generation; :meth:`sync` writes the current one into a model
    that does not have it yet.
    """

    def __init__(self) -> None:
        self.boxes: list[tuple[np.ndarray, np.ndarray, float]] = []
        self.generation = 0
        self.dropped = 0
        """Boxes beyond the pool's size left out at the last :meth:`set` (the smallest)."""
        self._synced: dict[int, tuple[mujoco.MjModel, int]] = {}

    def set(self, boxes: Sequence[tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, float]],
            unseen: Sequence[tuple[np.ndarray, np.ndarray, float]] = ()) -> bool:
        """Take new boxes (centre, half-sizes, optional yaw [rad]); True if they changed.

        ``boxes`` are what the camera saw, ``unseen`` the space it never saw; of each the largest first, the seen
        before the unseen, :data:`POOL` in all. Each half-size is at most :data:`MAX_HALF`.
        """
        def largest(group: Sequence[Any]) -> list[tuple[np.ndarray, np.ndarray, float]]:
            return sorted(((np.asarray(b[0], dtype=float), np.minimum(np.asarray(b[1], dtype=float), MAX_HALF),
                            float(b[2]) if len(b) > 2 else 0.0) for b in group), key=lambda b: -float(np.prod(b[1])))

        kept = largest(boxes) + largest(unseen)
        self.dropped = max(len(kept) - POOL, 0)
        kept = kept[:POOL]
        same = len(kept) == len(self.boxes) and all(
            np.array_equal(c, c0) and np.array_equal(h, h0) and y == y0
            for (c, h, y), (c0, h0, y0) in zip(kept, self.boxes, strict=True))
        if same:
            return False
        self.boxes = kept
        self.generation += 1
        return True

    def sync(self, model: mujoco.MjModel) -> bool:
        """Write the boxes into ``model``'s pool unless it has them already; True when it wrote."""
        key = id(model)
        held = self._synced.get(key)
        if held is not None and held[0] is model and held[1] == self.generation:
            return False
        pool = pool_geoms(model)
        for k, g in enumerate(pool):
            if k < len(self.boxes):
                centre, half, yaw = self.boxes[k]
            else:
                centre, half, yaw = PARK, np.full(3, IDLE), 0.0
            body = int(model.geom_bodyid[g])
            model.body_pos[body] = centre
            model.body_quat[body] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
            model.geom_size[g] = half
            model.geom_aabb[g] = [0.0, 0.0, 0.0, *half]
            if model.body_bvhnum[body]:
                model.bvh_aabb[model.body_bvhadr[body]] = [0.0, 0.0, 0.0, *half]
        self._synced[key] = (model, self.generation)
        return True
