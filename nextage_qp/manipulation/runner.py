r"""Execute a manipulation config.

The runner only sequences phases; the servo, the simulation and the metrics do the rest.

Each control tick the current phase reads the :class:`~.sim_view.SimView` and returns a command; the
:class:`~nextage_qp.loop.servo.Servo` turns it into commanded joints for Ruckig; the simulation runs one control
period of PD-controlled physics; the outcome monitor watches contacts and the clamp.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from functools import partial
from typing import Any

import mujoco
import numpy as np

from nextage_qp.errors import ConfigError, InfeasibleError, NextageQPError, PhaseError, UnknownNameError
from nextage_qp.estimation.report import SHOVE_SETTLE_S
from nextage_qp.ik import QPIK
from nextage_qp.ik.look_at import watch
from nextage_qp.loop.diagnosis import at_limits, contact_forces, saturated, what_holds
from nextage_qp.loop.servo import HOLD, Command, Servo
from nextage_qp.loop.simulation import Simulation
from nextage_qp.manipulation.config import ManipulationConfig
from nextage_qp.manipulation.joint_checks import check_angles
from nextage_qp.manipulation.metrics import OutcomeMonitor, PhaseRecord, RunResult, summarize
from nextage_qp.manipulation.phases import Phase, build, names_in
from nextage_qp.manipulation.phases.base import DEFAULT_TIMEOUT, TIMEOUT_MARGIN
from nextage_qp.manipulation.phases.grasp.spec import GraspSpec
from nextage_qp.manipulation.phases.push.spec import FULL_ORIENT_JOINTS, PushSpec
from nextage_qp.manipulation.placement import FREE_SPOT_MARGIN, Placement, check_placement, free_spots, spot_room
from nextage_qp.manipulation.sim_view import SimView
from nextage_qp.manipulation.workspace import to_world
from nextage_qp.mobile.build import BASE_BODY
from nextage_qp.mobile.odometry import base_report
from nextage_qp.planning.rrt import PathPlan
from nextage_qp.robots.check_report import check_own_names
from nextage_qp.robots.description import load_robot
from nextage_qp.robots.gains import config_gains, robot_gains
from nextage_qp.robots.model import Robot, robot_bodies, scene_bodies, tool_frames
from nextage_qp.scene.checks import check_clear, check_robot_clear
from nextage_qp.scene.clutter import ClutterDecl
from nextage_qp.scene.files import BodyPose, SceneOverrides
from nextage_qp.scene.seen_obstacles import SeenBoxes
from nextage_qp.sensing.sensors import WrenchSensor, unsensed
from nextage_qp.sensing.setup import attach_camera, log_estimates, perception_of, source_of

TickCallback = Callable[["Runner", Phase | None], None]
SEARCH_S = 3.0
"""With a camera, how long [s] the run waits, still, for every object to be seen before its first phase."""
SCAN_GRID = 3
"""The head's scan of the mapped space looks at a ``SCAN_GRID`` x ``SCAN_GRID`` grid of points over it."""
SCAN_AIM = 0.05
"""A scan's point is looked at once the camera's optical axis is within this [rad] of it..."""
SCAN_DWELL_S = 0.3
"""...and stays there this long [s] (the map takes the frames of that time)."""
SCAN_POINT_S = 2.0
"""The longest a scan waits for the head to turn to one point [s] (one the head cannot turn to is left)."""
HELD_SLACK = 1e-3
"""A timed-out phase names the collision pairs within this [m] of their minimum distance (what may have held it)."""


def start_q(cfg: ManipulationConfig, robot: Robot) -> np.ndarray:
    """The robot's start posture [rad]: the config's ``start`` keyframe, or its joints on top of ``home``."""
    return (robot.keyframe_q(cfg.start) if isinstance(cfg.start, str)
            else robot.q_from_names(cfg.start, base=robot.keyframe_q("home")))


def start_footprint(robot: Robot, q: np.ndarray, clutter: ClutterDecl) -> tuple[tuple[float, float, float], ...]:
    """Where clutter may not stand: circles (x, y, radius [m]) of the robot's geoms at ``q``.

    Those that reach down within the clutter's tallest height (plus its keep-out) of the table top.
    """
    m = robot.model
    d = mujoco.MjData(m)
    d.qpos[robot.qpos_idx] = q
    mujoco.mj_kinematics(m, d)
    groups = robot.collision_geoms()
    top = max((float(d.geom_xpos[g][2] + m.geom_rbound[g]) for g in groups.get("table", ())), default=0.0)
    reach = top + clutter.height[1] + clutter.keep_out
    circles = []
    for b in robot_bodies(robot):
        for g in range(int(m.body_geomadr[b]), int(m.body_geomadr[b] + m.body_geomnum[b])):
            if (m.geom_contype[g] or m.geom_conaffinity[g]) and d.geom_xpos[g][2] - m.geom_rbound[g] < reach:
                circles.append((float(d.geom_xpos[g][0]), float(d.geom_xpos[g][1]), float(m.geom_rbound[g])))
    return tuple(circles)


