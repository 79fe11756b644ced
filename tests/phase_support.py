"""A scripted view for the phases' tests: no simulation, only the contract start(view) -> update(view) -> Command."""

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nextage_qp.geometry import Pose, rot_z
from nextage_qp.ik import RelativeTarget
from nextage_qp.manipulation.context import Grip
from nextage_qp.manipulation.phases import REGISTRY, build
from nextage_qp.sensing.sensors import Wrench

DT = 0.004


def rot_of(target):
    """A target's rotation; for an axis target, the yaw turn that puts the frame's y axis on the direction."""
    if target.rot is not None:
        return np.asarray(target.rot)
    if target.axis is not None:
        d = np.asarray(target.direction)
        return rot_z(float(np.arctan2(-d[0], d[1])))
    return np.eye(3)


PLAN_STEP = 0.02
"""A scripted plan's joint vector is its index times this [rad] (small: neighbouring plans are near in joints)."""


def plan_index(q) -> int:
    """The index of the scripted plan whose joint vector ``q`` is."""
    return round(float(q[0]) / PLAN_STEP)


@dataclass
class ScriptedView:
    """A View whose every answer the test sets; :meth:`act` plays an ideal robot (frames go where commanded).

    The planner reaches every target unless ``reach(targets)`` says no; a plan's joint vector is its index (times
    ``PLAN_STEP``), and
    :meth:`pose_at` gives back the targets it was planned for.
    """

    t: float = 0.0
    dt: float = DT
    grip: Grip | None = None
    bodies: dict = field(default_factory=dict)
    frames: dict = field(default_factory=dict)
    commanded: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    is_settled: bool = True
    tracking: float = 0.0
    half: float = 0.035
    reach: Callable | None = None
    blocked: Callable | None = None  # blocked(targets of the plans along a path) -> what blocks it, or None
    plans: list = field(default_factory=list)
    reach_checked: list = field(default_factory=list)  # (frame, goal) of every check_reach call
    forces: dict = field(default_factory=dict)
    symmetry: float = np.pi
    rest: float = 0.91
    table: float = 0.875
    obstacle: float = 0.875
    unseen: float = 0.0
    kg: float = 0.3
    home: Pose = field(default_factory=lambda: pose(0.25, 0.25, 1.0))  # every frame in the default posture

    def body_pose(self, name):
        return self.bodies[name]

    def frame_pose(self, name):
        return self.frames[name]

    def commanded_pose(self, name):
        return self.commanded[name]

    def joint_positions(self, names):
        return np.array([self.joints.get(n, -1.0) for n in names])  # the scripted planner's one joint: home

    def settled(self):
        return self.is_settled

    def tracking_error(self):
        return self.tracking

    def extent(self, obj, direction):
        return self.half

    def joint_names(self):
        return ("plan",)

    def default_posture(self):
        return np.array([-1.0])  # pose_at: the home pose

    def looking_joints(self):
        return np.zeros(0, dtype=int)

    def plan_path(self, q_start, q_goal, *, near=(), always=False, escape=False):
        from nextage_qp.planning.rrt import PathPlan

        self.paths = [*getattr(self, "paths", []), (np.asarray(q_start), np.asarray(q_goal), tuple(near), always)]
        return PathPlan([np.asarray(q_start), np.asarray(q_goal)], "straight")

    def path_blocked(self, path, clearance=None, near=(), allow=()):
        if self.blocked is None:
            return None
        planned = [self.plans[plan_index(q)] for q in path if q[0] >= 0]
        return self.blocked(planned)

    def obstacle_groups(self):
        return ()

    def room_at(self, q, near=(), allow=()):
        return 1.0

    def clearance_at(self, obj, pos, yaw, beside=False):
        return 0.1, np.zeros(3)

    def plan(self, targets, start=None, allow=frozenset(), pos_tol=None, restarts=True):
        if self.reach is not None and not self.reach(tuple(targets)):
            return None
        self.plans.append(tuple(targets))
        return np.array([(len(self.plans) - 1) * PLAN_STEP])

    def check_reach(self, frame, pos, where):
        self.reach_checked.append((frame, tuple(np.round(pos, 6))))

    def pose_at(self, frame, q):
        if q[0] < 0:
            return self.home
        target = next(t for t in self.plans[plan_index(q)] if t.frame == frame)
        return Pose(np.asarray(target.pos, dtype=float), rot_of(target))

    def wrench(self, site):
        return Wrench(np.asarray(self.forces.get(site, np.zeros(3)), dtype=float), np.zeros(3))

    def rest_height(self, obj, on=None):
        return self.rest

    def table_top(self):
        return self.table

    def obstacle_top(self):
        return self.obstacle

    def yaw_symmetry(self, obj):
        return self.symmetry

    def weight(self, obj):
        return 9.81 * self.kg

    def unseen_s(self, obj):
        return self.unseen

    def act(self, cmd):
        """An ideal robot: the frames (commanded and real) take the planned joints' or the targets' poses."""
        if cmd.joints is not None:
            for target in self.plans[plan_index([cmd.joints["plan"]])]:
                self.commanded[target.frame] = self.frames[target.frame] = Pose(np.asarray(target.pos), rot_of(target))
        for target in cmd.targets:
            self.commanded[target.frame] = self.frames[target.frame] = Pose(np.asarray(target.pos), rot_of(target))


