r"""PD gains per robot joint: a YAML file, or a rule on each joint's reflected inertia.

A gains file has one entry per robot joint (``configs/gains/*.yaml`` are for the bundled Nextage)::

    gravity_compensation: true
    joints:
      JOINT_NAME: {kp: 400.0, kd: 40.0}     # [N m/rad], [N m s/rad]
      ...

A robot file without one (``gains: {bandwidth: 30, damping_ratio: 1}``) gets gains from a rule: each joint as a
second-order loop on its reflected inertia :math:`I_i = M_{ii}(q_{home})` (armature included),

.. math:: K_{p,i} = I_i\,\omega^2, \qquad K_{d,i} = \max(2 \zeta I_i \omega - d_i,\ 0)

with bandwidth :math:`\omega` [rad/s], damping ratio :math:`\zeta` and the joint's own damping :math:`d_i`
[N m s/rad], which the model already applies.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import mujoco
import numpy as np
from pydantic import Field

from nextage_qp.errors import ConfigError
from nextage_qp.io.schema import YamlModel
from nextage_qp.io.yaml_file import read_yaml_mapping, validate
from nextage_qp.robots.robot_file import GainRule
from nextage_qp.scene.files import package_root

if TYPE_CHECKING:
    from nextage_qp.robots.model import Robot

NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False, strict=True)]


class JointGains(YamlModel):
    """One joint's gains: ``kp`` [N·m/rad] and ``kd`` [N·m·s/rad], finite and >= 0."""

    kp: NonNegative = Field(description="Proportional gain [N m/rad].")
    kd: NonNegative = Field(description="Derivative gain [N m s/rad].")


class GainsFile(YamlModel):
    """The schema of a gains YAML: one entry per robot joint and the gravity-compensation switch."""

    gravity_compensation: bool = Field(
        default=True, strict=True,
        description="Add MuJoCo's bias force (gravity, Coriolis and centrifugal) to the PD torque.")
    joints: dict[str, JointGains] = Field(description="Joint -> its gains; every robot joint, and no other.")


