r"""``grasp``: clamp an object between two pads and squeeze it to a measured force.

1. **Heading and grip.** The pads close along the object's lateral axis at heading :math:`\psi`; of the headings
   the object's symmetry makes equivalent, the nearest the robot's own (pads along world y) that the arms reach
   is taken. The pads clamp the faces' centre or, where the arms cannot reach that, up to ``off_centre`` along the
   faces; with ``place_at``, a grip (pad rolls and that shift) with which the clamp also reaches the placement is
   preferred, and a placement no grip reaches fails the phase before anything moves.
2. **Approach.** Both pads rise where they are, then go ``HIGH`` over their approach point (so the arms' swing
   passes over the object), then ``clearance`` above the object's top, then straight down to ``gap`` outside its
   faces, through planned joints (:class:`~nextage_qp.manipulation.route.PlannedRoute`, continuous: the arms may
   reconfigure on the first leg only), so nothing touches the object before the pads close. With ``place_at``, no
   approach is planned at a height where no grip reaches the placement (the search goes on to the next heading or
   height). Each pad's roll about the clamp axis is the one the planner found reachable
   (a palm is a disc); from then on it is held, so the object cannot pivot about that axis.
3. **Close.** The pads move in at ``close_speed`` until the wrist force/torque sensors read ``force`` [N] along
   the pad axis on both sides (or fail past ``max_squeeze`` inside the surface: nothing there).
4. **Hold.** Each pad's inward offset follows the force error, :math:`\dot\delta = k_F (F^* - F)`, for
   ``hold`` seconds; the phase leaves a :class:`~nextage_qp.manipulation.context.Grip` that carries the offsets
   and the force loop on.
"""

from __future__ import annotations

from collections.abc import Iterator
from enum import Enum
from itertools import chain

import numpy as np

from nextage_qp.geometry import rot_z, wrap, yaw_of
from nextage_qp.ik import FrameTarget, RelativeTarget
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import ROUND_HEADINGS, Forces, Geometry, Grip, Poses, View
from nextage_qp.manipulation.phases.base import SETTLE_S, Phase
from nextage_qp.manipulation.phases.grasp.spec import (
    APPROACH_TOL,
    GRIP_MARGIN,
    GRIP_STEP,
    HIGH,
    KNOCKED,
    OFF_CENTRE_STEP,
    SIDES,
    GraspSpec,
)
from nextage_qp.manipulation.route import PlannedRoute


def squeeze_force(view: Forces, frame: str, side: float, lateral: np.ndarray) -> float:
    """Force [N] with which the object pushes a pad outwards along the clamp axis (``lateral`` = +y of the grip)."""
    return float(side * (view.wrench(frame).force @ lateral))


class Stage(str, Enum):
    """The grasp's stages (a ``str`` enum: each compares equal to its name)."""

    APPROACH = "approach"
    """Planned joints to ``gap`` outside the object's faces."""
    CLOSE = "close"
    """The pads move in until both wrists feel ``force``."""
    HOLD = "hold"
    """The squeeze follows the force error for ``hold`` seconds."""