def pose(x, y, z, yaw=0.0):
    return Pose(np.array([x, y, z], dtype=float), rot_z(yaw))


def make(kind, **fields):
    spec_type, _ = REGISTRY[kind]
    return build(spec_type.model_validate({"kind": kind, **fields}), kind)


def run_until_done(phase, view, ticks=20000, each=None):
    for _ in range(ticks):
        cmd = phase.update(view)
        view.act(cmd)
        view.t += DT
        if each:
            each(cmd)
        if cmd.done:
            return cmd
    raise AssertionError("phase never finished")


def push_view(**kw):
    return ScriptedView(bodies={"cube": pose(0.33, 0.0, 0.91), "cube_target": pose(0.70, 0.0, 0.91)},
                        commanded={"left_tool": pose(0.5, 0.23, 1.03)}, frames={"left_tool": pose(0.5, 0.23, 1.03)},
                        **kw)


def pushed_along_the_tool_face(view):
    """A kinematic cube: a tool below the cube's top that reaches into its face carries it along the face normal."""

    def push(_cmd):
        tool, cube = view.frames["left_tool"], view.bodies["cube"]
        normal = tool.rot[:, 0]
        depth = float((tool.pos - cube.pos) @ normal) + view.half
        if tool.pos[2] < cube.pos[2] + view.half and depth > 0:
            view.bodies["cube"] = Pose(cube.pos + depth * normal, cube.rot)

    return push


class HiddenCubeView(ScriptedView):
    """A camera that loses the cube while the tool is within ``blind`` [m] of it (the hand in front): the phase then
    gets the last pose seen, and :meth:`unseen_s` grows; the wrist feels 2 N while the tool pushes the cube."""

    blind: float = 0.06
    seen: Pose | None = None
    seen_t: float = 0.0

    def body_pose(self, name):
        if name != "cube":
            return self.bodies[name]
        tool, cube = self.frames["left_tool"].pos, self.bodies["cube"].pos
        if self.seen is None or np.linalg.norm((tool - cube)[:2]) > self.blind:
            self.seen, self.seen_t = self.bodies["cube"], self.t
        return self.seen

    def unseen_s(self, obj):
        if obj != "cube":
            return 0.0
        HiddenCubeView.body_pose(self, "cube")  # the camera looks whether or not the phase asks for the pose
        return self.t - self.seen_t


def grasp_view():
    pads = {"left_pad": pose(0.5, 0.25, 1.05), "right_pad": pose(0.5, -0.25, 1.05)}
    return ScriptedView(bodies={"dumbbell": pose(0.5, 0.0, 1.015)}, commanded=dict(pads), frames=dict(pads))


def squeezed_by_the_pads(view, half_width=0.084, stiffness=1000.0):
    """A rigid object of ``half_width`` along y: a pad inside its face feels ``stiffness`` x depth outwards."""

    def squeeze(_cmd):
        obj = view.bodies["dumbbell"].pos
        for frame, side in (("left_pad", 1.0), ("right_pad", -1.0)):
            depth = half_width - side * float(view.frames[frame].pos[1] - obj[1])
            view.forces[frame] = np.array([0.0, side * stiffness * max(depth, 0.0), 0.0])

    return squeeze


def make_grasp(**kw):
    return make("grasp", object="dumbbell", frames=["left_pad", "right_pad"], half_width=0.084, height=0.105,
                gap=0.04, hold=0.3, **kw)


def held_grip():
    rel = RelativeTarget("left_pad", "right_pad", np.array([0.0, 0.144, 0.0]), np.eye(3), 1.0)
    return Grip("dumbbell", ("left_pad", "right_pad"),
                {"left_pad": np.array([0.0, 0.072, 0.105]), "right_pad": np.array([0.0, -0.072, 0.105])},
                {"left_pad": np.eye(3), "right_pad": np.eye(3)}, rel)
