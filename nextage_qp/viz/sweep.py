"""Figure of a sweep: the object-error CDF against the success threshold, and the error against every parameter."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from nextage_qp.sweep.episode import UNRATED, Episode
from nextage_qp.sweep.nested import choice_label
from nextage_qp.sweep.spec import SweepSpec
from nextage_qp.sweep.summary import error_limit, object_error, param_value, parameter_components


def plot_sweep(spec: SweepSpec, episodes: Sequence[Episode], path: Path) -> None:
    """PNG: the CDF of the object error against the success threshold, and error against every parameter."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ran = [e for e in episodes if e.status not in UNRATED and object_error(e) is not None]
    comps = parameter_components(spec)
    ncols = 3
    nrows = 1 + math.ceil(len(comps) / ncols)
    fig = plt.figure(figsize=(4.2 * ncols, 3.3 * nrows), constrained_layout=True)
    grid = fig.add_gridspec(nrows, ncols)
    ax = fig.add_subplot(grid[0, :])
    err = np.sort([object_error(e) for e in ran]) if ran else np.array([])
    limit = error_limit(episodes)
    if err.size:
        ax.step(np.maximum(err, 1e-5), np.arange(1, err.size + 1) / err.size, where="post", lw=1.8,
                label=f"{err.size} episodes")
    if limit is not None:
        ax.axvline(limit, color="k", ls="--", lw=1, label=f"success threshold {limit * 1e3:g} mm")
    ax.set(xscale="log", xlabel="object error [m]", ylabel="fraction of episodes", ylim=(0, 1.02),
           title=f"{spec.name}: object error CDF ({sum(e.status == 'success' for e in ran)}/{len(ran)} succeed)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="lower right", fontsize=8)
    ok = [e.status == "success" for e in ran]
    for n, (label, key, comp, span) in enumerate(comps):
        a = fig.add_subplot(grid[1 + n // ncols, n % ncols])
        x = [param_value(e, key, comp) for e in ran]
        y = [max(object_error(e) or 0.0, 1e-5) for e in ran]
        numeric = all(isinstance(v, (int, float)) for v in x)
        xs = x if numeric else [choice_label(v) for v in x]
        for flag, colour, name in ((True, "tab:green", "success"), (False, "tab:red", "failure")):
            px = [xv for xv, o in zip(xs, ok, strict=True) if o is flag]
            py = [yv for yv, o in zip(y, ok, strict=True) if o is flag]
            if px:
                a.scatter(px, py, s=12, color=colour, alpha=0.7, label=name)
        if limit is not None:
            a.axhline(limit, color="k", ls="--", lw=0.8)
        a.set(yscale="log", xlabel=label, ylabel="object error [m]")
        if span is not None:
            a.set_xlim(span[0] - 0.03 * (span[1] - span[0]), span[1] + 0.03 * (span[1] - span[0]))
        a.grid(alpha=0.3)
        if n == 0:
            a.legend(fontsize=7)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
