r"""``place``: carry a clamped object over the obstacles and set it down on its target pose.

The object's setpoint :math:`(p, \psi)` goes

1. straight up to the carry height: the obstacles' top plus ``clearance`` plus the object's own depth below its
   origin (computed from the scene's geometry, not a fixed offset);
2. across to above the target, turning to the target's yaw (the equivalent yaw, modulo the object's symmetry,
   nearest the one it has);

   or, where that route would bring the arms or the object within the planner's clearance of anything (clutter
   beside or under it; ``plan: auto``) or always (``plan: always``), up by ``lift`` and then along a collision-free
   joint path to the hover, planned with the object attached to the pads (:meth:`View.plan_path`) and followed as
   object setpoints at the path's points (a few centimetres apart), the path's joints the IK's posture target;
3. down to ``hover`` above its resting height, where it waits for the sway to settle and corrects its planar
   position and yaw from the live pose (the average over ``settle`` seconds, so the correction does not chase
   the swing), up to ``corrections`` times;
4. slowly down until the object stands on the table (its height within 1 mm of its resting height), the setpoint
   drifting against the live planar error at ``descend_gain`` until the object touches.

The planar error is that of the object's *footprint*, the centre of its lowest face: a held object tilted by
:math:`\theta` lands on an edge and drops flat when the pads open, which moves its origin by about
:math:`h \sin\theta` (``h`` its origin's height over that face) but leaves the footprint where it touched.

The pads follow the setpoint through the grip's offsets and keep squeezing at the grip's force
(:class:`~nextage_qp.manipulation.context.Clamp`).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from nextage_qp.geometry import clamp, nearest_equivalent, rot_z, wrap, yaw_of
from nextage_qp.loop.servo import Command
from nextage_qp.manipulation.context import ROUND_HEADINGS, Setpoint, View
from nextage_qp.manipulation.phases.base import MAX_SECONDS, Phase, Spec, name_field, plan_field
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
"""Spacing [m] of the object setpoints at which the carry's route is solved and checked, or a planned path followed."""
ROUTE_SLACK = 0.005
"""The route over the obstacles is checked at ``clearance`` less this [m]: it passes exactly ``clearance`` over
their tops."""
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
        self.goal = np.array([tgt[0], tgt[1], self.rest + c.hover])
        self.goal_yaw, self.posture = self._reachable_yaw(view, yaw_of(trot))
        self.posture_from, self.t0 = view.default_posture(), view.t
        self._blended: np.ndarray | None = None  # the posture target once the blend is over
        self.legs = [np.array([obj[0], obj[1], carry]), np.array([tgt[0], tgt[1], carry]), self.goal]
        self.yaws = [self.yaw, self.goal_yaw, self.goal_yaw]
        self.postures: list[np.ndarray | None] = [None, None, None]  # per leg, the joints the IK heads for
        self.leg, self.stage = 0, "transit"
        self.samples: list[tuple[np.ndarray, float]] = []
        self.corrections = 0
        self.bottom_from: float | None = None
        self.info.update(stage="transit", carry_height_m=round(carry, 4), corrections=0)
        if c.plan != "never":
            self._route(view, obj)

    def _route(self, view: View, obj: np.ndarray) -> None:
        """The transit as object setpoints every ``ROUTE_STEP``, each with the joints the IK heads for there.

        The route over the obstacles, solved point by point and checked between them (the rise not to touch
        anything: the grasp may have left the arms near something; the rest to keep ``clearance``); where it is out
        of reach or blocked (or always, ``plan: always``), a planned one.
        """
        c = self.spec
        points, yaws, at, yaw = [], [], self.sp.pos.copy(), self.yaw
        for goal, goal_yaw in zip(self.legs, self.yaws, strict=True):
            n = max(1, int(np.ceil(np.linalg.norm(goal - at) / ROUTE_STEP)))
            points += [at + (goal - at) * (k / n) for k in range(1, n + 1)]
            yaws += [yaw + (goal_yaw - yaw) * (k / n) for k in range(1, n + 1)]
            at, yaw = goal, goal_yaw
        start = view.joint_positions(view.joint_names())
        qs = self._solve_along(view, points, yaws, start)
        lift = next(k for k, p in enumerate(points) if p[2] >= self.legs[0][2] - 1e-9) + 1  # the rise's points
        why = "plan: always" if c.plan == "always" else \
            "the route over the obstacles is out of the clamp's reach" if qs is None else \
            view.path_blocked([start, *qs[:lift]], clearance=0.0, near=(c.target,)) or \
            view.path_blocked(qs[lift - 1:], clearance=c.clearance - ROUTE_SLACK, near=(c.target,))
        if why is not None:
            self._plan_carry(view, obj, why)
            return
        self.info["carry"] = "over"

    def _solve_along(self, view: View, points: list[np.ndarray], yaws: list[float],
                     start: np.ndarray | None) -> list[np.ndarray] | None:
        """The clamp's joints at each object setpoint, each solved from the previous one (None: one is out of reach)."""
        qs, q = [], start
        for p, y in zip(points, yaws, strict=True):
            q = view.plan(self.clamp.pads(p, y)[0], start=q, allow=frozenset({self.spec.object}), pos_tol=HOVER_TOL,
                          restarts=False)
            if q is None:
                return None
            qs.append(q)
        return qs

    def _plan_carry(self, view: View, obj: np.ndarray, why: str) -> None:
        """Replace the route over the obstacles by a lift and a planned joint path to the hover."""
        c = self.spec
        lift = np.array([obj[0], obj[1], obj[2] + max(c.lift, 0.005)])
        lifted = self._solve_along(view, [lift], [self.yaw], view.joint_positions(view.joint_names()))
        if lifted is None:
            raise self.failure(f"the clamp cannot lift {c.object} {c.lift * 1e3:.0f} mm")
        plan = view.plan_path(lifted[0], self.posture, always=c.plan == "always", clearance=c.clearance,
                              near=(c.target,))
        if not plan.found:
            raise self.failure(f"no collision-free path to carry {c.object} to {c.target}: {plan.reason()}")
        g = self.clamp.grip
        legs, yaws, postures = [lift], [self.yaw], [lifted[0]]
        for qa, qb in zip(plan.path, plan.path[1:], strict=False):
            steps = max(1, int(np.ceil(max(float(np.linalg.norm(view.pose_at(f, qb).pos - view.pose_at(f, qa).pos))
                                           for f in g.frames) / ROUTE_STEP)))
            for k in range(1, steps + 1):
                q = qa + (qb - qa) * (k / steps)
                pos, yaw = self._object_at(view, q)
                legs.append(pos)
                yaws.append(yaws[-1] + wrap(yaw - yaws[-1]))  # unwrapped along the path
                postures.append(q)
        yaws[-1] = self.goal_yaw  # the path ends at the hover's joints: exactly the goal
        legs[-1] = self.goal
        self.legs, self.yaws, self.postures = legs, yaws, postures
        self.info.update(carry="planned", carry_blocked=why, carry_plan=plan.status,
                         carry_plan_ms=round(plan.time_s * 1e3, 1), carry_height_m=None)

    def _object_at(self, view: View, q: np.ndarray) -> tuple[np.ndarray, float]:
        """The object setpoint (origin, yaw) that puts the pads where joints ``q`` put them."""
        g = self.clamp.grip
        pos, yaws = np.zeros(3), []
        for f in g.frames:
            pad = view.pose_at(f, q)
            yaw = yaw_of(pad.rot @ g.rotations[f].T)
            yaws.append(yaw)
            pos += pad.pos - rot_z(yaw) @ g.offsets[f]
        yaw = yaws[0] + float(np.mean([wrap(y - yaws[0], 2 * np.pi) for y in yaws]))
        return pos / len(g.frames), yaw

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
            arrived = self.sp.advance(goal, c.speed, view.dt)
            self.yaw += clamp(float(goal_yaw - self.yaw), -c.turn_rate * view.dt, c.turn_rate * view.dt)
            if arrived and abs(goal_yaw - self.yaw) < 1e-9:
                self.leg += 1
                if self.leg == len(self.legs):
                    self.stage, self.wait_from, self.samples = "hover", view.t, []
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
        planned = self.postures[min(self.leg, len(self.postures) - 1)] if self.stage == "transit" else None
        if planned is not None:  # along the checked route: its joints (they start where the arms are)
            posture = planned
        else:
            posture = self._blended if blend == 1.0 and self._blended is not None else \
                self.posture_from + blend * blend * (3.0 - 2.0 * blend) * (self.posture - self.posture_from)
            if blend == 1.0:  # the same array from now on: the IK keeps its posture target instead of setting it
                self._blended = posture
        return Command(targets, (relative,), allow=frozenset({c.object}), posture=posture, done=done)

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
        """Planar offset [m] of the object's footprint (the centre of its lowest face) from the target."""
        obj, rot = view.body_pose(self.spec.object)
        down = -rot[:, 2]
        foot = obj + down * view.extent(self.spec.object, down)
        return np.asarray(foot[:2] - view.body_pose(self.spec.target).pos[:2])

    def _hover(self, view: View) -> None:
        """Wait for the sway to settle, then correct the setpoint by the averaged planar and yaw error."""
        c = self.spec
        if not view.settled():
            self.samples = []
            return
        obj, rot = view.body_pose(c.object)
        tgt, trot = view.body_pose(c.target)
        self.samples.append((obj[:2] - tgt[:2], wrap(yaw_of(rot) - yaw_of(trot), view.yaw_symmetry(c.object))))
        if len(self.samples) * view.dt < c.settle:
            return
        err = np.mean([s[0] for s in self.samples], axis=0)
        yaw_err = float(np.mean([s[1] for s in self.samples]))
        self.samples = []
        self.info.update(hover_error_xy_m=round(float(np.linalg.norm(err)), 5), hover_yaw_error_rad=round(yaw_err, 4))
        within = np.linalg.norm(err) <= c.tolerance and abs(yaw_err) <= c.yaw_tolerance
        if within or self.corrections >= c.corrections:
            self.stage = "descend"
            return
        self.corrections += 1
        self.info["corrections"] = self.corrections
        self.sp.jump(self.sp.pos - np.array([*err, 0.0]))
        self.yaw -= yaw_err