def for_robot(cfg: ManipulationConfig, robot: Robot) -> ManipulationConfig:
    """``cfg`` with what it leaves to the robot decided.

    A push's ``orient: auto`` (see ``FULL_ORIENT_JOINTS``), and its height and pitch where unset (the robot file's
    ``push_face``).
    """
    phases = []
    face = robot.description.push_face
    for spec in cfg.phases:
        if isinstance(spec, PushSpec):
            update: dict[str, object] = {}
            if spec.orient == "auto":
                tools = [spec.frame, *spec.other_frames]
                full = min(len(robot.chain_joints(f)) for f in tools) >= FULL_ORIENT_JOINTS
                update["orient"] = "full" if full else "normal"
            if spec.height is None:
                update["height"] = face.height
            if spec.pitch is None:
                update["pitch"] = face.pitch
            spec = spec.model_copy(update=update)
        phases.append(spec)
    return cfg.model_copy(update={"phases": phases})


FREE_SPOT_TRIES = 12
"""Free spots a target takes in turn while a phase that names it fails at its start (out of the clamp's reach, say)."""


FreeSpotRequest = tuple[str, str, float, Any]
"""A target placed by ``free_spot``: its name, its object's, its yaw [rad] and the ``free_spot`` declaration."""


@dataclasses.dataclass
class PlacedSpot:
    """A target placed by ``free_spot``: the spots offered in turn, the one it has, its request, the refusals so far."""

    body: int
    spots: Iterator[tuple[np.ndarray, float]]
    pos: np.ndarray
    clearance: float
    request: FreeSpotRequest
    refused: list[str] = dataclasses.field(default_factory=list)

    def take_next(self, models: Sequence[mujoco.MjModel], why: str) -> bool:
        """Move the target to the next spot in each of ``models`` (this one refused: ``why``); False if none is left."""
        return len(self.refused) + 1 < FREE_SPOT_TRIES and self.move(self.spots, models, why)

    def move(self, spots: Iterator[tuple[np.ndarray, float]], models: Sequence[mujoco.MjModel], why: str) -> bool:
        """Take the spots of ``spots`` from now on (this one no longer serves: ``why``) and move to the first; False,
        and no move, if ``spots`` has none.
        """  # noqa: D205
        try:
            nxt = next(spots, None)
        except InfeasibleError:
            return False
        if nxt is None:
            return False
        self.refused.append(why)
        self.spots, (self.pos, self.clearance) = spots, nxt
        self.put(models)
        return True

    def put(self, models: Sequence[mujoco.MjModel]) -> None:
        """Stand the target at its spot in each of ``models``."""
        for model in models:
            model.body_pos[self.body][:2] = self.pos

    def report(self) -> dict[str, Any]:
        """Where the target went, the object's clearance there [m], and the spots refused before it."""
        return {"pos": [round(float(v), 4) for v in self.pos], "clearance_m": round(self.clearance, 4),
                "spots_refused": len(self.refused)}


def free_spot_requests(cfg: ManipulationConfig, robot: Robot, source: str) -> list[FreeSpotRequest]:
    """The targets the scene places by ``free_spot`` (see :func:`place_free_spots`), checked.

    A target's object is the task's object for the task's target, else the object ``NAME`` of a marker
    ``NAME_target``.

    Raises:
        ConfigError: A free spot is given for a body that is no object's target.
    """
    scene = to_world(cfg.scene, robot.description.workspace, cfg.robot, source)
    out: list[FreeSpotRequest] = []
    m = robot.model
    for name, pose in scene.poses.items():
        spot = pose.free_spot
        if spot is None:
            continue
        obj = cfg.object if name == cfg.target else name.removesuffix("_target")
        if obj not in robot.object_names or obj == name:
            raise ConfigError(f"{source}: scene.poses.{name}.free_spot: {name!r} is no object's target; give it for "
                              f"{cfg.target!r} or a marker NAME_target of an object ({', '.join(robot.object_names)})",
                              key=f"scene.poses.{name}.free_spot")
        quat = m.body_quat[m.body(name).id]
        out.append((name, obj, float(2.0 * np.arctan2(quat[3], quat[0])), spot))
    return out


