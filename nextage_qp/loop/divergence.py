"""What stops a run whose state diverged: the joint and the time to name in the message."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def divergence_message(names: Sequence[str], t: float, q: np.ndarray, qd: np.ndarray,
                       recent: tuple[np.ndarray, np.ndarray, np.ndarray], *, max_speed: float, sim_dt: float,
                       warnings: Sequence[str] = ()) -> str:
    """The one line that names the first non-finite or too fast joint, and MuJoCo's first warning.

    Args:
        names: The robot's joint names, in the order of ``q`` and ``qd``.
        t: Time of the state [s].
        q: Joint positions [rad or m] at ``t``.
        qd: Joint velocities [rad/s or m/s] at ``t``.
        recent: The recorder's last tick ``(times, q, qd)`` (NaN spreads to every joint within a step: the joint
            already bad at the start of the tick is the one named).
        max_speed: A joint faster than this [rad/s] counts as diverged.
        sim_dt: The physics step [s] (named in the hint).
        warnings: MuJoCo's warnings of the run when it reported a bad state (the first is quoted).
    """
    finite = np.isfinite(q) & np.isfinite(qd)
    fast = np.abs(np.nan_to_num(qd, nan=np.inf)) > max_speed
    if not finite.all():
        ts, qs, qds = recent
        if qs.size and not (np.isfinite(qs[0]).all() and np.isfinite(qds[0]).all()):
            t, q, qd = float(ts[0]), qs[0], qds[0]
            finite = np.isfinite(q) & np.isfinite(qd)
        j = int(np.flatnonzero(~finite)[0])
        what = f"joint {names[j]} state is not finite (q={q[j]}, qd={qd[j]})"
    elif fast.any():
        j = int(np.argmax(np.abs(qd)))
        what = f"joint {names[j]} velocity {qd[j]:.3g} rad/s exceeds {max_speed:g} rad/s"
    else:
        what = "MuJoCo reported a bad position, velocity or acceleration (an object's state is not finite)"
    if warnings:
        what += f" (MuJoCo: {warnings[0].rstrip('.')})"
    return f"t={t:.3f} s: {what}; the simulation diverged (gains too stiff for sim_dt={sim_dt} s?)"
