"""The physics steps of one control tick as one compiled loop (numba), calling MuJoCo's own ``mj_step``.

:meth:`~nextage_qp.loop.simulation.Simulation.tick` sets one control vector per physics step and keeps the actuator
forces
each step applied; in Python that loop costs about 1 µs a step around a 15-35 µs ``mj_step``. :func:`substeps` is
the same loop compiled: it calls ``mj_step`` of the shared library the ``mujoco`` package loaded, through its
address (as :mod:`nextage_qp.native.kernels` calls ``mj_geomDistance``), on the same ``mjModel``/``mjData``, so the
state it leaves is the Python loop's to the bit. It also counts the steps in which a contact sensor reads a touch
(the outcome monitor's obstacle contacts), so that watch needs no Python hook either.

The simulation takes the Python loop when a Python hook must see every physics step, or when MuJoCo's library is
not found (:data:`NATIVE` false).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from nextage_qp.native.kernels import address

__all__ = ["NATIVE", "STEP", "substeps", "touching"]

STEP = address("mj_step")
"""Address of ``mj_step`` (0: not found; the simulation steps from Python)."""
NATIVE = bool(STEP)
"""True when :func:`substeps` can call MuJoCo."""


def _step_typing(typingctx, fn, m, d):  # pragma: no cover - compiled
    """``mj_step(m, d)`` through its address ``fn``."""
    if not all(isinstance(a, types.Integer) for a in (fn, m, d)):
        raise TypeError(f"integer addresses expected, got {(fn, m, d)}")
    sig = types.void(fn, m, d)

    def codegen(context, builder, signature, args):
        fn, m, d = args
        i8p = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i8p])
        builder.call(builder.inttoptr(fn, fnty.as_pointer()), [builder.inttoptr(m, i8p), builder.inttoptr(d, i8p)])
        return context.get_dummy_value()

    return sig, codegen


_step: Any = intrinsic(_step_typing)


def touching(sensordata: np.ndarray, adr: int) -> bool:
    """A contact sensor's ``(found, dist)`` at ``adr`` reads a touch: something found, penetrating."""
    return bool(sensordata[adr] > 0 and sensordata[adr + 1] < 0)


@njit(cache=True)
def substeps(fn, m, d, ctrl, ramp, act_force, force, sensordata, touch):  # pragma: no cover - compiled
    """``len(ramp)`` physics steps: ``ctrl[:] = ramp[k]``, ``mj_step``, ``force[k] = act_force``.

    Returns the number of steps after which the contact sensor at ``sensordata[touch]`` read a touch
    (``touch < 0``: none watched).
    """
    count = 0
    for k in range(ramp.shape[0]):
        ctrl[:] = ramp[k]
        _step(fn, m, d)
        force[k, :] = act_force
        if touch >= 0 and sensordata[touch] > 0 and sensordata[touch + 1] < 0:
            count += 1
    return count