def place_spot(robot: Robot, request: FreeSpotRequest, models: Sequence[mujoco.MjModel], source: str) -> PlacedSpot:
    """Place one target where its object fits among ``robot``'s obstacles, in each of ``models``.

    Raises:
        InfeasibleError: No spot of the region keeps the clearance.
    """
    name, obj, yaw, spot = request
    spots = free_spots(robot, obj, yaw, spot.region, spot.centre(), spot.clearance,
                       f"{source}: scene.poses.{name}.free_spot")
    xy, room = next(spots)
    placed = PlacedSpot(robot.model.body(name).id, spots, xy, room, request)
    placed.put(models)
    return placed


def place_free_spots(cfg: ManipulationConfig, robot: Robot, source: str) -> dict[str, PlacedSpot]:
    """Move each target the scene places by ``free_spot`` to where its object fits, in the compiled model.

    Raises:
        ConfigError: A free spot is given for a body that is no object's target.
        InfeasibleError: No spot of a region keeps the clearance (exit 2, before anything moves).
    """
    return {request[0]: place_spot(robot, request, (robot.model,), source)
            for request in free_spot_requests(cfg, robot, source)}


def build_robot(cfg: ManipulationConfig, source: str) -> Robot:
    """Compile the config's scene with its overrides, and check every name the config uses.

    Raises:
        ConfigError: A body, frame, object or joint named in the config is not in the scene (the message names
            the dotted key and the valid names).
    """
    try:
        description = load_robot(cfg.robot)
    except ConfigError as exc:
        raise ConfigError(f"{source}: robot: {exc}") from None
    scene = to_world(cfg.scene, description.workspace, cfg.robot, source)
    poses = {name: BodyPose(pos=p.pos, yaw=p.yaw) for name, p in scene.poses.items()}
    stereo = cfg.perception.source == "camera" and cfg.perception.depth == "stereo"
    clutter = scene.clutter
    if clutter is not None and clutter.seed is None:  # drawn from the run's seed
        clutter = clutter.model_copy(update={"seed": cfg.seed})
    later = tuple(name for name, p in scene.poses.items() if p.free_spot is not None)  # placed once compiled
    overrides = SceneOverrides(poses=poses, masses=dict(scene.masses), friction_scale=dict(scene.friction_scale),
                               objects=dict(scene.objects), speckle=stereo, clutter=clutter, placed_later=later,
                               seen_pool=cfg.perception.obstacles == "camera")
    if cfg.mount is not None:
        description = dataclasses.replace(description, mount=cfg.mount)
    try:
        if clutter is not None and clutter.count:  # clutter keeps clear of the robot's start posture
            bare = Robot.from_scene(scene.file, dataclasses.replace(overrides, clutter=None), description)
            overrides = dataclasses.replace(overrides, clutter_avoid=start_footprint(bare, start_q(cfg, bare),
                                                                                     clutter))
        robot = Robot.from_scene(scene.file, overrides, description)
    except UnknownNameError as exc:
        raise ConfigError(f"{source}: scene: {exc}") from None
    except ConfigError as exc:
        if exc.key is not None and exc.source is None:  # a declaration's error: name the config it is in
            raise ConfigError(f"{source}: {exc}", source=source, key=exc.key) from None
        raise
    check_own_names(robot)  # the robot file's own names: its error, not the task config's
    check_names(cfg, robot, source)
    check_clamps(cfg, robot, source)
    check_angles(cfg, robot, source)
    check_clear(robot.model, robot.joint_names, robot.object_names, source)
    return robot


def check_names(cfg: ManipulationConfig, robot: Robot, source: str) -> None:
    """Check every name field of the config (top level and every phase) against the scene, in one loop.

    Raises:
        ConfigError: ``source: dotted.key: 'name' is not valid; valid: ...``.
    """
    bodies = sorted(robot.body_names)
    objects = (*robot.object_names, *((BASE_BODY,) if robot.base is not None else ()))  # a base parks, judged
    arm_frames = [f for arm in robot.arms for f in (arm.tool, arm.pad, arm.wrist)]  # a body's name too, often
    frames = list(dict.fromkeys([*robot.site_names, *arm_frames]))
    valid = {"frame": frames, "object": objects, "body": bodies, "place": scene_bodies(robot),
             "reference": ["world", *bodies], "joint": robot.joint_names}
    accepted = {**valid, "frame": robot.frame_names}
    for key, kind, name in names_in(cfg, ""):
        if name not in accepted[kind]:
            raise ConfigError(f"{source}: {key.lstrip('.')}: {name!r} is not valid; valid: {', '.join(valid[kind])}")


