"""``robot check``: a robot file (or a bare model) read, compiled on its own and diagnosed, on one screen.

:func:`check_robot` returns a :class:`CheckReport`: the joints with their limits, the arms and their frames, the
masses, the actuators, and the findings of :mod:`nextage_qp.robots.model_checks`, each a line with its fix. A robot
file's
names that the model lacks are findings here (``info`` and task commands refuse them at once).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from nextage_qp.robots import model_checks as checks
from nextage_qp.robots import physics_checks
from nextage_qp.robots.description import RobotDescription, load_robot
from nextage_qp.robots.model_checks import Finding
from nextage_qp.robots.modelfile import compile_alone, model_spec

if TYPE_CHECKING:
    from nextage_qp.robots.model import Robot


@dataclass
class CheckReport:
    """What ``robot check`` prints: tables of plain data and the findings."""

    source: str
    model: str
    joints: list[dict[str, Any]] = field(default_factory=list)
    arms: list[dict[str, Any]] = field(default_factory=list)
    actuators: list[dict[str, Any]] = field(default_factory=list)
    total_mass_kg: float = 0.0
    moving_mass_kg: float = 0.0
    findings: list[Finding] = field(default_factory=list)

    @property
    def problems(self) -> list[Finding]:
        """The findings that need a fix."""
        return [f for f in self.findings if f.level == "problem"]

    def as_dict(self) -> dict[str, Any]:
        """Plain data for ``--json``."""
        out = {k: v for k, v in self.__dict__.items() if k != "findings"}
        return out | {"findings": [f._asdict() for f in self.findings], "problems": len(self.problems)}


def describe(ref: str | Path) -> RobotDescription:
    """The description to check: a robot file's, or a bare model's (arms found as ``robot init`` finds them).

    Raises:
        ConfigError: The file cannot be read.
    """
    path = Path(ref)
    if path.suffix.lower() in (".xml", ".urdf"):
        from nextage_qp.robots.survey import bare_description

        return bare_description(path)
    return load_robot(path)


def check_robot(ref: str | Path) -> CheckReport:
    """Diagnose a robot file or a model file (see the module doc).

    Raises:
        ConfigError: The file, or its model, cannot be read or compiled at all.
    """
    desc = describe(ref)
    spec, issues = model_spec(desc.model, desc.package_paths, desc.source, lenient=True)
    found = checks.meshes(issues) + checks.angle_unit(desc, spec) + checks.reversed_ranges(desc, spec)
    if desc.angle is not None:
        spec.compiler.degree = desc.angle == "degree"
    bodies = {b.name for b in spec.bodies if b.name}
    for name, frame in desc.frames.items():
        if spec.site(name) is not None:
            found.append(Finding("problem", "frame", f"frames.{name}: the model has a site {name!r} already",
                                 "use the model's site, or give the frame another name"))
        elif frame.body in bodies:
            spec.body(frame.body).add_site(name=name, pos=list(frame.pos), quat=list(frame.quat))
    for a, b in desc.exclude:
        if a in bodies and b in bodies:
            spec.add_exclude(bodyname1=a, bodyname2=b)
    own = (bool(spec.compiler.balanceinertia), float(spec.compiler.boundmass), float(spec.compiler.boundinertia))
    model, refused = compile_alone(spec, desc.source)
    found += checks.names(model, desc)
    if desc.model.suffix.lower() == ".urdf":
        fused, _ = model_spec(desc.model, desc.package_paths, desc.source, lenient=True, fuse=True)
        found += checks.fused_urdf_links(desc.model, model, compile_alone(fused, desc.source)[0])
    else:
        found += checks.fused_mjcf_bodies(desc.model, model)
    found += physics_checks.inertias(spec, model, refused, own)
    home, home_problem = home_qpos(model, desc)
    found += home_problem + physics_checks.self_contact(model, home) + physics_checks.home_load(model, desc, home)
    found += checks.reach(model, desc) + checks.left_out(model, desc) + physics_checks.actuators(model, desc)
    if Path(ref).suffix.lower() not in (".xml", ".urdf") and not any(f.level == "problem" for f in found):
        found += _as_the_commands_load_it(ref)
    report = CheckReport(desc.source, str(desc.model), findings=found)
    _tables(report, model, desc)
    return report


def _as_the_commands_load_it(ref: str | Path) -> list[Finding]:
    """What the commands refuse of the robot file in a task scene: its gains, limits and keyframes as they load them."""
    from nextage_qp.errors import ConfigError
    from nextage_qp.robots.gains import robot_gains
    from nextage_qp.robots.model import Robot

    try:
        robot = Robot.from_scene("scene", robot=str(ref))
        robot_gains(robot)
        check_own_names(robot)
    except ConfigError as exc:
        return [Finding("problem", "load", str(exc), "the commands refuse the robot file so: fix what it names")]
    return []


def check_own_names(robot: Robot) -> None:
    """Resolve the names the robot file itself gives: its collision groups' bodies and its keyframes' joints.

    Raises:
        ConfigError: Naming the robot file and the key (``keyframes.home: unknown joint 'FOO'; valid: ...``), or a
            keyframe value out of its joint's range.
    """
    from nextage_qp.errors import ConfigError, UnknownNameError

    where = "collision_groups"
    try:
        robot.collision_geoms()
        for key in robot.description.keyframes:
            where = f"keyframes.{key}"
            robot.keyframe_q(key)
    except UnknownNameError as exc:
        raise ConfigError(f"{robot.description.source}: {where}: {exc}") from None


def home_qpos(model: mujoco.MjModel, desc: RobotDescription) -> tuple[np.ndarray, list[Finding]]:
    """The full ``qpos`` of the robot file's ``home`` (its joints not named are 0), and what is wrong with it."""
    key = desc.keyframes.get("home")
    qpos = model.qpos0.copy()
    problems: list[Finding] = []
    if isinstance(key, str):
        kid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home")
        if kid < 0:
            return qpos, [Finding("problem", "home", "keyframes.home: model, but the model has no keyframe 'home'",
                                  "give home as joint -> value, or run robot init for a pose free of contact")]
        qpos = model.key_qpos[kid].copy()
        values = {name: float(qpos[model.jnt_qposadr[j]]) for name in desc.joints
                  if (j := mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)) >= 0}
    else:
        for name in desc.joints:
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if j >= 0:
                qpos[model.jnt_qposadr[j]] = 0.0
        values = dict(key or {})
    for name, value in values.items():
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j < 0 or name not in desc.joints:
            problems.append(Finding("problem", "home", f"keyframes.home.{name}: not a joint of the robot",
                                    "name the robot file's joints"))
            continue
        qpos[model.jnt_qposadr[j]] = value
        lo, hi = model.jnt_range[j]
        if not np.isfinite(value) or (model.jnt_limited[j] and not lo - 1e-9 <= value <= hi + 1e-9):
            problems.append(Finding("problem", "home", f"keyframes.home.{name}: {value:g} is outside the range "
                                    f"[{lo:.4g}, {hi:.4g}]", "choose a value in range"))
    return qpos, problems


