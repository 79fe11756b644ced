"""What every study's evaluation provides: tasks for a parameter set, their score, and the tuned file.

An evaluator turns a trial's parameters (dotted key -> value) into sweep tasks, runs nowhere itself (the
study runs the tasks on a sweep backend), scores the returned episodes, and writes the base file with the
tuned keys as a complete YAML. :class:`~nextage_qp.tune.sweep_eval.SweepEvaluator` evaluates a sweep's
episodes, :class:`~nextage_qp.tune.steps.StepsEvaluator` joint step responses.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import yaml

from nextage_qp.manipulation.config import apply_override
from nextage_qp.sweep.keys import yaml_scalar


@dataclass
class Score:
    """A trial's value (lower is better), a one-line account of it and the figures behind it (JSON-able)."""

    value: float
    line: str
    details: dict[str, Any] = field(default_factory=dict)


class Evaluator(Protocol):
    """The evaluation of one study kind (see the module docstring)."""

    kind: str
    wall_limit: float
    episode_fn: Any  # task -> Episode, importable by a spawned worker

    def base_value(self, key: str) -> Any:
        """The key's value in the base file (None when the base file leaves it unset)."""

    def check_value(self, key: str, value: Any) -> None:
        """Raise ConfigError when the base file with ``key = value`` is not valid."""

    def tasks(self, params: dict[str, Any], held_out: bool = False) -> list[Any]:
        """Sweep tasks evaluating ``params``, on the objective's set or on the held-out set."""

    def score(self, episodes: Sequence[Any]) -> Score:
        """The score of the episodes of one parameter set."""

    def tuned_doc(self, params: dict[str, Any], out_dir: Path) -> dict[str, Any]:
        """The base file's mapping with ``params`` applied, its file paths valid from ``out_dir``."""


def apply_params(doc: dict[str, Any], params: dict[str, Any], source: str = "tuned") -> dict[str, Any]:
    """A deep copy of ``doc`` with every ``key: value`` of ``params`` set (as ``--set key=value`` would)."""
    out = copy.deepcopy(doc)
    for key, value in params.items():
        apply_override(out, f"{key}={yaml_scalar(value)}", source)
    return out


def relocate(doc: dict[str, Any], keys: Sequence[tuple[str, ...]], base_dir: Path, out_dir: Path) -> None:
    """Rewrite the file paths at ``keys`` (relative to ``base_dir``) so they resolve from ``out_dir``, in place."""
    for path in keys:
        holder: Any = doc
        for part in path[:-1]:
            holder = holder.get(part) if isinstance(holder, dict) else None
        if not isinstance(holder, dict):
            continue
        value = holder.get(path[-1])
        if isinstance(value, str) and not Path(value).is_absolute() and (base_dir / value).is_file():
            holder[path[-1]] = os.path.relpath((base_dir / value).resolve(), out_dir.resolve())


def dump_yaml(doc: dict[str, Any], header: str) -> str:
    """``doc`` as block YAML (keys in their order) under a ``#`` comment header."""
    lines = "".join(f"# {line}\n" if line else "#\n" for line in header.splitlines())
    return lines + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120)
