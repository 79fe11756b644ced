"""The clamp: two pads around a held object, squeezing at a force measured by the wrist force/torque sensors."""

from __future__ import annotations

import numpy as np

from nextage_qp.errors import PhaseError
from nextage_qp.geometry import axis_angle, clamp, rot_z
from nextage_qp.ik import FrameTarget, RelativeTarget
from nextage_qp.manipulation.context import Grip, View

FORCE_WINDOW = 0.1
"""Time constant of the squeeze-force filter of the clamp's force loop [s]."""
MAX_EASE = 0.0
"""Most the force loop may open a pad from where the grasp left it [m]."""
MAX_DEEPEN = 0.01
"""Most the force loop may push a pad further in than the grasp left it [m]."""


MAX_ROLL = 0.6
"""Most the levelling loop rolls the pads [rad]."""
LOST_FRACTION = 0.2
"""A clamp whose pads both feel less than this fraction of the grip force has lost the object."""


class Clamp:
    r"""The pads of a :class:`Grip` around an object setpoint, squeezing at the grip's force.

    Each pad's target is the setpoint plus its grip offset turned by the setpoint yaw, moved in along the clamp
    axis by a depth that follows the measured squeeze force, :math:`\dot\delta = k_F (F^* - F)`.
    """

    SIDES = (1.0, -1.0)

    def __init__(self, grip: Grip, relative_cost: float) -> None:
        self.grip, self.relative_cost = grip, relative_cost
        self.depth = [0.0 for _ in grip.frames]
        self.felt = [grip.force for _ in grip.frames]
        self.roll = 0.0
        """Roll [rad] of both pads about the clamp axis that levels the object (see :meth:`level`)."""
        self.level_gain = 0.0
        """Gain [1/s] of the levelling loop (0: off)."""

    def level(self, view: View, yaw: float) -> float:
        r"""Integrate the object's tilt about the clamp axis into the pads' roll; returns the tilt [rad].

        An object held between two pads can creep about the pads' axis (it only has their friction to hold it
        there); the loop rolls both pads together, :math:`\dot\rho = -k\,\theta`, which turns the object back
        upright without changing the pads' positions or their pose relative to each other.
        """
        rot = view.body_pose(self.grip.object).rot
        lateral = rot_z(yaw) @ self.grip.lateral
        z = rot[:, 2]
        tilt = float(np.arcsin(clamp(float(z[0] * lateral[1] - z[1] * lateral[0]), -1.0, 1.0)))  # (e_z x z) . lateral
        self.roll = clamp(self.roll - self.level_gain * tilt * view.dt, -MAX_ROLL, MAX_ROLL)
        return tilt

    def targets(self, view: View, pos: np.ndarray, yaw: float) -> tuple[tuple[FrameTarget, ...], RelativeTarget]:
        """Pad targets for the object setpoint ``(pos, yaw)`` and the relative target that ties them.

        The squeeze depths follow the measured force first (low-passed over ``FORCE_WINDOW``), and never back off
        more than ``MAX_EASE`` from where the grasp left them: the loop may ease a squeeze, never open the clamp.
        """
        g = self.grip
        lateral = rot_z(yaw) @ g.lateral
        if g.force > 0:
            alpha = min(1.0, view.dt / FORCE_WINDOW)
            for i, (frame, side) in enumerate(zip(g.frames, self.SIDES, strict=False)):
                felt = float(side * (view.wrench(frame).force @ lateral))
                self.felt[i] += alpha * (felt - self.felt[i])
                step = clamp(float(g.force_gain * (g.force - self.felt[i])), -0.01, 0.01) * view.dt
                self.depth[i] = clamp(self.depth[i] + step, -MAX_EASE, MAX_DEEPEN)
            self.check_hold()
        if self.level_gain > 0:
            self.level(view, yaw)
        return self.pads(pos, yaw)

    def check_hold(self) -> None:
        """Fail when both pads' filtered squeeze force fell below ``LOST_FRACTION`` of the grip force.

        Raises:
            PhaseError: The object slipped out of the clamp or dropped (the force sensors no longer feel it).
        """
        g = self.grip
        if max(self.felt) < LOST_FRACTION * g.force:
            felt = " and ".join(f"{f:.1f} N" for f in self.felt)
            raise PhaseError(f"the clamp lost {g.object}: the pads feel {felt} of the {g.force:.3g} N squeeze "
                             "(slipped out of the clamp or dropped)")

    def pads(self, pos: np.ndarray, yaw: float) -> tuple[tuple[FrameTarget, ...], RelativeTarget]:
        """Pad targets for the object setpoint ``(pos, yaw)`` at the current squeeze depths, and their tie.

        The tie is the pads' commanded relative pose when the clamp closed, drawn together by the squeeze depths
        since: what the arms held then, so taking it on does not jolt them (a pad the arm could not quite bring
        to its target would otherwise be pulled there at once, and the joints' lag would open the clamp).
        """
        g, rz = self.grip, rot_z(yaw)
        lateral = rz @ g.lateral
        points = [pos + rz @ g.offsets[f] - side * depth * lateral
                  for f, side, depth in zip(g.frames, self.SIDES, self.depth, strict=False)]
        turn = axis_angle(lateral, self.roll) @ rz
        targets = tuple(FrameTarget(f, pos=p, rot=turn @ g.rotations[f])
                        for f, p in zip(g.frames, points, strict=False))
        rel = g.relative
        closer = sum(self.depth) * (g.rotations[g.frames[1]].T @ g.lateral)  # first pad's lateral, in the second's
        return targets, RelativeTarget(rel.frame, rel.root, rel.pos - closer, rel.rot, self.relative_cost)
