"""Estimate of an object the robot holds: its pose relative to the hand, filtered, composed with the hand's pose.

A clamped object moves with the pads. In the world frame its pose changes all through a carry, and a filter
there must trade noise against lag; relative to the pad it is (nearly) constant, so a filter on the *relative*
pose averages the camera's noise down over the whole hold, and the hand's pose (the pad frame's pose, as the
phases read every robot frame) carries it through the motion without lag. Each measurement is expressed in the
carrier frame of the moment it describes (the carrier's poses of the last second are kept, which compensates
the camera's latency); the estimate is the carrier's pose now composed with the filtered relative pose. A slip
in the pads is a change of the relative pose, which the filter's moving model and its gate follow.

The carrier frame is the first pad's frame turned by the object's orientation relative to it when the hold
began, so the relative orientation starts at the identity, far from the roll-pitch-yaw singularity.

A *pushed* object (the tool's contact takes it along, it is not held) rests on the table: only its carrier's motion
along the table carries it (x, y and turn about the vertical; a push's carrier advances with the tool along the push
only, :meth:`~nextage_qp.manipulation.phases.push.contact.PushContact.carrier`), so a tool that rides up its face or
tilts while
the hand hides it leaves its height, roll and pitch where they were seen; and its relative pose is held at its last
measurement rather than extrapolated.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from nextage_qp.estimation.imm import PoseKalman
from nextage_qp.geometry import Pose, pose_vector, rot_z, vector_pose, yaw_of

HISTORY_S = 1.0
"""How long the carrier's poses are kept for latency compensation [s]."""


class HeldEstimate:
    """The pose of one held object, filtered relative to its carrier (see the module doc).

    Args:
        t: Time the hold begins [s].
        carrier: The carrier's (first pad's) world pose at ``t``.
        world: The object's world pose estimate at ``t`` (x, y, z, roll, pitch, yaw).
        variance: Its variance per axis (6,), the relative filter's starting uncertainty.
        kalman: A fresh filter for the relative pose (same noise model as the world filter).
    """

    def __init__(self, t: float, carrier: Pose, world: np.ndarray, variance: np.ndarray, kalman: PoseKalman, *,
                 pushed: bool = False) -> None:
        self.pushed = pushed
        """A pushed object (see the module doc); False: a held one, its relative pose predicted past its last
        measurement."""
        carrier = self._along(carrier)
        self.offset = carrier.rot.T @ vector_pose(world).rot
        self.history: deque[tuple[float, Pose]] = deque([(t, carrier)])
        self.kalman = kalman
        self.kalman.start(t, self._relative(carrier, world), variance)

    def _frame(self, carrier: Pose) -> Pose:
        return Pose(carrier.pos, carrier.rot @ self.offset)

    def _relative(self, carrier: Pose, z: np.ndarray) -> np.ndarray:
        f, p = self._frame(carrier), vector_pose(z)
        return pose_vector(Pose(f.rot.T @ (p.pos - f.pos), f.rot.T @ p.rot))

    def _along(self, carrier: Pose) -> Pose:
        """The carrier's pose as it carries the object: of a pushed one, its motion along the table only."""
        if not self.pushed:
            return carrier
        return Pose(np.array([carrier.pos[0], carrier.pos[1], 0.0]), rot_z(yaw_of(carrier.rot)))

    def observe(self, t: float, carrier: Pose) -> None:
        """Keep the carrier's pose at ``t`` [s] (every control tick)."""
        self.history.append((t, self._along(carrier)))
        while self.history[0][0] < t - HISTORY_S:
            self.history.popleft()

    def _carrier_at(self, stamp: float) -> Pose:
        for t, pose in reversed(self.history):
            if t <= stamp + 1e-9:
                return pose
        return self.history[0][1]

    def update(self, stamp: float, z: np.ndarray, spread: float = 1.0) -> bool:
        """Apply a world measurement ``z`` of time ``stamp`` [s] (``spread``: PoseKalman.update's); False if gated."""
        return self.kalman.update(stamp, self._relative(self._carrier_at(stamp), z), spread=spread)

    def estimate(self, t: float) -> np.ndarray:
        """World pose (x, y, z, roll, pitch, yaw) at ``t`` [s]: the latest carrier pose with the relative estimate."""
        at = t if not self.pushed or self.kalman.t is None else min(t, self.kalman.t)
        f, r = self._frame(self.history[-1][1]), vector_pose(self.kalman.estimate(at))
        return pose_vector(Pose(f.pos + f.rot @ r.pos, f.rot @ r.rot))

    def variance(self, t: float | None = None) -> np.ndarray:
        """Variance per axis (6,) of the relative estimate at its last measurement, or predicted to ``t`` [s]."""
        return self.kalman.variance(t)
