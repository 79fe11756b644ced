"""Contact between a pushing tool and the object, felt by the wrist's force/torque sensor."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from nextage_qp.errors import UnknownNameError
from nextage_qp.geometry import Pose
from nextage_qp.manipulation.context import View

WINDOW = 0.05
"""Time constant of the push-force filter [s]."""
ON_N, OFF_N = 0.5, 0.2
"""Filtered push force [N] above which contact begins, and below which it ends (hysteresis against noise)."""


class PushContact:
    """The push force along the push direction at a tool frame, and contact onsets and losses from it.

    A tool on a body without a force/torque sensor reports no contact (the push then relies on geometry).

    Attributes:
        force: Filtered force the tool exerts along the push direction [N].
        in_contact: Whether the tool pushes now.
        onsets, losses: Contact changes counted so far.
    """

    def __init__(self, frame: str) -> None:
        self.frame, self.available = frame, True
        self.force, self.in_contact = 0.0, False
        self.onsets = self.losses = 0
        self._last_t: float | None = None
        # (carrier position, tool position it last moved with, how far the tool is back from its furthest advance)
        self._carried: tuple[np.ndarray, np.ndarray, float] | None = None

    def carrier(self, view: View, direction: np.ndarray | None) -> Callable[[], Pose] | None:
        """The pose that carries a pushed object while the tool pushes along ``direction`` (None: it does not).

        The tool takes the object only as far as it advances along the push: sliding along the object's face or
        turning, it does not move it (else a tool recentred sideways in contact drags the estimate off an object that
        stays put), and backing off it leaves it where it is (a tool cannot pull: an arm pressed into the object
        springs back a few millimetres once the push stops, while the object stays). The pose moves by the tool's
        advance along ``direction`` beyond the furthest it had come, level, never turning.
        """
        if direction is None:
            self._carried = None
            return None
        d = np.array([direction[0], direction[1], 0.0])

        def pose() -> Pose:
            now = view.frame_pose(self.frame).pos
            at, last, back = self._carried if self._carried is not None else (now, now, 0.0)
            step = float((now - last) @ d)
            ahead = max(step - back, 0.0)  # beyond the furthest advance: the object moves with the tool
            self._carried = (at + ahead * d, now, max(back - step, 0.0))
            return Pose(self._carried[0].copy(), np.eye(3))

        return pose

    def retarget(self, frame: str) -> None:
        """Read the sensor of another tool ``frame`` from now on (a push handed over to another arm)."""
        self.frame, self.available = frame, True

    def restart(self) -> None:
        """Forget the last push's contact (a new push starts from none, before its first reading)."""
        self.force, self.in_contact = 0.0, False

    def update(self, view: View, direction: np.ndarray) -> bool:
        """Read the sensor for one tick of a push along ``direction`` (planar unit vector); True in contact.

        A call after a pause (the push resumed) starts again from no contact.
        """
        if not self.available:
            return False
        try:
            wrench = view.wrench(self.frame)
        except UnknownNameError:
            self.available = False
            return False
        if self._last_t is None or view.t - self._last_t > 1.5 * view.dt:  # a new push: start from no contact
            self.restart()
        self._last_t = view.t
        push = -float(wrench.force[:2] @ direction)  # the object pushes back on the tool
        self.force += min(1.0, view.dt / WINDOW) * (push - self.force)
        now = self.force > (OFF_N if self.in_contact else ON_N)
        self.onsets += int(now and not self.in_contact)
        self.losses += int(self.in_contact and not now)
        self.in_contact = now
        return now
