"""Limits for the IK QP that send the solver only what matters: a joint box and active collision rows.

Both subclass :class:`mink.Limit`, so they also work with plain :func:`mink.solve_ik`.

* :class:`JointBoxLimit` merges mink's ``ConfigurationLimit`` and ``VelocityLimit`` into one box
  (15 bounds instead of 60 rows), which :class:`~nextage_qp.ik.qp.QPIK` passes as ``lb``/``ub``.
* :class:`ActiveCollisionLimit` is mink's ``CollisionAvoidanceLimit`` with per-pair distances, a
  vectorised bounding-sphere broadphase, a distance cache between ticks, and one row per pair that can
  bind: closer than its detection distance *and* (given a joint box) able to close its gap within one
  step of the box. A row that cannot bind does not change the QP's solution, so dropping it is exact.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import mink
import mujoco
import numpy as np
from mink.limits.collision_avoidance_limit import (
    _are_geom_bodies_parent_child,
    _is_pass_contype_conaffinity_check,
    _is_welded_together,
    compute_contact_normal_jacobian,
)
from mink.limits.limit import Constraint


class JointBoxLimit(mink.Limit):
    r"""Joint position and velocity limits as one box on the step :math:`\Delta q` [rad].

    .. math::

        \max(-g (q - q_{min}), -v_{max} dt) \le \Delta q \le \min(g (q_{max} - q), v_{max} dt)

    with limit gain :math:`g` and speed limit :math:`v_{max}` [rad/s] (``inf`` where unlimited).
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray, vmax: np.ndarray, gain: float = 0.95) -> None:
        self.lower, self.upper, self.vmax, self.gain = lower, upper, vmax, gain
        n = len(lower)
        self._G = np.vstack([np.eye(n), -np.eye(n)])

    def bounds(self, q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        r"""``(lb, ub)`` of :math:`\Delta q` at configuration ``q`` for a step of ``dt`` [s]."""
        step = self.vmax * dt
        lb = np.maximum(-self.gain * (q - self.lower), -step)
        ub = np.minimum(self.gain * (self.upper - q), step)
        return lb, ub

    def violated(self, q: np.ndarray, lb: np.ndarray, ub: np.ndarray, names: Sequence[str]) -> list[str]:
        """One line per joint whose step bounds ``(lb, ub)`` exclude zero or cross (named by ``names``)."""
        return [
            f"joint {names[int(i)]} at {q[i]:.4f} rad outside [{self.lower[i]:.4f}, {self.upper[i]:.4f}]"
            f" with step bound {self.vmax[i]:.3g} rad/s"
            for i in np.flatnonzero((lb > 0) | (ub < 0) | (lb > ub))
        ]

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> Constraint:
        """The box as rows ``[I; -I] dq <= [ub; -lb]`` (for use with plain mink)."""
        lb, ub = self.bounds(configuration.q, dt)
        return Constraint(G=self._G, h=np.concatenate([ub, -lb]))


class ActiveCollisionLimit(mink.Limit):
    r"""Keep geom pairs apart, emitting one QP row per pair closer than its detection distance.

    For an active pair at distance :math:`d` [m] with contact normal :math:`n` and witness-point Jacobians
    :math:`J_1, J_2`, the row is (mink's formulation)

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
                    and not _are_geom_bodies_parent_child(model, a, b)
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
        rbound = model.geom_rbound
        # A plane has rbound 0 (unbounded): never filter it out.
        unbounded = (rbound[self.geom1] == 0) | (rbound[self.geom2] == 0)
        self._reach = np.where(unbounded, np.inf, rbound[self.geom1] + rbound[self.geom2] + self.detection_distance)
        # Distance cache reused between ticks: pairs are queried up to detection + margin; a pair whose cached
        # distance minus how far either geom can have moved since (centre shift + rbound * rotation chord)
        # still exceeds its detection distance needs no narrow-phase query.
        self.margin = 0.05
        n = len(keys)
        self._rb1, self._rb2 = rbound[self.geom1], rbound[self.geom2]
        self._cached = np.full(n, -np.inf)
        self._bounded = ~unbounded
        self._ref_p1, self._ref_p2 = np.zeros((n, 3)), np.zeros((n, 3))
        self._ref_r1, self._ref_r2 = np.zeros((n, 9)), np.zeros((n, 9))
        self._fromto, self._normal = np.empty(6), np.empty(3)
        self._jac1, self._jac2 = np.empty((3, model.nv)), np.empty((3, model.nv))
        self.active: list[tuple[int, float]] = []
        """(pair index, distance [m]) of the pairs sent to the QP at the last call."""
        self.slack = 0
        """Pairs within detection distance at the last call that could not bind within the box (no row)."""
        # Reach bound: a point of geom g moves at most sum_j |dq_j| (|x_g - anchor_j| + rbound_g) over the
        # hinge dofs j of its chain (any other dof kind: unbounded, never pruned).
        self._geoms = np.unique(np.concatenate([self.geom1, self.geom2]))
        chain = np.zeros((len(self._geoms), model.nv))
        for row, g in enumerate(self._geoms):
            body = int(model.geom_bodyid[g])
            while body > 0:
                for dof in range(model.body_dofadr[body], model.body_dofadr[body] + model.body_dofnum[body]):
                    hinge = model.jnt_type[model.dof_jntid[dof]] == mujoco.mjtJoint.mjJNT_HINGE
                    chain[row, dof] = 1.0 if hinge else np.inf
                body = int(model.body_parentid[body])
        self._chain, self._dof_jnt = chain, model.dof_jntid.copy()
        self._approach = np.zeros(model.ngeom)

    @property
    def num_pairs(self) -> int:
        """Number of geom pairs watched."""
        return len(self.geom1)

    def candidates(self, data: mujoco.MjData) -> np.ndarray:
        """Indices of the pairs whose bounding spheres are within detection distance (broadphase)."""
        delta = data.geom_xpos[self.geom1] - data.geom_xpos[self.geom2]
        centre_sq = np.einsum("ij,ij->i", delta, delta)
        return np.flatnonzero(centre_sq < self._reach**2)

    def _stale(self, data: mujoco.MjData, idx: np.ndarray) -> np.ndarray:
        """Candidates whose cached distance no longer proves them beyond detection distance."""
        if idx.size == 0:
            return idx
        g1, g2 = self.geom1[idx], self.geom2[idx]
        move = (
            np.linalg.norm(data.geom_xpos[g1] - self._ref_p1[idx], axis=1)
            + np.linalg.norm(data.geom_xpos[g2] - self._ref_p2[idx], axis=1)
            + self._rb1[idx] * np.linalg.norm(data.geom_xmat[g1] - self._ref_r1[idx], axis=1) / np.sqrt(2.0)
            + self._rb2[idx] * np.linalg.norm(data.geom_xmat[g2] - self._ref_r2[idx], axis=1) / np.sqrt(2.0)
        )
        proven_far = self._bounded[idx] & (self._cached[idx] - move >= self.detection_distance[idx])
        return idx[~proven_far]

    def distances(self, data: mujoco.MjData, indices: Sequence[int] | np.ndarray) -> np.ndarray:
        """Signed distances [m] of the given pairs, capped at their detection distance."""
        out = np.empty(len(indices))
        for k, idx in enumerate(indices):
            dmax = float(self.detection_distance[idx])
            out[k] = mujoco.mj_geomDistance(self.model, data, int(self.geom1[idx]), int(self.geom2[idx]), dmax, None)
        return out

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> Constraint:
        """Rows of the active pairs only; an inactive constraint when no pair is within detection distance."""
        model, data, fromto = self.model, configuration.data, self._fromto
        rows: list[np.ndarray] = []
        bounds: list[float] = []
        self.active, self.slack = [], 0
        need = self._stale(data, self.candidates(data))
        approach = self._max_approach(configuration, dt) if self.box is not None and need.size else None
        for idx in need:
            g1, g2 = int(self.geom1[idx]), int(self.geom2[idx])
            dmax = float(self.detection_distance[idx])
            dist = mujoco.mj_geomDistance(model, data, g1, g2, dmax + self.margin, fromto)
            self._cached[idx] = dist
            if dist >= dmax:
                continue
            bound = self.gain * max(dist - float(self.min_distance[idx]), 0.0)
            if approach is not None and bound > approach[g1] + approach[g2]:
                self.slack += 1
                continue
            row = compute_contact_normal_jacobian(model, data, g1, g2, fromto, self._normal, self._jac1, self._jac2)
            rows.append(-row if dist >= 0 else row)
            bounds.append(bound)
            self.active.append((int(idx), dist))
        self._ref_p1[need], self._ref_p2[need] = data.geom_xpos[self.geom1[need]], data.geom_xpos[self.geom2[need]]
        self._ref_r1[need], self._ref_r2[need] = data.geom_xmat[self.geom1[need]], data.geom_xmat[self.geom2[need]]
        if not rows:
            return Constraint()
        return Constraint(G=np.vstack(rows), h=np.array(bounds))

    def _max_approach(self, configuration: mink.Configuration, dt: float) -> np.ndarray:
        """Per geom id: how far [m] any point of the geom can move in one step inside the joint box."""
        assert self.box is not None
        lb, ub = self.box.bounds(configuration.q, dt)
        step = np.maximum(np.abs(lb), np.abs(ub))
        data = configuration.data
        rel = data.geom_xpos[self._geoms][:, None, :] - data.xanchor[self._dof_jnt][None, :, :]
        lever = np.linalg.norm(rel, axis=2) + self.model.geom_rbound[self._geoms][:, None]
        with np.errstate(invalid="ignore"):
            reach = np.where(self._chain > 0, self._chain * lever, 0.0)
        self._approach[self._geoms] = reach @ step
        return self._approach

    def violated(self, model: mujoco.MjModel) -> list[str]:
        """One line per pair at or below its minimum distance at the last call."""
        return [
            f"collision pair {self.pair_name(model, idx)} at {dist * 1000:.1f} mm"
            for idx, dist in self.active
            if dist <= self.min_distance[idx]
        ]

    def pair_name(self, model: mujoco.MjModel, idx: int) -> str:
        """Readable name of a pair: geom (or body) names of both sides."""

        def name(g: int) -> str:
            return model.geom(g).name or f"{model.body(int(model.geom_bodyid[g])).name}/geom{g}"

        return f"{name(int(self.geom1[idx]))}<->{name(int(self.geom2[idx]))}"
