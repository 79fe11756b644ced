"""Phase kinds: each turns live poses into IK targets every control tick and says when it is done.

A phase's :meth:`~PhaseRunner.update` returns ``(targets, done)``: the frame targets for this tick's IK
step (``None`` to hold the commanded joints as they are) and whether the phase has finished. Targets
are re-resolved from the live poses of objects and targets every tick, and every move walks a
:class:`~nextage_qp.manipulation.context.Setpoint` along a straight line at a bounded speed.
"""

from __future__ import annotations

from typing import Any

import mink
import mujoco
import numpy as np

from nextage_qp.errors import PhaseError
from nextage_qp.ik import FrameTarget
from nextage_qp.manipulation.config import (
    CarryPhase,
    GraspPhase,
    JointsPhase,
    MovePhase,
    PushPhase,
    ReleasePhase,
    WaitPhase,
)
from nextage_qp.manipulation.context import RunContext, Setpoint, rot_z, yaw_of

Targets = list[FrameTarget] | None


def settled(ctx: RunContext, qd_tol: float = 0.05) -> bool:
    """True when the reference has caught up with the IK's joints and the robot is nearly still."""
    ref_gap = float(np.max(np.abs(ctx.sim.ref.q - ctx.q_cmd)))
    return ref_gap < 2e-3 and float(np.max(np.abs(ctx.sim.qd))) < qd_tol


class PhaseRunner:
    """Base class: a phase of a run. Subclasses fill :meth:`start` and :meth:`update`."""

    def __init__(self, cfg: Any, name: str) -> None:
        self.cfg, self.name = cfg, name
        self.t0 = 0.0
        self.info: dict[str, Any] = {}

    def start(self, ctx: RunContext) -> None:
        """Called once on the tick the phase begins."""
        self.t0 = ctx.sim.time

    def update(self, ctx: RunContext) -> tuple[Targets, bool]:
        """Targets for this tick and whether the phase is done."""
        raise NotImplementedError


class Move(PhaseRunner):
    """Straight-line moves of one or two frames to body-relative goals (``move``)."""

    cfg: MovePhase

    def start(self, ctx: RunContext) -> None:  # noqa: D102
        super().start(ctx)
        self.points = [Setpoint(ctx.commanded_pose(t.frame)[0]) for t in self.cfg.targets]

    def update(self, ctx: RunContext) -> tuple[Targets, bool]:  # noqa: D102
        targets, done = [], True
        for spec, sp in zip(self.cfg.targets, self.points, strict=True):
            goal, _ = ctx.resolve_point(spec)
            done &= sp.advance(goal, self.cfg.speed, ctx.dt)
            targets.append(ctx.frame_target(spec, sp.pos))
            err = float(np.linalg.norm(ctx.frame_pose(spec.frame)[0] - goal))
            done &= err < self.cfg.tolerance
            self.info[f"{spec.frame}_error_m"] = err
        return targets, done and settled(ctx)


def support_extent(ctx: RunContext, obj: str, direction: np.ndarray) -> float:
    """Half-extent [m] of an object's collision boxes along a world direction (its pushing half-width)."""
    m, d = ctx.robot.model, ctx.sim.data
    body = m.body(obj).id
    extent = 0.0
    for g in range(m.ngeom):
        if m.geom_bodyid[g] != body or m.geom_type[g] != mujoco.mjtGeom.mjGEOM_BOX:
            continue
        local = d.geom_xmat[g].reshape(3, 3).T @ direction
        centre = float((d.geom_xpos[g] - d.xpos[body]) @ direction)
        extent = max(extent, centre + float(np.abs(local) @ m.geom_size[g]))
    return extent


