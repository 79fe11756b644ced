"""Plots of a tuning study: the optimisation history and the parameters' importances."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def plot_history(summary: dict[str, Any], path: Path) -> Path | None:
    """Every complete trial's value, the best so far, and the base value (lower is better)."""
    hist = summary["history"]
    if not hist:
        return None
    n = np.array([h["number"] for h in hist])
    v = np.array([h["value"] for h in hist], dtype=float)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(n, v, "o", ms=4, alpha=0.6, label="trial")
    ax.step(n, np.minimum.accumulate(v), where="post", color="C3", label="best so far")
    base = (summary.get("base") or {}).get("value")
    if base is not None:
        ax.axhline(base, color="0.4", ls="--", lw=1, label=f"base ({base:.4g})")
    ax.set_xlabel("trial")
    ax.set_ylabel("objective (lower is better)")
    ax.set_title(f"{summary['study']}: {summary['kind']} study, {summary['sampler']}")
    if np.all(v > 0) and v.max() / max(v.min(), 1e-12) > 30:
        ax.set_yscale("log")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_importances(study: Any, path: Path) -> Path | None:
    """Importances (fANOVA) of the searched keys (None when fewer than 2 complete trials vary them)."""
    import optuna

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            imp = optuna.importance.get_param_importances(study)
    except (RuntimeError, ValueError, ZeroDivisionError):
        return None
    if not imp:
        return None
    keys = list(imp)[::-1]
    fig, ax = plt.subplots(figsize=(7, 0.8 + 0.3 * len(keys)))
    ax.barh(keys, [imp[k] for k in keys], color="C0")
    ax.set_xlabel("importance (fANOVA, normalised)")
    ax.set_title(f"{study.study_name}: which keys move the objective")
    ax.grid(alpha=0.3, axis="x")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