def check_clamps(cfg: ManipulationConfig, robot: Robot, source: str) -> None:
    """Refuse a clamp the robot cannot make: pads it does not declare, or pads that feel no force.

    A ``grasp`` closes until force/torque sensors on the pads' bodies read its squeeze, so each pad frame (the
    phase's ``frames``, or each arm's ``pad``) must be on a body that carries a force and a torque sensor, and pads
    left to the robot must be ones its robot file declares (an undeclared pad is the wrist's origin, not a face).

    Raises:
        InfeasibleError: ``source: phases[i] (name): robot 'r' cannot clamp: why; what would do``.
    """
    for i, spec in enumerate(cfg.phases):
        if not isinstance(spec, GraspSpec):
            continue
        where = f"{source}: phases[{i}] ({spec.name or spec.kind}): robot {cfg.robot!r} cannot clamp"
        if spec.frames is None:
            if len(robot.arms) < 2:
                raise InfeasibleError(f"{where}: it has {len(robot.arms)} arm, the clamp needs two", source=source,
                                      key=f"phases[{i}]")
            bare = [arm.name for arm in robot.arms[:2] if not arm.clamps]
            if bare:
                many = len(bare) > 1
                raise InfeasibleError(
                    f"{where}: arm{'s' if many else ''} {', '.join(bare)} declare{'' if many else 's'} no pad "
                    "(arms[].pad in its robot file: a frame on the face that clamps, on a body with a force/torque "
                    "sensor)", source=source, key=f"phases[{i}]")
            frames: tuple[str, ...] = tuple(arm.pad for arm in robot.arms[:2])
        else:
            frames = spec.frames
        numb = unsensed(robot, frames)
        if numb:
            frame, body = numb[0]
            found = ", ".join(f"{robot.model.body(s.body).name} ({s.name})"
                              for s in WrenchSensor.of_model(robot.model)) or "none"
            raise InfeasibleError(
                f"{where}: pad {frame!r} is on body {body!r}, which has no force/torque sensor to feel the squeeze "
                f"(bodies with one: {found}); add a force and a torque sensor at a site on it to the model",
                source=source, key=f"phases[{i}]")


