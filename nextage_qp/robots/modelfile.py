"""A robot's model file on its own: read as a spec (MJCF or URDF), its angle unit, compiled alone, its contacts.

``robot init`` and ``robot check`` look at the model before any robot file shapes it; the task scenes compose it
with :mod:`nextage_qp.robots.compose` instead.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, one_line
from nextage_qp.robots.urdf import KEEP_FRAMES, MeshIssue, read_urdf, resolve_meshes, set_compiler, spec_from_tree

MASS_WORDS = ("mass", "inertia")
"""Words of MuJoCo's compile errors about a body's mass or inertia."""


def model_spec(path: Path, package_paths: tuple[Path, ...], source: str, *, lenient: bool = False,
               fuse: bool = False) -> tuple[mujoco.MjSpec, list[MeshIssue]]:
    """The model file as a spec, with the meshes a URDF cannot use (none for an MJCF).

    Args:
        path: An MJCF (``.xml``) or URDF (``.urdf``) file.
        package_paths: Folders ``package://`` mesh paths are looked up in.
        source: What messages name.
        lenient: A URDF's unusable meshes are left out (and returned) instead of refused.
        fuse: A URDF's fixed-joint links are fused as MuJoCo does by default (to see which ones would vanish).

    Raises:
        ConfigError: The file cannot be read or parsed (a mesh of a URDF, unless ``lenient``).
    """
    if path.suffix.lower() != ".urdf":
        try:
            return mujoco.MjSpec.from_file(str(path)), []
        except ValueError as exc:
            raise ConfigError(f"{source}: model {path}: {one_line(exc)}") from None
    if not lenient and not fuse:
        from nextage_qp.robots.urdf import urdf_spec

        return urdf_spec(path, package_paths, source), []
    root = read_urdf(path, source)
    issues = resolve_meshes(root, path.parent, package_paths, drop=True)
    set_compiler(root, **{**KEEP_FRAMES, "fusestatic": "true" if fuse else "false"})
    return spec_from_tree(root, path, source), issues


def _compilers(path: Path, seen: set[Path]) -> list[ET.Element]:
    """The ``<compiler>`` elements of an MJCF and the files it includes (comments are not elements)."""
    if path in seen or not path.is_file():
        return []
    seen.add(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return []
    found = list(root.iter("compiler"))
    for include in root.iter("include"):
        if file := include.get("file"):
            found += _compilers((path.parent / file).resolve(), seen)
    return found


def declared_angle(path: Path) -> str | None:
    """The angle unit the model file states: a URDF's is radian; an MJCF's ``<compiler angle>``, or None."""
    if path.suffix.lower() == ".urdf":
        return "radian"
    angles = [c.get("angle") for c in _compilers(path.resolve(), set()) if c.get("angle")]
    return angles[-1] if angles else None


def hinge_ranges(spec: mujoco.MjSpec) -> list[tuple[str, float, float]]:
    """Each hinge joint's range as written in the file (before the compiler converts degrees)."""
    out = []
    for joint in spec.joints:
        lo, hi = (float(v) for v in joint.range)
        if joint.type == mujoco.mjtJoint.mjJNT_HINGE and (lo, hi) != (0.0, 0.0):
            out.append((joint.name, lo, hi))
    return out


def ranges_look_like_radians(spec: mujoco.MjSpec) -> bool:
    """True when the spec has hinge ranges and every one lies within +-2 pi (a few degrees, were they degrees)."""
    ranges = hinge_ranges(spec)
    return bool(ranges) and all(-2 * math.pi <= lo and hi <= 2 * math.pi for _, lo, hi in ranges)


def angle_trap(path: Path, spec: mujoco.MjSpec) -> bool:
    """An MJCF that states no angle unit (so MuJoCo reads degrees) while its hinge ranges look like radians."""
    return (path.suffix.lower() != ".urdf" and declared_angle(path) is None and bool(spec.compiler.degree)
            and ranges_look_like_radians(spec))


def compile_alone(spec: mujoco.MjSpec, source: str) -> tuple[mujoco.MjModel, str | None]:
    """The spec compiled on its own; MuJoCo's complaint about a mass or inertia, if it had one.

    A model MuJoCo refuses for its masses or inertias is compiled again with them bounded (1e-10) and balanced, so
    the other checks can still look at it.

    Raises:
        ConfigError: MuJoCo refuses the model for another reason.
    """
    try:
        return spec.compile(), None
    except ValueError as exc:
        message = one_line(exc)
        if not any(word in message.lower() for word in MASS_WORDS):
            raise ConfigError(f"{source}: the model does not compile: {message}") from None
    spec.compiler.boundmass = max(spec.compiler.boundmass, 1e-10)  # above MuJoCo's floor, below every check's
    spec.compiler.boundinertia = max(spec.compiler.boundinertia, 1e-10)
    spec.compiler.balanceinertia = True
    try:
        return spec.compile(), message
    except ValueError as exc:
        raise ConfigError(f"{source}: the model does not compile: {one_line(exc)}") from None


def body_names(model: mujoco.MjModel) -> list[str]:
    """Names of the model's bodies, world excluded."""
    return [model.body(b).name for b in range(1, model.nbody)]


def self_contacts(model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray) -> list[tuple[str, str]]:
    """Pairs of bodies (world excluded) in contact at ``qpos``, sorted, each once."""
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_collision(model, data)
    pairs = set()
    for c in data.contact[: data.ncon]:
        b1, b2 = (int(model.geom_bodyid[g]) for g in c.geom)
        if b1 and b2 and b1 != b2:
            n1, n2 = model.body(b1).name, model.body(b2).name
            pairs.add((n1, n2) if n1 <= n2 else (n2, n1))
    return sorted(pairs)


def descendants(model: mujoco.MjModel, body: int) -> list[int]:
    """``body`` and every body below it, in model order."""
    return [b for b in range(body, model.nbody) if _below(model, b, body)]


def _below(model: mujoco.MjModel, b: int, root: int) -> bool:
    while b > root:
        b = int(model.body_parentid[b])
    return b == root


def moved_by(model: mujoco.MjModel, body: int) -> list[int]:
    """The joints that move ``body`` (on it and on its ancestors), root first."""
    chain: list[int] = []
    while body > 0:
        adr, num = int(model.body_jntadr[body]), int(model.body_jntnum[body])
        chain = list(range(adr, adr + num)) + chain
        body = int(model.body_parentid[body])
    return chain


def model_torque_limit(model: mujoco.MjModel, joint: int) -> float | None:
    """The torque limit [N m] the model gives a joint, or None.

    The tightest of: a joint actuator's force range, the joint's actuator-force range, a motor's control range x gear.
    """
    found = [float(max(abs(model.jnt_actfrcrange[joint])))] if model.jnt_actfrclimited[joint] else []
    for a in range(model.nu):
        if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT) or int(model.actuator_trnid[a, 0]) != joint:
            continue
        if model.actuator_forcelimited[a]:
            found.append(float(max(abs(model.actuator_forcerange[a]))))
        motor = (int(model.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED)
                 and int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_NONE))
        if motor and model.actuator_ctrllimited[a]:
            found.append(float(max(abs(model.actuator_ctrlrange[a])) * abs(model.actuator_gear[a, 0])))
    return min(found) if found else None
