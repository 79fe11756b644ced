"""The measured-state seam: what the controller sees of the joints and the objects.

:class:`~nextage_qp.sim.Simulation` passes the joint state the PD law uses and the free-object poses the phases
read through one :class:`Sensors` object; :class:`PerfectSensors` (the default) reports the truth. Noise, delay,
dropouts or an estimator are another ``Sensors``, with no edit to the loop.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from nextage_qp.geometry import Pose


@dataclass(frozen=True)
class Measurement:
    """What the controller knows after a tick.

    Time [s], joint positions [rad] and velocities [rad/s], and the pose of every free object.
    """

    t: float
    q: np.ndarray
    qd: np.ndarray
    objects: Mapping[str, Pose] = field(default_factory=dict)


class Sensors(Protocol):
    """The seam between physics and controller (default: :class:`PerfectSensors`)."""

    def joints(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured joint positions [rad] and velocities [rad/s] at time ``t`` [s] (every physics step)."""

    def objects(self, t: float, true: Mapping[str, Pose]) -> Mapping[str, Pose]:
        """Measured object poses at time ``t`` [s] (every control tick)."""


class PerfectSensors:
    """Sensors that report the simulator's state exactly."""

    def joints(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        return q, qd

    def objects(self, t: float, true: Mapping[str, Pose]) -> Mapping[str, Pose]:  # noqa: D102
        return true
