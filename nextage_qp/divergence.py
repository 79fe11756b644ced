"""What stops a run whose state diverged: the joint and the time to name in the message."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from nextage_qp.errors import SimulationError
from nextage_qp.mj_warnings import MUJOCO_WARNINGS

if TYPE_CHECKING:
    from nextage_qp.sim import Simulation


def raise_divergence(sim: Simulation) -> None:
    """Raise :class:`SimulationError` naming the first non-finite or too fast joint and MuJoCo's warning.

    Called once the simulation's fast check found a NaN, a joint faster than ``max_speed`` or a MuJoCo bad-state
    warning; the message is also kept in the recorder's ``meta["error"]``.
    """
    d, robot = sim.data, sim.robot
    q, qd = d.qpos[robot.qpos_idx], d.qvel[robot.dof_idx]
    bad_warn = any(w.number for w in sim._bad_warnings)
    finite = np.isfinite(q) & np.isfinite(qd)
    fast = np.abs(np.nan_to_num(qd, nan=np.inf)) > sim.max_speed
    names, t = robot.joint_names, sim.time
    if not finite.all():
        # NaN spreads to every joint within a step: name the joint already bad at the start of the tick.
        ts, qs, qds = sim.recorder.recent(1)
        if qs.size and not (np.isfinite(qs[0]).all() and np.isfinite(qds[0]).all()):
            t, q, qd = float(ts[0]), qs[0], qds[0]
            finite = np.isfinite(q) & np.isfinite(qd)
        j = int(np.flatnonzero(~finite)[0])
        what = f"joint {names[j]} state is not finite (q={q[j]}, qd={qd[j]})"
    elif fast.any():
        j = int(np.argmax(np.abs(qd)))
        what = f"joint {names[j]} velocity {qd[j]:.3g} rad/s exceeds {sim.max_speed:g} rad/s"
    else:
        what = "MuJoCo reported a bad position, velocity or acceleration (an object's state is not finite)"
    if bad_warn and MUJOCO_WARNINGS:
        what += f" (MuJoCo: {MUJOCO_WARNINGS[0].rstrip('.')})"
    msg = f"t={t:.3f} s: {what}; the simulation diverged (gains too stiff for sim_dt={sim.sim_dt} s?)"
    sim.recorder.meta["error"] = msg
    raise SimulationError(msg)