class Runner:
    """Runs one :class:`ManipulationConfig` and measures the outcome.

    Args:
        cfg: The validated config.
        source: Where it came from (for messages).
        robot: A robot built from the config (default: :func:`build_robot`).
    """

    def __init__(self, cfg: ManipulationConfig, source: str = "<config>", robot: Robot | None = None) -> None:
        self.robot = robot or build_robot(cfg, source)
        self.cfg, self.source = for_robot(cfg, self.robot), source
        cfg = self.cfg
        self.seen = SeenBoxes() if cfg.perception.obstacles == "camera" else None
        self.free_spots: dict[str, PlacedSpot] = {}
        self._unplaced: list[FreeSpotRequest] = []
        """Free-spot targets placed once the camera has looked (at the start of the first phase naming them)."""
        if self.seen is None:
            self.free_spots = place_free_spots(cfg, self.robot, source)
        else:
            self._unplaced = free_spot_requests(cfg, self.robot, source)
        self.controlled = self.robot.blinded_copy() if self.seen is not None else self.robot
        """The robot as the controller knows it: with camera obstacles, blind to the clutter (the physics is not)."""
        self._target_models = (self.robot.model, *((self.controlled.model,) if self.seen is not None else ()))
        """The models a free-spot target stands in: the physics' and, when it has its own, the controller's."""
        try:
            gains = robot_gains(self.robot) if cfg.gains is None else config_gains(cfg.gains, self.robot)
        except ConfigError as exc:
            raise ConfigError(f"{source}: gains: {exc}") from None
        try:
            self.ik = QPIK(self.controlled, cfg.ik)
        except UnknownNameError as exc:
            raise ConfigError(f"{source}: ik: {exc}") from None
        except ConfigError as exc:
            raise ConfigError(f"{source}: {exc}", source=source, key=exc.key) from None
        frames = tool_frames(self.robot)
        self.sensors, self.shoves = perception_of(cfg, self.robot, source)
        self.sim = Simulation(self.robot, gains, cfg.trajectory, timing=cfg.timing, frames=frames, sensors=self.sensors)
        if self.sensors is not None:
            places = [spot.region for *_, spot in self._unplaced]  # mapped too: spots are chosen among what it sees
            attach_camera(cfg, self.sensors, self.robot, self.sim.data, source, places)
        q0 = start_q(cfg, self.robot)
        if self.robot.base is not None and cfg.object == BASE_BODY:  # a base that parks: nothing to place
            self.placement = Placement(np.zeros(3), None)
        else:
            self.placement = check_placement(self.controlled, cfg.object, cfg.target, q0, source)
        self.q0 = q0
        self.sim.reset(q0)
        mask = np.zeros(self.robot.model.nbody, dtype=bool)
        mask[list(robot_bodies(self.robot))] = True
        check_robot_clear(self.robot.model, self.sim.data, mask, source)
        self.servo = Servo(self.ik, self.sim, q0)
        self.camera = None if self.sensors is None else self.sensors.measurer
        if self.camera is not None and cfg.perception.look_at:
            self.servo.look = watch(self.ik, cfg.perception.camera, cfg.perception.look_cost)
        self.view = SimView(self.controlled, self.sim, self.servo, planning=self.cfg.planning, seen=self.seen)
        self.mapper = getattr(self.camera, "mapper", None)
        """The camera's occupancy map of the obstacles (``perception.map`` or camera obstacles), or None."""
        if self.seen is not None and self.mapper is not None:
            self.view.coverage = self.mapper.seen_share
            assert self.camera is not None  # (the map is the camera's)
            self.view.meets = partial(self.mapper.met, *self.camera.world)  # scored with the scene: the report's
        self._map_frames = 0  # the camera map's frames the controller's obstacles were last taken from
        self._scan_at: np.ndarray | None = None  # where the head looks while it scans the mapped space
        self.scan: dict[str, Any] | None = None  # the scan's report
        self.records = [PhaseRecord(cfg.phase_name(i), p.kind) for i, p in enumerate(cfg.phases)]
        self.monitor = OutcomeMonitor(self.robot, cfg.object)
        self.monitor.attach(self.sim)
        self.monitor.record_starts(self.sim)
        for name, target in cfg.success.objects.items():  # judged objects: known bodies, or exit 2 now
            for kind, body, valid in (("object", name, self.robot.object_names),
                                      ("target", target, self.robot.body_names)):
                if body not in valid:
                    raise ConfigError(f"{source}: success.objects: {UnknownNameError(kind, body, valid)}",
                                      key="success.objects")
        self.error: str | None = None
        self.wall_s = 0.0
        self.current: Phase | None = None
        self._phase: tuple[str, str, float] | None = None  # (name, kind, start [s]) of the running phase

    def tick(self, command: Command) -> None:
        """One control tick: the servo applies ``command``, the simulation runs, the clamp is watched."""
        if self.shoves is not None:
            self.shoves.update(self.sim.data, self.sim.time, self._phase)
        objects = {name: (pose.pos, pose.quat) for name, pose in self.sim.measured.objects.items()}
        if self.servo.look is not None:
            self.servo.look.point = self._scan_at if self._scan_at is not None else self._look_point()
        if self.sensors is not None:  # a held object is estimated relative to the first pad, a pushed one the tool
            grip = self.view.grip
            carried = (grip.object, partial(self.view.frame_pose, grip.frames[0])) if grip is not None else (
                self.current.carrier(self.view) if self.current is not None else None)
            self.sensors.carry(*(carried or (None, None)), pushed=grip is None)
        self.servo.step(command, objects)
        self.monitor.grip = self.view.grip
        self.sim.tick()
        if self.seen is not None:
            self._take_seen()
        if self.view.grip is not None:
            self.monitor.check_hold(self.sim, self.view.grip)

    def _take_seen(self) -> None:
        """Give the controller the camera map's obstacle boxes once a new whole frame is in it (when they changed)."""
        mapper = self.mapper
        if mapper is None or mapper.map.frames == self._map_frames:
            return
        self._map_frames = mapper.map.frames
        assert self.seen is not None
        unseen = mapper.unknown_boxes() if self.cfg.perception.unknown == "occupied" else []
        if self.seen.set(mapper.boxes(), unseen):
            self.seen.sync(self.ik.model)
            self.ik.world_changed()
            self.view.world_changed()

    def _start(self, phase: Phase) -> None:
        """Start a phase; one that names a target placed by ``free_spot`` and fails at its start (the clamp cannot
        reach the placement there, no route carries the object to it) gets the target's next spot instead.
        """  # noqa: D205
        spec = phase.spec
        named = {getattr(spec, "target", None), getattr(spec, "place_at", None)}
        for name in [n for n in self.free_spots if n in named and self.seen is not None]:
            self._check_spot(name)  # chosen from the map by an earlier phase: the map has seen more since
        for request in [r for r in self._unplaced if r[0] in named]:  # among the obstacles the camera has seen
            self._unplaced.remove(request)
            try:
                self.free_spots[request[0]] = place_spot(self.controlled, request, self._target_models, self.source)
            except InfeasibleError as exc:
                raise PhaseError(f"{exc} (among the obstacles the camera has seen)") from None
            self._moved_target()
        spots = [p for name, p in self.free_spots.items() if name in named]
        while True:
            try:
                phase.start(self.view)
                return
            except (InfeasibleError, PhaseError) as exc:
                if not any(p.take_next(self._target_models, str(exc)) for p in spots):
                    raise
                self._moved_target()

    def _spot_robot(self) -> Robot:
        """The controller's robot on a copy of its model whose obstacles are those a chosen free spot is judged
        against again: the camera map's seen obstacles grown into the space the robot hides beside them
        (:meth:`~nextage_qp.sensing.camera.seen.ObstacleMapper.boxes`), and the never-seen space.
        """  # noqa: D205
        if self.mapper is None:
            return self.controlled
        twin = self.controlled.blinded_copy()
        boxes = SeenBoxes()
        boxes.set(self.mapper.boxes(hidden=True),
                  self.mapper.unknown_boxes() if self.cfg.perception.unknown == "occupied" else [])
        boxes.sync(twin.model)
        return twin

    def _check_spot(self, name: str) -> None:
        """Judge a free spot chosen from the camera's map again on the map as it is now; where it no longer keeps its
        clearance, move it to the nearest spot that does (the phase's start then judges that one).
        """  # noqa: D205
        placed = self.free_spots[name]
        _, obj, yaw, spot = placed.request
        twin = self._spot_robot()
        room = spot_room(twin, obj, yaw, placed.pos)
        if room >= spot.clearance + FREE_SPOT_MARGIN:
            return
        where = f"{self.source}: scene.poses.{name}.free_spot"
        spots = free_spots(twin, obj, yaw, spot.region, (float(placed.pos[0]), float(placed.pos[1])), spot.clearance,
                           where)
        if placed.move(spots, self._target_models, f"the map now keeps {obj} {room * 1e3:.0f} mm from an obstacle at "
                                                   f"({placed.pos[0]:.3f}, {placed.pos[1]:.3f})"):
            self._moved_target()

    def _moved_target(self) -> None:
        """A target took a new place: the physics' poses follow (nothing else moved), and its placement is checked."""
        mujoco.mj_kinematics(self.robot.model, self.sim.data)
        self.placement = check_placement(self.controlled, self.cfg.object, self.cfg.target, self.q0, self.source)

    def run(self, on_tick: TickCallback | None = None) -> RunResult:
        """Run every phase, then settle; returns the result (also on failure, with ``error``)."""
        wall0 = time.perf_counter()
        view = self.view
        try:
            self._find_objects()
            self._scan()
            for i, spec in enumerate(self.cfg.phases):
                rec = self.records[i]
                phase = build(spec, rec.name)
                self.current = phase
                rec.start_s, rec.status = self.sim.time, "running"
                phase.t0 = self.sim.time
                self._phase = (rec.name, spec.kind, self.sim.time)
                clamped0, steps0 = self.sim.pd.saturated_ticks.copy(), self.sim.pd.ticks  # the phase's own, below
                self._start(phase)
                phase.timeout, rec.budget_s = phase.time_limit(view)
                rec.timeout_s = phase.timeout
                view.grip = phase.grip(view.grip)
                while True:
                    command = phase.update(view)
                    view.grip = phase.grip(view.grip)
                    self.tick(command)
                    if on_tick:
                        on_tick(self, phase)
                    if command.done:
                        break
                    if self.sim.time - rec.start_s > phase.timeout:
                        rec.info = dict(phase.info)
                        cause = phase.stalled(view)
                        held = self.ik.collision.violated(self.ik.model, HELD_SLACK) if self.ik.collision else []
                        held = ["; held by ik.collision_pairs: " + ", ".join(h.removeprefix("collision pair ")
                                                                             for h in held[:3])] if held else []
                        holds = self._what_holds(clamped0, steps0)
                        given = "" if rec.budget_s is None else (
                            f" (unset: {TIMEOUT_MARGIN:g} x its budget of {rec.budget_s:.1f} s, at least "
                            f"{DEFAULT_TIMEOUT:g} s; phases[{i}].timeout sets it)")
                        after = _seconds(phase.timeout)
                        raise PhaseError(f"phase {rec.name!r} ({spec.kind}) timed out after {after} s "
                                         f"of simulated time{given}{': ' + cause if cause else ''}; "
                                         f"last state: {_brief(phase.info)}"
                                         f"{''.join(held)}{'; ' + holds if holds else ''}", phase=rec.name)
                rec.status, rec.duration_s, rec.info = "done", self.sim.time - rec.start_s, dict(phase.info)
            self.current, self._phase = None, None
            end = self.sim.time + self.cfg.timing.settle
            while self.sim.time < end:
                self.tick(HOLD)
                if on_tick:
                    on_tick(self, None)
        except NextageQPError as exc:
            if isinstance(exc, InfeasibleError) and self.sim.time == 0.0:
                raise  # refused before anything moved (exit 2, like an overlapping target)
            self.error = str(exc)
            if self._phase is not None and exc.phase is None:  # say which phase it ended in
                self.error = f"phase {self._phase[0]!r} ({self._phase[1]}): {self.error}"
            for rec in self.records:
                if rec.status == "running":
                    rec.status, rec.duration_s = "failed", self.sim.time - rec.start_s
                    if self.current is not None and not rec.info:
                        rec.info = dict(self.current.info)
        finally:
            self.wall_s = time.perf_counter() - wall0
            if self.sensors is not None:
                log_estimates(self.sensors, self.sim.recorder)
            if self.camera is not None:
                self.camera.close()
        return RunResult(self.summary())

    def _what_holds(self, clamped0: np.ndarray, steps0: int) -> str:
        """What may hold the robot up now: its contacts, the joints clamped since the phase began, those at a limit."""
        robot, sim = self.robot, self.sim
        contacts = contact_forces(robot.model, sim.data, robot_bodies(robot))
        clamped = saturated(robot.joint_names, sim.pd.saturated_ticks - clamped0, sim.pd.ticks - steps0)
        limits = at_limits(robot.joint_names, sim.data.qpos[robot.qpos_idx], robot.lower, robot.upper)
        return what_holds(contacts, clamped, limits)

    def _look_point(self) -> np.ndarray:
        """Where the head looks: the middle of the task's object and target, as estimated.

        Before an object is first seen: where the config placed it.
        """
        seen, points = self.sim.measured.objects, []
        for name in (self.cfg.object, self.cfg.target):
            if name in seen:
                points.append(seen[name].pos)
            elif name in self.robot.object_names:
                points.append(self.robot.model.body(name).pos)
            else:  # a marker: the task's own goal
                points.append(self.view.body_pose(name).pos)
        return np.mean(points, axis=0)

    def _find_objects(self) -> None:
        """With a camera, hold still (the head turning) until every object has been seen, or fail after SEARCH_S."""
        if self.camera is None or self.sensors is None:
            return
        names = self.robot.object_names
        while not self.sensors.found(names):
            if self.sim.time > SEARCH_S:
                report = self.camera.report()["objects"]
                lost = {n: {k: v for k, v in report[n].items() if v} for n in names if not self.sensors.found([n])}
                raise PhaseError(f"perception: {', '.join(lost)} not found by camera {self.cfg.perception.camera} "
                                 f"in {SEARCH_S:g} s (frames by outcome: {lost})")
            self.tick(HOLD)

    def _scan(self) -> None:
        """With camera obstacles, look over the mapped space before the first phase (``perception.scan``).

        The head turns to each point of a grid over the map's space at the table top (row by row, the row nearest the
        robot first), holding each ``SCAN_DWELL_S`` once the camera points within ``SCAN_AIM`` of it (``SCAN_POINT_S``
        at most); the arms hold still.
        """
        p, mapper, look = self.cfg.perception, self.mapper, self.servo.look
        if not (p.scan if p.scan is not None else p.obstacles == "camera") or mapper is None or look is None:
            return
        lo, hi = mapper.region()
        xs = np.linspace(lo[0], hi[0], SCAN_GRID + 2)[1:-1]
        ys = np.linspace(lo[1], hi[1], SCAN_GRID + 2)[1:-1]
        points = [np.array([x, y, mapper.table]) for i, x in enumerate(xs) for y in (ys if i % 2 == 0 else ys[::-1])]
        t0, before, aimed_at = self.sim.time, mapper.seen_share(), 0
        for point in points:
            self._scan_at, start, since = point, self.sim.time, None
            while self.sim.time - start < SCAN_POINT_S:
                self.tick(HOLD)
                on = look.off_axis(self.sim.data) <= SCAN_AIM
                since = (since if since is not None else self.sim.time) if on else None
                if since is not None and self.sim.time - since >= SCAN_DWELL_S:
                    aimed_at += 1
                    break
        self._scan_at = None
        self.scan = {"points": len(points), "looked_at": aimed_at, "time_s": round(self.sim.time - t0, 3),
                     "seen_share_before": round(before, 4), "seen_share_after": round(mapper.seen_share(), 4)}

    @property
    def handled(self) -> frozenset[str]:
        """The free objects some phase names (as its object, target or placement): not bystanders."""
        names = set(self.robot.object_names)
        return frozenset(v for spec in self.cfg.phases for v in spec.model_dump().values()
                         if isinstance(v, str) and v in names)

    def summary(self) -> dict[str, Any]:
        """The result record printed by ``nextage-qp run --json``."""
        c = self.cfg
        out = summarize(task=c.task, robot=self.robot, sim=self.sim, monitor=self.monitor, records=self.records,
                         obj=c.object, target=c.target, criteria=c.success, error=self.error, wall_s=self.wall_s,
                         handled=self.handled,
                         extra={"target_clearance_m": self.placement.target_clearance_m,
                                **({"free_spots": {n: p.report() for n, p in self.free_spots.items()}}
                                   if self.free_spots else {}),
                                "estimation": None if self.sensors is None else self.sensors.report(
                                    self.shoves.windows(SHOVE_SETTLE_S) if self.shoves is not None else ()),
                                "shoves": self.shoves.applied if self.shoves is not None else [],
                                "planning": plan_report(self.view.plans),
                                **({"scan": self.scan} if self.scan is not None else {}),
                                **({"swept_seen": swept_report(self.view.swept_seen, self.view.swept_met)}
                                   if self.view.coverage is not None else {}),
                                "planning_time_s": round(sum(p.time_s for p in self.view.plans), 4),
                                **({"base": base_report(self.sim.base.log, self.robot.base)}
                                   if self.sim.base is not None and self.robot.base is not None else {})})
        where, true = source_of(c), out.get("object_error_xy_m")
        if out.get("error") and where != "truth" and true is not None:  # the phases judged what the robot estimated
            out["error"] += (f" [{c.object}'s pose as estimated ({where} perception); it truly ends "
                             f"{true * 1e3:.1f} mm from {c.target} in the plane]")
        return out


