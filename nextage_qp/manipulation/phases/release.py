"""``release``: hand a set-down object's weight to the table, ease the squeeze, open the pads, then lift them."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.ik import FrameTarget
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import Forces, Grip, Setpoint, View
from nextage_qp.manipulation.phases.base import SETTLE_S, Phase, Spec, name_field, plan_field
from nextage_qp.manipulation.phases.grasp.phase import SIDES, squeeze_force
from nextage_qp.manipulation.route import PlanMode

UNLOAD_SPEED = 0.005
"""Speed [m/s] at which the pads go down to hand the object's weight to the table."""
UNLOADED = 0.3
"""Vertical load [N] on the pads below which the table carries the object."""
EASE_SPEED = 0.002
"""Speed [m/s] at which a pad still squeezing backs off before the pads open."""
EASED = 0.5
"""Squeeze force [N] below which a pad has let go (it then holds still until the other has too)."""
OPEN_FRACTIONS = (1.0, 0.6, 0.35)
"""Fractions of ``gap`` the pads back away by, the first that touches nothing taken."""
OPEN_TOL = 0.02
"""Position error [m] within which the check of an opening solves the pads' targets."""
MAX_EASE_TRAVEL = 0.005
"""Farthest a pad backs off while easing [m]; past it the pads open anyway."""


class ReleaseSpec(Spec):
    """Open the pads away from the object along the clamp axis, then retreat upwards."""

    grip = "ends"

    kind: Literal["release"]
    object: str = name_field("object", description="The object an earlier grasp phase clamped (the clamp ends).")
    gap: float = Field(default=0.05, gt=0, le=0.3, description="How far the pads back away from the object [m].")
    lift: float = Field(default=0.08, ge=0, le=0.5, description="How far the pads then rise [m].")
    open_speed: float = Field(default=0.02, gt=0, le=0.5, description="Opening speed [m/s] (slow: no tug).")
    unload: float = Field(default=0.006, ge=0, le=0.05, description=(
        "Most the pads go down before opening [m], until the table carries the object's whole weight (a pad "
        "that still holds some of it lifts and tips the object as it opens)."))
    speed: float = Field(default=0.1, gt=0, le=0.5, description="Lifting speed [m/s].")
    plan: PlanMode = plan_field()


