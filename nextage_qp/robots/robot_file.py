"""The robot file: one YAML per robot, validated like every config (unknown keys, bad numbers: one line, exit 2).

A robot file names the model (MJCF or URDF) and says what the framework needs to know that the model does not:

.. code-block:: yaml

    name: twin
    model: twin/twin.xml             # MJCF or URDF, relative to this file (or package://NAME/PATH)
    arms:                            # shoulder to wrist; the first arm is the one on the +y side
      - name: left
        joints: [l_shoulder_pan, l_shoulder_lift, l_elbow, l_wrist_pitch, l_wrist_roll]
        wrist: l_flange              # end-effector frames: the model's sites or bodies, or frames added below
        tool: l_tool                 # the face that pushes
        pad: l_pad                   # the face that clamps
      - name: right
        joints: [r_shoulder_pan, r_shoulder_lift, r_elbow, r_wrist_pitch, r_wrist_roll]
        wrist: r_flange
    joint_groups: {torso: [waist]}
    frames:                          # frames the file adds: a site on a body, at an offset
      l_tool: {body: l_wrist_roll_link, pos: [0.06, 0, 0]}
      l_pad: {body: l_wrist_roll_link, pos: [0.03, -0.02, 0], quat: [0.7071, 0.7071, 0, 0]}
    collision_groups:
      left_arm: {subtrees: [l_shoulder_link]}
      torso: {bodies: [base, chest]}
    exclude: [[chest, l_shoulder_link]]
    keyframes: {home: model}         # the model's own keyframe, or joint -> rad (others 0)
    gains: gains/twin.yaml           # a gains file, or the rule on the joints' reflected inertia (the default)
    torque_limits: 40.0              # N m, one value or per joint; the file's value wins over the model's
    velocity_limits: 2.0             # rad/s, one value or per joint: caps the trajectory's limits
    cameras: {head: {body: head_link, pos: [0.1, 0, 0.05], pitch: 0.3, fovx: 70}}  # see nextage_qp.robots.cameras
    wrench_sensors: [l_pad]          # a force/torque sensor at each of these sites, where the model has none
    base: {type: diff_drive, wheel_radius: 0.1, track: 0.7}   # a wheeled base under it: nextage_qp.mobile.base_file
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from nextage_qp.io.schema import YamlModel
from nextage_qp.mobile.base_file import BaseFile
from nextage_qp.robots.cameras import CameraFile

Name = Annotated[str, Field(min_length=1)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class ArmFile(YamlModel):
    """One arm: its joints (shoulder to wrist) and the frames the phases use on it."""

    name: Name = Field(description="Arm name, e.g. left; arm groups are named NAME_arm.")
    joints: tuple[Name, ...] = Field(min_length=1, description="Joints, shoulder to wrist.")
    wrist: Name = Field(description="Wrist frame (a site or body of the model, or a frame of this file).")
    tool: Name | None = Field(default=None, description="Frame whose face pushes (default: the wrist).")
    pad: Name | None = Field(default=None, description="Frame on the clamping face (default: the wrist).")


class FrameFile(YamlModel):
    """A frame the robot file adds to the model: a site on a body, at an offset in the body's frame."""

    body: Name = Field(description="Body of the model the frame is fixed to.")
    pos: tuple[float, float, float] = Field(default=(0.0, 0.0, 0.0), description="Position in the body's frame [m].")
    quat: tuple[float, float, float, float] = Field(
        default=(1.0, 0.0, 0.0, 0.0), description="Orientation in the body, a non-zero quaternion [1] (w, x, y, z)."
    )

    @model_validator(mode="after")
    def _rotation(self) -> FrameFile:
        if math.hypot(*self.quat) < 1e-6:
            raise ValueError(f"quat must be a non-zero quaternion (w, x, y, z), got {list(self.quat)}; "
                             "[1, 0, 0, 0] keeps the body's axes")
        return self


class GroupFile(YamlModel):
    """A collision group: bodies, and whole subtrees (a body and every body below it)."""

    bodies: tuple[Name, ...] = Field(default=(), description="Bodies whose collision geoms are in the group.")
    subtrees: tuple[Name, ...] = Field(
        default=(), description="Bodies whose collision geoms, and those of every body below them, are in the group."
    )

    @model_validator(mode="after")
    def _not_empty(self) -> GroupFile:
        if not self.bodies and not self.subtrees:
            raise ValueError("a collision group needs bodies or subtrees")
        return self


class GainRule(YamlModel):
    """PD gains from each joint's reflected inertia at ``home``: ``kp = I w^2``, ``kd = 2 zeta I w - d``."""

    bandwidth: Positive = Field(default=30.0, le=500.0, description="Closed-loop natural frequency w [rad/s].")
    damping_ratio: Positive = Field(default=1.0, le=5.0, description="Damping ratio zeta [1] (1: critically damped).")
    gravity_compensation: bool = Field(
        default=True, description="Add MuJoCo's bias force (gravity, Coriolis and centrifugal) to the PD torque."
    )


class MountFile(YamlModel):
    """Where the robot's root sits in the world of a task scene."""

    pos: tuple[float, float, float] = Field(
        default=(0.0, 0.0, 0.0), description="Position of the robot's own frame in the world [m]."
    )
    yaw: float = Field(default=0.0, ge=-7.0, le=7.0, description="Yaw of the robot's own frame about world z [rad].")


