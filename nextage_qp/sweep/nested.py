"""Distributions nested inside a ``choice``, drawn after the choice itself.

Each choice may hold ``{uniform: [lo, hi]}`` or ``{choice: [...]}`` wherever a value goes (a shape, then sizes
that fit that shape)::

    scene.objects.cube: {choice: [
      {shape: box, size: [{uniform: [0.016, 0.048]}, {uniform: [0.016, 0.048]}, 0.035]},
      {shape: cylinder, size: [{uniform: [0.02, 0.04]}, 0.035]}]}
"""

from __future__ import annotations

from typing import Any

import numpy as np

NESTED = ("uniform", "choice")


def is_nested(value: Any) -> bool:
    """True for a mapping that is one nested distribution (``{uniform: [lo, hi]}`` or ``{choice: [...]}``)."""
    return isinstance(value, dict) and len(value) == 1 and next(iter(value)) in NESTED


def check_nested(value: Any) -> None:
    """Raise ValueError for a malformed nested distribution anywhere in ``value``."""
    if is_nested(value):
        kind, arg = next(iter(value.items()))
        if kind == "uniform":
            if (not isinstance(arg, list) or len(arg) != 2
                    or not all(isinstance(v, int | float) and np.isfinite(v) for v in arg) or arg[0] > arg[1]):
                raise ValueError(f"a nested uniform takes [lo, hi], finite numbers with lo <= hi; got {arg!r}")
        elif not isinstance(arg, list) or not arg:
            raise ValueError(f"a nested choice takes a non-empty list; got {arg!r}")
        for v in arg if kind == "choice" else ():
            check_nested(v)
    elif isinstance(value, dict):
        for v in value.values():
            check_nested(v)
    elif isinstance(value, list):
        for v in value:
            check_nested(v)


def draw_nested(value: Any, rng: np.random.Generator) -> Any:
    """``value`` with every nested distribution drawn (depth first, in order); plain values consume no draws."""
    if is_nested(value):
        kind, arg = next(iter(value.items()))
        if kind == "uniform":
            return float(arg[0] + (arg[1] - arg[0]) * rng.random())
        return draw_nested(arg[int(rng.integers(len(arg)))], rng)
    if isinstance(value, dict):
        return {k: draw_nested(v, rng) for k, v in value.items()}
    if isinstance(value, list):
        return [draw_nested(v, rng) for v in value]
    return value


def extremes(value: Any) -> list[Any]:
    """``value`` with every nested distribution at its low end (first choice), and at its high end (last choice)."""
    def at(v: Any, end: int) -> Any:
        if is_nested(v):
            kind, arg = next(iter(v.items()))
            return float(arg[end]) if kind == "uniform" else at(arg[end], end)
        if isinstance(v, dict):
            return {k: at(x, end) for k, x in v.items()}
        if isinstance(v, list):
            return [at(x, end) for x in v]
        return v

    low, high = at(value, 0), at(value, -1)
    return [low] if low == high else [low, high]


def choice_label(value: Any) -> str:
    """A short name for a drawn choice, for grouping episodes: its non-float content (``shape=prism sides=6``).

    A value with no floats is its own name; drawn floats (sizes, say) are left out, so the episodes that drew the
    same entry of a choice share a name.
    """
    if isinstance(value, dict):
        parts = [f"{k}={choice_label(v)}" for k, v in value.items() if not _only_floats(v)]
        return " ".join(parts) or "{...}"
    if isinstance(value, list):
        return "[...]" if _only_floats(value) else "[" + ", ".join(choice_label(v) for v in value) + "]"
    return str(value)


def _only_floats(value: Any) -> bool:
    if isinstance(value, float):
        return True
    if isinstance(value, (list, dict)):
        items = value.values() if isinstance(value, dict) else value
        return all(_only_floats(v) for v in items)
    return False

