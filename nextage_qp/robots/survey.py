"""What ``robot init`` and ``robot check`` learn from a model file alone: arms, home, limits, angle unit, mount."""

from __future__ import annotations

import importlib.util
import os
import re
from dataclasses import dataclass
from pathlib import Path

import mujoco

from nextage_qp.errors import ConfigError
from nextage_qp.robots.arms import FoundArms, find_arms
from nextage_qp.robots.description import Arm, RobotDescription
from nextage_qp.robots.modelfile import (
    angle_trap,
    compile_alone,
    declared_angle,
    model_spec,
    model_torque_limit,
    self_contacts,
)
from nextage_qp.robots.poses import Home, find_home, lowest_point
from nextage_qp.robots.robot_file import GainRule, MountFile

MOVING = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
GENERIC_STEMS = ("robot", "model", "scene", "main")
"""Model file names that say nothing: the robot is named after the model's folder instead."""


@dataclass(frozen=True)
class Survey:
    """A model file as ``robot init`` sees it.

    Attributes:
        path: The model file.
        name: The robot's name (the file's stem, or its folder's when the stem is generic, e.g. ``robot.xml``).
        angle: The unit to write in the robot file (None: the model states it or needs none).
        angle_why: Why that unit.
        model: The model compiled on its own (with ``angle``).
        joints: Its hinge and slide joints.
        arms: The arms found.
        home: The home pose (the model's first keyframe, else searched).
        keyframe: The name of the model's keyframe used as home, or None.
        inertia: MuJoCo's complaint about a mass or inertia, if any.
    """

    path: Path
    name: str
    angle: str | None
    angle_why: str
    model: mujoco.MjModel
    joints: list[int]
    arms: FoundArms
    home: Home
    keyframe: str | None
    inertia: str | None


def robot_name(path: Path) -> str:
    """The robot's name from its model file: the stem, or the folder's name when the stem is generic."""
    return path.parent.name if path.stem.lower() in GENERIC_STEMS and path.parent.name else path.stem


def survey(path: Path, *, angle: str | None = None, search_home: bool = True, fix_angle: bool = True,
           lenient: bool = False) -> Survey:
    """Read a model file, find its arms and a home (see :mod:`nextage_qp.robots.arms`, :func:`find_home`).

    Args:
        path: An MJCF (``.xml``) or URDF (``.urdf``).
        angle: Force this angle unit; None: radian when the MJCF states none and its ranges look like radians.
        search_home: Without a keyframe, search a pose free of self-contact (else ``qpos0``).
        fix_angle: Read an MJCF whose ranges look like radians but states no unit in radians (else as MuJoCo does).
        lenient: Leave out a URDF's unusable meshes instead of refusing it (``robot check`` reports them).

    Raises:
        ConfigError: The file is not a model MuJoCo reads, or it has no arm.
    """
    shown = str(path)
    if path.suffix.lower() not in (".xml", ".urdf"):
        raise ConfigError(f"{shown}: expected an MJCF (.xml) or URDF (.urdf) model")
    if not path.is_file():
        raise ConfigError(f"{shown}: model file not found")
    spec, _ = model_spec(path, (), shown, lenient=lenient)
    why = ""
    if angle is None and fix_angle and angle_trap(path, spec):
        angle, why = "radian", "the MJCF states no angle unit (MuJoCo would read degrees) and every hinge range " \
                               "lies within +-2 pi, so they are radians"
    elif angle is not None:
        stated = declared_angle(path)
        why = "as asked" + (f" (the model states {stated})" if stated and stated != angle else "")
    if angle is not None:
        spec.compiler.degree = angle == "degree"
    model, inertia = compile_alone(spec, shown)
    joints = [j for j in range(model.njnt) if int(model.jnt_type[j]) in MOVING]
    data = mujoco.MjData(model)
    keyframe = None
    if model.nkey:
        keyframe = model.key(0).name or "0"
        qpos = model.key_qpos[0].copy()
        home = Home(qpos, f"the model's keyframe {keyframe!r}", self_contacts(model, data, qpos))
    elif search_home:
        home = find_home(model, joints)
    else:
        home = Home(model.qpos0.copy(), "qpos0", self_contacts(model, data, model.qpos0))
    data.qpos[:] = home.qpos
    mujoco.mj_kinematics(model, data)
    arms = find_arms(model, data, re.sub(r"[^a-z0-9]+", "_", robot_name(path).lower()).strip("_") or "arm")
    if not arms.arms:
        raise ConfigError(f"{shown}: no arm found (an arm is a chain of at least 4 hinge or slide joints from the "
                          f"root); write the robot file by hand (docs/robots.md)")
    return Survey(path, robot_name(path), angle, why, model, joints, arms, home, keyframe, inertia)


