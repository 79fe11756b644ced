"""``robot init``: a robot file drafted from a model (MJCF or URDF), ready to run and to review.

What the draft holds (see :mod:`nextage_qp.robots.survey` for how each is found): the arms, left first, with their
end-effector frame; the shared joints as ``torso`` and other branches as groups; collision groups per arm
(``NAME_arm``, ``NAME_upper_arm``, ``NAME_forearm``, ``NAME_hand``) and ``torso``; ``home`` (the model's keyframe,
else a pose free of self-contact); the pairs still in contact there as ``exclude``; gains from the rule; torque
limits where the model gives none, or less than holding the arm up takes; ``angle: radian`` where the MJCF needs it;
a mount that puts the lowest collision geometry on the floor.
"""

from __future__ import annotations

import math
import re
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.io.yaml_file import load_yaml, validate
from nextage_qp.robots.modelfile import descendants, model_torque_limit
from nextage_qp.robots.poses import TORQUE_FACTOR, TORQUE_FLOOR_NM, default_torque_limit, static_torques
from nextage_qp.robots.robot_file import FrameFile, GainRule, RobotFile, WorkspaceFile
from nextage_qp.robots.survey import Survey, home_values, joint_names, lowest_z, model_reference

WIDTH = 118
"""Longest line the draft writes."""
_PLAIN = re.compile(r"[A-Za-z_][A-Za-z0-9_./\-]*")
_WORDS = {"true", "false", "yes", "no", "on", "off", "null", "none", "y", "n"}


TABLE_GAP = 0.004
"""Least gap [m] between an arm and the table while its tool pushes at its ``push_face`` height."""


@dataclass
class Ready:
    """What makes a draft ready for a table (:func:`nextage_qp.experiments.table_ready.make_ready`).

    Frames by name, each arm's tool, the push height, the workspace, a ready home and notes for the file's comments.
    """

    frames: dict[str, FrameFile] = field(default_factory=dict)
    tools: dict[str, str] = field(default_factory=dict)
    pads: dict[str, str] = field(default_factory=dict)
    """Each of the first two arms' pad: its tool's face, turned to the clamp's frame (y along the robot's +y)."""
    wrench_sensors: list[str] = field(default_factory=list)
    """The pads on bodies without a force/torque sensor: the robot file gives them one."""
    push_height: float = 0.0
    push_pitch: float = 0.0
    workspace: WorkspaceFile | None = None
    every_side: bool = False
    """A tool reaches behind an object from each of its sides all over the work region (else both tools reach it)."""
    home: dict[str, float] | None = None
    notes: list[str] = field(default_factory=list)


def collision_groups(s: Survey) -> dict[str, dict[str, list[str]]]:
    """Collision groups of the arms and the torso.

    Per arm ``NAME_arm`` (its subtree), ``NAME_upper_arm`` and ``NAME_forearm`` (the chain's bodies split in
    halves, the forearm from the elbow on), ``NAME_hand`` (the last moving body and below); ``torso``: the
    colliding bodies no arm holds.
    """
    m = s.model
    groups: dict[str, dict[str, list[str]]] = {}
    in_arms: set[int] = set()
    for arm in s.arms.arms:
        chain = [b for b in arm.bodies if m.body(b).name]
        if not chain:
            continue
        subtree = descendants(m, chain[0])
        in_arms |= set(subtree)
        groups[f"{arm.name}_arm"] = {"subtrees": [m.body(chain[0]).name]}
        if len(chain) >= 2:
            elbow = chain[len(chain) // 2]
            fore = set(descendants(m, elbow))
            groups[f"{arm.name}_upper_arm"] = {"bodies": [m.body(b).name for b in subtree if b not in fore
                                                          and m.body(b).name]}
            groups[f"{arm.name}_forearm"] = {"subtrees": [m.body(elbow).name]}
        groups[f"{arm.name}_hand"] = {"subtrees": [m.body(chain[-1]).name]}
    colliding = {int(m.geom_bodyid[g]) for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]}
    torso = [m.body(b).name for b in range(1, m.nbody) if b not in in_arms and b in colliding and m.body(b).name]
    if torso:
        groups["torso"] = {"bodies": torso}
    return groups


class TorqueLimits(NamedTuple):
    """Torque limits [N m] the draft writes, by where each comes from (joint name to limit)."""

    from_model: dict[str, float]
    """The model's own limits (a URDF's effort) of the joints without an actuator: the motor added takes its limit
    from the robot file."""
    defaults: dict[str, float]
    """Where the model gives none: :func:`default_torque_limit`."""
    raised: dict[str, float]
    """Where the model's limit is below the joint's largest gravity torque (its motors cannot hold the arm up): the
    joint's own actuator-force range where that is larger, else :func:`default_torque_limit`."""


