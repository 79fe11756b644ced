"""The planner: collision-free joint paths in clutter, narrow passages, a held object's collisions, the new keys."""

from pathlib import Path

import numpy as np
import pytest

from nextage_qp.cli import main
from nextage_qp.geometry import Pose
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import build_robot
from nextage_qp.planning.rrt import plan_path
from nextage_qp.planning.world import RESOLUTION, CollisionWorld, Held

ROOT = Path(__file__).resolve().parents[1]
CLUTTER = ROOT / "configs" / "push_clutter.yaml"


@pytest.fixture(scope="module")
def cluttered():
    cfg = load_config(CLUTTER, ["scene.clutter.count=8", "scene.clutter.seed=4"])
    return build_robot(cfg, str(CLUTTER))


def _arm(robot):
    return [robot.joint_index(f"LARM_JOINT{i}") for i in range(6)]


def _valid_samples(world, robot, n, rng):
    home, arm, found = robot.keyframe_q("home"), _arm(robot), []
    while len(found) < n:
        q = home.copy()
        q[arm] = rng.uniform(robot.lower[arm], robot.upper[arm])
        if world.valid(q):
            found.append(q)
    return found


def test_clutter_is_placed_from_its_seed_clear_of_the_objects_and_forms_a_group(cluttered):
    robot = cluttered
    names = [robot.model.body(b).name for b in range(robot.model.nbody)]
    assert [n for n in names if n.startswith("clutter_")] == [f"clutter_{i}" for i in range(8)]
    assert len(robot.collision_geoms()["clutter"]) == 8
    again = build_robot(load_config(CLUTTER, ["scene.clutter.count=8", "scene.clutter.seed=4"]), str(CLUTTER))
    assert np.array_equal(again.model.body_pos, robot.model.body_pos)  # the same seed, the same clutter
    other = build_robot(load_config(CLUTTER, ["scene.clutter.count=8", "scene.clutter.seed=5"]), str(CLUTTER))
    assert not np.array_equal(other.model.body_pos, robot.model.body_pos)
    cube = robot.model.body("cube").pos[:2]
    for i in range(8):
        assert np.linalg.norm(robot.model.body(f"clutter_{i}").pos[:2] - cube) > 0.05


def test_a_planned_path_checked_at_a_finer_resolution_never_collides(cluttered):
    robot = cluttered
    world = CollisionWorld(robot, clearance=0.01)
    world.set_world({}, robot.keyframe_q("home"))
    fine = CollisionWorld(robot, clearance=0.0)  # a finer check, at a third of the planner's resolution
    fine.set_world({}, robot.keyframe_q("home"))
    rng = np.random.default_rng(3)
    planned = 0
    for k in range(12):
        a, b = _valid_samples(world, robot, 2, rng)
        plan = plan_path(world, a, b, lower=robot.lower, upper=robot.upper, seed=k + 1, straight_first=False,
                         time_limit=2.0)
        if not plan.found:
            continue
        planned += 1
        for qa, qb in zip(plan.path, plan.path[1:], strict=False):
            n = 3 * world.steps(qa, qb)
            for s in np.linspace(0.0, 1.0, n + 1):
                assert fine.first_collision(qa + s * (qb - qa)) is None
    assert planned >= 8
    assert RESOLUTION <= 0.005


class _Slot:
    """A joint space (7 joints) split by a wall at q0 = 0 with one slot 0.04 rad wide in q1 (and the checker's API)."""

    checks = 0

    def valid(self, q):
        self.checks += 1
        return not (abs(q[0]) < 0.05 and abs(q[1] - 0.6) > 0.02)

    def first_collision(self, q):
        return None if self.valid(q) else "wall"

    def first_on_segment(self, qa, qb):
        for s in np.linspace(0.0, 1.0, 400):
            if not self.valid(qa + s * (qb - qa)):
                return s, "wall"
        return None

    def first_on_path(self, path):
        for i in range(len(path) - 1):
            if (hit := self.first_on_segment(path[i], path[i + 1])) is not None:
                return i, hit[0], hit[1]
        return None


def test_a_narrow_passage_a_slot_through_a_wall_is_found():
    world = _Slot()
    lower, upper = np.full(7, -1.0), np.full(7, 1.0)
    a, b = np.array([-0.8, -0.5, 0, 0, 0, 0, 0]), np.array([0.8, -0.5, 0, 0, 0, 0, 0])
    plan = plan_path(world, a, b, lower=lower, upper=upper, time_limit=5.0, joints=range(7))
    assert plan.status == "planned", plan.reason()
    crossing = [q for q in plan.path if abs(q[0]) < 0.05]
    assert world.first_on_path(plan.path) is None
    assert all(abs(q[1] - 0.6) <= 0.02 for q in crossing)


