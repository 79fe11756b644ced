"""Collision avoidance rows for the IK QP, sending the solver only the pairs that can bind.

:class:`ActiveCollisionLimit` is mink's ``CollisionAvoidanceLimit`` with per-pair distances and three filters
in front of the narrow phase, each exact (a filtered pair could not have produced an active row):

1. **Travel bound** and 2. **bounding spheres** (:class:`~nextage_qp.ik.broadphase.PairBounds`): a pair whose
   distance bound exceeds its detection distance is skipped with a few vectorised operations.
3. **Reach bound.** With the joint box of the same QP, a pair within detection distance whose gap bound
   exceeds how far its two geoms can approach in one step of the box gets no row: it could never bind.

The offline solver's collision-safe step on the same bounds is :func:`nextage_qp.ik.safe_step.advance`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import mink
import mujoco
import numpy as np
from mink.limits.collision_avoidance_limit import (
    _is_pass_contype_conaffinity_check,
    _is_welded_together,
)
from mink.limits.limit import Constraint

from nextage_qp.ik.broadphase import PairBounds
from nextage_qp.ik.kinematic_model import lever_bounds, moved_by_a_joint
from nextage_qp.ik.limits import JointBoxLimit
from nextage_qp.native import kernels


def parent_and_child(model: mujoco.MjModel, a: int, b: int) -> bool:
    """Whether geoms ``a`` and ``b`` are on a parent and its child (each body taken with what is welded to it).

    mink's test (``_are_geom_bodies_parent_child``), except that the world is no one's parent here: a body moving on
    its own joints from the world (a mobile base, a shoulder on a mount fixed in the world) and a body welded to the
    world (a crate, the table) are not a parent and its child, and a collision pair keeps them apart.
    """
    weld = model.body_weldid
    wa, wb = int(weld[model.geom_bodyid[a]]), int(weld[model.geom_bodyid[b]])
    pa, pb = int(weld[model.body_parentid[wa]]), int(weld[model.body_parentid[wb]])
    return (wa == pb and wa != 0) or (wb == pa and wb != 0)


def apart_at(model: mujoco.MjModel, qpos: np.ndarray, geoms_a: Sequence[int], geoms_b: Sequence[int],
             min_distance: float) -> list[tuple[int, int]]:
    """The geom pairs of two groups that a collision pair can keep ``min_distance`` [m] apart, judged at ``qpos``.

    Each pair once, on two bodies that are neither the same nor parent and child. A pair of the robot's own geoms (or
    of the robot and the static scene) nearer than ``min_distance`` at ``qpos`` (the robot's home) is left out: it
    touches where the links join or where the robot stands, and no row could keep it apart. A pair with an object
    (a mocap body of the IK model: it moves) is always kept.
    """
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    body, mocap = model.geom_bodyid, model.body_mocapid
    out = set()
    for a, b in itertools.product(sorted(set(geoms_a)), sorted(set(geoms_b))):
        a, b = min(a, b), max(a, b)
        if body[a] == body[b] or (a, b) in out or parent_and_child(model, a, b):
            continue
        if mocap[body[a]] >= 0 or mocap[body[b]] >= 0 or \
                mujoco.mj_geomDistance(model, data, a, b, min_distance + 0.01, None) >= min_distance:
            out.add((a, b))
    return sorted(out)


class ActiveCollisionLimit(mink.Limit):
    r"""Keep geom pairs apart, emitting one QP row per pair that is within detection distance and can bind.

    For an active pair at distance :math:`d` [m] with contact normal :math:`n` and witness-point Jacobians
    :math:`J_1, J_2`, the row is

    .. math::

        -n^T (J_2 - J_1) \Delta q \le g\,\max(d - d_{min}, 0)

    with collision gain :math:`g`, so the gap closes by at most a fraction ``g`` of its excess per step.

    Args:
        model: Kinematic model.
        group_pairs: ``(geoms_a, geoms_b, min_distance [m], detection_distance [m])`` per group pair.
        gain: Collision gain in (0, 1].
        box: The joint box of the same QP. With it, a pair whose gap bound exceeds how far its two geoms
            can approach each other within one step of the box gets no row (it could never bind).
    """

    margin = 0.05
    """Narrow-phase queries look this far [m] beyond the detection distance, so the bound lasts longer."""

    def __init__(
        self,
        model: mujoco.MjModel,
        group_pairs: Sequence[tuple[Sequence[int], Sequence[int], float, float]],
        gain: float,
        box: JointBoxLimit | None = None,
    ) -> None:
        self.model, self.gain, self.box = model, gain, box
        pairs: dict[tuple[int, int], tuple[float, float]] = {}
        for geoms_a, geoms_b, dmin, ddet in group_pairs:
            for a, b in itertools.product(set(geoms_a), set(geoms_b)):
                if (
                    a != b
                    and not _is_welded_together(model, a, b)
                    and not parent_and_child(model, a, b)
                    and _is_pass_contype_conaffinity_check(model, a, b)
                ):
                    key = (min(a, b), max(a, b))
                    old = pairs.get(key, (0.0, 0.0))
                    pairs[key] = (max(old[0], dmin), max(old[1], ddet))
        keys = sorted(pairs)
        self.geom1 = np.array([k[0] for k in keys], dtype=int)
        self.geom2 = np.array([k[1] for k in keys], dtype=int)
        self.min_distance = np.array([pairs[k][0] for k in keys])
        self.detection_distance = np.array([pairs[k][1] for k in keys])
        self.bounds = PairBounds(model, self.geom1, self.geom2)
        """The pairs' distance lower bounds (travel and bounding spheres)."""
        # Per pair, how far each dof's step can bring its two geoms together [m per rad]: the lever arms of both
        # geoms, but 0 for a dof that moves both (a motion of both alike keeps their distance; its column of the
        # row, n^T (J2 - J1) = n^T (w x (p2 - p1)), is exactly 0 as p2 - p1 is along n).
        lever = lever_bounds(model)
        shared = (lever[self.geom1] > 0) & (lever[self.geom2] > 0)
        self._pair_lever = np.where(shared, 0.0, lever[self.geom1] + lever[self.geom2])
        self._lever_inf = bool(np.isinf(self._pair_lever).any())
        self._lists = (self.geom1.tolist(), self.geom2.tolist(), self.detection_distance.tolist(),
                       self.min_distance.tolist())
        # Per pair, its last narrow-phase measurement: distance [m] and witness points (from, to), with views of
        # them made once; valid while the pair's bound is exact (PairBounds.exact).
        self._kept = np.empty((len(keys), 7))
        self._kept_fromto = list(self._kept[:, 1:])
        self._kept_points = [(w[:3], w[3:]) for w in self._kept_fromto]
        # Body of each geom, or -1 where no joint moves it (welded to the world, or a mocap object): its witness
        # point has a zero Jacobian, so that side of a row costs nothing.
        self._body = [int(b) if moved_by_a_joint(model, int(b)) else -1 for b in model.geom_bodyid]
        # Per active pair of one call: the point Jacobians of its two witness points (geom2's, then geom1's).
        self._jacs = np.zeros((len(keys), 2, 3, model.nv))
        self._jac_slots = [(j[0], j[1]) for j in self._jacs]  # views made once
        self._zero1 = np.ones(len(keys), dtype=bool)  # per slot: geom1's Jacobian is zeros
        self._model_at, self._body_at = model._address, np.array(self._body, dtype=np.int64)
        self._dists = np.empty(len(keys))  # per near pair of one call: its distance [m]
        self._out = (np.empty(len(keys), dtype=np.int64), np.empty(len(keys)), np.empty(len(keys)))  # rows' pairs,
        # distances and bounds of a compiled call
        self.enabled = np.ones(len(keys), dtype=bool)
        """Pairs watched at the next call (see :meth:`allow`)."""
        self._watch_within = self.detection_distance.copy()
        self._allowed_geoms: np.ndarray | None = None
        self.active: list[tuple[int, float]] = []
        """(pair index, distance [m]) of the pairs sent to the QP at the last call."""
        self._active_pairs: list[int] = []  # the same pairs' indices
        self.queries = 0
        """Narrow-phase distance queries made at the last call."""
        self.slack = 0
        """Pairs not ruled out by the travel and sphere bounds that could not bind within the box (no row)."""
        kernels.warm_up(model.nv, box is not None)

    def forget(self) -> None:
        """Measure every pair anew: the model's obstacle geometry changed in place (:meth:`PairBounds.forget`)."""
        self.bounds.forget()

    def allow(self, geoms: np.ndarray) -> None:
        """Let the given geoms touch: pairs with a geom in ``geoms`` (a boolean mask over geoms) get no row.

        The mask is taken as read-only: passing the same array object again keeps the pairs as they are.
        """
        if geoms is self._allowed_geoms:
            return
        self._allowed_geoms = geoms
        self.enabled = ~(geoms[self.geom1] | geoms[self.geom2])
        self._watch_within = np.where(self.enabled, self.detection_distance, -np.inf)  # no pair allowed is near

    @property
    def num_pairs(self) -> int:
        """Number of geom pairs watched."""
        return len(self.geom1)

    def distances(self, data: mujoco.MjData, indices: Sequence[int] | np.ndarray) -> np.ndarray:
        """Signed distances [m] of the given pairs, capped at their detection distance."""
        geom1, geom2, detect, _ = self._lists
        model, distance = self.model, mujoco.mj_geomDistance
        idx = indices.tolist() if isinstance(indices, np.ndarray) else indices
        return np.array([distance(model, data, geom1[i], geom2[i], detect[i], None) for i in idx], dtype=float)

    def measure(self, data: mujoco.MjData, pairs: np.ndarray) -> np.ndarray:
        """Distances [m] of ``pairs`` as the rows' narrow phase measures them, kept with their witness points.

        :meth:`compute_qp_inequalities` takes a kept measurement instead of measuring again while the pair's bound
        is exact (nothing moved since; the caller marks it with ``bounds.remember(..., exact=True)``).
        """
        geom1, geom2, detect, _ = self._lists
        model, distance, margin, kept, fromto = self.model, mujoco.mj_geomDistance, self.margin, self._kept, \
            self._kept_fromto
        for i in pairs.tolist():
            kept[i, 0] = distance(model, data, geom1[i], geom2[i], detect[i] + margin, fromto[i])
        return kept[pairs, 0]

    def clear(self, data: mujoco.MjData) -> bool:
        """Whether every watched pair is at or above its minimum distance at ``data``'s configuration.

        Only pairs whose distance bound (:attr:`bounds`) is below their minimum are measured; the measurements are
        kept for the next call's rows.
        """
        lower = self.bounds.lower(data)
        check = ((lower < self.min_distance) & self.enabled).nonzero()[0]
        dists = self.measure(data, check)
        self.bounds.remember(check, dists, exact=True)
        return bool((dists >= self.min_distance.take(check) - 1e-6).all())

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> Constraint:
        """Rows of the pairs that can bind only; an inactive constraint when there are none."""
        data = configuration.data
        # Reach bound: how far the two geoms can approach in one step of the box (each joint at most its speed
        # limit times dt); a pair whose gap bound exceeds it cannot bind. Checked on the distance's lower bound
        # first (no narrow phase), then on it.
        step = self.box.step_bound(dt) if self.box is not None else None
        near, _, reach, self.slack = self.bounds.near_reach(data, self._watch_within, self._pair_lever, step,
                                                             self.gain, self.min_distance)
        self.queries = len(near)
        if kernels.NATIVE:  # the loop below, compiled
            k, slack = kernels.narrow_rows(
                kernels.GEOM_DISTANCE, kernels.JAC, self._model_at, data._address, near, reach, step is not None,
                self.geom1, self.geom2, self.detection_distance, self.min_distance, self.bounds.exact, self._kept,
                self._body_at, self.gain, self.margin, self._jacs, self._zero1, self._dists, *self._out)
            pairs, h = self._out[0][:k].tolist(), self._out[2][:k].copy()
            self.active, self.slack = list(zip(pairs, self._out[1][:k].tolist(), strict=True)), self.slack + slack
        else:
            pairs, h = self._narrow(data, near.tolist(), reach.tolist() if step is not None else None)
        self._active_pairs = pairs
        self.bounds.remember(near, self._dists[: len(near)], exact=True)
        if not pairs:
            return Constraint()
        return Constraint(G=self._rows(len(pairs)), h=h)

    def _narrow(self, data: mujoco.MjData, near: list[int], reach: list[float] | None) -> tuple[list[int], np.ndarray]:
        """The narrow phase of the ``near`` pairs and their witness points' Jacobians: the rows' pairs and bounds."""
        model, bounds, pairs = self.model, list[float](), list[int]()
        self.active = []
        geom1, geom2, detect, minimum = self._lists
        gain, margin, distance = self.gain, self.margin, mujoco.mj_geomDistance
        dists = self._dists
        body, jacs, jac, zero1 = self._body, self._jac_slots, mujoco.mj_jac, self._zero1
        exact, kept, kept_fromto, points = self.bounds.exact, self._kept, self._kept_fromto, self._kept_points
        for k, idx in enumerate(near):
            g1, g2, dmax = geom1[idx], geom2[idx], detect[idx]
            if exact[idx]:  # measured here already (by the collision-safe step that led here, or a call here)
                dist = float(kept[idx, 0])
            else:
                dist = distance(model, data, g1, g2, dmax + margin, kept_fromto[idx])
                kept[idx, 0] = dist
            dists[k] = dist
            if dist >= dmax:
                continue
            gap = dist - minimum[idx]
            bound = gain * gap if gap > 0.0 else 0.0
            if reach is not None and bound > reach[k]:
                self.slack += 1
                continue
            # The witness points' Jacobians (zero on a side no joint moves): geom2's ("to"), then geom1's ("from").
            slot = len(bounds)
            jac2, jac1 = jacs[slot]
            start, end = points[idx]
            b1, b2 = body[g1], body[g2]
            if b2 >= 0:
                jac(model, data, jac2, None, end, b2)
            else:
                jac2.fill(0.0)
            if b1 >= 0:
                jac(model, data, jac1, None, start, b1)
                zero1[slot] = False
            elif not zero1[slot]:  # a side no joint moves: zeros (the slot keeps them until a moving side writes it)
                jac1.fill(0.0)
                zero1[slot] = True
            bounds.append(bound)
            self.active.append((idx, dist))
            pairs.append(idx)
        return pairs, np.array(bounds)

    def _rows(self, k: int) -> np.ndarray:
        r"""The rows :math:`s\,n^T (J_2(p_2) - J_1(p_1))` of the ``k`` pairs in :attr:`active`, in one product.

        As mink's ``compute_contact_normal_jacobian``: :math:`n` the unit vector from witness point :math:`p_1`
        to :math:`p_2`, :math:`s = -1` (sign flipped, :math:`+1`, for a penetrating pair).
        """
        kept = self._kept.take(self._active_pairs, axis=0)  # per row: distance, from, to
        normal = kept[:, 4:] - kept[:, 1:4]
        normal *= (np.copysign(1.0, -kept[:, 0]) / np.sqrt(np.vecdot(normal, normal)))[:, None]  # s n
        jacs = self._jacs[:k]
        return np.matmul(normal[:, None, :], jacs[:, 0] - jacs[:, 1])[:, 0]

    def violated(self, model: mujoco.MjModel, slack: float = 0.0) -> list[str]:
        """One line per pair at or below its minimum distance (plus ``slack`` [m]) at the last call."""
        return [
            f"collision pair {self.pair_name(model, idx)} at {dist * 1e3:.1f} mm (min {self.min_distance[idx] * 1e3:g})"
            for idx, dist in self.active
            if dist <= self.min_distance[idx] + slack
        ]

    def pair_name(self, model: mujoco.MjModel, idx: int) -> str:
        """Readable name of a pair: geom (or body) names of both sides."""

        def name(g: int) -> str:
            return model.geom(g).name or f"{model.body(int(model.geom_bodyid[g])).name}/geom{g}"

        return f"{name(int(self.geom1[idx]))}<->{name(int(self.geom2[idx]))}"
