"""The offline solver's collision-safe step: a step of the joints that never brings a watched pair below its minimum.

The IK QP's collision rows are linear in the step; a long offline step (``ik.dt``) can still close a pair below its
minimum distance, or bring in a pair that was beyond detection distance. :func:`advance` halves such a step until
it does not, measuring only the pairs whose distance bounds (:class:`~nextage_qp.ik.broadphase.PairBounds`) do not
already clear their floor.
"""

from __future__ import annotations

import mink
import numpy as np

from nextage_qp.ik.collision import ActiveCollisionLimit


def advance(limit: ActiveCollisionLimit, configuration: mink.Configuration, q: np.ndarray, dq: np.ndarray,
            lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """``clip(q + dq, lower, upper)``, halving ``dq`` while a pair ``limit`` watches would drop below its minimum.

    A pair already below its minimum distance may not get closer; every other pair must stay at or above it.
    Only pairs whose distance bound before the step, less how far their geoms moved in it, is not already
    above that floor, and whose bounding spheres after it are not either, are measured after it: the others
    cannot have dropped below. Returns ``q`` itself (the configuration back at it) when eight halvings all
    fail. The measurements of the configuration it accepts are kept for the next call's rows.
    """
    data, bounds, enabled = configuration.data, limit.bounds, limit.enabled
    # Floors: bounds before the step, measured where a pair may be below its minimum (unless the step's own
    # rows measured it here already); after it, how far each geom moved.
    before = bounds.lower(data)
    low = np.flatnonzero((before < limit.min_distance) & enabled & ~bounds.exact)
    before[low] = limit.distances(data, low)
    floor = np.minimum(before, limit.min_distance)
    pos0, mat0 = data.geom_xpos.copy(), data.geom_xmat.copy()
    violators = np.zeros(0, dtype=int)  # pairs below their floor after the last step tried
    for _ in range(8):
        q_new = np.minimum(np.maximum(q + dq, lower), upper)
        configuration.update(q_new)
        if violators.size:  # the pairs that failed the last try, first: one still below rejects this try too
            dists = limit.measure(data, violators)
            still = dists < floor.take(violators) - 1e-6
            if still.any():
                violators = violators[still]
                dq = dq * 0.5
                continue
        moved = bounds.moved(data, pos0, mat0)
        check = np.flatnonzero(~(before - moved.take(limit.geom1) - moved.take(limit.geom2) >= floor) & enabled)
        check = check[bounds.sphere_gaps(data, check) < floor.take(check)]
        dists = limit.measure(data, check)
        ok = dists >= floor.take(check) - 1e-6
        if ok.all():
            bounds.update(data)
            bounds.remember(check, dists, exact=True)
            return q_new
        violators = check[~ok]
        dq = dq * 0.5
    configuration.update(q)
    return q

