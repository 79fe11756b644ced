r"""Sweep statistics: success rate with its Wilson interval, error quantiles, failures grouped, rates per parameter bin.

The 95 % Wilson score interval of :math:`k` successes in :math:`n` episodes, :math:`\hat p = k/n`, :math:`z = 1.96`:

.. math:: \frac{\hat p + z^2/2n \pm z\sqrt{\hat p(1-\hat p)/n + z^2/4n^2}}{1 + z^2/n}
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from nextage_qp.io.json_out import dumps
from nextage_qp.sweep.episode import STATUSES, UNRATED, Episode
from nextage_qp.sweep.nested import choice_label
from nextage_qp.sweep.run import replay_commands
from nextage_qp.sweep.spec import SweepSpec

Z95 = 1.959963984540054
BINS = 4
"""Equal-width bins per randomised parameter component in the per-parameter table."""


def wilson(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate (``(0, 1)`` when ``n`` is 0)."""
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def object_error(ep: Episode) -> float | None:
    """The error the episode's success criterion tests [m] (None when the run never produced a result)."""
    if ep.result is None:
        return None
    crit = ep.result.get("criteria", {}).get("object_error")
    return float(crit["value"]) if crit else float(ep.result["object_error_m"])


def error_limit(episodes: Sequence[Episode]) -> float | None:
    """The success threshold of the object error [m], as the results state it."""
    for ep in episodes:
        crit = (ep.result or {}).get("criteria", {}).get("object_error")
        if crit:
            return float(crit["limit"])
    return None


def _quantiles(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "p90": None, "p99": None, "max": None}
    a = np.asarray(values)
    return {"median": float(np.median(a)), "p90": float(np.percentile(a, 90)), "p99": float(np.percentile(a, 99)),
            "max": float(a.max())}


def parameter_components(spec: SweepSpec) -> list[tuple[str, str, int | None, tuple[float, float] | None]]:
    """(label, key, component index or None, range) of every randomised quantity that varies.

    A choice has range None; a vector key yields one entry per component whose range is not a point.
    """
    out: list[tuple[str, str, int | None, tuple[float, float] | None]] = []
    for key, dist in spec.distributions.items():
        if dist.bounds is None:
            out.append((key, key, None, None))
            continue
        lo, hi = (np.atleast_1d(np.asarray(spec.value_at(key, b), dtype=float)) for b in dist.bounds)
        for j in range(lo.size):
            if hi[j] - lo[j] <= 1e-15:
                continue
            label = key if lo.size == 1 else f"{key}.{'xyz'[j]}" if lo.size == 3 else f"{key}[{j}]"
            out.append((label, key, None if lo.size == 1 else j, (float(lo[j]), float(hi[j]))))
    return out


def param_value(ep: Episode, key: str, component: int | None) -> Any:
    """One randomised quantity of an episode."""
    value = ep.params[key]
    return value if component is None else value[component]


def by_parameter(spec: SweepSpec, episodes: Sequence[Episode]) -> list[dict[str, Any]]:
    """Success rate per bin of every randomised quantity (refused episodes left out)."""
    ran = [e for e in episodes if e.status not in UNRATED]
    rows = []
    for label, key, comp, span in parameter_components(spec):
        values = [param_value(e, key, comp) for e in ran]
        if span is None:
            groups: dict[str, list[Episode]] = {}
            for e, v in zip(ran, values, strict=True):
                groups.setdefault(choice_label(v), []).append(e)
            cells = [(name, members) for name, members in groups.items()]
        else:
            edges = np.linspace(span[0], span[1], BINS + 1)
            which = np.clip(np.searchsorted(edges, np.asarray(values, dtype=float), side="right") - 1, 0, BINS - 1)
            cells = [(f"[{edges[b]:.4g}, {edges[b + 1]:.4g}]", [e for e, w in zip(ran, which, strict=True) if w == b])
                     for b in range(BINS)]
        for name, members in cells:
            k = sum(e.status == "success" for e in members)
            rows.append({"parameter": label, "bin": name, "episodes": len(members), "successes": k,
                         "success_rate": k / len(members) if members else None})
    return rows


TIGHT_CLEARANCE = 0.010
"""Target clearance [m] (object at rest on its target to the nearest obstacle) below which a target counts as tight."""


def by_target_clearance(episodes: Sequence[Episode]) -> list[dict[str, Any]]:
    """Success of the episodes that ran, split by their target's clearance to the obstacles (empty without one)."""
    ran = [(e, (e.result or {}).get("target_clearance_m")) for e in episodes if e.status not in UNRATED]
    if not any(c is not None for _, c in ran):
        return []
    rows = []
    for label, members in ((f"clear (>= {TIGHT_CLEARANCE * 1e3:g} mm)", [e for e, c in ran if c is not None
                                                                          and c >= TIGHT_CLEARANCE]),
                           (f"tight (< {TIGHT_CLEARANCE * 1e3:g} mm)", [e for e, c in ran if c is not None
                                                                         and c < TIGHT_CLEARANCE])):
        k = sum(e.status == "success" for e in members)
        rows.append({"targets": label, "episodes": len(members), "successes": k,
                     "success_rate": k / len(members) if members else None,
                     "success_rate_ci95": list(wilson(k, len(members)))})
    return rows