def torque_limits(s: Survey) -> TorqueLimits:
    """Torque limits [N m] the robot file must give (:class:`TorqueLimits`).

    Gravity torques are the largest over home and a few random poses (:func:`static_torques`).
    """
    m = s.model
    driven = {int(m.actuator_trnid[a, 0]) for a in range(m.nu)
              if int(m.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)}
    limits = {j: model_torque_limit(m, j) for j in s.joints}
    given = {m.joint(j).name: limit for j, limit in limits.items() if j not in driven and limit is not None}
    peaks = dict(zip(s.joints, static_torques(m, list(s.joints), s.home.qpos), strict=True))
    defaults = {m.joint(j).name: default_torque_limit(float(peaks[j])) for j, limit in limits.items() if limit is None}
    raised = {}
    for j, limit in limits.items():
        if limit is None or limit >= peaks[j]:
            continue
        own = float(np.max(np.abs(m.jnt_actfrcrange[j]))) if m.jnt_actfrclimited[j] else 0.0
        raised[m.joint(j).name] = own if own > peaks[j] else default_torque_limit(float(peaks[j]))
    return TorqueLimits(given, defaults, raised)


def _scalar(value: object) -> str:
    if isinstance(value, float):
        return repr(round(value, 6)) if value == value else ".nan"
    text = str(value)
    return text if _PLAIN.fullmatch(text) and text.lower() not in _WORDS else '"' + text.replace('"', '\\"') + '"'


def _comment(text: str) -> list[str]:
    return textwrap.wrap(text, WIDTH, initial_indent="# ", subsequent_indent="#   ")


def _flow(items: list[str], indent: int) -> str:
    """``[a, b, ...]`` wrapped at :data:`WIDTH` under the opening bracket."""
    lines, line, shift = [], "[", indent  # the first line follows a prefix ``indent`` wide; the others are padded
    for k, item in enumerate(items):
        piece = item + (", " if k < len(items) - 1 else "]")
        if len(line) + len(piece) + shift > WIDTH and line.strip() not in ("[", ""):
            lines.append(line.rstrip())
            line, shift = " " * (indent + 1), 0
        line += piece
    return "\n".join([*lines, line if items else "[]"])


