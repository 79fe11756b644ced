"""Contact between a pushing tool and the object, felt by the wrist's force/torque sensor."""

from __future__ import annotations

import numpy as np

from nextage_qp.errors import UnknownNameError
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
