"""The start configurations of an offline solve: the given joints, then seeded random restarts."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np


class Starts:
    """Start configurations of the descents: ``q0``, then ``count - 1`` seeded random restarts, drawn when used.

    Restarts re-draw only the ``moving`` joints (within ``lower``/``upper``, given for the last joints only where
    ``q0`` starts with a mobile robot's base variables); the others keep their ``q0`` values.
    """

    def __init__(self, q0: np.ndarray, moving: np.ndarray, lower: np.ndarray, upper: np.ndarray, count: int,
                 seed: int) -> None:
        self.q0, self.moving, self.lower, self.upper, self.count = q0, moving, lower, upper, count
        self._rng = np.random.default_rng(seed)
        self._drawn: list[np.ndarray] = [q0]

    def __getitem__(self, k: int) -> np.ndarray:
        if not 0 <= k < self.count:
            raise IndexError(k)
        while len(self._drawn) <= k:
            fixed = len(self.q0) - len(self.lower)  # a mobile robot's base variables: never drawn
            drawn = np.r_[self.q0[:fixed], self._rng.uniform(self.lower, self.upper)] if fixed else \
                self._rng.uniform(self.lower, self.upper)
            self._drawn.append(np.where(self.moving, drawn, self.q0))
        return self._drawn[k]

    def __iter__(self) -> Iterator[np.ndarray]:
        return (self[k] for k in range(self.count))
