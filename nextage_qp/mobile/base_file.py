"""The ``base:`` section of a robot file: a wheeled base under the robot, built with MjSpec.

.. code-block:: yaml

    base:
      type: diff_drive          # diff_drive | bicycle | holonomic
      wheel_radius: 0.1         # [m]
      track: 0.76               # between the driven wheels (the bicycle's rear wheels) [m]
      wheelbase: 0.6            # bicycle: rear axle to front axle [m]
      axle_x: -0.19             # the driven axle's x in the robot's frame (the base's reference point) [m]
      lift: 0.04                # the robot sits this much higher than on its own feet [m]
      chassis: {mass: 20.0}     # [kg]
      limits: {wheel_speed: 8.0, wheel_torque: 30.0, speed: 0.5, turn_rate: 1.0, steer: 0.6, steer_rate: 1.5}

The base's reference point (where the IK's base frame and the odometry live) is the middle of the driven axle on
the floor: a differential drive turns about it and a bicycle's rear axle cannot slide sideways there. A holonomic
base has no wheels to model: its planar joints are driven by velocity actuators (an omnidirectional platform).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from nextage_qp.io.schema import YamlModel

Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class BaseLimits(YamlModel):
    """What the base's motors and steering can do."""

    wheel_speed: Positive = Field(default=8.0, le=200.0, description="Largest wheel speed [rad/s].")
    wheel_torque: Positive = Field(default=30.0, le=1e4, description="Wheel motor torque limit [N m].")
    speed: Positive = Field(default=0.5, le=10.0, description="Largest base speed the IK asks for [m/s].")
    turn_rate: Positive = Field(default=1.0, le=20.0, description="Largest turn rate the IK asks for [rad/s].")
    steer: Positive = Field(default=0.6, lt=1.5, description="Bicycle: largest steering angle [rad].")
    steer_rate: Positive = Field(default=1.5, le=50.0, description="Bicycle: steering speed [rad/s].")


class ChassisFile(YamlModel):
    """The base's own body (the robot stands on it)."""

    mass: Positive = Field(default=20.0, le=1e4, description="Chassis mass [kg].")
    half_height: Positive = Field(default=0.04, le=1.0, description="Chassis plate half-height [m].")


class BaseFile(YamlModel):
    """The schema of a robot file's ``base:`` section (see the module docstring)."""

    type: Literal["diff_drive", "bicycle", "holonomic"] = Field(
        description="diff_drive: two driven wheels and casters, turns in place; bicycle: car-like, driven rear wheels "
                    "and two steered front wheels; holonomic: planar joints driven by velocity actuators, no wheels.")
    wheel_radius: Positive = Field(default=0.1, le=2.0, description="Wheel radius [m].")
    track: Positive = Field(default=0.7, le=10.0, description="Between the driven wheels [m].")
    wheelbase: Positive | None = Field(default=None, le=20.0, description="Bicycle: rear to front axle [m].")
    axle_x: float = Field(default=0.0, ge=-5.0, le=5.0, description="Driven axle's x in the robot's frame [m].")
    lift: float = Field(default=0.0, ge=0.0, le=2.0, description="How much higher the robot sits [m].")
    chassis: ChassisFile = Field(default=ChassisFile(), description="The base's own body, the robot stands on it.")
    limits: BaseLimits = Field(
        default=BaseLimits(), description="What the motors and steering can do: wheel speed and torque, the base "
                                          "speed and turn rate the IK asks for, steering angle and rate.")

    @model_validator(mode="after")
    def _wheelbase(self) -> BaseFile:
        if self.type == "bicycle" and self.wheelbase is None:
            raise ValueError("a bicycle base needs wheelbase (rear axle to front axle [m])")
        if self.type != "bicycle" and self.wheelbase is not None:
            raise ValueError(f"wheelbase is for a bicycle base, not {self.type}")
        return self