@dataclass(frozen=True)
class Gains:
    """PD gains of the robot's joints, as arrays in the robot's joint order.

    Attributes:
        kp: Proportional gains [N·m/rad], one per joint.
        kd: Derivative gains [N·m·s/rad].
        gravity_compensation: Add MuJoCo's bias force (gravity + Coriolis) to the PD torque.
        source: Where the gains came from (file path, ``"rule"`` or ``"<code>"``).
        names: The joints, in the arrays' order (empty: not named).
    """

    kp: np.ndarray
    kd: np.ndarray
    gravity_compensation: bool = True
    source: str = "<code>"
    names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        n = len(np.atleast_1d(self.kp))
        for name in ("kp", "kd"):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.shape != (n,) or not np.all(np.isfinite(arr)) or np.any(arr < 0):
                raise ConfigError(f"{self.source}: {name} must be {n} finite values >= 0, got {arr}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if self.names and len(self.names) != n:
            raise ConfigError(f"{self.source}: {n} gains for {len(self.names)} joints")

    @classmethod
    def from_file(cls, doc: GainsFile, source: str, names: Sequence[str]) -> Gains:
        """Arrays in the order of ``names`` from a validated gains file (every joint, no other).

        Raises:
            ConfigError: A joint is missing or unknown; the message lists the robot's joints.
        """
        valid = ", ".join(names)
        if bad := [j for j in doc.joints if j not in names]:
            raise ConfigError(f"{source}: joints: unknown joint {bad[0]!r}; valid joints: {valid}")
        if missing := [j for j in names if j not in doc.joints]:
            raise ConfigError(
                f"{source}: joints: missing {', '.join(missing)}; every joint needs an entry; joints: {valid}"
            )
        kp = [doc.joints[j].kp for j in names]
        kd = [doc.joints[j].kd for j in names]
        return cls(np.array(kp), np.array(kd), doc.gravity_compensation, source, tuple(names))

    def as_dict(self) -> dict[str, dict[str, float]]:
        """``{joint: {"kp": .., "kd": ..}}``."""
        return {j: {"kp": float(p), "kd": float(d)} for j, p, d in zip(self.names, self.kp, self.kd, strict=True)}


def gains_path(name: str | Path, bundled: Path | None = None) -> Path:
    """Resolve a gains file given as a path or a bundled name (``default``, ``report``: in ``bundled``).

    Raises:
        ConfigError: Neither a file nor a bundled name; the message lists the bundled ones.
    """
    path = Path(name)
    if path.is_file():
        return path
    bundled = bundled or package_root() / "configs" / "gains"
    for cand in (bundled / path, bundled / f"{path}.yaml"):
        if cand.is_file():
            return cand
    names = sorted(p.stem for p in bundled.glob("*.yaml"))
    raise ConfigError(
        f"gains file {str(name)!r} not found; bundled: {', '.join(names) or 'none'} (or a path to a YAML file)"
    )


@functools.cache
def _default_robot() -> Robot:
    from nextage_qp.robots.model import Robot

    return Robot.from_scene("scene")


def load_gains(path: str | Path, robot: Robot | None = None) -> Gains:
    """Load and validate a gains YAML file for a robot (default: the default robot), one entry per joint.

    A bare name (``default``) is looked up in the robot file's ``gains_dir``.

    Raises:
        ConfigError: The file is missing or malformed, a joint is missing or unknown, a key is unknown,
            or a gain is not a finite number >= 0. The message names the file, the key and the valid values.
    """
    robot = robot or _default_robot()
    file = gains_path(path, robot.description.gains_dir)
    doc = read_yaml_mapping(file, "a mapping with keys 'joints' and 'gravity_compensation'")
    try:
        shown = str(file.resolve().relative_to(package_root()))
    except ValueError:
        shown = str(file)
    return Gains.from_file(validate(GainsFile, doc, str(file)), shown, robot.joint_names)


def robot_gains(robot: Robot) -> Gains:
    """The robot file's gains: its gains file, or the rule (see the module docstring)."""
    spec = robot.description.gains
    if isinstance(spec, Path):
        return load_gains(spec, robot)
    return rule_gains(robot, spec)


PROFILES = {"default": 1.0, "stiff_wrist": 2.0}
"""Named gains a task config may ask of any robot (``gains: NAME``) where its robot file has no file of that name:
the rule's gains with the last three joints of each arm (forearm roll and wrist) this many times faster (a stiff
wrist holds the hand's pose under contact forces; ``default``: the rule's own)."""


def config_gains(name: str, robot: Robot) -> Gains:
    """The gains a task config names: a file (a path, or bundled in the robot file's ``gains_dir``), or a profile.

    A profile (:data:`PROFILES`) serves a robot whose gains come from the rule and that bundles no file of that name.

    Raises:
        ConfigError: Neither a gains file nor a profile this robot has.
    """
    desc = robot.description
    if name in PROFILES and isinstance(desc.gains, GainRule) and not Path(name).is_file() and (
            desc.gains_dir is None or not any((desc.gains_dir / n).is_file() for n in (name, f"{name}.yaml"))):
        wrists = [robot.joint_index(j) for arm in robot.arms for j in arm.joints[-3:]]
        return rule_gains(robot, desc.gains, faster=dict.fromkeys(wrists, PROFILES[name]), source=name)
    return load_gains(name, robot)


def rule_gains(robot: Robot, rule: GainRule, faster: dict[int, float] | None = None,
               source: str = "rule") -> Gains:
    """Gains from each joint's reflected inertia at ``home`` (see the module docstring).

    ``faster``: joint index -> factor on the rule's bandwidth for that joint.
    """
    m = robot.model
    d = mujoco.MjData(m)
    robot.set_q(d, robot.keyframe_q("home"))
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    if hasattr(d, "qM"):  # MuJoCo 3: mj_fullM(m, dst, qM)
        mujoco.mj_fullM(m, full, d.qM)
    else:  # MuJoCo 4: mj_fullM(m, d, dst)
        mujoco.mj_fullM(m, d, full)
    inertia = full[robot.dof_idx, robot.dof_idx]
    w, zeta = np.full(robot.nq, rule.bandwidth), rule.damping_ratio
    for j, factor in (faster or {}).items():
        w[j] *= factor
    kp = inertia * w * w
    kd = np.maximum(2.0 * zeta * inertia * w - m.dof_damping[robot.dof_idx], 0.0)
    return Gains(kp, kd, rule.gravity_compensation, source, robot.joint_names)