class Push(PhaseRunner):
    r"""Closed-loop pushing (``push``): approach behind the object on its line to the target, push, re-check.

    Each attempt re-plans from the live poses: direction :math:`\hat d = (p_t - p_o)_{xy} / \|\cdot\|`,
    approach point :math:`p_o - \hat d (h + a)`, and the push ends where the tool face puts the object's
    centre on the target, :math:`p_t - \hat d h` (:math:`h` = the object's half-extent along
    :math:`\hat d`, :math:`a` = approach gap [m]).
    """

    cfg: PushPhase

    def start(self, ctx: RunContext) -> None:  # noqa: D102
        super().start(ctx)
        self.attempt = 0
        self.sp = Setpoint(ctx.commanded_pose(self.cfg.frame)[0])
        self._plan(ctx)

    def _plan(self, ctx: RunContext) -> None:
        c = self.cfg
        obj, _ = ctx.body_pose(c.object)
        tgt, _ = ctx.body_pose(c.target)
        delta = (tgt - obj)[:2]
        d = np.array([*delta / max(np.linalg.norm(delta), 1e-9), 0.0])
        half = support_extent(ctx, c.object, d)
        z = obj[2] + c.height
        behind = obj - d * (half + c.approach)
        behind[2] = z
        finish = tgt - d * half
        finish[2] = z
        start = self.sp.pos
        lift_z = max(start[2], obj[2] + half + c.clearance)
        self.rot = rot_z(float(np.arctan2(d[1], d[0])) + c.yaw)
        self.legs = [
            (np.array([start[0], start[1], lift_z]), c.speed),
            (np.array([behind[0], behind[1], lift_z]), c.speed),
            (behind, c.speed),
            (finish, c.push_speed),
        ]
        self.leg = 0
        self.wait_from: float | None = None
        self.attempt += 1
        self.info.update(attempts=self.attempt, direction=d[:2].round(4).tolist())

    def update(self, ctx: RunContext) -> tuple[Targets, bool]:  # noqa: D102
        c = self.cfg
        if self.leg < len(self.legs):
            goal, speed = self.legs[self.leg]
            if self.sp.advance(goal, speed, ctx.dt) and (self.leg < len(self.legs) - 1 or settled(ctx)):
                self.leg += 1
        elif self.wait_from is None:
            self.wait_from = ctx.sim.time
        elif ctx.sim.time - self.wait_from > 0.2:
            obj, _ = ctx.body_pose(c.object)
            tgt, _ = ctx.body_pose(c.target)
            err = float(np.linalg.norm((obj - tgt)[:2]))
            self.info["object_error_xy_m"] = err
            if err <= c.tolerance:
                return [FrameTarget(c.frame, pos=self.sp.pos, rot=self.rot)], True
            if self.attempt >= c.attempts:
                raise PhaseError(f"phase {self.name!r} (push): {c.object} is still {err * 1e3:.1f} mm from "
                                 f"{c.target} after {c.attempts} attempts (tolerance {c.tolerance * 1e3:g} mm)")
            back = self.sp.pos - np.array([*self.info["direction"], 0.0]) * c.approach
            self.sp.advance(back, 1.0, 1.0)  # retreat along the line before the next attempt
            self._plan(ctx)
        return [FrameTarget(c.frame, pos=self.sp.pos, rot=self.rot)], False


class Grasp(PhaseRunner):
    """Clamp an object between two pads (``grasp``): open approach, close past the surface, hold."""

    cfg: GraspPhase

    def start(self, ctx: RunContext) -> None:  # noqa: D102
        super().start(ctx)
        c = self.cfg
        obj, rot = ctx.body_pose(c.object)
        self.yaw = yaw_of(rot)
        self.rz = rot_z(self.yaw)

        def at(dy: float) -> list[np.ndarray]:
            return [obj + self.rz @ np.array([0.0, s * dy, c.height]) for s in (1.0, -1.0)]

        self.stages = [(at(c.half_width + c.gap), c.speed), (at(c.half_width - c.squeeze), c.speed / 2)]
        self.stage = 0
        self.hold_from: float | None = None
        self.points = [Setpoint(ctx.commanded_pose(f)[0]) for f in c.frames]

    def update(self, ctx: RunContext) -> tuple[Targets, bool]:  # noqa: D102
        c = self.cfg
        if self.stage < len(self.stages):
            goals, speed = self.stages[self.stage]
            reached = all([sp.advance(g, speed, ctx.dt) for sp, g in zip(self.points, goals, strict=True)])
            if reached and (self.stage > 0 or settled(ctx)):
                self.stage += 1
                self.hold_from = ctx.sim.time
        targets = [FrameTarget(f, pos=sp.pos, rot=self.rz) for f, sp in zip(c.frames, self.points, strict=True)]
        done = self.hold_from is not None and self.stage == len(self.stages)
        done = done and ctx.sim.time - (self.hold_from or 0.0) >= c.hold
        if done:
            obj, rot = ctx.body_pose(c.object)
            ctx.holding = c.object
            ctx.grasp_offsets = {f: rot.T @ (sp.pos - obj) for f, sp in zip(c.frames, self.points, strict=True)}
            ctx.grasp_rot = {f: rot.T @ self.rz for f in c.frames}
        return targets, done


