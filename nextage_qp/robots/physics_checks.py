"""The physical diagnoses of ``robot check``: masses and inertias, self-contact at home, actuators, gravity load."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

import mujoco
import numpy as np

from nextage_qp.robots.description import RobotDescription
from nextage_qp.robots.model_checks import MOVING, Finding
from nextage_qp.robots.modelfile import model_torque_limit, self_contacts

MIN_MASS = 1e-6
"""[kg] and [kg m^2]: a moving body lighter than this, or with a principal moment below it, is flagged."""
SPEED = 1.0
"""[rad/s]: the joint speed the shipped task configs allow (their trajectories' ``max_velocity``): a joint whose
damping at this speed takes more torque than its motor has left after holding home is named."""


def inertias(spec: mujoco.MjSpec, model: mujoco.MjModel, refused: str | None,
             corrections: tuple[bool, float, float]) -> list[Finding]:
    """Masses and inertias MuJoCo refuses or corrects, moving bodies too light, moments breaking a + b >= c.

    ``corrections``: the model's own ``balanceinertia``, ``boundmass`` and ``boundinertia``.
    """
    out = []
    if refused:
        out.append(Finding("problem", "inertia", f"MuJoCo refuses the model: {refused}",
                           "give the body a realistic <inertial>: mass > 0, principal moments with a + b >= c"))
    if any(corrections):
        out.append(Finding("info", "inertia", "the model asks MuJoCo to correct inertias (balanceinertia, boundmass "
                           "or boundinertia)", "give the real values to rely on them"))
    for body in spec.bodies:
        if not body.explicitinertial:
            continue
        full = np.asarray(body.fullinertia, dtype=float)
        if np.isnan(full[0]):
            moments = np.sort(np.asarray(body.inertia, dtype=float))
        else:
            moments = np.linalg.eigvalsh(np.array([[full[0], full[3], full[4]], [full[3], full[1], full[5]],
                                                   [full[4], full[5], full[2]]]))
        if np.any(moments > 0) and moments[0] + moments[1] < moments[2] * (1 - 1e-6):
            out.append(Finding("problem", "inertia", f"body {body.name!r}: principal moments {np.round(moments, 8)} "
                               "break the triangle inequality (a + b >= c)", "fix the inertia tensor"))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    for b in range(1, model.nbody):
        if not any(int(model.jnt_type[j]) in MOVING for j in range(model.body_jntadr[b],
                                                                    model.body_jntadr[b] + model.body_jntnum[b])):
            continue
        mass, moments = _rigid(model, data, b)
        if mass < MIN_MASS or moments[0] < MIN_MASS:
            out.append(Finding("problem", "inertia", f"body {model.body(b).name!r} moves on a joint with mass "
                               f"{mass:.3g} kg, smallest moment {moments[0]:.3g} kg m^2 (with what is fixed to it)",
                               "give it a realistic <inertial>"))
    return out


def _rigid(model: mujoco.MjModel, data: mujoco.MjData, body: int) -> tuple[float, np.ndarray]:
    """Mass [kg] and principal moments [kg m^2] of ``body`` with the bodies welded to it."""
    group = [b for b in range(model.nbody) if int(model.body_weldid[b]) == body]
    mass = float(sum(model.body_mass[b] for b in group))
    if mass <= 0:
        return mass, np.zeros(3)
    com = sum(model.body_mass[b] * data.xipos[b] for b in group) / mass
    inertia = np.zeros((3, 3))
    for b in group:
        rot = data.ximat[b].reshape(3, 3)
        r = data.xipos[b] - com
        inertia += rot @ np.diag(model.body_inertia[b]) @ rot.T
        inertia += model.body_mass[b] * (r @ r * np.eye(3) - np.outer(r, r))
    return mass, np.linalg.eigvalsh(inertia)


def self_contact(model: mujoco.MjModel, qpos: np.ndarray) -> list[Finding]:
    """Body pairs in contact at home."""
    pairs = self_contacts(model, mujoco.MjData(model), qpos)
    if not pairs:
        return []
    shown = ", ".join(f"[{a}, {b}]" for a, b in pairs)
    return [Finding("problem", "contact", f"at home these bodies touch: {shown}",
                    f"add them to exclude (exclude: [{shown}]) or choose another home")]


def actuators(model: mujoco.MjModel, desc: RobotDescription) -> list[Finding]:
    """Actuators that are not gear-1 joint motors, and robot joints without a torque limit.

    The PD loop writes torques [N m] into ``ctrl``: a gear or a servo would misread them.
    """
    out = []
    listed = set(desc.joints)
    for a in range(model.nu):
        joint = model.joint(int(model.actuator_trnid[a, 0])).name if int(model.actuator_trntype[a]) == int(
            mujoco.mjtTrn.mjTRN_JOINT) else None
        motor = (int(model.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED) and float(
            model.actuator_gainprm[a, 0]) == 1.0 and int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_NONE))
        if joint is not None and motor and abs(float(model.actuator_gear[a, 0]) - 1.0) < 1e-12:
            continue
        what = ("drives no joint" if joint is None else f"is not a gear-1 motor (gear "
                f"{model.actuator_gear[a, 0]:g}{'' if motor else ', a servo'})")
        level: Literal["problem", "info"] = "problem" if joint in listed else "info"
        out.append(Finding(level, "actuator", f"actuator {model.actuator(a).name!r} {what}"
                           + (f" on robot joint {joint!r}: the PD torque would be misread" if level == "problem"
                              else ""), "make it a <motor gear=\"1\"> on the joint, or remove it (the robot file's "
                           "torque_limits then bound the motor added)" if level == "problem" else ""))
    given = desc.torque_limits
    driven = {int(model.actuator_trnid[a, 0]) for a in range(model.nu)
              if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)}
    for name in desc.joints:
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j < 0 or isinstance(given, float | int) or (given is not None and name in given):
            continue
        limit = model_torque_limit(model, j)
        if j not in driven:
            value = f"{limit:g}" if limit is not None else "N"
            out.append(Finding("problem", "torque", f"joint {name!r} has no actuator and the robot file gives it no "
                               "torque limit, which the motor added for it needs", f"torque_limits: {{{name}: "
                               f"{value}}} [N m] in the robot file" + (" (the model's effort limit)" if limit else "")))
        elif limit is None:
            out.append(Finding("problem", "torque", f"joint {name!r}: neither the model nor the robot file gives a "
                               "torque limit", f"torque_limits: {{{name}: N}} [N m] in the robot file"))
    return out


def file_or_model_limit(model: mujoco.MjModel, joint: int, given: float | Mapping[str, float] | None) -> float | None:
    """A joint's torque limit [N m]: the robot file's ``torque_limits`` where given, else the model's, else None."""
    if isinstance(given, float | int):
        return float(given)
    name = model.joint(joint).name
    if given is not None and name in given:
        return float(given[name])
    return model_torque_limit(model, joint)


def home_load(model: mujoco.MjModel, desc: RobotDescription, qpos: np.ndarray) -> list[Finding]:
    """Robot joints whose motors cannot hold home (they sag: a problem) or lag references at :data:`SPEED`.

    Both from each joint's torque limit and its gravity torque at home: the damping finding names joints whose
    viscous damping at that speed takes more than the motor has left after gravity (the TIAGo of robosuite: 100 N m
    s/rad on a +-50 N m shoulder), with the velocity limit at which the motor still drives them.
    """
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    weak, slow = [], {}
    for name in desc.joints:
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        limit = file_or_model_limit(model, j, desc.torque_limits) if j >= 0 else None
        if limit is None:
            continue
        dof = model.jnt_dofadr[j]
        load = abs(float(data.qfrc_bias[dof]))
        if load > limit:
            weak.append(f"{name} ({load:.3g} > {limit:g} N m)")
        damping, spare = float(model.dof_damping[dof]), limit - load
        if damping * SPEED > spare > 0:
            slow[name] = (damping, limit, np.floor(100 * spare / damping) / 100)  # rounded down: it holds
    out = []
    if weak:
        out.append(Finding("problem", "torque", f"holding home takes more gravity torque than the limit: "
                           f"{', '.join(weak)}; these joints sag under PD control", "give them larger torque_limits "
                           "in the robot file (they override the model's) if the real actuators allow it, or choose "
                           "another home"))
    if slow:
        named = ", ".join(f"{n} ({d:g} N m s/rad, {lim:g} N m: {v:g} rad/s)" for n, (d, lim, v) in slow.items())
        limits = ", ".join(f"{n}: {v:g}" for n, (_, _, v) in slow.items())
        out.append(Finding("info", "torque", f"at {SPEED:g} rad/s the damping of these joints takes more torque than "
                           f"their motors have left after holding home, so they lag faster references: {named}",
                           f"velocity_limits: {{{limits}}} [rad/s] in the robot file, or lower damping where the "
                           "model overstates it"))
    return out