def model_reference(path: Path, folder: Path) -> str:
    """How a robot file in ``folder`` names the model.

    ``package://NAME/...`` inside an installed Python package (found with :func:`importlib.util.find_spec`, never
    imported), else a path relative to ``folder``.
    """
    path = path.resolve()
    for parent in path.parents:
        if not parent.name.isidentifier() or parent.name.startswith("_"):
            continue
        try:
            spec = importlib.util.find_spec(parent.name)
        except (ImportError, ValueError):
            continue
        if spec and spec.submodule_search_locations and any(
                Path(p).resolve() == parent for p in spec.submodule_search_locations):
            if "site-packages" in parent.parts or "dist-packages" in parent.parts:
                return f"package://{parent.name}/{path.relative_to(parent).as_posix()}"
    return Path(os.path.relpath(path, folder.resolve())).as_posix()


def home_values(s: Survey) -> dict[str, float]:
    """The home pose as joint -> value [rad or m], every moving joint."""
    return {s.model.joint(j).name: float(s.home.qpos[s.model.jnt_qposadr[j]]) for j in s.joints}


def bare_description(path: Path) -> RobotDescription:
    """A robot description of a model file on its own, for ``robot check MODEL``.

    The arms found, the model's angle unit as it stands, home = its first keyframe (else ``qpos0``), every moving
    joint listed.

    Raises:
        ConfigError: As :func:`survey`.
    """
    s = survey(path.resolve(), search_home=False, fix_angle=False, lenient=True)
    names = [s.model.joint(j).name for j in s.joints]
    arms = tuple(Arm(a.name, tuple(names[s.joints.index(j)] for j in a.joints), a.wrist, a.wrist, a.wrist, False)
                 for a in s.arms.arms)
    groups = {"torso": tuple(s.model.joint(j).name for j in s.arms.torso)} if s.arms.torso else {}
    groups |= {k: tuple(s.model.joint(j).name for j in v) for k, v in s.arms.groups.items()}
    driven = {int(s.model.actuator_trnid[a, 0]) for a in range(s.model.nu)
              if int(s.model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)}
    own = {names[k]: limit for k, j in enumerate(s.joints)  # a URDF's efforts: what robot init writes
           if j not in driven and (limit := model_torque_limit(s.model, j)) is not None}
    return RobotDescription(
        name=s.name, source=str(path), model=path.resolve(), angle=None, package_paths=(), mount=MountFile(),
        arms=arms, joint_groups=groups, frames={}, collision_groups={}, exclude=(),
        keyframes={"home": {k: v for k, v in home_values(s).items() if v != 0.0}}, gains=GainRule(),
        gains_dir=None, torque_limits=own or None, velocity_limits=None,
    )


def lowest_z(s: Survey) -> float | None:
    """World z [m] of the lowest collision geometry at home."""
    return lowest_point(s.model, s.home.qpos)


def joint_names(s: Survey, joints: tuple[int, ...] | list[int]) -> list[str]:
    """Names of model joints."""
    return [s.model.joint(int(j)).name for j in joints]
