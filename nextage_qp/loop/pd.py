r"""Joint PD torque control with optional bias compensation and feed-forward, clamped to the actuators.

The law (the report's Eq. 3 plus what a real controller needs), per joint :math:`i`:

.. math::

    u_i = \operatorname{clip}\big(K_{p,i}(q^{ref}_i - q_i) + K_{d,i}(\dot q^{ref}_i - \dot q_i)
          + b_i + \tau^{ff}_i,\ -\tau^{max}_i,\ \tau^{max}_i\big)

with :math:`q` [rad], :math:`\dot q` [rad/s], :math:`K_p` [N·m/rad], :math:`K_d` [N·m·s/rad], the bias
:math:`b` = MuJoCo's ``qfrc_bias`` (gravity + Coriolis/centrifugal) [N·m] when gravity compensation is on,
a feed-forward torque :math:`\tau^{ff}` [N·m] and the actuator range :math:`\tau^{max}` [N·m].

In the simulation the law runs inside MuJoCo (:meth:`PDController.install`): each joint's actuator becomes an
affine ``general`` actuator, force :math:`= c - K_p q - K_d \dot q` clamped to :math:`\pm\tau^{max}`, fed
:math:`c = K_p q^{ref} + K_d \dot q^{ref} + b + \tau^{ff}` once per physics step
(:meth:`PDController.ctrl`), so ``mj_step`` evaluates the feedback on the state it integrates and no torque is
computed in Python. :meth:`PDController.torque` is the same law in numpy (tests, analysis).

Gains come from :mod:`nextage_qp.robots.gains` (a YAML file per robot, or a rule on the joints' inertia).
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.robots.gains import Gains, GainsFile, gains_path, load_gains

__all__ = ["ActuatorBlock", "Gains", "GainsFile", "PDController", "gains_path", "index_view", "load_gains"]


class PDController:
    r"""Joint PD torque law with bias compensation, feed-forward and actuator clamping (see module doc).

    Args:
        gains: Per-joint gains and the gravity-compensation switch.
        torque_limit: Actuator limit :math:`\tau^{max}` [N·m] per joint, (n,).

    Attributes:
        ticks: Number of torque evaluations so far.
        saturated_ticks: Per joint, how many evaluations were clamped.
        any_saturated_ticks: Evaluations where at least one joint was clamped.
    """

    def __init__(self, gains: Gains, torque_limit: np.ndarray) -> None:
        self.gains = gains
        self.torque_limit = np.asarray(torque_limit, dtype=float).copy()
        if self.torque_limit.shape != gains.kp.shape or np.any(self.torque_limit <= 0):
            raise ConfigError(f"torque limits must be {gains.kp.size} values > 0 N m, got {self.torque_limit}")
        self._saturated = self.torque_limit - 1e-9  # a force this large counts as clamped
        self.reset_counters()

    def install(self, model: Any, actuator_ids: np.ndarray) -> None:
        """Make the joints' actuators compute this PD law inside MuJoCo (see the module doc).

        Each actuator becomes ``general`` with gain 1, affine bias ``(0, -kp, -kd)``, an unlimited control and
        its torque limit as force range. The model is changed in place: a second simulation of the same model
        installs its own gains.

        Raises:
            ConfigError: An actuator does not drive its joint with gear 1 (the law assumes joint torque = force).
        """
        ids = np.asarray(actuator_ids, dtype=int)
        if not np.allclose(model.actuator_gear[ids, 0], 1.0) or not np.allclose(model.actuator_gear[ids, 1:], 0.0):
            raise ConfigError("the PD law needs every joint actuator to have gear 1")
        g = self.gains
        model.actuator_gaintype[ids] = mujoco.mjtGain.mjGAIN_FIXED
        model.actuator_gainprm[ids] = 0.0
        model.actuator_gainprm[ids, 0] = 1.0
        model.actuator_biastype[ids] = mujoco.mjtBias.mjBIAS_AFFINE
        model.actuator_biasprm[ids] = 0.0
        model.actuator_biasprm[ids, 1] = -g.kp
        model.actuator_biasprm[ids, 2] = -g.kd
        model.actuator_dyntype[ids] = mujoco.mjtDyn.mjDYN_NONE
        model.actuator_ctrllimited[ids] = 0
        model.actuator_forcelimited[ids] = 1
        model.actuator_forcerange[ids, 0], model.actuator_forcerange[ids, 1] = -self.torque_limit, self.torque_limit

    def ctrl(self, q_ref: np.ndarray, qd_ref: np.ndarray, bias: np.ndarray | None = None,
             q_offset: np.ndarray | None = None, qd_offset: np.ndarray | None = None) -> np.ndarray:
        r"""The control of the installed actuators: :math:`c = K_p q^{ref} + K_d \dot q^{ref} + b`, one per joint.

        ``q_offset`` / ``qd_offset`` [rad, rad/s] are ``true - measured`` joint states: with them the actuator's
        feedback on the true state acts on the measured one (noisy or delayed sensors).
        """
        g = self.gains
        c = g.kp * q_ref + g.kd * qd_ref
        if bias is not None and g.gravity_compensation:
            c += bias
        if q_offset is not None:
            c += g.kp * q_offset
        if qd_offset is not None:
            c += g.kd * qd_offset
        return c

    def count(self, force: np.ndarray) -> None:
        """Count applied actuator forces [N·m], (joints,) or (steps, joints), in the saturation counters."""
        force = force if force.ndim == 2 else np.atleast_2d(force)
        self.ticks += force.shape[0]
        sat = np.abs(force) >= self._saturated
        if sat.any():
            self.saturated_ticks += sat.sum(axis=0)
            self.any_saturated_ticks += int(sat.any(axis=1).sum())

    def reset_counters(self) -> None:
        """Zero the tick and saturation counters."""
        self.ticks = 0
        self.any_saturated_ticks = 0
        self.saturated_ticks = np.zeros(self.torque_limit.size, dtype=np.int64)

    def torque(
        self,
        q: np.ndarray,
        qd: np.ndarray,
        q_ref: np.ndarray,
        qd_ref: np.ndarray,
        bias: np.ndarray | None = None,
        tau_ff: np.ndarray | None = None,
    ) -> np.ndarray:
        r"""Clamped joint torque [N·m], one per joint.

        .. math:: u = \operatorname{clip}(K_p(q^{ref} - q) + K_d(\dot q^{ref} - \dot q) + b + \tau^{ff})

        Args:
            q: Joint positions [rad].
            qd: Joint velocities [rad/s].
            q_ref: Reference positions [rad].
            qd_ref: Reference velocities [rad/s].
            bias: Bias torque [N·m] (``qfrc_bias`` at the robot dofs); used only with gravity compensation on.
            tau_ff: Feed-forward torque [N·m], e.g. :math:`M(q)\ddot q^{ref}`; optional.
        """
        g = self.gains
        u = g.kp * (q_ref - q) + g.kd * (qd_ref - qd)
        if bias is not None and g.gravity_compensation:
            u += bias
        if tau_ff is not None:
            u += tau_ff
        lim = self.torque_limit
        sat = np.abs(u) > lim
        self.ticks += 1
        if sat.any():
            self.saturated_ticks += sat
            self.any_saturated_ticks += 1
            np.clip(u, -lim, lim, out=u)
        return u


def index_view(idx: np.ndarray) -> slice | np.ndarray:
    """A slice for a contiguous index array (numpy then returns views, not copies), else the array."""
    idx = np.asarray(idx, dtype=int)
    if idx.size and np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size)):
        return slice(int(idx[0]), int(idx[0]) + idx.size)
    return idx


class ActuatorBlock:
    """The robot's actuators as one contiguous block of the model's controls, written and read through views.

    MuJoCo models list actuators in any order (the G1's legs, torso, right arm, then left arm), and a block may hold
    actuators that are not the robot's (a gripper's between an arm's): :meth:`spread` puts a tick's controls, in joint
    order, into the block's order (the others held at their values), and :meth:`joint_order` takes the block's
    forces back. Where the robot's actuators are the block in joint order (every bundled robot), both are identities.

    Args:
        actuator_ids: The actuator of each robot joint, in joint order.
        data: The simulation's data (the views are into it).
    """

    def __init__(self, actuator_ids: np.ndarray, data: mujoco.MjData) -> None:
        ids = np.asarray(actuator_ids, dtype=int)
        lo, hi = (int(ids.min()), int(ids.max()) + 1) if ids.size else (0, 0)
        self.ctrl, self.force = data.ctrl[lo:hi], data.actuator_force[lo:hi]
        """Views of the block's controls and actuator forces."""
        cols = ids - lo
        self.cols = None if np.array_equal(cols, np.arange(hi - lo)) else cols
        """Each joint's column in the block (None: the block is in joint order)."""
        self.width = hi - lo

    def spread(self, ramp: np.ndarray) -> np.ndarray:
        """Controls per substep (n, joints) in the block's order (n, width); actuators not the robot's held."""
        if self.cols is None:
            return ramp
        block = np.repeat(self.ctrl[None, :], len(ramp), axis=0)
        block[:, self.cols] = ramp
        return block

    def joint_order(self, force: np.ndarray) -> np.ndarray:
        """Forces per substep in the block's order (n, width), in joint order (n, joints)."""
        return force if self.cols is None else force[:, self.cols]