def _post_world(post: str):
    """The push scene with a box ``post`` (its flow mapping) added, its collision world and the robot's home, set."""
    robot = build_robot(load_config(ROOT / "configs" / "push_cube.yaml", [f"scene.objects.post={post}"]), "post")
    world = CollisionWorld(robot, clearance=0.005)
    home = robot.keyframe_q("home")
    world.set_world({}, home)
    return robot, world, home


def test_a_held_object_blocks_a_path_that_drags_it_through_an_obstacle():
    robot, world, home = _post_world("{shape: box, size: [0.02, 0.02, 0.03], pos: [0.59, 0.12]}")
    sweep = home.copy()
    sweep[robot.joint_index("LARM_JOINT0")] -= 0.5  # the left hand swings across the table towards the middle
    hand = Pose(np.zeros(3), np.eye(3))
    free = world.first_on_segment(home, sweep)
    post = robot.model.body("post")
    # the same sweep, carrying the cube 12 cm under the tool: it hangs below the post's top, the hand above it
    world.set_world({}, home, held=Held("cube", "left_tool", Pose(np.array([0.0, 0.0, -0.12]), hand.rot)))
    blocked = world.first_on_segment(home, sweep)
    assert free is None, free
    assert blocked is not None and "post" in (blocked[1].body1 + blocked[1].body2), blocked
    assert post.name == "post"
    plan = plan_path(world, home, sweep, lower=robot.lower, upper=robot.upper, time_limit=2.0)
    assert not plan.found or world.first_on_path(plan.path) is None


def test_a_path_of_one_state_is_that_state_checked():
    """A pose alone (a placement's joints) is judged as a path of one state: in collision, it says what it touches."""
    robot, world, home = _post_world("{shape: box, size: [0.03, 0.03, 0.03], pos: [0.60, 0.26, 0.99], fixed: true}")
    hit = world.first_on_path([home])
    assert hit is not None and hit[:2] == (0, 0.0) and "post" in hit[2].body1 + hit[2].body2, hit
    clear = home.copy()
    clear[robot.joint_index("LARM_JOINT0")] += 0.4  # the left hand swung away from the post
    assert world.first_collision(clear) is None and world.first_on_path([clear]) is None


def test_a_start_inside_an_obstacle_is_left_first_only_where_the_robot_stands():
    """The hand 4 mm into a post at home: invalid as a waypoint; as the robot's own state, left, then planned."""
    robot, world, home = _post_world("{shape: box, size: [0.03, 0.03, 0.03], pos: [0.60, 0.26, 0.99], fixed: true}")
    start = world.first_collision(home)
    assert start is not None and start.distance < 0 and "post" in start.body2, start
    goal = home.copy()
    goal[robot.joint_index("LARM_JOINT1")] -= 0.3  # the arm lifts
    arm = robot.moved_groups([robot.joint_index("LARM_JOINT1")])
    strict = plan_path(world, home, goal, lower=robot.lower, upper=robot.upper, joints=arm)
    assert strict.status == "invalid_start" and "post" in strict.reason()
    plan = plan_path(world, home, goal, lower=robot.lower, upper=robot.upper, joints=arm, escape_start=True)
    assert plan.found, plan.reason()
    np.testing.assert_array_equal(plan.path[0], home)
    np.testing.assert_array_equal(plan.path[-1], goal)
    assert world.first_on_path(plan.path[1:]) is None  # free once out
    out = plan.path[1]
    depth = world.room(home)[0]
    n = 4 * world.steps(home, out)
    assert all(world.room(home + s * (out - home))[0] >= depth - 0.0015 for s in np.linspace(0.0, 1.0, n + 1))
    assert float(np.abs(out - home).max()) <= 0.2  # near: within the largest escape radius
    _, buried, _ = _post_world("{shape: box, size: [0.15, 0.15, 0.12], pos: [0.59, 0.26, 1.0], fixed: true}")
    assert plan_path(buried, home, goal, lower=robot.lower, upper=robot.upper, joints=arm,
                     escape_start=True).status == "invalid_start"  # the hand inside the post: no way out nearby


