"""The diagnoses of ``robot check`` on names, frames, meshes and units; each returns findings, a line and its fix.

A finding is a ``problem`` (the robot will misbehave or not load: ``robot check`` exits 1) or ``info`` (worth
knowing, nothing to fix). :mod:`nextage_qp.robots.physics_checks` holds the physical ones.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Literal, NamedTuple

import mujoco
import numpy as np

from nextage_qp.robots.description import RobotDescription
from nextage_qp.robots.modelfile import angle_trap, declared_angle, hinge_ranges, moved_by
from nextage_qp.robots.urdf import MeshIssue

MOVING = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


class Finding(NamedTuple):
    """One line of ``robot check``: the level, the topic, what is wrong and what to do."""

    level: Literal["problem", "info"]
    topic: str
    message: str
    fix: str = ""


def meshes(issues: list[MeshIssue]) -> list[Finding]:
    """Unresolved ``package://`` paths, missing mesh files, mesh formats MuJoCo cannot read (a URDF's)."""
    topic = {"package": "package", "missing": "mesh file", "format": "mesh format"}
    return [Finding("problem", topic[i.kind], f"link {i.link!r}: mesh {i.mesh!r}: {i.problem}", i.fix) for i in issues]


def fused_urdf_links(path: Path, kept: mujoco.MjModel, fused: mujoco.MjModel) -> list[Finding]:
    """URDF links hung on fixed joints that MuJoCo's default import (``fusestatic``) would fuse into their parent."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return []
    names = {fused.body(b).name for b in range(fused.nbody)}
    out = []
    for joint in root.iter("joint"):
        child = joint.find("child")
        link = child.get("link") if child is not None else None
        if joint.get("type") == "fixed" and link and link not in names and _body(kept, link) >= 0:
            out.append(Finding("info", "fixed frame", f"link {link!r} (fixed joint {joint.get('name')!r}) would be "
                               "fused into its parent by MuJoCo's default URDF import; nextage-qp keeps it as a body",
                               "converting the URDF to MJCF yourself: <compiler fusestatic=\"false\"/>"))
    return out


def fused_mjcf_bodies(path: Path, model: mujoco.MjModel) -> list[Finding]:
    """Named bodies of an MJCF that the compiled model lacks (``<compiler fusestatic="true">`` fused them)."""
    if path.suffix.lower() == ".urdf":
        return []
    try:
        written = [b.get("name") for b in ET.parse(path).getroot().iter("body") if b.get("name")]
    except (OSError, ET.ParseError):
        return []
    gone = [n for n in written if n and _body(model, n) < 0]
    if not gone:
        return []
    return [Finding("problem", "fused frame", f"bodies {', '.join(gone)} are fused away (fusestatic): no frame can "
                    "name them", "set <compiler fusestatic=\"false\"/> in the model, or put a site where they were")]


def _body(model: mujoco.MjModel, name: str) -> int:
    return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name))


def frame_body(model: mujoco.MjModel, desc: RobotDescription, name: str) -> int:
    """The body a frame name lives on (a site's body, a body, a robot-file frame's body), or -1."""
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid >= 0:
        return int(model.site_bodyid[sid])
    if name in desc.frames:
        return _body(model, desc.frames[name].body)
    return _body(model, name)


def names(model: mujoco.MjModel, desc: RobotDescription) -> list[Finding]:
    """Joints, frames and bodies (of frames, exclusions, collision groups, cameras) the model lacks."""
    out = []
    joints = {model.joint(j).name for j in range(model.njnt)}
    keys = [(f"arms[{i}].joints", j) for i, a in enumerate(desc.arms) for j in a.joints]
    keys += [(f"joint_groups.{g}", j) for g, js in desc.joint_groups.items() for j in js]
    for key, joint in keys:
        if joint not in joints:
            out.append(Finding("problem", "name", f"{key}: {joint!r} is not a joint of the model",
                               "name one of the model's joints (the joints table)"))
    for i, arm in enumerate(desc.arms):
        for role in dict.fromkeys(("wrist", "tool", "pad")):
            frame = getattr(arm, role)
            if frame_body(model, desc, frame) < 0:
                out.append(Finding("problem", "frame", f"arms[{i}].{role}: {frame!r} is not a site, body or frame",
                                   "name a site or body of the model, or add it under frames"))
    for name, frame in desc.frames.items():
        if _body(model, frame.body) < 0:
            out.append(Finding("problem", "frame", f"frames.{name}.body: {frame.body!r} is not a body of the model",
                               "name a body of the model (a URDF link)"))
    for i, pair in enumerate(desc.exclude):
        for body in pair:
            if _body(model, body) < 0:
                out.append(Finding("problem", "name", f"exclude[{i}]: {body!r} is not a body of the model",
                                   "name bodies of the model"))
    bodies = [(f"collision_groups.{g}.{part}", b) for g, group in desc.collision_groups.items()
              for part in ("bodies", "subtrees") for b in getattr(group, part)]
    bodies += [(f"cameras.{c}.body", cam.body) for c, cam in desc.cameras.items()]
    for key, body in bodies:
        if _body(model, body) < 0:
            out.append(Finding("problem", "name", f"{key}: {body!r} is not a body of the model",
                               "name a body of the model (the commands refuse the file until then)"))
    return out


def angle_unit(desc: RobotDescription, spec: mujoco.MjSpec) -> list[Finding]:
    """Ranges that look like the wrong angle unit, and an ``angle:`` the model does not need."""
    path, given = desc.model, desc.angle
    stated = declared_angle(path)
    if given is None and angle_trap(path, spec):
        name, lo, hi = max(hinge_ranges(spec), key=lambda r: r[2] - r[1])
        return [Finding("problem", "angle", f"{path.name} states no angle unit, so MuJoCo reads its ranges as "
                        f"degrees: {name!r} [{lo:g}, {hi:g}] becomes [{np.deg2rad(lo):.3f}, {np.deg2rad(hi):.3f}] "
                        "rad", "angle: radian in the robot file (robot init writes it)")]
    if given is not None and stated is not None:
        if given == stated:
            return [Finding("info", "angle", f"angle: {given} repeats what {path.name} states", "remove it")]
        return [Finding("problem", "angle", f"angle: {given} overrides the {stated} that {path.name} states",
                        f"remove angle: (or set angle: {stated})")]
    if given == "radian" and hinge_ranges(spec) and not angle_trap(path, spec):
        return [Finding("problem", "angle", f"angle: radian, but hinge ranges of {path.name} exceed 2 pi: they look "
                        "like degrees", "remove angle: radian")]
    return []


def reversed_ranges(desc: RobotDescription, spec: mujoco.MjSpec) -> list[Finding]:
    """Robot joints whose range is written upper bound first: MuJoCo then leaves them unlimited, without a word."""
    return [Finding("problem", "range", f"{desc.model.name}: joint {j.name!r} range [{j.range[0]:g}, {j.range[1]:g}] "
                    "has its lower bound above its upper, so MuJoCo leaves the joint unlimited",
                    "swap the two values in the model")
            for j in spec.joints if j.name in desc.joints and j.type in (mujoco.mjtJoint.mjJNT_HINGE,
                                                                        mujoco.mjtJoint.mjJNT_SLIDE)
            and j.range[0] > j.range[1]]


def reach(model: mujoco.MjModel, desc: RobotDescription) -> list[Finding]:
    """Arm frames that none of the arm's joints moves; robot-file frames that no arm moves."""
    out = []
    ids = {model.joint(j).name: j for j in range(model.njnt)}
    armed: set[int] = set()
    for i, arm in enumerate(desc.arms):
        joints = {ids[j] for j in arm.joints if j in ids}
        armed |= joints
        for role in dict.fromkeys(("wrist", "tool", "pad")):
            body = frame_body(model, desc, getattr(arm, role))
            if body >= 0 and not joints & set(moved_by(model, body)):
                out.append(Finding("problem", "reach", f"arms[{i}].{role}: {getattr(arm, role)!r} is on body "
                                   f"{model.body(body).name!r}, which none of arm {arm.name!r}'s joints moves",
                                   "name a frame on the arm's last link"))
    for name, frame in desc.frames.items():
        body = _body(model, frame.body)
        if body >= 0 and not armed & set(moved_by(model, body)):
            out.append(Finding("problem", "reach", f"frames.{name}: body {frame.body!r} is moved by no arm",
                               "put the frame on an arm's link, or remove it"))
    return out


def left_out(model: mujoco.MjModel, desc: RobotDescription) -> list[Finding]:
    """Moving joints of the model that the robot file does not list (nothing holds them)."""
    listed = set(desc.joints)
    free = [model.joint(j).name for j in range(model.njnt)
            if int(model.jnt_type[j]) in MOVING and model.joint(j).name not in listed]
    if not free:
        return []
    return [Finding("info", "joints", f"joints the robot file leaves out, which no PD loop holds: {', '.join(free)}",
                    "list them under joint_groups to hold them at home")]
