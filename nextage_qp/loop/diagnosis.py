"""What holds a motion up, in words: the robot's contacts and their forces, saturated joints, joints at a limit.

A phase that times out or stalls names these (the runner adds them to its message), so a failure says why without a
log and a script of one's own.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

CONTACT_MIN_N = 1.0
"""Contacts pressing with less than this normal force [N] are not named (a resting touch)."""
SATURATED_SHARE = 0.2
"""A joint whose torque was clamped in at least this share of a phase's physics steps is named."""
AT_LIMIT_RAD = 0.01
"""A joint within this [rad or m] of an end of its range counts as at the limit."""


def contact_forces(model: mujoco.MjModel, data: mujoco.MjData, bodies: frozenset[int]) -> list[tuple[str, str, float]]:
    """Body pairs in contact now of which at least one is in ``bodies``, with their summed normal force [N].

    Strongest first; each pair ``(one of bodies, the other)``, by body name.
    """
    force6 = np.zeros(6)
    pairs: dict[tuple[int, int], float] = {}
    for i in range(data.ncon):
        contact = data.contact[i]
        b1, b2 = int(model.geom_bodyid[contact.geom1]), int(model.geom_bodyid[contact.geom2])
        if b1 not in bodies and b2 not in bodies:
            continue
        if b1 not in bodies:
            b1, b2 = b2, b1
        mujoco.mj_contactForce(model, data, i, force6)
        pairs[(b1, b2)] = pairs.get((b1, b2), 0.0) + abs(float(force6[0]))
    named = [(_body(model, a), _body(model, b), f) for (a, b), f in pairs.items()]
    return sorted(named, key=lambda p: -p[2])


def saturated(names: Sequence[str], clamped_steps: np.ndarray, steps: int) -> list[tuple[str, float]]:
    """Joints whose torque was clamped in at least :data:`SATURATED_SHARE` of ``steps``, with that share, most first."""
    if steps <= 0:
        return []
    share = np.asarray(clamped_steps, dtype=float) / steps
    order = np.argsort(-share)
    return [(names[j], float(share[j])) for j in order if share[j] >= SATURATED_SHARE]


def at_limits(names: Sequence[str], q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> list[tuple[str, str]]:
    """Joints within :data:`AT_LIMIT_RAD` of an end of their range (or past it): ``(name, "lower" | "upper")``."""
    out = []
    for j, name in enumerate(names):
        if q[j] <= lower[j] + AT_LIMIT_RAD:
            out.append((name, "lower"))
        elif q[j] >= upper[j] - AT_LIMIT_RAD:
            out.append((name, "upper"))
    return out


def what_holds(contacts: list[tuple[str, str, float]], clamped: list[tuple[str, float]],
               limits: list[tuple[str, str]], *, most: int = 3) -> str:
    """One clause naming what may hold a motion up (empty when nothing does), e.g.

    ``in contact: elbow_link-torso_link 84 N; torque saturated: shoulder_pitch 97 % of the phase; at a
    limit: elbow (upper)``.
    """
    parts = []
    pressing = [c for c in contacts if c[2] >= CONTACT_MIN_N]
    if pressing:
        parts.append("in contact: " + ", ".join(f"{a}-{b} {f:.0f} N" for a, b, f in pressing[:most]))
    if clamped:
        parts.append("torque saturated: " + ", ".join(f"{n} {100 * s:.0f} % of the phase" for n, s in clamped[:most]))
    if limits:
        parts.append("at a limit: " + ", ".join(f"{n} ({end})" for n, end in limits[:most]))
    return "; ".join(parts)


def limit_violation(names: Sequence[str], t: np.ndarray, q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    tolerance: float) -> str | None:
    """The worst excursion past a joint limit in a log, in words (None: none beyond ``tolerance``).

    ``t`` [s] (k,), ``q`` (k, joints) [rad or m]: e.g. ``elbow 12.3 mrad past its upper limit (worst at
    t=3.410 s, first past at t=3.396 s, 7 ticks)``.
    """
    if not len(q):
        return None
    below, above = lower - tolerance - q, q - upper - tolerance
    over = np.maximum(below, above)
    if not (over > 0).any():
        return None
    row, j = (int(i) for i in np.unravel_index(int(np.argmax(over)), over.shape))
    rows = np.flatnonzero((over > 0).any(axis=1))
    end = "upper" if above[row, j] >= below[row, j] else "lower"
    by = float(over[row, j]) + tolerance
    return (f"{names[j]} {by * 1e3:.1f} mrad past its {end} limit (worst at t={float(t[row]):.3f} s, first past at "
            f"t={float(t[rows[0]]):.3f} s, {len(rows)} ticks)")


def _body(model: mujoco.MjModel, body: int) -> str:
    return model.body(body).name or f"body {body}"