@pytest.mark.parametrize(("override", "says"), [
    ("scene.clutter.count=-1", "scene.clutter.count"),
    ("scene.clutter.size=[0.05, 0.02]", "size"),
    ("scene.clutter.region=[[0.8, 0.0], [0.2, 0.3]]", "region"),
    ("scene.clutter.shapes=[cone]", "scene.clutter.shapes"),
    ("scene.clutter.keep_out=nan", "scene.clutter.keep_out"),
    ("planning.clearance=-0.01", "planning.clearance"),
    ("planning.time_limit=0", "planning.time_limit"),
    ("success.clutter_contacts=-1", "success.clutter_contacts"),
    ("phases[0].plan=sometimes", "phases[0].plan"),
    ("scene.clutter.count=40", "scene.clutter: placed"),
    ("scene.objects.post={shape: box, size: [0.02, 0.02, 0.05], fixed: maybe}", "scene.objects.post.fixed"),
    ("success.knocked=-1", "success.knocked"),
    ("success.objects={cube: nowhere}", "success.objects: unknown target 'nowhere'"),
    ("phases[0].kind=place", "phases[0]"),
])
def test_every_planning_and_clutter_key_is_validated_in_one_line(override, says, capsys):
    assert main(["run", str(CLUTTER), "--set", override]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err


def test_a_placement_that_puts_the_arms_into_the_clutter_is_refused_naming_the_piece(capsys):
    """A sweep episode's scene: the clamp at the box's target puts the left forearm into a clutter piece (the pose
    solved with the clutter ignored), and the IK keeping clear of it stalls short. Refused before anything moves, in
    one line naming the link and the piece, not claiming a clear pose."""
    sets = ["scene.objects.box.size=[0.0273694609596842,0.04264597299399814,0.12]",
            "scene.objects.box.pos=[0.5171660035542716,0.021578978261265896]", "scene.objects.box.yaw=-0.04290161171814",
            "scene.poses.box_target.pos=[0.39087506749303746,0.3323907576992709,0.905]",
            "scene.poses.box_target.yaw=0.5203765058435428", "scene.clutter.count=6", "seed=76924364"]
    config = ROOT / "configs" / "pick_place_clutter.yaml"
    assert main(["run", str(config), *[a for s in sets for a in ("--set", s)]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "an obstacle is in the way" in err[0] and "mm into clutter_" in err[0], err


def test_touching_the_clutter_is_counted_per_physics_step_and_judged(cluttered):
    """The monitor counts a step in which a robot link touches a clutter body; the criterion judges the count."""
    from types import SimpleNamespace

    import mujoco

    from nextage_qp.manipulation.config import SuccessCriteria
    from nextage_qp.manipulation.metrics import ObjectState, OutcomeMonitor, judge

    robot = cluttered
    monitor = OutcomeMonitor(robot, "cube")
    assert monitor.has_clutter
    data = mujoco.MjData(robot.model)
    data.qpos[robot.qpos_idx] = robot.keyframe_q("home")
    mujoco.mj_forward(robot.model, data)
    monitor.on_clutter_step(SimpleNamespace(data=data))
    assert monitor.clutter_contacts == 0  # clutter stands clear of the start posture
    piece = robot.model.body("clutter_0")
    hand = robot.model.body("LARM_JOINT5_Link").id
    where = robot.model.body_pos[piece.id].copy()
    try:
        robot.model.body_pos[piece.id] = data.xpos[hand]
        mujoco.mj_forward(robot.model, data)
        monitor.on_clutter_step(SimpleNamespace(data=data))
    finally:
        robot.model.body_pos[piece.id] = where  # the fixture's model is shared
    assert monitor.clutter_contacts == 1
    touches = monitor.clutter_report()  # which body touched which piece, when and how deep
    assert touches[0]["clutter"] == "clutter_0" and touches[0]["steps"] == 1 and touches[0]["depth_m"] > 0
    assert "LARM_JOINT5_Link" in {t["body"] for t in touches}
    state = ObjectState(np.zeros(3), np.zeros(3), 0.0, 0.0, 0.0, 0.0, True)
    verdict = judge(SuccessCriteria(clutter_contacts=0), state, completed=True, dropped=False, limit_violations=0,
                    obstacle_contacts=0, clutter_contacts=monitor.clutter_contacts, clutter_touches=touches)
    assert verdict["clutter_contacts"]["value"] == 1 and not verdict["clutter_contacts"]["ok"]
    detail = verdict["clutter_contacts"]["detail"]
    assert detail.startswith(f"{touches[0]['body']} on clutter_0 at 0.00-0.00 s, 1 step, "), detail


def test_a_shelf_is_reached_by_a_route_between_its_boards_not_over_them():
    """The route over everything (the shelf's top board) is out of reach; the carry takes the lowest free one."""
    from nextage_qp.manipulation.config import load_config
    from nextage_qp.manipulation.runner import Runner

    path = ROOT / "configs" / "shelf_place.yaml"
    result = Runner(load_config(path, []), path).run()
    place = next(p for p in result["phases"] if p["kind"] == "place")
    assert result.success, result["error"] or result["failed_criteria"]
    assert place["carry"] == "routed" and "cannot reach" in place["carry_blocked"]
    assert place["carry_height_m"] < 1.34  # under the top board's underside
    assert result["object_error_xy_m"] < 0.005 and result["criteria"]["resting"]["ok"]  # standing on the board


def test_a_turning_torso_plans_over_both_arms_an_arm_over_itself(cluttered):
    robot = cluttered
    left, right = list(robot.group("left_arm")), list(robot.group("right_arm"))
    chest = robot.joint_index("CHEST_JOINT0")
    assert robot.moved_groups([left[2]]) == sorted(left)
    assert robot.moved_groups([chest]) == sorted([chest, *left, *right])  # the chest carries both arms
    assert robot.moved_groups([]) == []


def test_a_chest_turn_that_swings_the_other_arm_into_clutter_is_planned_around_it(cluttered):
    """The right arm, held still, would sweep through the clutter as the chest turns: it moves aside and back."""
    robot = cluttered
    world = CollisionWorld(robot, clearance=0.01)
    home = robot.keyframe_q("home")
    world.set_world({}, home)
    chest = robot.joint_index("CHEST_JOINT0")
    right = list(robot.group("right_arm"))
    rng = np.random.default_rng(0)
    for _ in range(400):  # a chest turn whose straight sweep puts the right hand into something
        a, b = home.copy(), home.copy()
        a[chest], b[chest] = rng.uniform(-1.0, 1.0, 2)
        if world.valid(a) and world.valid(b) and (hit := world.first_on_segment(a, b)) is not None:
            break
    else:
        pytest.skip("no blocked chest turn in this clutter")
    assert hit is not None
    narrow = plan_path(world, a, b, lower=robot.lower, upper=robot.upper, joints=[chest], time_limit=0.5)
    wide = plan_path(world, a, b, lower=robot.lower, upper=robot.upper, joints=robot.moved_groups([chest]),
                     time_limit=2.0)
    assert wide.found and set(right) <= set(wide.joints)
    assert world.first_on_path(wide.path) is None
    assert not narrow.found or narrow.joints == (chest,)


def test_the_compiled_validity_rule_equals_its_array_statement(cluttered):
    """Every state's worst contact, as :meth:`CollisionWorld.room` finds it, against the rule written with arrays."""
    from nextage_qp.planning.world import LOOKAHEAD, RESTING, SELF_SLOP

    robot = cluttered
    world = CollisionWorld(robot, clearance=0.02, table_clearance=0.005)
    held = Held("cube", "left_pad", Pose(np.array([0.0, 0.0, -0.08]), np.eye(3)))
    world.set_world({}, robot.keyframe_q("home"), held=held, near=["clutter_0"], allow=["clutter_1"])
    rng = np.random.default_rng(1)
    m, d = world.model, world.data
    compared = 0
    for _ in range(150):
        q = robot.keyframe_q("home")
        arm = _arm(robot)
        q[arm] = rng.uniform(robot.lower[arm], robot.upper[arm])
        room, why = world.room(q)
        if d.ncon == 0:
            continue
        bodies = m.geom_bodyid[d.contact.geom[: d.ncon]]
        dist = d.contact.dist[: d.ncon]
        mine = world._robot_bodies[bodies] | world._held_body[bodies]
        is_held = world._held_body[bodies].any(axis=1)
        both, one = mine.all(axis=1), mine.any(axis=1) & ~mine.all(axis=1)
        selfhit = both & ~is_held
        other = np.where(mine[:, 0], bodies[:, 1], bodies[:, 0])
        table = world._table[other]
        needed = np.where(table, world.table_clearance, np.where(world._near_body[other], 0.0, world.clearance))
        needed = np.where(table & is_held, -RESTING, needed)
        needed = np.where(selfhit, np.where(world._chain[bodies[:, 0], bodies[:, 1]], -world.chain_slop,
                                            -SELF_SLOP), needed)
        counted = ~world._allowed_body[bodies].any(axis=1) & (one | selfhit) & (bodies != 0).all(axis=1)
        slack = np.where(selfhit, 0.5 * (dist - needed), dist - needed)[counted]
        free = LOOKAHEAD - max(world.clearance, world.table_clearance)
        expected = free if not counted.any() or slack.min() >= free else float(slack.min())
        assert room == pytest.approx(expected)
        assert (why is None) == (not counted.any() or slack.min() >= 0)
        compared += 1
    assert compared > 100