def _tables(report: CheckReport, model: mujoco.MjModel, desc: RobotDescription) -> None:
    """Fill the report's tables from the compiled model."""
    group = {j: arm.name for arm in desc.arms for j in arm.joints}
    group |= {j: g for g, joints in desc.joint_groups.items() for j in joints}
    given = desc.torque_limits
    for j in range(model.njnt):
        if int(model.jnt_type[j]) not in checks.MOVING:
            continue
        name = model.joint(j).name
        limit = physics_checks.file_or_model_limit(model, j, given)
        report.joints.append({
            "name": name, "group": group.get(name, "-"),
            "type": "hinge" if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE) else "slide",
            "lower": float(model.jnt_range[j, 0]) if model.jnt_limited[j] else None,
            "upper": float(model.jnt_range[j, 1]) if model.jnt_limited[j] else None,
            "damping": float(model.dof_damping[model.jnt_dofadr[j]]),
            "armature": float(model.dof_armature[model.jnt_dofadr[j]]),
            "torque_limit_nm": limit,
        })
    for arm in desc.arms:
        frames = {role: getattr(arm, role) for role in ("wrist", "tool", "pad")}
        bodies = {role: checks.frame_body(model, desc, f) for role, f in frames.items()}
        report.arms.append({"name": arm.name, "joints": list(arm.joints), **frames,
                            "wrist_body": model.body(bodies["wrist"]).name if bodies["wrist"] >= 0 else None})
    for a in range(model.nu):
        on_joint = int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
        report.actuators.append({
            "name": model.actuator(a).name, "joint": model.joint(int(model.actuator_trnid[a, 0])).name
            if on_joint else None, "gear": float(model.actuator_gear[a, 0]),
            "ctrlrange": model.actuator_ctrlrange[a].tolist() if model.actuator_ctrllimited[a] else None,
        })
    robot = list(range(1, model.nbody))
    report.total_mass_kg = float(np.sum(model.body_mass[robot])) if robot else 0.0
    report.moving_mass_kg = float(sum(model.body_mass[b] for b in robot if model.body_weldid[b] != 0))