class Carry(PhaseRunner):
    r"""Carry a clamped object through waypoints (``carry``); the pads keep their relative pose.

    The object setpoint :math:`(p, \psi)` walks the waypoints at ``speed``; each pad's target is
    :math:`p + R_z(\psi)\,o_i` with its grasp offset :math:`o_i`, and a mink ``RelativeFrameTask`` holds
    the first pad's pose in the second pad's frame.
    """

    cfg: CarryPhase

    def start(self, ctx: RunContext) -> None:  # noqa: D102
        super().start(ctx)
        c = self.cfg
        if ctx.holding != c.object:
            raise PhaseError(f"phase {self.name!r}: carry needs {c.object!r} clamped by a grasp phase first")
        obj, rot = ctx.body_pose(c.object)
        self.sp, self.yaw0 = Setpoint(obj), yaw_of(rot)
        self.goals = [ctx.resolve_point(w) for w in c.waypoints]
        self.nominal = list(self.goals)
        self.leg, self.leg_from, self.yaw = 0, (obj.copy(), self.yaw0), self.yaw0
        self.corrections = 0
        frames = list(ctx.grasp_offsets)
        rel = mink.RelativeFrameTask(frames[0], "site", frames[1], "site", position_cost=c.relative_cost,
                                     orientation_cost=c.relative_cost)
        p0, r0 = ctx.commanded_pose(frames[0])
        p1, r1 = ctx.commanded_pose(frames[1])
        t0 = mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(r0), p0)
        t1 = mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(r1), p1)
        rel.set_target(t1.inverse() @ t0)
        ctx.extra_tasks.append(rel)
        self.rel = rel

    def update(self, ctx: RunContext) -> tuple[Targets, bool]:  # noqa: D102
        c = self.cfg
        if self.leg < len(self.goals):
            goal, goal_yaw = self.goals[self.leg]
            start, start_yaw = self.leg_from
            if self.sp.advance(goal, c.speed, ctx.dt) and self._leg_finished(ctx):
                self.leg += 1
                self.leg_from = (goal.copy(), goal_yaw)
            span = float(np.linalg.norm(goal - start))
            frac = 1.0 if span < 1e-9 else 1.0 - float(np.linalg.norm(goal - self.sp.pos)) / span
            self.yaw = start_yaw + frac * (goal_yaw - start_yaw)
        rz = rot_z(self.yaw)
        targets = [FrameTarget(f, pos=self.sp.pos + rz @ off, rot=rz @ ctx.grasp_rot[f])
                   for f, off in ctx.grasp_offsets.items()]
        return targets, self.leg == len(self.goals) and settled(ctx)

    def _leg_finished(self, ctx: RunContext) -> bool:
        """At a waypoint marked ``correct``: once settled, shift it and the rest by the object's planar error."""
        c = self.cfg
        if not c.waypoints[min(self.leg, len(c.waypoints) - 1)].correct or self.leg >= len(c.waypoints):
            return True
        if not settled(ctx):
            return False
        obj, _ = ctx.body_pose(c.object)
        goal = self.nominal[self.leg][0]  # the waypoint itself, not the already shifted setpoint goal
        err = np.array([*(goal - obj)[:2], 0.0])
        self.info["object_error_xy_m"] = float(np.linalg.norm(err))
        if np.linalg.norm(err) <= c.tolerance or self.corrections >= c.corrections:
            return True
        self.corrections += 1
        self.info["corrections"] = self.corrections
        self.goals = self.goals[: self.leg] + [(g + err, y) for g, y in self.goals[self.leg :]]
        return False


class Release(PhaseRunner):
    """Open the pads away from the object, then lift them (``release``)."""

    cfg: ReleasePhase

    def start(self, ctx: RunContext) -> None:  # noqa: D102
        super().start(ctx)
        c = self.cfg
        ctx.extra_tasks.clear()
        _, rot = ctx.body_pose(c.object)
        self.frames = list(ctx.grasp_offsets) or ["left_pad", "right_pad"]
        self.points = [Setpoint(ctx.commanded_pose(f)[0]) for f in self.frames]
        self.rots = [ctx.commanded_pose(f)[1] for f in self.frames]
        sides = (1.0, -1.0)
        opened = [sp.pos + rot @ np.array([0.0, s * c.gap, 0.0]) for sp, s in zip(self.points, sides, strict=False)]
        self.stages = [opened, [p + np.array([0.0, 0.0, c.lift]) for p in opened]]
        self.stage = 0
        ctx.holding = None

    def update(self, ctx: RunContext) -> tuple[Targets, bool]:  # noqa: D102
        if self.stage < len(self.stages):
            goals = self.stages[self.stage]
            if all([sp.advance(g, self.cfg.speed, ctx.dt) for sp, g in zip(self.points, goals, strict=True)]):
                self.stage += 1
        targets = [FrameTarget(f, pos=sp.pos, rot=r) for f, sp, r in zip(self.frames, self.points, self.rots,
                                                                          strict=True)]
        return targets, self.stage == len(self.stages) and settled(ctx)


class Joints(PhaseRunner):
    """Drive named joints to angles; the others hold (``joints``)."""

    cfg: JointsPhase

    def start(self, ctx: RunContext) -> None:  # noqa: D102
        super().start(ctx)
        self.idx = np.array([ctx.robot.joint_index(j) for j in self.cfg.positions])
        self.goal = np.array(list(self.cfg.positions.values()))
        ctx.q_cmd[self.idx] = np.clip(self.goal, ctx.robot.lower[self.idx], ctx.robot.upper[self.idx])

    def update(self, ctx: RunContext) -> tuple[Targets, bool]:  # noqa: D102
        err = float(np.max(np.abs(ctx.sim.q[self.idx] - self.goal)))
        self.info["joint_error_rad"] = err
        return None, err < self.cfg.tolerance


class Wait(PhaseRunner):
    """Hold the commanded joints (``wait``)."""

    cfg: WaitPhase

    def update(self, ctx: RunContext) -> tuple[Targets, bool]:  # noqa: D102
        return None, ctx.sim.time - self.t0 >= self.cfg.duration


RUNNERS: dict[str, type[PhaseRunner]] = {
    "move": Move, "push": Push, "grasp": Grasp, "carry": Carry, "release": Release, "joints": Joints, "wait": Wait,
}
"""Phase kind -> its runner class."""
