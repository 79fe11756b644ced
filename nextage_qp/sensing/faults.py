"""What a real robot sees: the ``faults:`` and ``estimation:`` blocks of a task config.

``faults`` makes the controller's view of the world imperfect; metrics and success still use the truth::

    faults:
      object_pose:            # what the controller receives about each free object
        rate_hz: 30           # measurement rate of the simulated camera
        latency_s: 0.02       # each measurement describes the object this long ago
        noise_pos_m: 0.002    # Gaussian, per axis
        noise_rot_rad: 0.0175 # Gaussian rotation vector
        dropout: 0.1          # probability that a measurement is lost
      joint_sensors:
        noise_rad: 0.0005     # on measured joint positions
        noise_rad_s: 0.01     # on measured joint velocities
      wrench:                 # the wrist force/torque sensors
        noise_n: 0.05         # Gaussian, per force axis
        fail: {site: PAD, at_s: 3.0, mode: freeze}        # or nan: the run fails, naming the sensor
      shoves:                 # external impulses through MuJoCo's xfrc_applied over a short window
        - {body: cube, at_s: 6.0, impulse_ns: [0.0, 0.15, 0.0]}
        - {body: dumbbell, phase: place, after_s: 1.5, impulse_ns: [0.3, 0.0, 0.0]}
    estimation:
      object_filter: kalman   # or none: the phases see the latest raw measurement

All noise is drawn from the run's ``seed``, so a run is reproducible. Without a ``faults`` block the sensors
are perfect and nothing changes.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from nextage_qp.io.schema import YamlModel
from nextage_qp.io.yaml_file import MAX_SECONDS, name_field

Finite = Annotated[float, Field(allow_inf_nan=False)]


class ObjectPoseFaults(YamlModel):
    """The simulated camera that reports every free object's pose."""

    rate_hz: float = Field(default=30.0, gt=0, le=1000, allow_inf_nan=False, description="Measurement rate [Hz].")
    latency_s: float = Field(default=0.0, ge=0, le=1.0, allow_inf_nan=False,
                             description="Age of a measurement when it arrives [s].")
    noise_pos_m: float = Field(default=0.0, ge=0, le=0.1, allow_inf_nan=False, description="Position noise [m].")
    noise_rot_rad: float = Field(default=0.0, ge=0, le=0.5, allow_inf_nan=False,
                                 description="Rotation-vector noise [rad].")
    dropout: float = Field(default=0.0, ge=0, le=0.95, allow_inf_nan=False,
                           description="Probability [1] that a measurement is lost.")


class JointSensorFaults(YamlModel):
    """Noise on the measured joint state (the PD law and the phases see it)."""

    noise_rad: float = Field(default=0.0, ge=0, le=0.05, allow_inf_nan=False, description="On positions [rad].")
    noise_rad_s: float = Field(default=0.0, ge=0, le=1.0, allow_inf_nan=False, description="On velocities [rad/s].")


class SensorFailure(YamlModel):
    """A force/torque sensor that stops working at a time: it freezes at its last value or returns NaN."""

    site: str = Field(description="The sensor's site (e.g. an arm's pad frame).")
    at_s: float = Field(ge=0, le=MAX_SECONDS, allow_inf_nan=False, description="Simulated time of the failure [s].")
    mode: Literal["freeze", "nan"] = Field(
        default="freeze", description="freeze: the sensor keeps its last reading; nan: it reads NaN. Either fails the "
                                      "run once noticed.")


class WrenchFaults(YamlModel):
    """Noise on the wrist force/torque sensors, and an optional sensor failure."""

    noise_n: float = Field(default=0.0, ge=0, le=10.0, allow_inf_nan=False, description="Force noise [N].")
    noise_nm: float = Field(default=0.0, ge=0, le=1.0, allow_inf_nan=False, description="Torque noise [N m].")
    fail: SensorFailure | None = Field(
        default=None, description="A sensor that stops working at a time, which fails the run (unset: none fails).")


class Shove(YamlModel):
    """An external impulse on a body, spread over ``duration_s``: at ``at_s`` or ``after_s`` into a phase."""

    body: str = name_field("object", description="The free object shoved.")
    impulse_ns: tuple[Finite, Finite, Finite] = Field(description="World-frame impulse [N s].")
    at_s: float | None = Field(default=None, ge=0, le=MAX_SECONDS, allow_inf_nan=False,
                               description="Simulated time of the shove [s].")
    phase: str | None = Field(default=None, description="Phase (name or kind) the shove is timed from.")
    after_s: float = Field(default=0.0, ge=0, le=MAX_SECONDS, allow_inf_nan=False,
                           description="Time into that phase [s].")
    duration_s: float = Field(default=0.05, gt=0, le=0.5, allow_inf_nan=False, description="Window [s].")

    @model_validator(mode="after")
    def _one_time(self) -> Shove:
        if (self.at_s is None) == (self.phase is None):
            raise ValueError("give exactly one of at_s (absolute time) or phase (with after_s)")
        if float(np.linalg.norm(self.impulse_ns)) > 10.0:
            raise ValueError(f"impulse_ns {list(self.impulse_ns)} is over 10 N s; a shove, not a crash")
        return self


class FaultsConfig(YamlModel):
    """Every fault of a run (see the module doc); each block is optional."""

    object_pose: ObjectPoseFaults | None = Field(
        default=None, description="The simulated camera that reports every free object's pose: rate, latency, noise, "
                                  "dropouts (unset: exact poses every tick).")
    joint_sensors: JointSensorFaults | None = Field(
        default=None, description="Noise on the measured joint positions and velocities (unset: exact).")
    wrench: WrenchFaults | None = Field(
        default=None, description="Noise on the wrist force/torque sensors, and a sensor failure (unset: exact).")
    shoves: list[Shove] = Field(
        default_factory=list, description="External impulses on free objects, each at a time or into a phase.")


class EstimationConfig(YamlModel):
    """How object measurements become the poses the phases see."""

    object_filter: Literal["kalman", "none"] = Field(
        default="kalman", description="kalman: Kalman filter (resting / moving / manoeuvring IMM); none: the latest "
        "raw measurement.")
    accel_pos: float = Field(default=1e-4, gt=0, le=1e4, allow_inf_nan=False,
                             description="Process noise of the filter's moving model, position axes [m^2/s^3].")
    accel_rot: float = Field(default=1e-3, gt=0, le=1e4, allow_inf_nan=False,
                             description="Process noise of the filter's moving model, rotation axes [rad^2/s^3].")
