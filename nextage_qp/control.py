r"""Joint PD torque control with optional bias compensation and feed-forward, clamped to the actuators.

The law (the report's Eq. 3 plus what a real controller needs), per joint :math:`i`:

.. math::

    u_i = \operatorname{clip}\big(K_{p,i}(q^{ref}_i - q_i) + K_{d,i}(\dot q^{ref}_i - \dot q_i)
          + b_i + \tau^{ff}_i,\ -\tau^{max}_i,\ \tau^{max}_i\big)

with :math:`q` [rad], :math:`\dot q` [rad/s], :math:`K_p` [N·m/rad], :math:`K_d` [N·m·s/rad], the bias
:math:`b` = MuJoCo's ``qfrc_bias`` (gravity + Coriolis/centrifugal) [N·m] when gravity compensation is on,
a feed-forward torque :math:`\tau^{ff}` [N·m] and the actuator range :math:`\tau^{max}` [N·m].

Gains live in YAML, one entry per joint (``configs/gains/*.yaml``)::

    gravity_compensation: true
    joints:
      CHEST_JOINT0: {kp: 400.0, kd: 40.0}   # [N m/rad], [N m s/rad]
      ...
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.robot import JOINT_NAMES
from nextage_qp.scene import package_root
from nextage_qp.yaml_file import read_yaml_mapping


@dataclass(frozen=True)
class Gains:
    """PD gains of the 15 robot joints.

    Attributes:
        kp: Proportional gains [N·m/rad], (15,) in :data:`~nextage_qp.robot.JOINT_NAMES` order.
        kd: Derivative gains [N·m·s/rad], (15,).
        gravity_compensation: Add MuJoCo's bias force (gravity + Coriolis) to the PD torque.
        source: Where the gains came from (file path or ``"<code>"``).
    """

    kp: np.ndarray
    kd: np.ndarray
    gravity_compensation: bool = True
    source: str = "<code>"

    def __post_init__(self) -> None:
        for name in ("kp", "kd"):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.shape != (len(JOINT_NAMES),) or not np.all(np.isfinite(arr)) or np.any(arr < 0):
                raise ConfigError(f"{self.source}: {name} must be {len(JOINT_NAMES)} finite values >= 0, got {arr}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    def as_dict(self) -> dict[str, dict[str, float]]:
        """``{joint: {"kp": .., "kd": ..}}``."""
        return {j: {"kp": float(p), "kd": float(d)} for j, p, d in zip(JOINT_NAMES, self.kp, self.kd, strict=True)}


def gains_path(name: str | Path) -> Path:
    """Resolve a gains file given as a path or a bundled name (``default``, ``report``).

    Raises:
        ConfigError: Neither a file nor a bundled name; the message lists the bundled ones.
    """
    path = Path(name)
    if path.is_file():
        return path
    bundled = package_root() / "configs" / "gains"
    for cand in (bundled / path, bundled / f"{path}.yaml"):
        if cand.is_file():
            return cand
    names = sorted(p.stem for p in bundled.glob("*.yaml"))
    raise ConfigError(f"gains file {str(name)!r} not found; bundled: {', '.join(names)} (or a path to a YAML file)")


def load_gains(path: str | Path) -> Gains:
    """Load and validate a gains YAML file (one ``{kp, kd}`` entry for every robot joint).

    Raises:
        ConfigError: The file is missing or malformed, a joint is missing or unknown, a key is unknown,
            or a gain is not a number >= 0. The message names the file, the key and the valid values.
    """
    file = gains_path(path)
    doc = read_yaml_mapping(file, "a mapping with keys 'joints' and 'gravity_compensation'")
    if bad := sorted(set(doc) - {"joints", "gravity_compensation"}):
        raise ConfigError(f"{file}: unknown key {bad[0]!r}; valid: gravity_compensation, joints")
    joints = doc.get("joints")
    if not isinstance(joints, dict):
        raise ConfigError(f"{file}: joints: expected a mapping JOINT: {{kp, kd}} for every joint")
    valid = ", ".join(JOINT_NAMES)
    for name in joints:
        if name not in JOINT_NAMES:
            raise ConfigError(f"{file}: joints.{name}: unknown joint; valid joints: {valid}")
    if missing := [j for j in JOINT_NAMES if j not in joints]:
        raise ConfigError(f"{file}: joints: missing {', '.join(missing)}; every joint needs an entry; joints: {valid}")
    kp, kd = np.zeros(len(JOINT_NAMES)), np.zeros(len(JOINT_NAMES))
    for i, name in enumerate(JOINT_NAMES):
        entry = joints[name]
        if not isinstance(entry, dict) or set(entry) != {"kp", "kd"}:
            raise ConfigError(f"{file}: joints.{name}: expected {{kp: N m/rad, kd: N m s/rad}}, got {entry!r}")
        for key, arr in (("kp", kp), ("kd", kd)):
            value = entry[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value < np.inf:
                raise ConfigError(f"{file}: joints.{name}.{key}: expected a number >= 0, got {value!r}")
            arr[i] = value
    comp = doc.get("gravity_compensation", True)
    if not isinstance(comp, bool):
        raise ConfigError(f"{file}: gravity_compensation: expected true or false, got {comp!r}")
    try:
        shown = str(file.resolve().relative_to(package_root()))
    except ValueError:
        shown = str(file)
    return Gains(kp, kd, gravity_compensation=comp, source=shown)


class PDController:
    r"""Joint PD torque law with bias compensation, feed-forward and actuator clamping (see module doc).

    Args:
        gains: Per-joint gains and the gravity-compensation switch.
        torque_limit: Actuator limit :math:`\tau^{max}` [N·m] per joint, (15,).

    Attributes:
        ticks: Number of torque evaluations so far.
        saturated_ticks: Per joint, how many evaluations were clamped, (15,).
        any_saturated_ticks: Evaluations where at least one joint was clamped.
    """

    def __init__(self, gains: Gains, torque_limit: np.ndarray) -> None:
        self.gains = gains
        self.torque_limit = np.asarray(torque_limit, dtype=float).copy()
        if self.torque_limit.shape != gains.kp.shape or np.any(self.torque_limit <= 0):
            raise ConfigError(f"torque limits must be {gains.kp.size} values > 0 N m, got {self.torque_limit}")
        self.reset_counters()

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
        r"""Clamped joint torque [N·m], (15,).

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
