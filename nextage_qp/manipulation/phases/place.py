r"""``place``: carry a clamped object over the obstacles and set it down on its target pose.

The object's setpoint :math:`(p, \psi)` goes

1. straight up to the carry height: the obstacles' top plus ``clearance`` plus the object's own depth below its
   origin (computed from the scene's geometry, not a fixed offset);
2. across to above the target, turning to the target's yaw (the equivalent yaw, modulo the object's symmetry,
   nearest the one it has);

   every ``ROUTE_STEP`` of that route solved with the object in the clamp and checked with the object attached
   (:meth:`View.path_blocked`), and driven with the checked joints as the IK's posture target; where it is out of
   reach or blocked (clutter beside or under it, a shelf's top board; or always, ``plan: always``), the shortest
   free one of lower routes and routes through a via point aside, checked alike (``plan: never``: the route over
   the obstacles, unchecked, the posture sliding from the default to the hover's joints);
3. down to ``hover`` above its resting height (where the object at rest on the target comes within
   ``ALIGN_ROOM`` of an obstacle, a target beside a wall, the object's footprint is first aligned over the target
   at the top of the descent, as at the hover below, so that an object the carry left off-centre in the clamp does
   not land on the wall's edge), where it waits for the sway to settle and corrects its planar
   position and yaw from the live pose (the average over ``settle`` seconds, so the correction does not chase
   the swing), up to ``corrections`` times;
4. slowly down until the object stands on the table (its height within 1 mm of its resting height), the setpoint
   drifting against the live planar error at ``descend_gain`` until the object touches.

A target whose object at rest there comes within ``AIM_OFF`` of an obstacle is aimed that far off it (along the
obstacle's normal), so that the set-down's own error does not put the object on the obstacle's edge.

The planar error is that of the object's *footprint*, the centre of its lowest face: a held object tilted by
:math:`\theta` lands on an edge and drops flat when the pads open, which moves its origin by about
:math:`h \sin\theta` (``h`` its origin's height over that face) but leaves the footprint where it touched.

The pads follow the setpoint through the grip's offsets and keep squeezing at the grip's force
(:class:`~nextage_qp.manipulation.context.Clamp`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.geometry import clamp, nearest_equivalent, path_length, wrap, yaw_of
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import ROUND_HEADINGS, Setpoint, View
from nextage_qp.manipulation.phases.base import MAX_SECONDS, SETTLE_S, Phase, Spec, name_field, plan_field
from nextage_qp.manipulation.route import PlanMode

CONTACT = 0.001
"""The object counts as set down when its height is this close to its resting height [m]."""
TOUCH = 0.003
"""Height over its resting height [m] below which the descent stops steering (the object may touch)."""
HOVER_TOL = 0.006
"""Position error [m] within which the planner's clamp at the hover counts as reached (the hover corrects it)."""
STALL = 3.0
"""Time the object may stay up once the clamp has reached the bottom of its descent [s]."""
STALLED = 0.01
"""Height over its resting height [m] at which an object still up ``STALL`` s after that fails the phase."""
ROUTE_STEP = 0.03
"""Spacing [m] of the object setpoints at which the carry's route is solved, checked and followed."""
ROUTE_SLACK = 0.005
"""The route over the obstacles is checked at ``clearance`` less this [m]: it passes exactly ``clearance`` over
their tops."""
POSTURE_RATE = 0.3
"""Fastest a checked route's joints turn [rad/s]: the arms swing through the null space no faster (their lag would
open the clamp)."""
TOUCHING = 0.003
"""Penetration [m] a descent may show where its target touches an obstacle (the IK's and the contact's slop)."""
ROUTE_HEIGHTS = 4
"""Heights tried for a route lower than over the obstacles: evenly from the lowest to that one [count]."""
ROUTE_ASIDE = (0.0, 0.1, -0.1, 0.2, -0.2)
"""Sideways offsets [m] of a route's via point from the middle of the straight line to the target."""
AIM_OFF = 0.003
"""A target whose object at rest comes nearer an obstacle than this [m] is aimed this far from it: the set-down's own
error (``tolerance``) would put it on the obstacle's edge half the time. Only obstacles beside it count, not what it
stands on."""
PROBE_LIFT = 0.002
"""The object is measured this far over its rest [m]: what it stands on is then below it, not touching."""
ALIGN_ROOM = 0.01
"""A checked route to a target whose object at rest there comes this near an obstacle [m] (a target beside a wall)
aligns the object over the target at the top of its descent."""
BLEND = 2.0
"""Time [s] over which the IK's posture target slides from its default to the hover joints: a posture that jumped
would swing the arms through the null space at once, and their lag would open the clamp."""