def swept_report(shares: Sequence[float], met: Sequence[Sequence[dict[str, Any]]] = ()) -> dict[str, Any]:
    """How much of the space the run's legs swept the camera had seen when each was planned, and what stood in it.

    ``shares``: per leg, the share seen (``coverage``); ``met``: per leg, the obstacles at least 3 cm tall reaching
    into that space, counted once per leg: those the map held (``detected``), those standing wholly in never-seen
    space (planned around as occupied) and the others, by leg and name (``missed``).
    """
    pairs = [(k, o) for k, leg in enumerate(met) for o in leg]
    return {"legs": len(shares), "min_share": round(min(shares), 4) if shares else None,
            "median_share": round(float(np.median(shares)), 4) if shares else None,
            "obstacles_met": len(pairs), "obstacles_detected": sum(o["detected"] for _, o in pairs),
            "obstacles_unknown": sum(o["unknown"] for _, o in pairs),
            "missed": [f"leg {k}: {o['name']}" for k, o in pairs if not (o["detected"] or o["unknown"])]}


def plan_report(plans: Sequence[PathPlan]) -> dict[str, Any]:
    """The run's transit checks and plans: how many legs were checked, planned, and found no path."""
    return {"legs_checked": len(plans), "legs_planned": sum(p.status == "planned" for p in plans),
            "legs_without_path": sum(not p.found for p in plans)}


def _seconds(t: float) -> str:
    """``t`` [s] to a tenth, without a trailing zero: 90, 87.7, 1500.3."""
    return f"{t:.1f}".rstrip("0").rstrip(".")


def _brief(info: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in info.items()) or "n/a"
