"""The sides a correction can come from at the target, and pushes aimed so that what they leave stays correctable.

A push leaves an error: short along its line and off it by a few millimetres. A correction pushes the object from the
side the error points away from, and an arm must reach that side. Beside a free target every side facing away from the
robot is reachable; among obstacles an arm reaching for a side may meet one (a tall piece 20 cm away can stop the
forearm), and only a wedge of sides may be left. An error outside the wedge cannot be pushed back, and a push along the
nearest reachable side only moves the error onto a side no arm reaches.

So where obstacles stand, the push phase finds the sides reachable at the target once
(:func:`~nextage_qp.manipulation.phases.push.approach.reachable_sides`, for ``SIDE_STEPS`` directions either way of
the push line, every ``SIDE_STEP``) and aims its pushes so that the error stays inside them: the first push stops
``correction_room`` short of the target along the middle of the widest run of reachable sides (:func:`middle`); a
correction that can only come from a side off the error's direction pushes only as far as leaves the rest along
another reachable side (:func:`split`), from which the next correction pushes straight.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from nextage_qp.geometry import angle2, rotate2

SIDE_STEP = np.radians(15.0)
"""Spacing of the directions whose sides are checked at the target [rad]."""
SIDE_STEPS = 6
"""Directions checked either way of the push line (6 x 15 deg: every side that faces away from the robot)."""
CLEAR_STEPS = 4
"""Where every side within this many steps of the push line (60 deg either way) is reachable, no push aims short."""
STRAIGHT = np.radians(5.0)
"""A correction this close to the error's direction [rad] pushes the whole way: nothing to split."""


def side_directions(line: np.ndarray) -> list[np.ndarray]:
    """The directions whose sides are checked: ``line`` turned by ``k * SIDE_STEP``, k = -SIDE_STEPS..SIDE_STEPS."""
    return [rotate2(line, k * SIDE_STEP) for k in range(-SIDE_STEPS, SIDE_STEPS + 1)]


def middle(directions: Sequence[np.ndarray], reachable: Sequence[bool]) -> tuple[np.ndarray, int] | None:
    """The middle direction of the longest run of reachable ``directions`` (in angular order), and the run's length.

    None when none is reachable.
    """
    best: tuple[int, int] | None = None  # (start, length)
    k = 0
    while k < len(directions):
        if reachable[k]:
            j = k
            while j + 1 < len(directions) and reachable[j + 1]:
                j += 1
            if best is None or j - k + 1 > best[1]:
                best = (k, j - k + 1)
            k = j + 1
        else:
            k += 1
    if best is None:
        return None
    run = np.array(directions[best[0]: best[0] + best[1]])
    mean = run.sum(axis=0)
    return mean / float(np.linalg.norm(mean)), best[1]


def split(error: np.ndarray, along: np.ndarray, sides: Sequence[np.ndarray]) -> np.ndarray | None:
    """What a push along ``along`` should leave of ``error`` [m] so that a push from one of ``sides`` ends it, or None.

    ``error = t * along + r * side`` with t, r >= 0 for the reachable ``side`` angularly nearest ``error`` on the other
    side of it from ``along``; the push along ``along`` stops ``r * side`` short. None when ``along`` is (within
    ``STRAIGHT``) the error's own direction, or when no reachable side lies beyond the error.
    """
    norm = float(np.linalg.norm(error))
    if norm < 1e-9:
        return None
    e = error / norm
    turn = angle2(along, e)
    if abs(turn) <= STRAIGHT:
        return None
    beyond = [s for s in sides if np.sign(angle2(e, s)) == np.sign(turn) and abs(angle2(e, s)) < np.pi / 2]
    if not beyond:
        return None
    side = min(beyond, key=lambda s: abs(angle2(e, s)))
    basis = np.column_stack([along, side])
    t, r = np.linalg.solve(basis, error)
    if t < 0 or r < 0:
        return None
    return r * side