class PlaceSpec(Spec):
    """Carry a clamped object over the obstacles and set it down on a target body's pose."""

    grip = "needs"

    kind: Literal["place"]
    object: str = name_field("object", description="The object an earlier grasp phase clamped.")
    target: str = name_field("place", description="Body whose x, y and yaw the object should take.")
    clearance: float = Field(default=0.03, gt=0, le=0.3, description="Object's bottom over the obstacles [m].")
    lift: float = Field(default=0.03, ge=0, le=0.5, description="Least rise before moving sideways [m].")
    hover: float = Field(default=0.02, gt=0, le=0.2, description="Height over rest where it corrects [m].")
    speed: float = Field(default=0.1, gt=0, le=0.5, description="Setpoint speed in transit [m/s].")
    descend_speed: float = Field(default=0.01, gt=0, le=0.1, description="Speed of the final descent [m/s].")
    turn_rate: float = Field(default=0.5, gt=0, le=3.0, description="Yaw rate of the setpoint [rad/s].")
    tolerance: float = Field(default=0.0015, gt=0, le=0.05, description="Planar error accepted at the hover [m].")
    yaw_tolerance: float = Field(default=0.01, gt=0, le=0.5, description="Yaw error accepted at the hover [rad].")
    corrections: int = Field(default=4, ge=0, le=20, description="Corrections allowed at the hover [count].")
    settle: float = Field(default=0.4, gt=0, le=MAX_SECONDS, description="Time the live pose is averaged [s].")
    relative_cost: float = Field(default=10.0, ge=0, le=1e4,
                                 description="Weight of the pads' relative pose [1/m, 1/rad].")
    descend_gain: float = Field(default=1.0, ge=0, le=20, description=(
        "Gain [1/s] with which the setpoint drifts against the footprint's planar error while descending (0: off)."))
    level_gain: float = Field(default=2.0, ge=0, le=20, description=(
        "Gain [1/s] of the loop that rolls the pads to keep the object upright (0: off)."))
    plan: PlanMode = plan_field()