class Grasp(Phase):
    """See the module docstring. Its state is declared here; only its own methods write it."""

    spec: GraspSpec
    stage: Stage
    frames: tuple[str, ...]  # the pad frames, left first
    force: float  # the squeeze per pad [N]
    # the grip searched for in start()
    base: float  # the clamp's default height over the object's origin [m]
    yaw: float  # the clamp's heading [rad]
    rz: np.ndarray  # its rotation about z
    lateral: np.ndarray  # the clamp axis (+y of the grip) in the world
    height: float  # the pads' height over the object's origin [m]
    half: float  # the object's half width at the pads [m]
    shift: float  # the pads' shift along the faces from their centre [m]
    rots: list[np.ndarray] | None  # the pads' rotations, held from the approach on
    place_q: np.ndarray | None  # joints with which the clamp reaches the placement (``place_at``)
    placements: dict[tuple[float, ...], list[tuple[list[np.ndarray], np.ndarray] | None]]  # placements tried
    route: PlannedRoute  # the approach
    # closing and holding
    depth: list[float]  # each pad's target depth inside the surface [m]
    hold_from: float  # when the hold began [s]
    made: Grip | None  # the grip left for the phases that follow

    def start(self, view: View) -> None:  # noqa: D102
        c = self.spec
        self.frames = c.frames or view.pad_frames()
        weight = view.weight(c.object) if c.force_per_weight else 0.0
        self.force = max(c.force, c.force_per_weight * weight)  # squeeze per pad [N]
        self.info["force_n"] = round(self.force, 2)
        obj, rot = view.body_pose(c.object)
        sym = view.yaw_symmetry(c.object) or ROUND_HEADINGS  # a round object: headings this far apart
        nearest = wrap(yaw_of(rot), sym)  # the equivalent heading nearest the robot's own comes first
        headings = sorted((wrap(nearest + k * sym) for k in range(max(1, round(2 * np.pi / sym)))), key=abs)
        top = obj[2] + view.extent(c.object, np.array([0.0, 0.0, 1.0]))
        self.rots = None
        self.place_q = None
        self.route = PlannedRoute([])
        self.shift = 0.0
        self.placements = {}
        found = None
        # the clamp's default height over the object's origin (the middle of its widest part), found once
        self.base = c.height if c.height is not None else view.grip_geometry(c.object, np.array([0.0, 1.0, 0.0]))[0]
        for raise_by in self._raises(view):
            for heading in headings:
                self.yaw, self.rz = heading, rot_z(heading)
                self.lateral = self.rz[:, 1]
                turn = wrap(heading - yaw_of(rot))
                turn = round(turn / sym) * sym if sym < 2 * np.pi else turn  # an equivalent heading: the same faces
                self._grip_at(view, np.array([-np.sin(turn), np.cos(turn), 0.0]), raise_by)
                found = self._plan_approach(view, obj, top)
                if found:
                    break
            if found and (c.place_at is None or self._placement_found()):  # else: higher, if it may
                break
        # checked before anything moves: no grip reaches the placement (at any height tried; or at the height found)
        placed = any(any(tried) for tried in self.placements.values()) if found is None else self._placement_found()
        if c.place_at is not None and not placed:
            raise self.refusal(view, f"the clamp cannot reach {c.place_at}'s pose with "
                             f"{c.object} at any of its equivalent yaws, at the faces' centre or up to "
                             f"{c.off_centre * 1e3:g} mm off it: {self._placement_blocker(view)}")
        if found is None:
            raise self.refusal(view, f"the pads cannot reach both sides of {c.object} "
                             f"({2e3 * self.half:.0f} mm wide at the pads) at any of its headings "
                             f"({', '.join(f'{np.degrees(h):.0f}' for h in headings)} deg): too wide for the "
                             "clamp, or out of the arms' reach")
        gap = found[0]
        self.info["rolls_fit_placement"] = found[1]
        self.rots = [view.pose_at(f, self.route.joints[-1]).rot for f in self.frames]  # the rolls found: held
        self.depth = [-gap, -gap]  # pad target depth inside the surface, per pad [m]
        self.info.update(approach_gap_m=round(gap, 4), off_centre_m=round(self.shift, 4))
        self.stage, self.hold_from = Stage.APPROACH, 0.0
        self.made = None
        self.info.update(heading_rad=round(self.yaw, 4))

    def _placement_found(self) -> bool:
        """Whether a grip at the current clamp height reaches the placement too."""
        at = (round(self.height, 6), round(self.half, 6))
        return any(any(tried) for key, tried in self.placements.items() if key[1:] == at)

    def _raises(self, view: Geometry) -> list[float]:
        """How far above its default height the clamp may go [m], in the order tried.

        Not at all first; then (a default height only) in ``GRIP_STEP`` steps while the clamp point stays
        ``GRIP_MARGIN`` below the object's top: an object whose middle the pads cannot reach down to is held higher.
        """
        c = self.spec
        if c.height is not None:
            return [0.0]
        room = view.extent(c.object, np.array([0.0, 0.0, 1.0])) - GRIP_MARGIN - self.base
        return [k * GRIP_STEP for k in range(int(max(room, 0.0) / GRIP_STEP) + 1)]

    def _grip_at(self, view: Geometry, lateral: np.ndarray, raise_by: float) -> None:
        """Set the clamp's height and half-width for pads closing along ``lateral`` (object frame)."""
        c = self.spec
        if c.half_width is not None and c.height is not None:
            self.height, self.half = c.height, c.half_width
        else:
            self.height, half = view.grip_geometry(c.object, lateral, self.base + raise_by)
            self.half = half if c.half_width is None else c.half_width
        self.info["grip_height_m"] = round(self.height, 4)

    def _plan_approach(self, view: View, obj: np.ndarray, top: float) -> tuple[float, bool] | None:
        """Plan the approach at the current heading: (gap, rolls fit the placement), or None when out of reach.

        The pads clamp the faces' centre or, when the arms cannot reach that (at the object or at the placement),
        a point up to ``off_centre`` along the faces (every ``OFF_CENTRE_STEP``, and ``off_centre`` itself): first
        those towards the robot, then the others; at each, a grip that also reaches the placement first, then any.
        """
        c = self.spec
        towards = -float(np.sign(self.rz[:2, 0] @ obj[:2]) or 1.0)  # along the faces, towards the chest axis
        steps = [*np.arange(0.0, c.off_centre - 1e-9, OFF_CENTRE_STEP), c.off_centre]
        near = [towards * float(d) for d in steps]
        shifts = list(dict.fromkeys([*near, *(-s for s in near)]))
        fitting = ((shift, grip) for shift in shifts for grip in self._placements(view, shift))  # lazily
        # Then any grip, but only where one reaches the placement at this height: else the search goes on (another
        # heading, or higher) and a grip here would be given up anyway.
        anywhere = ((shift, (None, None)) for shift in dict.fromkeys(near) if c.place_at is None
                    or self._placement_found())
        for shift, (rolls, place_q) in chain(fitting, anywhere):
            self.place_q, self.shift = place_q, shift
            self.rots = None if rolls is None else [self.rz @ r for r in rolls]
            for gap in (c.gap, 0.6 * c.gap, 0.35 * c.gap):  # nearer the faces when the arms cannot spread so far
                outside = [obj + self.rz @ np.array([shift, s * (self.half + gap), self.height]) for s in SIDES]
                above = [p + np.array([0.0, 0.0, max(top + c.clearance - p[2], 0.0)]) for p in outside]
                high = [a + np.array([0.0, 0.0, HIGH]) for a in above]
                down = [[a + f * (o - a) for a, o in zip(above, outside, strict=True)] for f in (0.0, 0.5, 1.0)]
                legs = [self._targets(points) for points in [high, *down]]
                for rise in (self._rise(view, high[0][2]), None):  # up where they are first, then over the object
                    self.route = PlannedRoute(legs if rise is None else [rise, *legs], pos_tol=APPROACH_TOL,
                                              continuous=True, plan=c.plan, near=(c.object,))
                    if self.route.plan(view):
                        return gap, rolls is not None
        return None

    def _rise(self, view: Poses, height: float) -> tuple[FrameTarget, ...]:
        """The pads straight up to ``height`` from where they are, as they are turned."""
        poses = [view.commanded_pose(f) for f in self.frames]
        return tuple(
            FrameTarget(f, pos=np.array([*p.pos[:2], max(p.pos[2], height)]), rot=p.rot)
            for f, p in zip(self.frames, poses, strict=True)
        )

    def _placements(self, view: View, shift: float) -> Iterator[tuple[list[np.ndarray], np.ndarray]]:
        """Grips with which the clamp, ``shift`` along the faces, also reaches ``place_at`` (none without it).

        Each is (pad rotations in the clamp frame, joints), one per equivalent yaw of the object there that the
        planner reaches. Each yaw is solved once per shift, height and half-width, and only when asked for: a route
        found with the first grip ends the search (:attr:`placements` keeps the yaws tried, None: out of reach).
        """
        c = self.spec
        if c.place_at is None:
            return
        tried = self.placements.setdefault((round(shift, 6), round(self.height, 6), round(self.half, 6)), [])
        sym = view.yaw_symmetry(c.object) or ROUND_HEADINGS  # a round object: headings this far apart
        for k in range(max(1, round(2 * np.pi / sym))):
            if k == len(tried):
                rz, targets = self._placement_pads(view, shift, k * sym)
                q = view.plan(targets, allow=frozenset({c.object}))
                tried.append(None if q is None else ([rz.T @ view.pose_at(f, q).rot for f in self.frames], q))
            grip = tried[k]
            if grip is not None:
                yield grip

    def _placement_pads(self, view: View, shift: float, turn: float) -> tuple[np.ndarray, list[FrameTarget]]:
        """The clamp's frame at ``place_at`` turned by ``turn`` [rad], and the pads' targets there.

        ``shift`` along the faces, at the current clamp height and half-width; each pad's y axis along the clamp axis,
        its roll free.
        """
        c = self.spec
        assert c.place_at is not None
        tgt, trot = view.body_pose(c.place_at)
        centre = np.array([tgt[0], tgt[1], view.rest_height(c.object, c.place_at) + self.height])
        rz = rot_z(yaw_of(trot) + turn)
        points = [centre + rz @ np.array([shift, s * self.half, 0.0]) for s in SIDES]
        return rz, [FrameTarget(f, pos=p, axis=np.array([0.0, 1.0, 0.0]), direction=rz[:, 1])
                    for f, p in zip(self.frames, points, strict=True)]

    def _placement_blocker(self, view: View) -> str:
        """Why no grip reaches the placement: an obstacle in the way (what the arms would touch), or the reach."""
        c = self.spec
        assert c.place_at is not None
        q = view.plan(self._placement_pads(view, 0.0, 0.0)[1], allow=frozenset({c.object, *view.obstacle_groups()}))
        if q is None:
            return "the target is out of the arms' reach"
        why = view.path_blocked([q], near=(c.object, c.place_at))
        if why is None:
            return "the IK, keeping clear of the obstacles, stalls short of it (a pose clear of them exists)"
        return f"an obstacle is in the way (the arms would reach it with {why})"

    def _targets(self, points: list[np.ndarray]) -> tuple[FrameTarget, ...]:
        """Pad targets at ``points``.

        Full poses once the approach has fixed each pad's roll about the clamp axis; before that only the pad's y
        axis along the clamp axis, so the planner picks the roll the arm reaches.
        """
        frames = self.frames
        if self.rots is None:
            return tuple(FrameTarget(f, pos=p, axis=np.array([0.0, 1.0, 0.0]), direction=self.lateral)
                         for f, p in zip(frames, points, strict=True))
        return tuple(FrameTarget(f, pos=p, rot=r) for f, p, r in zip(frames, points, self.rots, strict=True))

    def _pads(self, view: Poses) -> tuple[FrameTarget, ...]:
        c = self.spec
        obj = view.body_pose(c.object).pos
        points = [obj + self.rz @ np.array([self.shift, s * (self.half - d), self.height])
                  for s, d in zip(SIDES, self.depth, strict=True)]
        return self._targets(points)

    def forces(self, view: View) -> list[float]:
        """Measured squeeze force on each pad [N]."""
        return [squeeze_force(view, f, s, self.lateral) for f, s in zip(self.frames, SIDES, strict=True)]

    def budget(self, view: View) -> float:
        """The approach route at its straight legs' speed with a rest at each waypoint, closing by ``gap`` and up to
        ``max_squeeze`` at ``close_speed``, and the ``hold``.
        """  # noqa: D205
        c, route = self.spec, self.route  # start() found a route, or it refused the grasp
        start = view.commanded_pose(route.waypoints[0][0].frame).pos
        return (route.length(start) / route.speed + len(route.waypoints) * SETTLE_S
                + (c.gap + c.max_squeeze) / c.close_speed + c.hold + SETTLE_S)

    def update(self, view: View) -> Command:  # noqa: D102
        c = self.spec
        if self.stage is Stage.APPROACH:
            tilt = float(np.arccos(np.clip(view.body_pose(c.object).rot[2, 2], -1.0, 1.0)))
            if tilt > KNOCKED:
                raise self.failure(f"the arms knocked {c.object} over on the way in "
                                 f"(tilted {np.degrees(tilt):.0f} deg before the pads closed)")
            command = self.route.step(view)
            if self.route.done:
                self.stage = Stage.CLOSE
            return command
        forces = self.forces(view)
        self.info["squeeze_n"] = [round(f, 2) for f in forces]
        if self.stage is Stage.CLOSE:
            self.depth = [d if f >= self.force else d + c.close_speed * view.dt for d, f in zip(self.depth, forces,
                                                                                              strict=True)]
            if max(self.depth) > c.max_squeeze:
                raise self.failure(f"the pads closed {c.max_squeeze * 1e3:g} mm inside "
                                 f"{c.object}'s surface without feeling {self.force:g} N (felt {min(forces):.1f} N)")
            if min(forces) >= self.force:
                self.stage, self.hold_from = Stage.HOLD, view.t
        else:
            self.depth = [d + float(np.clip(c.force_gain * (self.force - f), -0.02, 0.02)) * view.dt
                          for d, f in zip(self.depth, forces, strict=True)]
        done = self.stage is Stage.HOLD and view.t - self.hold_from >= c.hold
        targets = self._pads(view)
        if done:
            obj, rot = view.body_pose(c.object)
            poses = {f: view.commanded_pose(f) for f in self.frames}
            self.made = Grip(
                object=c.object,
                frames=tuple(self.frames),
                offsets={t.frame: rot.T @ (np.asarray(t.pos) - obj) for t in targets},
                rotations={t.frame: rot.T @ np.asarray(t.rot) for t in targets},
                relative=RelativeTarget.between(self.frames[0], self.frames[1], poses, cost=1.0),
                lateral=rot.T @ self.lateral,
                force=self.force,
                force_gain=c.force_gain,
                place_joints=self.place_q,
            )
        return Command(targets, allow=frozenset({c.object}), done=done)

    def grip(self, current: Grip | None) -> Grip | None:  # noqa: D102
        return self.made if self.made is not None else current
