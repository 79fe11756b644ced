"""Solves remembered by their inputs: a planner that asks the same question twice gets the first answer.

A search over grasps or push approaches plans many routes whose first waypoints coincide (the pads rising where
they are, the tool lifting over the object): the same targets from the same joints, with the objects where they
were. :meth:`~nextage_qp.ik.qp.QPIK.solve` is a deterministic function of those inputs (its restarts are seeded),
so :class:`SolveMemo` keys each solve by the exact bytes of everything it reads and returns the stored result.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Iterable, Sequence
from typing import Generic, TypeVar

import numpy as np

from nextage_qp.ik.search import Descent
from nextage_qp.ik.targets import FrameTarget, IKResult

R = TypeVar("R", IKResult, Descent)

_NONE = b"\x00"


def _feed(h: hashlib.blake2b, value: np.ndarray | float | None) -> None:
    h.update(_NONE if value is None else np.ascontiguousarray(value, dtype=float).tobytes() + b"\x01")


class SolveMemo(Generic[R]):
    """At most ``size`` solve results or descents (records with joints ``q``), the least recently used dropped first.

    Args:
        size: How many results to keep.
    """

    def __init__(self, size: int = 512) -> None:
        self.size = size
        self._store: OrderedDict[bytes, R] = OrderedDict()
        self.hits = 0
        """Results returned from the memo since it was made."""

    @staticmethod
    def key(targets: Sequence[FrameTarget], q0: np.ndarray, arrays: Iterable[np.ndarray | float | None],
            labels: Iterable[str]) -> bytes:
        """The key of one solve: every target field, the start joints, and the other inputs (``arrays``, ``labels``)."""
        h = hashlib.blake2b(digest_size=20)
        for t in targets:
            h.update(t.frame.encode() + b"\x02")
            for value in (t.pos, t.rot, t.axis, t.direction, t.position_cost, t.orientation_cost):
                _feed(h, value)
        _feed(h, q0)
        for value in arrays:
            _feed(h, value)
        for label in labels:
            h.update(label.encode() + b"\x02")
        return h.digest()

    def get(self, key: bytes) -> R | None:
        """The stored result (its joints a fresh copy), or None."""
        found = self._store.get(key)
        if found is None:
            return None
        self._store.move_to_end(key)
        self.hits += 1
        return found._replace(q=found.q.copy())

    def clear(self) -> None:
        """Forget every stored result (what they were solved against changed)."""
        self._store.clear()

    def put(self, key: bytes, result: R) -> None:
        """Store a result (a copy of its joints)."""
        self._store[key] = result._replace(q=result.q.copy())
        self._store.move_to_end(key)
        while len(self._store) > self.size:
            self._store.popitem(last=False)