class Release(Phase):
    """Open along the clamp axis, then lift; the clamp ends as the pads start to open.

    The pads first go down (at most ``unload``) until the table carries the object's whole weight; then each pad
    still squeezing backs off slowly until its own force sensor reads no squeeze (so neither pad drags the object
    by friction, nor pushes it across once the other has let go); then each backs away by ``gap`` at
    ``open_speed`` and rises by ``lift``.
    """

    spec: ReleaseSpec

    def start(self, view: View) -> None:  # noqa: D102
        c = self.spec
        _, rot = view.body_pose(c.object)
        grip = view.grip
        self.frames = grip.frames if grip is not None else view.pad_frames()
        lateral = rot @ grip.lateral if grip is not None else rot[:, 1]
        self.points = [Setpoint(view.commanded_pose(f).pos) for f in self.frames]
        self.rots = [view.commanded_pose(f).rot for f in self.frames]
        self.lateral = lateral
        self.start_z = [float(sp.pos[2]) for sp in self.points]
        self.lowered = [sp.pos - np.array([0.0, 0.0, c.unload]) for sp in self.points]
        self.stage = "unload" if c.unload > 0 else "ease"
        self.legs: list[tuple[list[np.ndarray], float]] = []  # the moves of the "open" stage: (goals, speed)
        self.leg = 0
        self.eased = [0.0 for _ in self.frames]
        # The IK's posture target stays the joints the release starts from: going back to the default posture at
        # once would swing the arms through the null space while the pads still touch the object.
        self.posture = view.joint_positions(view.joint_names())

    def budget(self, view: View) -> float:
        """Unloading by ``unload``, easing the squeeze, backing away by ``gap`` at ``open_speed`` and rising by
        ``lift`` at ``speed``, then coming to rest.
        """  # noqa: D205
        c = self.spec
        return (c.unload / UNLOAD_SPEED + MAX_EASE_TRAVEL / EASE_SPEED + c.gap / c.open_speed + c.lift / c.speed
                + SETTLE_S)

    def _open(self, view: View) -> None:
        """The open stage's moves from where the pads are now: back away along the clamp axis, then rise.

        Each pad backs away by ``gap``, or where that would touch anything (clutter beside the object), by the
        widest of ``OPEN_FRACTIONS`` of it that does not (``plan: never``: by ``gap``, unchecked).
        """
        c = self.spec
        fractions = OPEN_FRACTIONS if c.plan != "never" else OPEN_FRACTIONS[:1]
        for k, fraction in enumerate(fractions):
            gap = fraction * c.gap
            opened = [sp.pos + s * gap * self.lateral for sp, s in zip(self.points, SIDES, strict=False)]
            lifted = [p + np.array([0.0, 0.0, c.lift]) for p in opened]
            if k == len(fractions) - 1 or self._free(view, opened, lifted):
                break
        self.info["opened_m"] = round(gap, 4)
        self.legs = [(opened, c.open_speed), (lifted, c.speed)]
        self.stage = "open"
        self.info["unloaded_m"] = round(max(z - float(sp.pos[2]) for z, sp in zip(self.start_z, self.points,
                                                                                     strict=True)), 4)

    def update(self, view: View) -> Command:  # noqa: D102
        if self.stage == "unload":  # hand the object's weight to the table
            if self._unloaded(view) or all([sp.advance(g, UNLOAD_SPEED, view.dt)
                                            for sp, g in zip(self.points, self.lowered, strict=True)]):
                self.stage = "ease"
        elif self.stage == "ease":  # ease the squeeze, pad by pad, on each pad's own force
            if self._ease(view):
                self._open(view)
        elif self.leg < len(self.legs):
            goals, speed = self.legs[self.leg]
            if all([sp.advance(g, speed, view.dt) for sp, g in zip(self.points, goals, strict=True)]):
                self.leg += 1
        targets = tuple(FrameTarget(f, pos=sp.pos, rot=r) for f, sp, r in zip(self.frames, self.points, self.rots,
                                                                               strict=True))
        touching = self.stage != "open" or self.leg == 0  # down, easing, opening: the pads may touch the object
        allow = frozenset({self.spec.object}) if touching else frozenset()
        done = self.stage == "open" and self.leg == len(self.legs) and view.settled()
        return Command(targets, allow=allow, posture=self.posture, done=done)

    def _free(self, view: View, opened: list[np.ndarray], lifted: list[np.ndarray]) -> bool:
        """Whether the pads open to ``opened`` and rise to ``lifted`` touching nothing but the object.

        Solved with the offline IK (to within ``OPEN_TOL``) and checked in the planner's collision world, at its
        clearance. A pad the IK's collision rows hold short of where it goes has something in its way too: opened
        that far, the running IK would press the arm against it.
        """
        q0 = view.joint_positions(view.joint_names())
        q1 = view.plan(self._targets(opened), start=q0, allow=frozenset({self.spec.object}), restarts=False,
                       pos_tol=OPEN_TOL)
        q2 = None if q1 is None else view.plan(self._targets(lifted), start=q1, restarts=False, pos_tol=OPEN_TOL)
        if q1 is None or q2 is None:
            return False  # the IK's collision rows hold a pad short of it: something is in the way
        return view.path_blocked([q0, q1], allow=(self.spec.object,)) is None and view.path_blocked([q1, q2]) is None

    def _targets(self, points: list[np.ndarray]) -> tuple[FrameTarget, ...]:
        return tuple(FrameTarget(f, pos=p, rot=r) for f, p, r in zip(self.frames, points, self.rots, strict=True))

    def _ease(self, view: View) -> bool:
        """Back off each pad that still squeezes; True once none does (or the travel allowed is used up)."""
        squeezing = False
        for i, (frame, side) in enumerate(zip(self.frames, SIDES, strict=False)):
            if squeeze_force(view, frame, side, self.lateral) > EASED and self.eased[i] < MAX_EASE_TRAVEL:
                squeezing = True
                step = EASE_SPEED * view.dt
                self.points[i].pos = self.points[i].pos + side * step * self.lateral
                self.eased[i] += step
        self.info["eased_mm"] = [round(e * 1e3, 2) for e in self.eased]
        return not squeezing

    def _unloaded(self, view: Forces) -> bool:
        """True once the pads no longer hold the object up (their contact forces no longer point down)."""
        load = sum(float(view.wrench(f).force[2]) for f in self.frames)
        return load >= -UNLOADED

    def grip(self, current: Grip | None) -> Grip | None:  # noqa: D102
        return None  # the clamp ends as the pads start to open
