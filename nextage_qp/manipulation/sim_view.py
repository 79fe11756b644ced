"""The :class:`~.context.View` of a running simulation: measured object poses, the model's geometry, the planner."""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

from nextage_qp.errors import UnknownNameError
from nextage_qp.geometry import GeomPart, Pose, cross, geom_parts, support
from nextage_qp.ik import QPIK, FrameTarget
from nextage_qp.kinematics.frames import Kinematics
from nextage_qp.loop.servo import Servo
from nextage_qp.loop.simulation import Simulation
from nextage_qp.manipulation.context import Grip
from nextage_qp.manipulation.placement import clearance_at, obstacle_top, rest_height, table_top
from nextage_qp.mobile.base import MobileBase
from nextage_qp.mobile.drive_models import Pose2
from nextage_qp.mobile.odometry import to_odometry
from nextage_qp.planning.rrt import PathPlan, PlanningConfig, plan_path
from nextage_qp.planning.world import CHAIN_SLOP, SELF_SLOP, CollisionWorld, Held
from nextage_qp.robots.model import Robot, robot_bodies
from nextage_qp.scene.seen_obstacles import SeenBoxes
from nextage_qp.sensing.sensors import Wrench

_NONE = np.zeros(0, dtype=int)

REACH_POS_TOL = 0.003
"""Position error [m] within which :meth:`SimView.plan` counts a target as reached."""
REACH_ROT_TOL = 0.05
"""Orientation error [rad] within which :meth:`SimView.plan` counts a target as reached."""
PLAN_MEMO = 1024
"""Solves the planner remembers by their inputs (a grasp search asks for the same first waypoints again)."""