class WorkspaceFile(YamlModel):
    """Where the robot works at a table: the frame of task configs written with ``scene.frame: workspace``.

    A point ``[x, y, z]`` of such a config is ``centre + (x, y)`` on the table top, ``z`` above it.
    """

    centre: tuple[float, float] = Field(description="World x-y [m] of the work region's centre on the table top.")
    size: tuple[Positive, Positive] = Field(
        description="Half-extent [m] of the work region both tools reach, along world x (forward) and y (left).")
    top: float = Field(ge=0.0, le=3.0, allow_inf_nan=False, description="Height of the table top [m].")
    table: tuple[float, float, float] | None = Field(
        default=None, description="Where the scene's table body stands for this robot [m] (default: where the "
                                  "scene has it).")


class PushFaceFile(YamlModel):
    """How a tool's face meets an object it pushes: the defaults of a push phase that leaves them unset."""

    height: float = Field(default=0.0, ge=-0.2, le=0.2, allow_inf_nan=False,
                          description="The tool frame's height over the pushed object's centre [m].")
    pitch: float = Field(default=0.0, ge=-0.8, le=0.8, allow_inf_nan=False,
                         description="The tool's pitch [rad]; < 0 tilts the face's normal up, so its lower rim "
                                     "leads (a round face pushes low, the object slides instead of tipping).")


class RobotFile(YamlModel):
    """The schema of a robot file (see the module docstring)."""

    name: Name = Field(description="Robot name, in messages (and the prefix of model assets whose names the scene "
                                   "uses too).")
    model: Name = Field(description="MJCF or URDF file, relative to the robot file, or package://NAME/PATH.")
    angle: Literal["radian", "degree"] | None = Field(
        default=None, description="Angle unit of the model where it does not say (MJCF default: degree)."
    )
    package_paths: tuple[Name, ...] = Field(
        default=(), description="Folders a URDF's package:// paths are resolved against (relative to this file)."
    )
    mount: MountFile = Field(
        default=MountFile(), description="Where the robot's own frame stands in a task scene (a task config's mount "
                                         "replaces it)."
    )
    arms: tuple[ArmFile, ...] = Field(
        min_length=1, description="The arms, the first on the +y side: joints (shoulder to wrist) and the wrist, tool "
                                  "and pad frames."
    )
    joint_groups: dict[Name, tuple[Name, ...]] = Field(
        default_factory=dict, description="Other joints by group, e.g. torso, head."
    )
    frames: dict[Name, FrameFile] = Field(
        default_factory=dict, description="Frames the file adds to the model, by name: a site on a body at an offset."
    )
    collision_groups: dict[Name, GroupFile] = Field(
        default_factory=dict, description="Named groups of the robot's collision geoms (e.g. left_arm, torso), for "
                                          "ik.collision_pairs and contact checks."
    )
    exclude: tuple[tuple[Name, Name], ...] = Field(default=(), description="Body pairs that never collide.")
    keyframes: dict[Name, Literal["model"] | dict[Name, float]] = Field(
        default_factory=dict, description="Named joint configurations [rad], home required: model (the model's "
                                          "keyframe of that name), or joint -> angle (others 0)."
    )
    gains: Name | GainRule = Field(
        default_factory=GainRule, description="A gains file (relative to this file) or the rule."
    )
    gains_dir: Name | None = Field(default=None, description="Folder of bundled gains files named in configs.")
    torque_limits: float | dict[Name, Positive] | None = Field(
        default=None, description="Joint torque limit [N m], one value or per joint; wins over the model's actuator "
                                  "limits."
    )
    velocity_limits: float | dict[Name, Positive] | None = Field(
        default=None, description="Joint velocity limit [rad/s], one value or per joint: caps the joint references' "
                                  "velocity."
    )
    cameras: dict[Name, CameraFile] = Field(
        default_factory=dict, description="Cameras on the robot (nextage_qp.robots.cameras), by name."
    )
    wrench_sensors: tuple[Name, ...] = Field(
        default=(), description="Sites (the model's, or frames of this file) that get a force and a torque sensor: "
                                "wrist force/torque sensing for a model that has none (a clamp's pads feel its "
                                "squeeze through them)."
    )
    base: BaseFile | None = Field(default=None, description="A wheeled base under the robot (nextage_qp.mobile).")
    push_face: PushFaceFile = Field(
        default=PushFaceFile(), description="How the tools' faces meet an object they push (a push phase's height "
                                            "and pitch where it leaves them unset).")
    workspace: WorkspaceFile | None = Field(
        default=None, description="Where the robot works at a table: the frame of task configs with scene.frame: "
                                  "workspace.")

    @field_validator("torque_limits", "velocity_limits", mode="before")
    @classmethod
    def _limits(cls, value: object, info: ValidationInfo) -> object:
        unit = "N m" if info.field_name == "torque_limits" else "rad/s"
        items = value.items() if isinstance(value, dict) else [(None, value)] if value is not None else []
        for joint, v in items:
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
                where = f" for joint {joint!r}" if joint is not None else ""
                raise ValueError(f"{v!r}{where} is not a limit: give a finite number > 0 [{unit}], one value or "
                                 f"joint -> value")
        return value

    @model_validator(mode="after")
    def _names_once(self) -> RobotFile:
        seen: dict[str, str] = {}
        places = [(f"arms[{i}].joints", j) for i, arm in enumerate(self.arms) for j in arm.joints]
        places += [(f"joint_groups.{g}", j) for g, joints in self.joint_groups.items() for j in joints]
        for where, joint in places:
            if joint in seen:
                raise ValueError(f"joint {joint!r} is listed twice ({seen[joint]} and {where})")
            seen[joint] = where
        arms = [a.name for a in self.arms]
        if len(set(arms)) != len(arms):
            raise ValueError(f"arm names must differ, got {arms}")
        if "home" not in self.keyframes:
            raise ValueError("keyframes needs 'home' (the model's keyframe: home: model; or joint -> rad)")
        return self
