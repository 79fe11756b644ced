r"""Sweep studies: a fixed set of a sweep's episodes under a trial's task-config keys, scored lexicographically.

Each trial runs episodes ``0..K-1`` of the sweep (drawn with the study's seed: the same scenes for every trial)
with the searched keys set on top of each episode's own overrides. The value is

.. math:: \frac{\text{failures} + e_{95} / (e_{95} + s)}{K_{ran}}

with :math:`e_{95}` the 95th percentile of the object error over the episodes that ran and :math:`s` the task's
error limit: one failure more always weighs more than any error, and among equal failure counts the smaller
p95 error wins (failure rate first, then p95 error). Refused scenes (exit 2 before moving) do not count.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.io.yaml_file import read_yaml_mapping
from nextage_qp.manipulation.config import load_config
from nextage_qp.sweep.episode import UNRATED, Episode, EpisodeTask, run_episode
from nextage_qp.sweep.keys import lookup, yaml_scalar
from nextage_qp.sweep.run import plan
from nextage_qp.sweep.spec import SweepSpec
from nextage_qp.sweep.summary import error_limit, object_error, wilson
from nextage_qp.tune.evaluate import Score, apply_params, relocate
from nextage_qp.tune.spec import HeldOut, SweepEval

MISSING_ERROR_M = 1.0
"""Object error counted for an episode that produced no result (an exception, the wall-time limit) [m]."""


class SweepEvaluator:
    """A sweep's episodes under a task config (see the module docstring)."""

    kind = "sweep"
    episode_fn = staticmethod(run_episode)

    def __init__(self, evaluation: SweepEval, held_out: HeldOut | None, folder: Path,
                 wall_limit: float | None = None) -> None:
        self.eval = evaluation
        self.spec = SweepSpec(folder / evaluation.file)
        self.held = held_out
        self.wall_limit = wall_limit or self.spec.wall_limit
        self.base_doc = read_yaml_mapping(self.spec.base_path, "a mapping at the top level")

    def base_value(self, key: str) -> Any:
        """The key's value in the sweep's base config (with the sweep's ``set:``)."""
        if key == "seed":
            raise ConfigError("space.seed: the sweep sets each episode's run seed itself; tune a task-config key "
                              "(e.g. ik.posture_cost), not the seed")
        if key in self.spec.distributions:
            raise ConfigError(f"space.{key}: the sweep randomises this key; tune keys the sweep leaves fixed")
        return lookup(self.spec.base, key.split("."), lambda msg: ConfigError(f"space.{key}: {msg}"))

    def check_value(self, key: str, value: Any) -> None:
        """Raise ConfigError when the base config with ``key = value`` is invalid."""
        load_config(self.spec.base_path, [*self.spec.fixed, f"{key}={yaml_scalar(value)}"])

    def tasks(self, params: dict[str, Any], held_out: bool = False) -> list[EpisodeTask]:
        """Episodes of the sweep (objective's seed, or the held-out seed) with ``params`` set."""
        held = self.held if held_out else None
        if held_out and held is None:
            return []
        n, seed = (held.episodes, held.seed) if held is not None else (self.eval.episodes, self.eval.seed)
        assert n is not None and seed is not None  # the study file's schema requires both for a held-out set
        extra = tuple(f"{key}={yaml_scalar(value)}" for key, value in params.items())
        return [replace(t, overrides=(*t.overrides[:-1], *extra, t.overrides[-1]), wall_limit=self.wall_limit)
                for t in plan(self.spec, seed, range(n))]  # the run seed stays the last override

    def score(self, episodes: Sequence[Episode]) -> Score:
        """Failure rate first, p95 object error second (see the module docstring)."""
        ran = [ep for ep in episodes if ep.status not in UNRATED]
        if not ran:
            return Score(1.0, "every scene was refused", {"episodes": len(episodes), "ran": 0})
        errors = np.array([MISSING_ERROR_M if (e := object_error(ep)) is None else e for ep in ran])
        successes = sum(ep.status == "success" for ep in ran)
        p95 = float(np.percentile(errors, 95))
        scale = error_limit(ran) or 0.005
        value = (len(ran) - successes + p95 / (p95 + scale)) / len(ran)
        lo, hi = wilson(successes, len(ran))
        failed = [{"index": ep.index, "status": ep.status, "reason": ep.reason} for ep in ran
                  if ep.status != "success"]
        line = (f"{successes}/{len(ran)} succeed ({100 * successes / len(ran):.1f} %), "
                f"p95 error {1e3 * p95:.2f} mm, median {1e3 * float(np.median(errors)):.2f} mm")
        details = {"episodes": len(episodes), "ran": len(ran), "refused": len(episodes) - len(ran),
                   "successes": successes, "success_rate": successes / len(ran), "success_rate_ci95": [lo, hi],
                   "p95_error_m": p95, "median_error_m": float(np.median(errors)), "failed": failed}
        return Score(value, line, details)

    def tuned_doc(self, params: dict[str, Any], out_dir: Path) -> dict[str, Any]:
        """The task config with ``params`` set, its gains and scene paths valid from ``out_dir``."""
        doc = apply_params(self.base_doc, params)
        relocate(doc, [("gains",), ("scene", "file")], self.spec.base_path.parent, out_dir)
        return doc