def draft_text(s: Survey, out: Path, ready: Ready | None = None) -> str:
    """The robot file for survey ``s``, to be written at ``out`` (YAML with comments).

    ``ready``: what makes it ready for a table (:func:`~nextage_qp.experiments.table_ready.make_ready`): tool frames,
    push_face, workspace and a ready home.
    """
    ready = ready or Ready()
    shown = s.path.name
    lines = [f"# Robot file drafted by `nextage-qp robot init` from {shown}.",
             "# Review: the arms (names, joints, wrist frame; tool and pad default to the wrist), home, the excluded",
             "# contact pairs, the collision groups, the torque limits and the mount; then run",
             f"# `nextage-qp robot check {out.name}`. Keys: docs/robots.md.",
             f"name: {_scalar(s.name)}", f"model: {_scalar(model_reference(s.path, out.parent))}"]
    if s.angle:
        lines += [*_comment(f"angle: {s.angle_why}"), f"angle: {s.angle}"]
    low = lowest_z(s)
    if low is not None and low < 0:
        lift = math.ceil(-low * 1000) / 1000
        lines += [*_comment(f"mount: lifts the lowest collision geometry at home ({low:.3f} m) onto the floor "
                            "(z = 0) [m]"), f"mount: {{pos: [0.0, 0.0, {lift!r}]}}"]
    lines.append("arms:  # the first arm is the one on the +y side")
    for arm in s.arms.arms:
        lines += [f"  - name: {arm.name}",
                  f"    joints: {_flow([_scalar(n) for n in joint_names(s, arm.joints)], 12)}",
                  f"    wrist: {_scalar(arm.wrist)}  # the last frame on the arm's last link"]
        if arm.name in ready.tools:
            lines.append(f"    tool: {_scalar(ready.tools[arm.name])}  # the hand's outermost face along its last "
                         "joint's axis")
        if arm.name in ready.pads:
            lines.append(f"    pad: {_scalar(ready.pads[arm.name])}  # that face, clamping")
    groups = ({"torso": s.arms.torso} if s.arms.torso else {}) | s.arms.groups
    if groups:
        lines.append("joint_groups:")
        lines += [f"  {k}: {_flow([_scalar(n) for n in joint_names(s, v)], len(k) + 4)}" for k, v in groups.items()]
    if ready.frames:
        lines.append("frames:  # tools: x the face's normal, out of the hand, z as near up as the hand at home allows;"
                     " pads: y along +y")
        for name, f in ready.frames.items():
            lines.append(f"  {name}: {{body: {_scalar(f.body)}, pos: [{', '.join(map(repr, f.pos))}], "
                         f"quat: [{', '.join(map(repr, f.quat))}]}}")
    if ready.wrench_sensors:
        lines.append(f"wrench_sensors: {_flow([_scalar(n) for n in ready.wrench_sensors], 16)}  # the model senses no "
                     "force at the pads: a force/torque sensor at each")
    lines.append("collision_groups:")
    for name, group in collision_groups(s).items():
        key, names = next(iter(group.items()))
        head = f"  {name}: {{{key}: "
        lines.append(head + _flow([_scalar(n) for n in names], len(head)) + "}")
    if s.home.contacts:
        pairs = [f"[{_scalar(a)}, {_scalar(b)}]" for a, b in s.home.contacts]
        lines.append(f"exclude: {_flow(pairs, 9)}  # in contact at home")
    if ready.workspace is not None:
        ws = ready.workspace
        face = (f"push_face: {{height: {ready.push_height:.4f}}}  # the lowest both tools reach, level, with the "
                f"arms {TABLE_GAP * 1e3:g} mm off the table [m]") if not ready.push_pitch else (
                f"push_face: {{height: {ready.push_height:.4f}, pitch: {ready.push_pitch:g}}}  # tipped down where the "
                f"hands lead into a cube lowest, the lowest both tools reach with the arms {TABLE_GAP * 1e3:g} mm off "
                "the table (level, none does) [m], [rad]")
        where = ("where a tool reaches behind an object from every side" if ready.every_side
                 else "where both tools, level, reach the table")
        lines += [face,
                  f"workspace:  # {where} (task configs with scene.frame: workspace)",
                  f"  centre: [{ws.centre[0]!r}, {ws.centre[1]!r}]  # world x-y [m]",
                  f"  size: [{ws.size[0]!r}, {ws.size[1]!r}]  # half-extent [m]",
                  f"  top: {ws.top!r}  # the table top [m]",
                  f"  table: [{', '.join(map(repr, ws.table or ()))}]  # its front edge clear of the body"]
    for note in ready.notes:
        lines += _comment(note)
    lines.append("keyframes:")
    if ready.home is not None:
        items = [f"{_scalar(k)}: {_scalar(v)}" for k, v in ready.home.items() if v != 0.0]
        lines.append("  home: {" + _flow(items, 9)[1:-1] + "}")
    elif s.keyframe == "home":
        lines.append("  home: model  # the model's keyframe 'home'")
    else:
        values = home_values(s)
        items = [f"{_scalar(k)}: {_scalar(v)}" for k, v in values.items() if v != 0.0]
        lines.append(f"  # home: {s.home.how}; joints not named are 0")
        lines.append("  home: {" + _flow(items, 9)[1:-1] + "}" if items else "  home: {}")
    rule = GainRule()
    lines += ["# gains: kp = I w^2, kd = 2 zeta I w - d on each joint's reflected inertia I at home",
              f"gains: {{bandwidth: {rule.bandwidth!r}, damping_ratio: {rule.damping_ratio!r}}}"]
    from_model, defaults, raised = torque_limits(s)
    if from_model or defaults or raised:
        lines.append("torque_limits:  # [N m]")
    if from_model:
        lines.append("  # the model's own limits (a URDF's effort) for the joints it gives no actuator")
        lines += [f"  {_scalar(k)}: {v!r}" for k, v in from_model.items()]
    if defaults:
        lines += [f"  {c}" for c in _comment(
            f"the model gives these joints no limit: {TORQUE_FACTOR:g} x the largest gravity torque over home and 8 "
            f"random poses, at least {TORQUE_FLOOR_NM:g} N m; replace them with the real ones")]
        lines += [f"  {_scalar(k)}: {v!r}" for k, v in defaults.items()]
    if raised:
        lines += [f"  {c}" for c in _comment(
            "the model's limits on these joints are below their largest gravity torque over home and 8 random "
            f"poses (its motors cannot hold the arm up): the joint's actuator-force range where larger, else "
            f"{TORQUE_FACTOR:g} x that torque, at least {TORQUE_FLOOR_NM:g} N m; check them against the real motors")]
        lines += [f"  {_scalar(k)}: {v!r}" for k, v in raised.items()]
    text = "\n".join(lines) + "\n"
    validate(RobotFile, load_yaml(text), str(out))  # what is written must read back
    return text


def write_draft(text: str, out: Path, *, force: bool = False) -> None:
    """Write the draft to ``out``.

    Raises:
        ConfigError: ``out`` exists and ``force`` is not given, or it cannot be written.
    """
    if out.is_dir():
        raise ConfigError(f"{out}: is a folder; give a file name ending in .yaml")
    if out.exists() and not force:
        raise ConfigError(f"{out}: exists; give --force to overwrite it, or --out another file")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{out}: cannot write: {exc.strerror or exc}") from None