def estimation(episodes: Sequence[Episode]) -> dict[str, Any] | None:
    """Object-estimation errors over the episodes that ran with faults (None when none did).

    Per error kind (``estimate``, ``estimate_outside_shoves``, ``estimate_unoccluded``, ``raw``, ``held``: see
    ``EstimateErrors.report``) the RMS over episodes of each episode's RMS [m], and the ratios of the estimate
    (and of the estimate outside the shoves) to the raw and held errors. With a robot camera, its detections over
    every episode's unoccluded frames (``camera_unoccluded``, ``camera_unoccluded_ok``, and their ratio
    ``camera_detected_of_unoccluded``).
    """
    runs = [e.result["estimation"] for e in episodes if e.result and e.result.get("estimation")]
    rows = [o for run in runs for o in run["objects"].values()]
    if not rows:
        return None
    out: dict[str, Any] = {"episodes": len(rows)}
    for kind in ("estimate", "estimate_outside_shoves", "estimate_unoccluded", "raw", "held"):
        values = [r[f"{kind}_rms_m"] for r in rows if r.get(f"{kind}_rms_m") is not None]
        out[f"{kind}_rms_m"] = float(np.sqrt(np.mean(np.square(values)))) if values else None
    for est in ("estimate", "estimate_outside_shoves"):
        for kind in ("raw", "held"):
            ref, value = out[f"{kind}_rms_m"], out[f"{est}_rms_m"]
            out[f"{est}_over_{kind}"] = value / ref if ref and value is not None else None
    out["shove_ticks"] = int(sum(r.get("shove_ticks", 0) for r in rows))
    out["dropouts"] = int(sum(r["dropouts"] for r in rows))
    out["measurements"] = int(sum(r["measurements"] for r in rows))
    out["shoves"] = int(sum(len(e.result.get("shoves", [])) for e in episodes if e.result))
    frames = [o for run in runs if run.get("camera") for o in run["camera"]["objects"].values()]
    if frames:
        clear, ok = sum(f["unoccluded"] for f in frames), sum(f["unoccluded_ok"] for f in frames)
        out.update(camera_unoccluded=clear, camera_unoccluded_ok=ok,
                   camera_detected_of_unoccluded=ok / clear if clear else None)
    return out


def mobile_base(episodes: Sequence[Episode]) -> dict[str, Any] | None:
    """A mobile robot's base over the episodes that ran (None when none had one).

    Quantiles of the odometry's drift [m] and of the time the drive phases took [s]; the largest true lateral
    speed [m/s] and the episodes with ticks sliding sideways.
    """
    rows = [e.result for e in episodes if e.result and e.result.get("base")]
    if not rows:
        return None
    drives = [p["duration_s"] for r in rows for p in r["phases"] if p["kind"] == "drive" and p["status"] == "done"]
    return {
        "episodes": len(rows),
        "odometry_drift_m": _quantiles([r["base"]["odometry_drift_m"] for r in rows]),
        "odometry_drift_rad": _quantiles([r["base"]["odometry_drift_rad"] for r in rows]),
        "drive_time_s": _quantiles(drives),
        "distance_m": _quantiles([r["base"]["distance_m"] for r in rows]),
        "max_lateral_speed_m_s": max(r["base"]["max_lateral_speed_m_s"] for r in rows),
        "episodes_sliding": sum(r["base"]["sliding_ticks"] > 0 for r in rows),
    }


def write_summary(out: Path, spec: SweepSpec, seed: int, episodes: Sequence[Episode], *, session_episodes: int,
                  session_wall_s: float) -> dict[str, Any]:
    """:func:`summarize`, with the records' folder as ``out``, also written to ``out/summary.json``."""
    summary = summarize(spec, seed, episodes, session_episodes=session_episodes, session_wall_s=session_wall_s)
    summary["out"] = str(out)
    (out / "summary.json").write_text(dumps(summary) + "\n")
    return summary


def summarize(spec: SweepSpec, seed: int, episodes: Sequence[Episode], *, session_episodes: int,
              session_wall_s: float) -> dict[str, Any]:
    """The sweep summary printed on the terminal and written by ``--json`` (see ``docs/sweep.md``)."""
    counts = Counter(e.status for e in episodes)
    ran = [e for e in episodes if e.status not in UNRATED]
    k = counts["success"]
    lo, hi = wilson(k, len(ran))
    errors = [v for e in ran if (v := object_error(e)) is not None]
    errors_xy = [float(e.result["object_error_xy_m"]) for e in ran if e.result is not None]
    failures = [e for e in ran if e.status != "success"]
    by_phase = Counter(e.failed_phase or ("(episode error)" if e.status == "error" else "(all phases done)")
                       for e in failures)
    by_criterion = Counter(c for e in failures for c in (e.failed_criteria or ["(no result)"]))
    listed = []
    for e in [*failures, *(e for e in episodes if e.status in UNRATED)]:
        listed.append({"index": e.index, "status": e.status, "failed_phase": e.failed_phase, "reason": e.reason,
                       "object_error_m": object_error(e), "replay": replay_commands(spec, seed, e)})
    return {
        "sweep": str(spec.path),
        "base": str(spec.base_path),
        "set": spec.extra,
        "seed": seed,
        "episodes": len(episodes),
        "counts": {s: counts[s] for s in STATUSES},
        "ran": len(ran),
        "retried": sum(e.attempts > 1 for e in episodes),
        "success_rate": k / len(ran) if ran else None,
        "success_rate_ci95": [lo, hi],
        "error_limit_m": error_limit(episodes),
        "object_error_m": _quantiles(errors),
        "object_error_xy_m": _quantiles(errors_xy),
        "failures_by_phase": dict(by_phase.most_common()),
        "failures_by_criterion": dict(by_criterion.most_common()),
        "by_parameter": by_parameter(spec, episodes),
        "by_target_clearance": by_target_clearance(episodes),
        "estimation": estimation(ran),
        "mobile_base": mobile_base(ran),
        "episodes_per_minute": 60.0 * session_episodes / session_wall_s if session_wall_s > 0 else None,
        "session": {"episodes_run": session_episodes, "wall_time_s": session_wall_s},
        "failed": listed,
    }