class SimView:
    """The :class:`View` of a running simulation (what the phases of :class:`~.runner.Runner` see).

    Object poses come from the simulation's measurement seam; everything else from the model and the servo.
    """

    def __init__(self, robot: Robot, sim: Simulation, servo: Servo, *, qd_tol: float = 0.05,
                 planning: PlanningConfig | None = None, seen: SeenBoxes | None = None) -> None:
        self.robot, self._sim, self._servo, self.qd_tol = robot, sim, servo, qd_tol
        self.seen = seen
        """The camera's obstacle boxes, for a ``robot`` blind to the clutter (:meth:`Robot.blinded_copy`), or None."""
        self.planning = planning or PlanningConfig()
        self._worlds: dict[float, CollisionWorld] = {}  # by clearance: 0 tells a touch
        self.plans: list[PathPlan] = []
        """Every path planned in this run (straight checks included), in order."""
        self.dt = sim.ctrl_dt
        self.grip: Grip | None = None
        self._parts: dict[str, list[GeomPart]] = {}
        self._planner: QPIK | None = None
        self._kinematics: Kinematics | None = None
        self.coverage: Callable[[np.ndarray, np.ndarray], float] | None = None
        """With obstacles from the camera: the share of a box (lo, hi) [m] the camera has seen."""
        self.swept_seen: list[float] = []
        """Per leg found (straight or planned) while ``coverage`` is set: the share of the space its moving links sweep
        (:func:`swept_box`) the camera had seen when it was planned."""
        self.meets: Callable[[np.ndarray, np.ndarray], list[dict[str, Any]]] | None = None
        """With obstacles from the camera: the scene's obstacles reaching into a box, each whether the map holds it
        (scored with the scene, for the report alone: :meth:`~nextage_qp.sensing.camera.seen.ObstacleMapper.met`)."""
        self.swept_met: list[list[dict[str, Any]]] = []
        """Per leg of ``swept_seen``: the obstacles reaching into its swept space when it was planned (``meets``)."""

    def world_changed(self) -> None:
        """The camera's obstacle boxes changed: the view's model and planner take them (the worlds as they are used)."""
        if self.seen is None:
            return
        self.seen.sync(self.robot.model)
        if self._planner is not None:
            self.seen.sync(self._planner.model)
            self._planner.world_changed()

    @property
    def t(self) -> float:
        """Simulated time [s]."""
        return self._sim.time

    def body_pose(self, name: str) -> Pose:  # noqa: D102
        measured = self._sim.measured.objects.get(name)
        if measured is not None:
            return Pose(measured.pos.copy(), measured.rot.copy())
        bid = mujoco.mj_name2id(self.robot.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if bid < 0:
            raise UnknownNameError("body", name, self.robot.body_names)
        d = self._sim.data
        return self._believed(Pose(d.xpos[bid].copy(), d.xmat[bid].reshape(3, 3).copy()))

    def unseen_s(self, obj: str) -> float:  # noqa: D102
        seen = self._sim.sensors.seen_at(obj)
        return 0.0 if seen is None else self._sim.time - seen

    def frame_pose(self, name: str) -> Pose:  # noqa: D102
        if not self._sim.sensors.joints_exact:  # noisy encoders: the frame where the measured joints put it
            return self.pose_at(name, self._sim.measured.q)
        kind, fid = self.robot.frame(name)
        d = self._sim.data
        if kind == "site":
            return self._believed(Pose(d.site_xpos[fid].copy(), d.site_xmat[fid].reshape(3, 3).copy()))
        return self._believed(Pose(d.xpos[fid].copy(), d.xmat[fid].reshape(3, 3).copy()))

    def _believed(self, pose: Pose) -> Pose:
        """A true world pose as the controller sees it: on a mobile robot, in the world of its odometry."""
        base, believed = self.robot.base, self._sim.measured.base
        if base is None or believed is None:
            return pose
        return to_odometry(pose, base.pose(self._sim.data), believed)

    def commanded_pose(self, name: str) -> Pose:  # noqa: D102
        return self._servo.commanded_pose(name)

    def joint_positions(self, names: tuple[str, ...]) -> np.ndarray:  # noqa: D102
        idx = [self.robot.joint_index(n) for n in names]
        return self._sim.measured.q[idx].copy()

    def settled(self) -> bool:  # noqa: D102
        ref_gap = float(np.max(np.abs(self._sim.ref.q - self._servo.q_cmd)))
        return ref_gap < 2e-3 and float(np.max(np.abs(self._sim.measured.qd))) < self.qd_tol

    def tracking_error(self) -> float:  # noqa: D102
        return float(np.max(np.abs(self._sim.measured.q - self._servo.q_cmd)))

    def plan(self, targets: Sequence[FrameTarget], start: np.ndarray | None = None,  # noqa: D102
             allow: frozenset[str] = frozenset(), pos_tol: float | None = None,
             restarts: bool = True) -> np.ndarray | None:
        if self._planner is None:
            config = self._servo.ik.config.model_copy(update={"restarts": 4, "max_iters": 80})
            self._planner = QPIK(self.robot, config, model=self._servo.ik.model, memo=PLAN_MEMO)
        poses = {name: (p.pos, p.quat) for name, p in self._sim.measured.objects.items()}
        self._planner.base_pose = self._servo.ik.base_pose.copy()  # a mobile robot plans from where it stands
        q0 = np.array(self._servo.q_cmd if start is None else start)
        tol = REACH_POS_TOL if pos_tol is None else pos_tol
        result = self._planner.solve(list(targets), q0, object_poses=poses, allow=allow,
                                     good_enough=(0.5 * tol, 0.5 * REACH_ROT_TOL), accept=(tol, REACH_ROT_TOL),
                                     restarts=None if restarts else 0)
        return result.q if result.pos_err_m <= tol and result.rot_err_rad <= REACH_ROT_TOL else None

    def _worlds_at(self, q: np.ndarray, near: Sequence[str] = (), clearance: float | None = None,
                   allow: Sequence[str] = ()) -> tuple[CollisionWorld, CollisionWorld]:
        """Two collision worlds as believed now, the robot at ``q``: one to tell a touch, one keeping a clearance.

        ``clearance``: default the planning config's.
        """
        cfg = self.planning
        keep = cfg.clearance if clearance is None else clearance
        for c in (0.0, keep):
            if c not in self._worlds:
                self._worlds[c] = CollisionWorld(self.robot, c, cfg.table_clearance if c > 0 else 0.0)
        worlds = (self._worlds[0.0], self._worlds[keep])
        if self.seen is not None:  # the camera's latest boxes in each world's copy of the model
            for world in worlds:
                self.seen.sync(world.model)
        poses = {name: Pose(p.pos, p.rot) for name, p in self._sim.measured.objects.items()}
        held = None
        if self.grip is not None:  # the held object moves with the first pad, as it sits in it now
            frame = self.grip.frames[0]
            pad, obj = self.commanded_pose(frame), self.body_pose(self.grip.object)
            held = Held(self.grip.object, frame, Pose(pad.rot.T @ (obj.pos - pad.pos), pad.rot.T @ obj.rot))
        for world in worlds:
            world.set_world(poses, q, held=held, near=near, allow=allow, qpos=self._sim.data.qpos)
        return worlds

    def path_blocked(self, path: Sequence[np.ndarray], clearance: float | None = None,  # noqa: D102
                     near: Sequence[str] = (), allow: Sequence[str] = ()) -> str | None:
        keep = self._worlds_at(np.asarray(path[0], dtype=float), near, clearance, allow)[1]
        keep.chain_slop = CHAIN_SLOP  # the IK drives the route: it presses a chain's own links together softly
        try:
            hit = keep.first_on_path([np.asarray(q, dtype=float) for q in path])
        finally:
            keep.chain_slop = SELF_SLOP
        return None if hit is None else str(hit[2])

    def obstacle_groups(self) -> tuple[str, ...]:  # noqa: D102
        return self.robot.obstacle_groups()

    def clearance_at(self, obj: str, pos: np.ndarray, yaw: float,  # noqa: D102
                     beside: bool = False) -> tuple[float, np.ndarray]:
        data = mujoco.MjData(self.robot.model)
        data.qpos[:] = self._sim.data.qpos
        return clearance_at(self.robot, data, obj, np.asarray(pos, dtype=float), yaw, self.obstacle_groups(), beside)

    def room_at(self, q: np.ndarray, near: Sequence[str] = (), allow: Sequence[str] = ()) -> float:  # noqa: D102
        touch = self._worlds_at(np.asarray(q, dtype=float), near, 0.0, allow)[0]
        return touch.room(np.asarray(q, dtype=float))[0]

    def plan_path(self, q_start: np.ndarray, q_goal: np.ndarray, *, near: Sequence[str] = (),  # noqa: D102
                  always: bool = False, escape: bool = False) -> PathPlan:
        qa, qb = np.asarray(q_start, dtype=float), np.asarray(q_goal, dtype=float)
        touch, keep = self._worlds_at(qa, near)
        seed = 1 + len(self.plans)  # a run's plans repeat: each seeded by its place in the run
        t0, checks0 = time.perf_counter(), touch.checks
        if not always and touch.first_on_segment(qa, qb) is None:
            plan = PathPlan([qa, qb], "straight", time_s=time.perf_counter() - t0, checks=touch.checks - checks0)
        else:
            joints = self.robot.moved_groups(np.flatnonzero(np.abs(qb - qa) > 1e-6))

            def planned(world: CollisionWorld) -> PathPlan:  # over the whole groups (arms, torso) that move
                return plan_path(world, qa, qb, lower=self.robot.lower, upper=self.robot.upper, joints=joints,
                                 time_limit=self.planning.time_limit, seed=seed, straight_first=False,
                                 escape_start=escape)

            plan = planned(keep)
            if plan.status in ("invalid_start", "invalid_goal") and plan.why is not None and plan.why.distance >= 0:
                plan = planned(touch)  # near but not inside: planned without the clearance
        self.plans.append(plan)
        if self.coverage is not None and plan.found:
            swept = swept_box(self.robot, plan.path)
            self.swept_seen.append(self.coverage(*swept))
            if self.meets is not None:
                self.swept_met.append(self.meets(*swept))
        return plan

    def base(self) -> MobileBase | None:  # noqa: D102
        return self.robot.base

    def base_pose(self) -> Pose2 | None:  # noqa: D102
        return self._sim.measured.base

    def footprint(self, name: str) -> tuple[float, float, float, float]:  # noqa: D102
        pos = self.body_pose(name).pos
        radius = max(self.extent(name, np.array([np.cos(a), np.sin(a), 0.0]))
                     for a in np.linspace(0.0, 2 * np.pi, 16, endpoint=False))
        top = float(pos[2]) + self.extent(name, np.array([0.0, 0.0, 1.0]))
        return float(pos[0]), float(pos[1]), float(radius), top

    def base_radius(self, below: float = np.inf) -> float:  # noqa: D102
        if self.robot.base is None:
            raise UnknownNameError("base", "base", ())
        return self.robot.base.radius(self._sim.data, below)

    def joint_names(self) -> tuple[str, ...]:  # noqa: D102
        return self.robot.joint_names

    def pose_at(self, frame: str, q: np.ndarray) -> Pose:  # noqa: D102
        if self.robot.base is not None:  # the base where the odometry says it is: the IK's model knows it
            return self._servo.pose_at(frame, q)
        if self._kinematics is None:
            self._kinematics = Kinematics(self.robot)
        return self._kinematics.fk(frame, q)

    def check_reach(self, frame: str, pos: np.ndarray, where: str) -> None:  # noqa: D102
        if self.robot.base is not None:  # a base drives: no sphere bounds where the arms reach
            return
        if self._kinematics is None:
            self._kinematics = Kinematics(self.robot)
        self._kinematics.check_reach(frame, pos, self._servo.q_cmd, where)

    def looking_joints(self) -> np.ndarray:  # noqa: D102
        look = self._servo.look
        return look.dofs - self._servo.ik.nb if look is not None and look.point is not None else _NONE

    def default_posture(self) -> np.ndarray:  # noqa: D102
        return self._servo.ik.default_posture.copy()

    def pad_frames(self) -> tuple[str, ...]:  # noqa: D102
        return tuple(arm.pad for arm in self.robot.arms)

    def wrench(self, site: str) -> Wrench:  # noqa: D102
        m, d = self.robot.model, self._sim.data
        kind, fid = self.robot.frame(site)
        body = fid if kind == "body" else int(m.site_bodyid[fid])
        for sensor in self._sim.wrench_sensors:
            if sensor.body == body:
                w = self._sim.measured.wrenches[sensor.name]
                here = d.xpos[fid] if kind == "body" else d.site_xpos[fid]
                wrench = Wrench(w.force, w.torque + cross(d.site_xpos[sensor.site] - here, w.force))
                if self.robot.base is not None and self._sim.measured.base is not None:  # the odometry's axes
                    rot = self._believed(Pose(np.zeros(3), np.eye(3))).rot
                    wrench = Wrench(rot @ wrench.force, rot @ wrench.torque)
                return wrench
        with_sensor = [n for n in self.robot.site_names if int(m.site_bodyid[m.site(n).id]) in
                       {s.body for s in self._sim.wrench_sensors}]
        raise UnknownNameError("site on a body with a force/torque sensor", site, with_sensor)

    def rest_height(self, obj: str, on: str | None = None) -> float:  # noqa: D102
        return rest_height(self.robot, self._sim.data, obj, on)

    def table_top(self) -> float:  # noqa: D102
        return table_top(self.robot, self._sim.data)[0]

    def obstacle_top(self) -> float:  # noqa: D102
        return obstacle_top(self.robot, self._sim.data)

    def yaw_symmetry(self, obj: str) -> float:  # noqa: D102
        return self.robot.yaw_symmetry(obj)

    def weight(self, obj: str) -> float:  # noqa: D102
        model = self.robot.model
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, obj)
        if bid < 0:
            raise UnknownNameError("object", obj, self.robot.object_names)
        return float(-model.opt.gravity[2] * model.body_subtreemass[bid])

    def extent(self, obj: str, direction: np.ndarray) -> float:  # noqa: D102
        local = self.body_pose(obj).rot.T @ direction
        return max((support(part, local) for part in self._parts_cached(obj)), default=0.0)

    def grip_geometry(self, obj: str, lateral: np.ndarray, height: float | None = None) -> tuple[float, float]:  # noqa: D102
        parts = self._parts_cached(obj)
        z = np.array([0.0, 0.0, 1.0])
        if height is None:  # the middle of the widest part (the highest of several)
            flat = [np.array([np.cos(a), np.sin(a), 0.0]) for a in np.linspace(0.0, 2 * np.pi, 8, endpoint=False)]
            width = [max(support(p, d) - float(p[1] @ d) for d in flat) for p in parts]
            best = max(width)
            height = max(float(p[1][2]) for p, w in zip(parts, width, strict=True) if w >= best - 1e-3)
        at = [p for p in parts if -support(p, -z) - 1e-9 <= height <= support(p, z) + 1e-9]
        return height, max((support(p, lateral) for p in at), default=0.0)

    def _parts_cached(self, obj: str) -> list[GeomPart]:
        parts = self._parts.get(obj)
        if parts is None:
            parts = self._parts[obj] = geom_parts(self.robot.model, obj)
        return parts


SWEPT_PAD = 0.08
"""The space a leg sweeps: the box of its moving bodies' origins grown by this [m] (a link's reach past its origin)."""


def swept_box(robot: Robot, path: Sequence[np.ndarray], steps: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """The box (lo, hi) [m] the robot bodies a joint path moves sweep.

    It holds their origins at ``steps`` states per segment, grown by ``SWEPT_PAD``.
    """
    data = mujoco.MjData(robot.model)
    bodies = np.array(sorted(robot_bodies(robot)), dtype=int)
    points = []
    for a, b in itertools.pairwise(path):
        for t in np.linspace(0.0, 1.0, steps + 1):
            robot.set_q(data, (1.0 - t) * a + t * b)
            mujoco.mj_kinematics(robot.model, data)
            points.append(data.xpos[bodies].copy())
    if not points:
        return np.zeros(3), np.zeros(3)
    stack = np.stack(points)  # (states, bodies, 3)
    moved = np.ptp(stack, axis=0).max(axis=1) > 1e-3
    if not moved.any():
        return np.zeros(3), np.zeros(3)
    swept = stack[:, moved].reshape(-1, 3)
    return swept.min(axis=0) - SWEPT_PAD, swept.max(axis=0) + SWEPT_PAD
