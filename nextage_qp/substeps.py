"""One control period's physics steps: a single call of MuJoCo's rollout, or a Python loop where one is needed.

Between two control ticks the simulation makes ``n`` physics steps, each with its own control vector (the ramp of
:meth:`~nextage_qp.sim.Simulation.tick`), and it needs every step's actuator forces (the saturation counters) and
sensor readings (contact with an obstacle). A loop in Python pays a few microseconds per step around each
``mj_step``; :func:`mujoco.rollout.rollout` makes the same steps in C with the controls given per step and returns
every step's sensor data, so the actuator forces come from an actuator-force sensor per actuator
(:func:`~nextage_qp.scene.add_force_sensors`). The two give the same state to the last bit (tested).

The loop is kept for what the rollout cannot do: hooks that must run at every step (``substep_hooks``), a model
without a force sensor on every actuator of the robot's block, and applied forces (``qfrc_applied``,
``xfrc_applied``: a shove), which the rollout's reset of the data would clear.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

from nextage_qp.control import ActuatorBlock
from nextage_qp.scene import FORCE_SUFFIX

try:
    from mujoco.rollout import Rollout
except ImportError:  # pragma: no cover - MuJoCo before 3.3.1: the loop only
    Rollout = None

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS
_CONTROL = int(mujoco.mjtState.mjSTATE_CTRL.value)


def force_sensor_addresses(model: mujoco.MjModel, actuators: Sequence[int]) -> np.ndarray | None:
    """Sensor-data address of each actuator's force sensor (:data:`~nextage_qp.scene.FORCE_SUFFIX`), or None."""
    adr = []
    for a in actuators:
        name = model.actuator(int(a)).name
        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, name + FORCE_SUFFIX) if name else -1
        if sid < 0 or model.sensor_type[sid] != mujoco.mjtSensor.mjSENS_ACTUATORFRC:
            return None
        adr.append(int(model.sensor_adr[sid]))
    return np.array(adr, dtype=int)


class Substeps:
    """Runs ``n`` physics steps per control period on ``data``, recording each step's forces and sensor data.

    Args:
        model: The model.
        data: Its data (stepped in place).
        block: The robot's actuators (:class:`~nextage_qp.control.ActuatorBlock`).
        n: Physics steps per control period.

    Attributes:
        force: Actuator forces [N·m] of the block at each step of the last period, (n, block width).
        sensordata: MuJoCo's sensor data at each step of the last period, (n, nsensordata).
        rolled: Whether the last period ran as one rollout (else the loop).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, block: ActuatorBlock, n: int) -> None:
        self.model, self.data, self.block, self.n = model, data, block, n
        self.force = np.zeros((n, block.width))
        self.sensordata = np.zeros((n, model.nsensordata))
        self.rolled = False
        lo, hi = block.span
        adr = force_sensor_addresses(model, range(lo, hi)) if Rollout is not None else None
        self._rollout: Any = Rollout(nthread=0) if adr is not None else None
        self._adr = adr if adr is not None else np.zeros(0, dtype=int)
        self._state0 = np.empty((1, mujoco.mj_stateSize(model, _STATE)))
        self._control = np.empty((1, n, model.nu))
        self._rows = self.sensordata[None]  # (1, n, nsensordata): the rollout writes here
        self._warm = data.qacc_warmstart[None]  # a view: the rollout starts from the current warm start

    def can_roll(self) -> bool:
        """Whether a period can be one rollout now: a force sensor per actuator and no applied forces."""
        d = self.data
        return self._rollout is not None and not d.xfrc_applied.any() and not d.qfrc_applied.any()

    def run(self, ctrl: np.ndarray, after_step: Callable[[], None] | None = None) -> float:
        """Step the period with the block's controls ``ctrl`` (n, block width); returns the wall time in MuJoCo [s].

        ``after_step``, if given, is called after every physics step (so the period runs as the loop). The time
        counted is that of the rollout call (MuJoCo's stepping, plus the copy of each step's sensor data it makes),
        or the sum of the loop's ``mj_step`` calls.
        """
        m, d = self.model, self.data
        clock = time.perf_counter
        self.rolled = after_step is None and self.can_roll()
        if self.rolled:
            lo, hi = self.block.span
            control = self._control[0]
            control[:] = d.ctrl
            control[:, lo:hi] = ctrl
            mujoco.mj_getState(m, d, self._state0[0], _STATE)
            t0 = clock()
            self._rollout.rollout([m], [d], self._state0, self._control, skip_checks=True, nstep=self.n,
                                  initial_warmstart=self._warm, sensordata=self._rows)
            physics = clock() - t0
            self.sensordata.take(self._adr, axis=1, out=self.force)
            return physics
        block, force, rows, physics = self.block.ctrl, self.force, self.sensordata, 0.0
        act_force, sensordata, step = self.block.force, d.sensordata, mujoco.mj_step
        for k in range(self.n):
            block[:] = ctrl[k]
            t0 = clock()
            step(m, d)
            physics += clock() - t0
            force[k] = act_force
            rows[k] = sensordata
            if after_step is not None:
                after_step()
        return physics
