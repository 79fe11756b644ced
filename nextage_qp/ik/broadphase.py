r"""Lower bounds on the distances of a fixed list of geom pairs, kept up to date for a few array operations.

Two bounds, both exact (a pair is never closer than its bound):

* **Travel.** Every distance measured is stored; each geom's travel since (centre shift plus bounding radius
  times the rotation chord :math:`\|R - R_0\|_F / \sqrt 2`, summed over the configurations seen) is subtracted
  from it. A pair whose bound stays above what the caller cares about needs no narrow phase.
* **Bounding spheres**: the centres' distance less both bounding radii.

The per-step test of every pair (:meth:`PairBounds.near_reach`) and :meth:`PairBounds.remember` are compiled loops
(:mod:`nextage_qp.native.kernels`); elsewhere gathers use ``take``, several times faster than fancy indexing on arrays
this small.
"""

from __future__ import annotations

import mujoco
import numpy as np

from nextage_qp.native import kernels


class PairBounds:
    """Distance lower bounds [m] of the pairs ``(geom1[i], geom2[i])`` of a model.

    Args:
        model: The model the geoms belong to.
        geom1: First geom of each pair.
        geom2: Second geom of each pair.
    """

    def __init__(self, model: mujoco.MjModel, geom1: np.ndarray, geom2: np.ndarray) -> None:
        self.geom1, self.geom2 = geom1, geom2
        rbound = model.geom_rbound
        # A plane has rbound 0 (unbounded): the sphere test never filters it.
        self._rsum = np.where((rbound[geom1] == 0) | (rbound[geom2] == 0), np.inf, rbound[geom1] + rbound[geom2])
        self._rbound_chord = rbound / np.sqrt(2.0)  # ||R1 - R2||_F / sqrt(2) bounds a unit vector's shift
        # Per geom: cumulative travel [m] and the pose it was last seen at.
        self._travel = np.zeros(model.ngeom)
        self._last_pos = np.full((model.ngeom, 3), np.nan)
        self._last_mat = np.full((model.ngeom, 9), np.nan)
        self._first = True
        # Per pair: the bound last stored plus both geoms' travel at that moment (-inf: none).
        self._base = np.full(len(geom1), -np.inf)
        self._exact, self._exact_any = np.zeros(len(geom1), dtype=bool), False
        n = len(geom1)
        self._out_idx, self._out_lower, self._out_reach = np.empty(n, dtype=np.int64), np.empty(n), np.empty(n)
        self._no_step = np.zeros(0)

    def forget(self) -> None:
        """Drop every stored distance: the model's geometry changed in place (a geom resized, not moved)."""
        self._base[:] = -np.inf
        self._exact[:], self._exact_any = False, False

    @property
    def exact(self) -> np.ndarray:
        """Pairs whose bound is their measured distance at the configuration last seen (no geom moved since)."""
        return self._exact

    def moved(self, data: mujoco.MjData, pos0: np.ndarray, mat0: np.ndarray) -> np.ndarray:
        """How far [m] any point of each geom moved from ``pos0``, ``mat0``: centre shift + radius x chord."""
        dpos, dmat = data.geom_xpos - pos0, data.geom_xmat - mat0
        chord = np.sqrt(np.vecdot(dmat, dmat))
        return np.sqrt(np.vecdot(dpos, dpos)) + self._rbound_chord * chord

    def update(self, data: mujoco.MjData) -> np.ndarray:
        """Add every geom's motion since the configuration last seen to its travel; returns the travel [m]."""
        moved = self.moved(data, self._last_pos, self._last_mat)
        if self._first:  # no pose stored yet (NaN), and no bound to void
            moved[:], self._first = 0.0, False
        if self._exact_any and np.count_nonzero(moved):
            self._exact[:], self._exact_any = False, False
        self._travel += moved
        self._last_pos[:], self._last_mat[:] = data.geom_xpos, data.geom_xmat
        return self._travel

    def sphere_gaps(self, data: mujoco.MjData, pairs: np.ndarray | None = None) -> np.ndarray:
        """Bounding-sphere lower bounds [m] of the given pairs (default: all) now."""
        g1, g2, rsum = self.geom1, self.geom2, self._rsum
        if pairs is not None:
            g1, g2, rsum = g1.take(pairs), g2.take(pairs), rsum.take(pairs)
        pos = data.geom_xpos
        delta = pos.take(g1, axis=0) - pos.take(g2, axis=0)
        return np.sqrt(np.vecdot(delta, delta)) - rsum

    def lower(self, data: mujoco.MjData) -> np.ndarray:
        """Lower bounds [m] of every pair now: the travel bound or the spheres' gap, whichever is larger."""
        travel = self.update(data)
        return np.maximum(self._base - travel.take(self.geom1) - travel.take(self.geom2), self.sphere_gaps(data))

    def near_reach(self, data: mujoco.MjData, within: np.ndarray, lever: np.ndarray, step: np.ndarray | None,
                   gain: float, minimum: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """Pairs whose bound is below ``within`` [m] (per pair) and that can bind within a step of the box.

        Adds every geom's motion to its travel (as :meth:`update`), then tests the travel bound first and the
        spheres after it (compiled: :func:`~nextage_qp.native.kernels.near_pairs`). A pair the spheres rule out is not
        stored (:meth:`remember`): its travel bound stays as it was, and next time the spheres rule it out again if
        they did now (their gap shrinks no faster than the travel grows). Then the reach bound: ``lever`` (pairs,
        nv) is how far each dof's step brings a pair's geoms together [m per rad], ``step`` (nv,) the box's step
        bound [rad] (None: no reach test); a pair with ``gain * (bound - minimum) > lever @ step`` could never bind.

        Returns the pairs left, their bounds, their reach (``lever @ step``) and how many the reach bound dropped
        (arrays overwritten by the next call).
        """
        n, slack, moved = kernels.near_pairs(
            data.geom_xpos, data.geom_xmat, self._last_pos, self._last_mat, self._travel, self._rbound_chord,
            self._first, self._base, self.geom1, self.geom2, self._rsum, within, lever,
            self._no_step if step is None else step, gain, minimum, step is not None, self._out_idx,
            self._out_lower, self._out_reach)
        self._first = False
        if moved and self._exact_any:
            self._exact[:], self._exact_any = False, False
        return self._out_idx[:n], self._out_lower[:n], self._out_reach[:n], slack

    def remember(self, pairs: np.ndarray, lower: np.ndarray, *, exact: bool = False) -> None:
        """Store lower bounds [m] of ``pairs`` at the configuration last seen (``exact``: their distances)."""
        kernels.remember(self._base, self._travel, self.geom1, self.geom2, pairs, lower, self._exact, exact)
        if exact and pairs.size:
            self._exact_any = True