class Place(Phase):
    """See the module docstring."""

    spec: PlaceSpec

    def start(self, view: View) -> None:  # noqa: D102
        c = self.spec
        self.clamp = self.held(view, c.object, c.relative_cost)
        self.clamp.level_gain = c.level_gain
        obj, rot = view.body_pose(c.object)
        tgt, trot = view.body_pose(c.target)
        self.rest = view.rest_height(c.object, c.target)  # on the table, or on the target object (a stack)
        depth = view.rest_height(c.object) - view.table_top()
        carry = max(obj[2] + c.lift, view.obstacle_top() + c.clearance + depth, self.rest + c.clearance)
        self.sp, self.yaw = Setpoint(obj.copy()), yaw_of(rot)
        # beside: not the board it stands on, nor one over it (a shelf's boards are obstacles too)
        probe = np.array([tgt[0], tgt[1], self.rest + PROBE_LIFT])
        beside, away = view.clearance_at(c.object, probe, yaw_of(trot), beside=True)
        self.aim = away[:2] * max(0.0, AIM_OFF - beside)  # a target (all but) touching a wall: aimed off it
        self.goal = np.array([tgt[0] + self.aim[0], tgt[1] + self.aim[1], self.rest + c.hover])
        self.info.update(target_room_m=round(beside, 5), aim_off_m=round(float(np.linalg.norm(self.aim)), 5))
        self.goal_yaw, self.posture = self._reachable_yaw(view, yaw_of(trot))
        self.posture_from, self.t0 = view.default_posture(), view.t
        self._blended: np.ndarray | None = None  # the posture target once the blend is over
        self.legs = [np.array([obj[0], obj[1], carry]), np.array([tgt[0], tgt[1], carry]), self.goal]
        self.yaws = [self.yaw, self.goal_yaw, self.goal_yaw]
        self.postures: list[np.ndarray | None] = [None, None, None]  # per leg, the joints the IK heads for
        self.leg, self.stage, self.frac = 0, "transit", 0.0
        self.descent, self.align = len(self.legs) - 1, False  # the descent's first leg; align over it first
        self.samples: list[tuple[np.ndarray, float]] = []
        self.corrections = 0
        self.bottom_from: float | None = None
        self.info.update(stage="transit", carry_height_m=round(carry, 4), corrections=0)
        if c.plan != "never":
            self._route(view, obj)

    def budget(self, view: View) -> float:
        """The route's legs at ``speed`` and its turn at ``turn_rate``, the descent from ``hover`` at
        ``descend_speed``, and a rest of ``settle`` at the hover and at each correction.
        """  # noqa: D205
        c = self.spec
        turn = abs(wrap(self.goal_yaw - self.yaw)) / c.turn_rate
        return (path_length([self.sp.pos, *self.legs]) / c.speed + turn + c.hover / c.descend_speed
                + (1 + c.corrections) * (c.settle + SETTLE_S))

    def _route(self, view: View, obj: np.ndarray) -> None:
        """Check the route over the obstacles; where it is blocked, take the shortest free lower or sideways one.

        ``plan: always`` skips the route over the obstacles (see the module docstring).
        """
        c = self.spec
        t0 = time.perf_counter()
        over = self.legs[0][2]
        low = max(obj[2] + c.lift, self.rest + c.clearance)
        heights = [over, *np.linspace(low, over, ROUTE_HEIGHTS)[:-1]] if over > low + 1e-6 else [over]
        across = self.goal[:2] - obj[:2]
        side = np.array([-across[1], across[0]]) / max(float(np.linalg.norm(across)), 1e-9)
        mid = 0.5 * (obj[:2] + self.goal[:2])
        candidates = [(float(h), mid + d * side if d else None) for h in heights for d in ROUTE_ASIDE]
        candidates = candidates[:1] + sorted(candidates[1:], key=lambda hv: self._length(obj, *hv))
        probe = np.array([*self.goal[:2], self.rest + PROBE_LIFT])  # where aimed, to what is beside it (see start)
        beside = view.clearance_at(c.object, probe, self.goal_yaw, beside=True)[0]
        room = min(view.room_at(self.posture, near=(c.target,)), beside)  # the hover's own room (the object's at rest)
        at_goal = max(-TOUCHING, room - ROUTE_SLACK)
        first_why = None
        for k, (height, via) in enumerate(candidates):
            if k == 0 and c.plan == "always":
                first_why = "plan: always"
                continue
            legs, yaws = self._corners(obj, height, via)
            checked = self._check(view, legs, yaws, at_goal)
            if isinstance(checked, str):
                first_why = first_why or checked
                continue
            self.info.update(carry="over" if k == 0 else "routed", carry_routes_checked=k + 1,
                             carry_check_ms=round((time.perf_counter() - t0) * 1e3, 1))
            points, point_yaws, qs = checked
            self.legs, self.yaws, self.postures = points, point_yaws, list(qs)
            self.descent = len(points) - max(1, int(np.ceil(np.linalg.norm(legs[-1] - legs[-2]) / ROUTE_STEP)))
            self.align = beside < ALIGN_ROOM  # the object resting on the target near a wall: align first
            self.start_pos, self.start_yaw = self.sp.pos.copy(), self.yaw
            self.start_q = view.joint_positions(view.joint_names())
            self.posture = qs[-1]
            self.info.update(carry_height_m=round(height, 4), carry_blocked=first_why,
                             carry_via=None if via is None else [round(float(v), 4) for v in via])
            return
        raise self.failure(f"no collision-free route to carry {c.object} to {c.target}: over the obstacles, "
                           f"{first_why}; {len(candidates) - 1} lower and sideways routes blocked too")

    def _corners(self, obj: np.ndarray, height: float,
                 via: np.ndarray | None) -> tuple[list[np.ndarray], list[float]]:
        """The corners of a route at ``height`` (through ``via`` on the way across) and the object's yaw there."""
        legs, yaws = [np.array([obj[0], obj[1], height])], [self.yaw]
        if via is not None:
            legs.append(np.array([via[0], via[1], height]))
            yaws.append(0.5 * (self.yaw + self.goal_yaw))
        legs += [np.array([self.goal[0], self.goal[1], height]), self.goal]
        yaws += [self.goal_yaw, self.goal_yaw]
        return legs, yaws

    def _length(self, obj: np.ndarray, height: float, via: np.ndarray | None) -> float:
        """A route's length [m]."""
        corners = [obj, *self._corners(obj, height, via)[0]]
        return path_length(corners)

    def _check(self, view: View, legs: list[np.ndarray], yaws: list[float],
               at_goal: float) -> tuple[list[np.ndarray], list[float], list[np.ndarray]] | str:
        """A route's setpoints every ``ROUTE_STEP`` with the clamp's joints at each, or what blocks it.

        Each point is solved from the previous one and the joint segment between them checked with the object
        attached: the rise not to touch anything (the grasp may have left the arms near something), the rest to
        keep ``clearance`` less ``ROUTE_SLACK``, or, where the arms are nearer something at the top of the rise,
        to come no more than twice that nearer; the descent to the hover, no nearer than ``at_goal`` [m] (the hover's
        own room less ``ROUTE_SLACK``: a target beside a wall; one touching it, ``TOUCHING`` into it).
        """
        c = self.spec
        points, point_yaws, at, yaw = [], [], self.sp.pos.copy(), self.yaw
        for goal, goal_yaw in zip(legs, yaws, strict=True):
            n = max(1, int(np.ceil(np.linalg.norm(goal - at) / ROUTE_STEP)))
            points += [at + (goal - at) * (k / n) for k in range(1, n + 1)]
            point_yaws += [yaw + (goal_yaw - yaw) * (k / n) for k in range(1, n + 1)]
            at, yaw = goal, goal_yaw
        rise = next(k for k, p in enumerate(points) if p[2] >= legs[0][2] - 1e-9)  # the rise's last point
        descent = len(points) - max(1, int(np.ceil(np.linalg.norm(legs[-1] - legs[-2]) / ROUTE_STEP)))
        q = view.joint_positions(view.joint_names())
        qs: list[np.ndarray] = []
        keep = c.clearance - ROUTE_SLACK
        for k, (p, y) in enumerate(zip(points, point_yaws, strict=True)):
            nxt = view.plan(self.clamp.pads(p, y)[0], start=q, allow=frozenset({c.object}), pos_tol=HOVER_TOL,
                            restarts=False)
            if nxt is None:
                return f"the clamp cannot reach {c.object} at {np.round(p, 3).tolist()}"
            if k == rise + 1:  # the arms may already be nearer something than the clearance: no nearer, then
                keep = min(keep, max(0.0, view.room_at(q, near=(c.target,)) - 2 * ROUTE_SLACK))
            clearance = 0.0 if k <= rise else min(keep, at_goal) if k >= descent else keep
            why = view.path_blocked([q, nxt], clearance=clearance, near=(c.target,))
            if why is not None:
                return why
            q = nxt
            qs.append(q)
        return points, point_yaws, qs

    def _reachable_yaw(self, view: View, target_yaw: float) -> tuple[float, np.ndarray]:
        """The equivalent target yaw nearest the object's own that the clamp can reach, and its hover joints.

        A yaw counts when the planner reaches the clamp at the hover over the target and from there at the set-down,
        solved from the commanded joints or, when that stalls (against the obstacle between here and there), from
        the joints with which the grasp found the placement reachable.
        """
        c = self.spec
        sym = view.yaw_symmetry(c.object) or ROUND_HEADINGS  # a round object: headings this far apart
        nearest = nearest_equivalent(target_yaw, self.yaw, sym)
        count = max(1, round(2 * np.pi / sym))
        hint = self.clamp.grip.place_joints
        for yaw in sorted((nearest + k * sym for k in range(-(count // 2), count - count // 2)),
                          key=lambda y: abs(y - self.yaw)):
            for start in (None,) if hint is None else (None, hint):  # from here, or from the grasp's check
                low = view.plan(self.clamp.pads(self.goal, yaw)[0], start=start, allow=frozenset({c.object}),
                                pos_tol=HOVER_TOL)
                down = self.goal - np.array([0.0, 0.0, c.hover])  # and down to the set-down from there
                if low is not None and view.plan(self.clamp.pads(down, yaw)[0], start=low,
                                                 allow=frozenset({c.object}), pos_tol=HOVER_TOL) is not None:
                    self.info["place_yaw_rad"] = round(yaw, 4)
                    return yaw, low
        raise self.failure(f"the clamp cannot reach {c.target}'s pose with "
                         f"{c.object} at any of its {count} equivalent yaws")

    def update(self, view: View) -> Command:  # noqa: D102
        c = self.spec
        done = False
        if self.stage == "transit":
            goal, goal_yaw = self.legs[self.leg], self.yaws[self.leg]
            if self.postures[self.leg] is not None:  # a checked route's point: timed by its joints' travel too
                arrived = self._follow(view)
            else:
                arrived = self.sp.advance(goal, c.speed, view.dt)
                self.yaw += clamp(float(goal_yaw - self.yaw), -c.turn_rate * view.dt, c.turn_rate * view.dt)
            if arrived and abs(goal_yaw - self.yaw) < 1e-9:
                self.frac = 0.0
                self.leg += 1
                if self.leg == len(self.legs):
                    self.stage, self.wait_from, self.samples = "hover", view.t, []
                elif self.leg == self.descent and self.align:
                    self.stage, self.align, self.samples = "align", False, []
        elif self.stage == "align":
            self._align(view)
        elif self.stage == "hover":
            self._hover(view)
        elif self.stage == "descend":
            height = view.body_pose(c.object).pos[2]
            if height > self.rest + TOUCH:  # not yet on the table: steer the footprint onto the target
                self.sp.pos[:2] -= c.descend_gain * view.dt * self._footprint_error(view)
            if self.sp.advance(np.array([*self.sp.pos[:2], self.rest - 0.005]), c.descend_speed, view.dt):
                self._check_stall(view)
            down = height <= self.rest + CONTACT
            done = down and view.settled()
            if down:
                self.sp.jump(np.array([*self.sp.pos[:2], max(self.sp.pos[2], self.rest)]))
        self.info["stage"] = self.stage  # a timeout names the stage it ended in
        targets, relative = self.clamp.targets(view, self.sp.pos, self.yaw)
        blend = clamp((view.t - self.t0) / BLEND, 0.0, 1.0)
        moving = self.stage in ("transit", "align")
        planned = self.postures[min(self.leg, len(self.postures) - 1)] if moving else None
        if planned is not None:  # along a checked route: its joints, as far as the setpoint has come (no jumps)
            posture = self._along(planned)
        elif self.postures[-1] is not None:  # after a checked route: its last joints, the hover's
            posture = self.posture
        else:
            posture = self._blended if blend == 1.0 and self._blended is not None else \
                self.posture_from + blend * blend * (3.0 - 2.0 * blend) * (self.posture - self.posture_from)
            if blend == 1.0:  # the same array from now on: the IK keeps its posture target instead of setting it
                self._blended = posture
        return Command(targets, (relative,), allow=frozenset({c.object}), posture=posture, done=done)

    def _follow(self, view: View) -> bool:
        """Move the setpoint (and yaw) from a checked route's last point towards its current one; True once there.

        At ``speed``, ``turn_rate`` and the joints' ``POSTURE_RATE``, whichever takes longest.
        """
        c, k = self.spec, self.leg
        prev, prev_yaw, prev_q = self._previous(k)
        q = self.postures[k]
        assert q is not None
        time = max(float(np.linalg.norm(self.legs[k] - prev)) / c.speed, abs(self.yaws[k] - prev_yaw) / c.turn_rate,
                   float(np.max(np.abs(q - prev_q))) / POSTURE_RATE, view.dt)
        self.frac = min(1.0, self.frac + view.dt / time)
        self.sp.jump(prev + self.frac * (self.legs[k] - prev))
        self.yaw = prev_yaw + self.frac * (self.yaws[k] - prev_yaw)
        if self.frac >= 1.0:
            self.yaw = self.yaws[k]
        return self.frac >= 1.0

    def _along(self, q: np.ndarray) -> np.ndarray:
        """The joints between the last point's and ``q`` (the current point's), as far as the setpoint has come."""
        prev_q = self._previous(min(self.leg, len(self.legs) - 1))[2]
        return prev_q + self.frac * (q - prev_q)

    def _previous(self, k: int) -> tuple[np.ndarray, float, np.ndarray]:
        """The setpoint, yaw and joints a checked route's point ``k`` starts from (the route's start for the first)."""
        if k == 0:
            return self.start_pos, self.start_yaw, self.start_q
        q = self.postures[k - 1]
        assert q is not None
        return self.legs[k - 1], self.yaws[k - 1], q

    def _check_stall(self, view: View) -> None:
        """Fail when the setpoint has been at the bottom of its descent ``STALL`` s and the object is ``STALLED`` up.

        An object a few millimetres up may still come down (the timeout bounds the wait); one held further up will not.
        """
        if self.bottom_from is None:
            self.bottom_from = view.t
        obj, rot = view.body_pose(self.spec.object)
        if view.t - self.bottom_from > STALL and obj[2] > self.rest + STALLED:
            tilt = np.degrees(np.arccos(np.clip(rot[2, 2], -1.0, 1.0)))
            pads = self.clamp.pads(self.sp.pos, self.yaw)[0]
            lag = max(float(view.frame_pose(t.frame).pos[2] - np.asarray(t.pos)[2]) for t in pads)
            raise self.failure(f"set-down stalled: {self.spec.object} is still "
                             f"{(obj[2] - self.rest) * 1e3:.0f} mm over its resting height, tilted {tilt:.0f} deg, "
                             f"{STALL:g} s after the clamp's setpoint reached the bottom of its descent (a pad "
                             f"{lag * 1e3:.0f} mm above its target)")

    def _footprint_error(self, view: View) -> np.ndarray:
        """Planar offset [m] of the object's footprint (the centre of its lowest face) from where it is aimed."""
        obj, rot = view.body_pose(self.spec.object)
        down = -rot[:, 2]
        foot = obj + down * view.extent(self.spec.object, down)
        return np.asarray(foot[:2] - view.body_pose(self.spec.target).pos[:2] - self.aim)

    def _averaged(self, view: View,
                  sample: Callable[[], tuple[np.ndarray, float]]) -> tuple[np.ndarray, float] | None:
        """``sample()``'s planar and yaw errors averaged over ``settle`` seconds once the arms are still, else None.

        Averaged so that a correction does not chase the swing; the samples restart whenever the arms move.
        """
        if not view.settled():
            self.samples = []
            return None
        self.samples.append(sample())
        if len(self.samples) * view.dt < self.spec.settle:
            return None
        err = np.mean([s[0] for s in self.samples], axis=0)
        yaw_err = float(np.mean([s[1] for s in self.samples]))
        self.samples = []
        return err, yaw_err

    def _align(self, view: View) -> None:
        """At the top of a descent beside an obstacle: correct the rest of the route by the footprint's planar error.

        As at the hover (:meth:`_hover`): the error averaged over ``settle`` seconds once the arms are still, up to
        ``corrections`` times.
        """
        c = self.spec
        averaged = self._averaged(view, lambda: (self._footprint_error(view), 0.0))  # no yaw corrected up there
        if averaged is None:
            return
        err = averaged[0]
        self.info.update(align_error_xy_m=round(float(np.linalg.norm(err)), 5))
        aligns = self.info.get("aligns", 0)
        if np.linalg.norm(err) <= c.tolerance or aligns >= c.corrections:
            self.stage = "transit"
            return
        self.info["aligns"] = aligns + 1
        shift = np.array([*err, 0.0])
        for k in range(self.leg - 1, len(self.legs)):  # the point it is at, and the rest of the route
            self.legs[k] = self.legs[k] - shift
        self.goal = self.goal - shift
        self.sp.jump(self.sp.pos - shift)
        self.stage = "align"

    def _hover(self, view: View) -> None:
        """Wait for the sway to settle, then correct the setpoint by the averaged planar and yaw error."""
        c = self.spec

        def sample() -> tuple[np.ndarray, float]:
            obj, rot = view.body_pose(c.object)
            tgt, trot = view.body_pose(c.target)
            return obj[:2] - tgt[:2] - self.aim, wrap(yaw_of(rot) - yaw_of(trot), view.yaw_symmetry(c.object))

        averaged = self._averaged(view, sample)
        if averaged is None:
            return
        err, yaw_err = averaged
        self.info.update(hover_error_xy_m=round(float(np.linalg.norm(err)), 5), hover_yaw_error_rad=round(yaw_err, 4))
        within = np.linalg.norm(err) <= c.tolerance and abs(yaw_err) <= c.yaw_tolerance
        if within or self.corrections >= c.corrections:
            self.stage = "descend"
            return
        self.corrections += 1
        self.info["corrections"] = self.corrections
        self.sp.jump(self.sp.pos - np.array([*err, 0.0]))
        self.yaw -= yaw_err
