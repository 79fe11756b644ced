import itertools

import mujoco
import numpy as np
import pytest
from tests_support import NEXTAGE_JOINTS as JOINT_NAMES

from nextage_qp.errors import ConfigError, UnknownFrameError, UnknownNameError
from nextage_qp.ik import QPIK, CollisionPairConfig, FrameTarget, IKConfig, IKInfeasibleError, kinematic_model
from nextage_qp.ik.targets import worst_errors
from nextage_qp.kinematics.frames import Kinematics
from nextage_qp.robots.model import Robot
from nextage_qp.scene.files import BodyPose, SceneOverrides


@pytest.fixture(scope="module")
def robot() -> Robot:
    return Robot.from_scene("dock_dumbbell")


@pytest.fixture(scope="module")
def kin(robot: Robot) -> Kinematics:
    return Kinematics(robot)


def test_kinematic_model_has_only_robot_joints(robot: Robot) -> None:
    model = kinematic_model(robot)
    assert model.nq == model.nv == 15
    assert model.nmocap == 1
    assert [model.joint(i).name for i in range(model.njnt)] == list(JOINT_NAMES)


def test_error_strictly_decreasing_on_easy_target(robot: Robot, kin: Kinematics) -> None:
    ik = QPIK(robot, IKConfig())
    home = robot.keyframe_q("home")
    pose = kin.fk("left_wrist", home)
    target = [FrameTarget("left_wrist", pos=pose.pos + np.array([0.05, -0.05, 0.04]), rot=pose.rot)]
    q, errors = home.copy(), []
    for _ in range(8):
        p = kin.fk("left_wrist", q)
        errors.append(np.linalg.norm(p.pos - target[0].pos))
        q = q + ik.step(q, target, 0.1) * 0.1
    assert all(b < a for a, b in itertools.pairwise(errors))
    res = ik.solve(target, home)
    assert res.converged and res.status == "converged" and res.pos_err_m <= 1e-4 and res.rot_err_rad <= 1e-3


def test_axis_target_points_tool_axis(robot: Robot, kin: Kinematics) -> None:
    ik = QPIK(robot, IKConfig())
    t = FrameTarget(
        "left_wrist", pos=np.array([0.45, 0.2, 1.0]), axis=np.array([0, 0, 1.0]), direction=np.array([0, 0, 1.0])
    )
    res = ik.solve([t], robot.keyframe_q("home"))
    assert res.converged
    rot = kin.fk("left_wrist", res.q).rot
    assert rot[:, 2] @ np.array([0, 0, 1.0]) > np.cos(1e-3)


def test_limits_never_violated_over_random_solves(robot: Robot, kin: Kinematics) -> None:
    ik = QPIK(robot, IKConfig(max_iters=40, restarts=1))
    rng = np.random.default_rng(3)
    for _ in range(25):
        goal = rng.uniform(robot.lower - 0.5, robot.upper + 0.5)  # some targets out of reach
        pose = kin.fk("right_wrist", np.clip(goal, robot.lower, robot.upper))
        res = ik.solve([FrameTarget("right_wrist", pos=pose.pos + rng.normal(0, 0.2, 3))], robot.keyframe_q("home"))
        assert robot.within_limits(res.q, tol=0.0)


def test_unreachable_target_returns_best_q(robot: Robot) -> None:
    ik = QPIK(robot, IKConfig(restarts=1))
    res = ik.solve([FrameTarget("left_wrist", pos=np.array([2.0, 0.5, 1.0]))], robot.keyframe_q("home"))
    assert not res.converged and res.status in ("stalled", "max_iters")
    assert 1.0 < res.pos_err_m < 1.5  # arm stretched towards the target
    assert robot.within_limits(res.q)


def test_relaxation_gate_ends_a_search_out_of_reach_without_collision_restarts(robot: Robot) -> None:
    """A target the search misses even without collision rows: no collision-aware descent runs at all."""
    pair = CollisionPairConfig(a="left_arm", b="table", min_distance=0.01, detection_distance=0.05)
    far = [FrameTarget("left_wrist", pos=np.array([2.0, 0.5, 1.0]))]
    gated = QPIK(robot, IKConfig(collision_pairs=(pair,), restarts=3, max_iters=60))
    free = QPIK(robot, IKConfig(restarts=3, max_iters=60))
    home = robot.keyframe_q("home")
    accept = (0.003, 0.05)
    res, relaxed = gated.solve(far, home, accept=accept), free.solve(far, home)
    assert not res.converged and not relaxed.converged and res.status == "stalled"
    # the relaxed search's four descents and nothing more; the answer is the start, its error measured there
    assert res.iters == relaxed.iters
    np.testing.assert_array_equal(res.q, home)
    gated.configuration.update(home)
    expected, _ = worst_errors(far, [gated.frame("left_wrist").pose(gated.configuration.data)])
    assert res.pos_err_m == pytest.approx(expected)
    # without an accepted error there is no gate: every collision-aware descent runs
    assert gated.solve(far, home).iters > res.iters


def test_relaxation_gate_answers_a_target_behind_a_collision_from_the_first_start(robot: Robot) -> None:
    """A target reachable only through a collision: the first start's collision-aware descent is the answer."""
    pair = CollisionPairConfig(a="left_hand", b="table", min_distance=0.01, detection_distance=0.05)
    below = [FrameTarget("left_wrist", pos=np.array([0.35, 0.25, 0.86]))]  # into the table top
    home = robot.keyframe_q("home")
    res = QPIK(robot, IKConfig(collision_pairs=(pair,), restarts=2, max_iters=80)).solve(below, home,
                                                                                        accept=(0.003, 0.05))
    free = QPIK(robot, IKConfig(restarts=2, max_iters=80)).solve(below, home)
    first = QPIK(robot, IKConfig(collision_pairs=(pair,), restarts=0, max_iters=80)).solve(below, home)
    assert free.converged and not res.converged and not first.converged
    # the restarts' relaxed descents reach it through the table: given up, no collision-aware descent from them
    np.testing.assert_array_equal(res.q, first.q)
    ungated = QPIK(robot, IKConfig(collision_pairs=(pair,), restarts=2, max_iters=80)).solve(below, home)
    assert res.iters < ungated.iters
    assert res.pos_err_m == first.pos_err_m


def test_relaxation_gate_takes_a_relaxed_solution_clear_of_every_pair(robot: Robot) -> None:
    """A target the first descent misses: a restart's relaxed descent that ends clear of every pair is the answer."""
    pairs = (CollisionPairConfig(a="left_arm", b="torso", min_distance=0.01, detection_distance=0.05),
             CollisionPairConfig(a="left_arm", b="right_arm", min_distance=0.01, detection_distance=0.05))
    home = robot.keyframe_q("home")
    target = [FrameTarget("left_wrist", pos=np.array([-0.04364933529323951, 0.33154360324374405,
                                                      0.8293550475549049]))]  # over the shoulder, near the torso

    def ik(restarts: int) -> QPIK:
        return QPIK(robot, IKConfig(collision_pairs=pairs, restarts=restarts, max_iters=80))

    assert not ik(0).solve(target, home).converged  # the first descent stalls against a pair
    ungated, gate = ik(3).solve(target, home), ik(3)
    res = gate.solve(target, home, accept=(0.003, 0.05))
    assert res.converged and ungated.converged and res.iters < ungated.iters
    # clear of every pair: each measured from scratch at the answer
    assert gate.collision is not None
    gate.configuration.update(res.q)
    watched = np.flatnonzero(gate.collision.enabled)
    distances = gate.collision.distances(gate.configuration.data, watched)
    assert (distances >= gate.collision.min_distance[watched] - 1e-6).all()
    # clear() agrees with every pair measured from scratch, in and out of collision
    rng, seen = np.random.default_rng(1), set()
    for _ in range(30):
        gate.configuration.update(np.clip(home + rng.normal(0.0, 0.7, home.shape), robot.lower, robot.upper))
        distances = gate.collision.distances(gate.configuration.data, watched)
        truth = bool((distances >= gate.collision.min_distance[watched] - 1e-6).all())
        assert gate.collision.clear(gate.configuration.data) == truth
        seen.add(truth)
    assert seen == {True, False}


def test_memo_returns_the_same_solve_without_iterating(robot: Robot, kin: Kinematics) -> None:
    pair = CollisionPairConfig(a="left_arm", b="table", min_distance=0.01, detection_distance=0.05)
    cfg = IKConfig(collision_pairs=(pair,), restarts=2, max_iters=80)
    memo, plain = QPIK(robot, cfg, memo=8), QPIK(robot, cfg)
    home = robot.keyframe_q("home")
    target = [FrameTarget("left_wrist", pos=np.array([0.4, 0.25, 1.0]), axis=np.array([0, 0, 1.0]),
                          direction=np.array([1.0, 0, 0]))]
    first, again, reference = memo.solve(target, home), memo.solve(target, home), plain.solve(target, home)
    assert memo.memo is not None and memo.memo.hits == 1
    np.testing.assert_array_equal(first.q, again.q)
    np.testing.assert_array_equal(first.q, reference.q)
    assert again.iters == first.iters and again.q is not first.q
    np.testing.assert_array_equal(memo.configuration.q, first.q)  # left at the answer, as a solve leaves it
    # any other input is another question
    nudged = home.copy()
    nudged[robot.joint_index("LARM_JOINT2")] += 0.01
    memo.solve(target, nudged)
    memo.solve(target, home, good_enough=(1e-3, 1e-2))
    other = [FrameTarget("left_wrist", pos=np.array([0.4, 0.25, 1.001]), axis=np.array([0, 0, 1.0]),
                         direction=np.array([1.0, 0, 0]))]
    memo.solve(other, home)
    memo.solve(target, home, object_poses={"dumbbell": (np.array([0.5, 0.1, 1.0]), np.array([1.0, 0, 0, 0]))})
    memo.step(home, [], 0.02, posture=nudged)  # a step that moved the posture target: the redundancy heads elsewhere
    memo.solve(target, home)
    assert memo.memo.hits == 1


def test_relaxed_descents_are_remembered_across_solves_that_restart_alike(robot: Robot) -> None:
    # An unreachable target: every start's descent without collision rows runs. From a start that differs only in a
    # joint the restarts re-draw, the restarts' descents are the same questions: answered from the memo, and the
    # solve's result is the one a solver without memo gives.
    pair = CollisionPairConfig(a="left_arm", b="table", min_distance=0.01, detection_distance=0.05)
    cfg = IKConfig(collision_pairs=(pair,), restarts=3, max_iters=60)
    memo, plain = QPIK(robot, cfg, memo=16), QPIK(robot, cfg)
    home = robot.keyframe_q("home")
    moved = home.copy()
    moved[robot.joint_index("LARM_JOINT2")] += 0.05
    far = [FrameTarget("left_wrist", pos=np.array([1.5, 0.25, 1.0]))]
    kwargs = {"accept": (0.005, 0.05), "good_enough": (0.0025, 0.025)}
    first = memo.solve(far, home, **kwargs)
    assert memo.relaxed_memo is not None and memo.relaxed_memo.hits == 0 and not first.converged
    second = memo.solve(far, moved, **kwargs)
    assert memo.relaxed_memo.hits == cfg.restarts  # every restart; the first start (moved) is a new question
    reference = plain.solve(far, moved, **kwargs)
    np.testing.assert_array_equal(second.q, reference.q)
    assert (second.pos_err_m, second.iters, second.status) == (reference.pos_err_m, reference.iters, reference.status)


def test_infeasible_start_raises_with_active_limits(robot: Robot) -> None:
    ik = QPIK(robot, IKConfig())
    q0 = robot.keyframe_q("home")
    q0[robot.joint_index("LARM_JOINT1")] = -3.5  # 1.06 rad below its limit, more than one step of 0.3 rad
    with pytest.raises(IKInfeasibleError, match="LARM_JOINT1"):
        ik.solve([FrameTarget("left_wrist", pos=np.array([0.4, 0.2, 1.0]))], q0)


def test_mirrored_targets_give_mirrored_joints(robot: Robot, kin: Kinematics) -> None:
    ik = QPIK(robot, IKConfig())
    m = np.diag([1.0, -1.0, 1.0])
    left = kin.fk("left_wrist", robot.q_from_names({"LARM_JOINT1": -0.8, "LARM_JOINT4": -0.6, "CHEST_JOINT0": 0.2}))
    right_pos = np.array([0.4, -0.3, 1.0])
    targets = [FrameTarget("left_wrist", pos=left.pos, rot=left.rot), FrameTarget("right_wrist", pos=right_pos)]
    mirrored = [
        FrameTarget("right_wrist", pos=m @ left.pos, rot=m @ left.rot @ m),
        FrameTarget("left_wrist", pos=m @ right_pos),
    ]
    home = robot.keyframe_q("home")
    a, b = ik.solve(targets, home), ik.solve(mirrored, home)
    assert a.converged and b.converged
    qa, qb = robot.q_to_names(a.q), robot.q_to_names(b.q)
    flip = ("JOINT0", "JOINT3", "JOINT5")
    for name, value in qa.items():
        other = name.replace("LARM", "X").replace("RARM", "LARM").replace("X", "RARM")
        sign = -1.0 if name.endswith(flip) and name != "HEAD_JOINT1" else 1.0
        assert qb[other] == pytest.approx(sign * value, abs=2e-3), name


def test_wrist_goes_over_table_edge_without_penetration(robot: Robot, kin: Kinematics) -> None:
    """Start with the hand in front of the table below its top; the target is above the table beyond the edge."""
    pair = CollisionPairConfig(a="left_hand", b="table", min_distance=0.01, detection_distance=0.05)
    ik = QPIK(robot, IKConfig(collision_pairs=(pair,), dt=0.05, max_iters=400))
    start = ik.solve([FrameTarget("left_wrist", pos=np.array([0.02, 0.42, 0.80]), axis=np.array([0, 0, 1.0]),
                                    direction=np.array([0, 0, 1.0]))], robot.keyframe_q("home"))  # fmt: skip
    assert start.pos_err_m < 0.01
    target = [FrameTarget("left_wrist", pos=np.array([0.30, 0.35, 0.97]))]
    data, model = ik.configuration.data, ik.model
    table = robot.collision_geoms()["table"][0]
    hand = robot.collision_geoms()["left_hand"]

    def clearance(q: np.ndarray) -> float:
        ik.configuration.update(q)
        return min(mujoco.mj_geomDistance(model, data, g, table, 1.0, None) for g in hand)

    assert clearance(start.q) > 0.01
    # The straight path of the wrist crosses the table top: below it at the edge x = 0.10.
    p0 = kin.fk("left_wrist", start.q).pos
    s = (0.10 - p0[0]) / (target[0].pos[0] - p0[0])
    assert p0[2] + s * (target[0].pos[2] - p0[2]) < 0.875 + 0.055
    q, dists = start.q.copy(), []
    for _ in range(300):
        ik.configuration.update(q)
        q = ik.offline._advance(q, ik.velocity(target, 0.05, ()) * 0.05)
        dists.append(clearance(q))
    assert min(dists) >= 0.01 - 1e-4
    assert np.linalg.norm(kin.fk("left_wrist", q).pos - target[0].pos) < 2e-3
    res = ik.solve(target, start.q)
    assert res.pos_err_m < 2e-3 and clearance(res.q) >= 0.01 - 1e-4


def test_rows_that_cannot_bind_are_dropped_without_changing_the_step(robot: Robot, kin: Kinematics) -> None:
    """The joint-box reach bound only drops collision rows the QP could never make active: same velocity."""
    pairs = tuple(
        CollisionPairConfig(a=a, b=b, min_distance=0.005, detection_distance=0.08)
        for a, b in (("left_arm", "table"), ("right_arm", "table"), ("left_arm", "right_arm"), ("left_arm", "torso"))
    )
    pruned = QPIK(robot, IKConfig(velocity_limit=1.0, collision_pairs=pairs))
    full = QPIK(robot, IKConfig(velocity_limit=1.0, collision_pairs=pairs))
    assert full.collision is not None and pruned.collision is not None
    full.collision.box = None
    rng, home = np.random.default_rng(3), robot.keyframe_q("home")
    dropped = 0
    for _ in range(60):
        q = np.clip(home + rng.normal(0.0, 0.5, robot.nq), robot.lower, robot.upper)
        target = [FrameTarget(f, pos=kin.fk(f, q).pos + rng.normal(0, 0.1, 3)) for f in ("left_wrist", "right_wrist")]
        v_pruned, v_full = pruned.step(q, target, 0.004), full.step(q, target, 0.004)
        assert v_pruned == pytest.approx(v_full, abs=1e-7)
        assert {i for i, _ in pruned.collision.active} <= {i for i, _ in full.collision.active}
        dropped += len(full.collision.active) - len(pruned.collision.active)
    assert dropped > 0


def test_travel_and_sphere_filters_miss_no_pair_within_detection(robot: Robot) -> None:
    """Over a random walk with small and large jumps, the rows are exactly the pairs a brute force finds."""
    pairs = tuple(
        CollisionPairConfig(a=a, b=b, min_distance=0.005, detection_distance=0.06)
        for a, b in (("left_arm", "table"), ("right_arm", "torso"), ("left_arm", "right_arm"), ("head", "left_arm"))
    )
    ik = QPIK(robot, IKConfig(collision_pairs=pairs))
    limit = ik.collision
    assert limit is not None
    limit.box = None  # rows for every pair within detection distance
    rng, q = np.random.default_rng(5), robot.keyframe_q("home")
    model, data = ik.model, ik.configuration.data
    seen = 0
    for k in range(300):
        q = np.clip(q + rng.normal(0.0, 0.3 if k % 25 == 0 else 0.01, robot.nq), robot.lower, robot.upper)
        ik.configuration.update(q)
        limit.compute_qp_inequalities(ik.configuration, 0.004)
        brute = {}
        for i in range(limit.num_pairs):
            det = limit.detection_distance[i]
            d = mujoco.mj_geomDistance(model, data, int(limit.geom1[i]), int(limit.geom2[i]), det, None)
            if d < det:
                brute[i] = d
        got = dict(limit.active)
        assert got.keys() == brute.keys(), k
        assert all(abs(got[i] - brute[i]) < 1e-9 for i in got)
        seen += len(got)
    assert seen > 300, seen  # pairs were within detection distance along the walk


def test_rows_equal_minks_contact_normal_jacobian(robot: Robot) -> None:
    """Every row (static sides skipped) is mink's contact normal Jacobian, sign-flipped as mink does."""
    from mink.limits.collision_avoidance_limit import compute_contact_normal_jacobian

    pairs = tuple(CollisionPairConfig(a=a, b=b, min_distance=0.005, detection_distance=0.06)
                  for a, b in (("left_arm", "table"), ("right_arm", "torso"), ("left_arm", "right_arm"),
                               ("left_arm", "dumbbell")))
    ik = QPIK(robot, IKConfig(collision_pairs=pairs))
    limit = ik.collision
    assert limit is not None
    limit.box = None
    rng, q = np.random.default_rng(7), robot.keyframe_q("home")
    model, data, nv = ik.model, ik.configuration.data, ik.model.nv
    checked = 0
    for _ in range(200):
        q = np.clip(q + rng.normal(0.0, 0.05, robot.nq), robot.lower, robot.upper)
        ik.configuration.update(q)
        cons = limit.compute_qp_inequalities(ik.configuration, 0.004)
        for row, (idx, dist) in zip(cons.G if cons.G is not None else (), limit.active, strict=True):
            g1, g2 = int(limit.geom1[idx]), int(limit.geom2[idx])
            fromto = np.empty(6)
            mujoco.mj_geomDistance(model, data, g1, g2, float(limit.detection_distance[idx]) + 0.05, fromto)
            ref = compute_contact_normal_jacobian(model, data, g1, g2, fromto, np.empty(3), np.empty((3, nv)),
                                                  np.empty((3, nv)))
            assert row == pytest.approx(-ref if dist >= 0 else ref, abs=1e-12)
            checked += 1
    assert checked > 100, checked


def test_scene_overrides_reach_the_ik_collision_model() -> None:
    """An obstacle moved by a scene override is where the IK's collision avoidance sees it."""
    moved = Robot.from_scene("dock_dumbbell", SceneOverrides(poses={"obstacle": BodyPose(pos=(0.45, 0.1, 0.9))}))
    ik = QPIK(moved, IKConfig(collision_pairs=(CollisionPairConfig(a="left_arm", b="obstacle"),)))
    body = ik.model.body("obstacle").id
    assert ik.configuration.data.xpos[body] == pytest.approx([0.45, 0.1, 0.9])
    assert ik.model.body_pos[body] == pytest.approx(moved.model.body_pos[moved.model.body("obstacle").id])


def test_object_poses_move_collision_geometry(robot: Robot) -> None:
    pair = CollisionPairConfig(a="left_arm", b="dumbbell")
    ik = QPIK(robot, IKConfig(collision_pairs=(pair,)))
    ik.set_object_poses({"dumbbell": (np.array([0.9, 0.0, 1.2]), np.array([1.0, 0, 0, 0]))})
    body = ik.model.body("dumbbell").id
    assert ik.configuration.data.xpos[body] == pytest.approx([0.9, 0.0, 1.2])
    with pytest.raises(UnknownNameError, match="dumbbell"):
        ik.set_object_poses({"cube": (np.zeros(3), np.array([1.0, 0, 0, 0]))})


def test_unknown_names_raise(robot: Robot) -> None:
    with pytest.raises(UnknownNameError, match="left_arm"):
        QPIK(robot, IKConfig(collision_pairs=(CollisionPairConfig(a="left_armm", b="table"),)))
    with pytest.raises(UnknownNameError, match="LARM_JOINT0"):
        QPIK(robot, IKConfig(velocity_limit={"LARM_JOINTX": 1.0}))
    with pytest.raises(UnknownNameError):
        QPIK(robot, IKConfig(posture_target={"NOPE": 0.0}))
    ik = QPIK(robot, IKConfig())
    with pytest.raises(UnknownFrameError, match="left_wrist"):
        ik.solve([FrameTarget("left_hnd", pos=np.zeros(3))], robot.keyframe_q("home"))


@pytest.mark.parametrize("solver", ["osqp", "proxqp"])
def test_other_solvers_agree(robot: Robot, solver: str) -> None:
    t = [FrameTarget("right_wrist", pos=np.array([0.45, -0.25, 1.0]))]
    res = QPIK(robot, IKConfig(solver=solver)).solve(t, robot.keyframe_q("home"))
    assert res.converged
    assert worst_errors(t, [(Kinematics(robot).fk("right_wrist", res.q).pos, np.eye(3))])[0] <= 1e-4


def test_both_wrists_one_qp_use_chest(robot: Robot, kin: Kinematics) -> None:
    q_goal = robot.q_from_names({"CHEST_JOINT0": 0.6, "LARM_JOINT1": -0.7, "RARM_JOINT1": -0.5})
    targets = [
        FrameTarget(f, pos=kin.fk(f, q_goal).pos, rot=kin.fk(f, q_goal).rot) for f in ("left_wrist", "right_wrist")
    ]
    res = QPIK(robot, IKConfig()).solve(targets, robot.keyframe_q("home"))
    assert res.converged and res.q[0] > 0.2  # the shared chest turns to serve both wrists


def test_frame_target_validation() -> None:
    with pytest.raises(ConfigError, match="pos"):
        FrameTarget("left_wrist", pos=np.array([1.0, 2.0]))
    with pytest.raises(ConfigError, match="rotation"):
        FrameTarget("left_wrist", rot=np.ones((3, 3)))
    with pytest.raises(ConfigError, match="together"):
        FrameTarget("left_wrist", axis=np.array([0, 0, 1.0]))
    with pytest.raises(ConfigError, match="not both"):
        FrameTarget("left_wrist", rot=np.eye(3), axis=np.array([0, 0, 1.0]), direction=np.array([0, 0, 1.0]))
    with pytest.raises(ConfigError, match="non-zero"):
        FrameTarget("left_wrist", axis=np.zeros(3), direction=np.array([0, 0, 1.0]))
    with pytest.raises(ConfigError, match="needs"):
        FrameTarget("left_wrist")
    with pytest.raises(ConfigError, match="position_cost"):
        FrameTarget("left_wrist", pos=np.zeros(3), position_cost=-1.0)


def test_objective_equals_minks_build_ik(robot: Robot, kin: Kinematics) -> None:
    """The reused-array objective is mink's (H, c) for frame, posture, relative-frame and axis tasks alike."""
    import mink

    from nextage_qp.ik.objective import Objective

    ik = QPIK(robot, IKConfig(lm_damping=0.3))
    objective = Objective(ik.model)
    rng, home = np.random.default_rng(11), robot.keyframe_q("home")
    posture = mink.PostureTask(ik.model, cost=0.05, lm_damping=0.2)
    relative = mink.RelativeFrameTask("left_pad", "site", "right_pad", "site", position_cost=2.0,
                                      orientation_cost=0.5)
    axis = mink.AxisAlignTask("right_tool", "site", lm_damping=0.1)
    for k in range(30):
        q = np.clip(home + rng.normal(0.0, 0.4, robot.nq), robot.lower, robot.upper)
        ik.configuration.update(q)
        goal = np.clip(q + rng.normal(0.0, 0.3, robot.nq), robot.lower, robot.upper)
        targets = [FrameTarget(f, pos=kin.fk(f, goal).pos, rot=kin.fk(f, goal).rot if k % 2 else None)
                   for f in ("left_wrist", "right_wrist")]
        posture.set_target(goal)
        relative.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(np.eye(3)),
                                                                   rng.normal(0, 0.1, 3)))
        axis.set_axis(np.array([1.0, 0, 0]))
        axis.set_target(np.array([0.0, 0.0, -1.0]))
        tasks = [*ik.tasks.frames(targets, ik.configuration.data), posture, relative, axis][: 3 + k % 3]
        H, c = objective.build(ik.configuration, tasks, 1e-6)
        ref = mink.build_ik(ik.configuration, tasks, 0.004, damping=1e-6, limits=[])
        assert H == pytest.approx(ref.P, rel=1e-10, abs=1e-12)
        assert c == pytest.approx(ref.q, rel=1e-10, abs=1e-12)


def test_step_equals_plain_minks_solve_ik(robot: Robot, kin: Kinematics) -> None:
    """Without collision pairs, one IK step is plain mink.solve_ik's with the same tasks and limits."""
    import mink

    cfg = IKConfig(velocity_limit=1.0, limit_margin=0.0)
    ik = QPIK(robot, cfg)
    config = mink.Configuration(ik.model)
    posture = mink.PostureTask(ik.model, cost=cfg.posture_cost)
    posture.set_target(robot.keyframe_q("home"))
    names = [ik.model.joint(i).name for i in range(ik.model.njnt)]
    limits = [mink.ConfigurationLimit(ik.model, gain=cfg.limit_gain, min_distance_from_limits=0.0),
              mink.VelocityLimit(ik.model, dict.fromkeys(names, 1.0))]
    rng, home = np.random.default_rng(2), robot.keyframe_q("home")
    for _ in range(40):
        q = np.clip(home + rng.normal(0.0, 0.4, robot.nq), robot.lower, robot.upper)
        goal = np.clip(q + rng.normal(0.0, 0.2, robot.nq), robot.lower, robot.upper)
        targets = [FrameTarget(f, pos=kin.fk(f, goal).pos, rot=kin.fk(f, goal).rot)
                   for f in ("left_wrist", "right_wrist")]
        v = ik.step(q, targets, 0.004)
        config.update(q)
        tasks = [*ik.tasks.frames(targets, config.data), posture]
        ref = mink.solve_ik(config, tasks, 0.004, "daqp", damping=cfg.damping, limits=limits)
        assert v == pytest.approx(ref, abs=1e-7)


def test_axis_targets_are_set_again_whenever_they_change(robot: Robot) -> None:
    """The task cache skips mink's setters for an unchanged axis target, and only then."""
    ik = QPIK(robot, IKConfig())
    data = ik.configuration.data
    down, side = np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0])
    for direction, cost in ((down, None), (down, None), (side, None), (side, 0.3), (down, 0.3)):
        target = FrameTarget("left_wrist", pos=np.array([0.4, 0.2, 1.0]), axis=np.array([1.0, 0.0, 0.0]),
                             direction=direction, orientation_cost=cost)
        (_, axis_task) = ik.tasks.frames([target], data)
        np.testing.assert_array_equal(axis_task.target_dir, direction)
        np.testing.assert_array_equal(axis_task.axis, [1.0, 0.0, 0.0])
        assert axis_task.cost[0] == (ik.config.orientation_cost if cost is None else cost)


def test_objective_of_a_frame_and_its_axis_target_equals_minks(robot: Robot, kin: Kinematics) -> None:
    """A position target with a tool axis (a frame task, then an axis task on the same frame) is mink's (H, c)."""
    import mink

    from nextage_qp.ik.objective import Objective

    ik = QPIK(robot, IKConfig(lm_damping=0.3))
    objective = Objective(ik.model)
    rng, home = np.random.default_rng(5), robot.keyframe_q("home")
    for _ in range(20):
        q = np.clip(home + rng.normal(0.0, 0.4, robot.nq), robot.lower, robot.upper)
        ik.configuration.update(q)
        targets = [FrameTarget(f, pos=kin.fk(f, home).pos + rng.normal(0, 0.05, 3), axis=rng.normal(size=3),
                               direction=rng.normal(size=3)) for f in ("left_wrist", "right_wrist")]
        tasks = ik.tasks.frames(targets, ik.configuration.data)
        assert [type(t) for t in tasks] == [mink.FrameTask, mink.AxisAlignTask] * 2
        H, c = objective.build(ik.configuration, [*tasks, ik.posture], 1e-6)
        ref = mink.build_ik(ik.configuration, [*tasks, ik.posture], 0.004, damping=1e-6, limits=[])
        assert H == pytest.approx(ref.P, rel=1e-10, abs=1e-12)
        assert c == pytest.approx(ref.q, rel=1e-10, abs=1e-12)


def test_a_descent_within_good_enough_ends_at_its_first_step_without_progress(robot: Robot) -> None:
    # With LM damping and a posture cost a descent creeps to a plateau above pos_tol (here ~1.4 mm) and stalls
    # there after stall_iters steps without 1 % progress. A caller content with millimetres (good_enough) gets its
    # answer back at the first such step once the errors are within good_enough.
    ik = QPIK(robot, IKConfig(restarts=0, lm_damping=0.1, posture_cost=0.01))
    home = robot.keyframe_q("home")
    target = [FrameTarget("left_wrist", pos=np.array([0.55, 0.35, 0.95]), rot=np.eye(3))]
    full = ik.solve(target, home)
    assert full.status == "stalled" and full.pos_err_m > ik.config.pos_tol  # a plateau above the tolerance
    enough = (2.0 * full.pos_err_m, 2.0 * full.rot_err_rad + 1e-3)
    short = ik.solve(target, home, good_enough=enough)
    assert short.status == "stalled" and short.iters < full.iters - ik.config.stall_iters // 2
    assert short.pos_err_m <= enough[0] and short.rot_err_rad <= enough[1]
    # a target it reaches is unchanged: the descent converges before good_enough matters
    reached = [FrameTarget("left_wrist", pos=np.array([0.4, 0.2, 1.0]))]
    plain = QPIK(robot, IKConfig(restarts=0))
    a, b = plain.solve(reached, home), plain.solve(reached, home, good_enough=(1e-3, 1e-2))
    assert a.converged and b.converged
    np.testing.assert_array_equal(a.q, b.q)


def test_a_group_paired_with_itself_keeps_its_own_links_apart_but_not_where_they_join(robot: Robot) -> None:
    """An arm with itself: rows for its links that can fold onto each other, none for a parent and its child (they
    touch at their joint) nor for geoms nearer than min_distance at home (they could never be kept apart)."""
    from nextage_qp.ik.collision import apart_at

    pair = CollisionPairConfig(a="left_arm", b="left_arm", min_distance=0.005, detection_distance=0.03)
    ik = QPIK(robot, IKConfig(collision_pairs=(pair,)))
    m = ik.model
    assert ik.collision is not None and ik.collision.geom1.size > 20
    d = mujoco.MjData(m)
    d.qpos[:] = ik.full(robot.keyframe_q("home"))
    mujoco.mj_kinematics(m, d)
    bodies = set()
    for a, b in zip(ik.collision.geom1, ik.collision.geom2, strict=True):
        ba, bb = int(m.geom_bodyid[a]), int(m.geom_bodyid[b])
        assert ba != bb and m.body_parentid[ba] != bb and m.body_parentid[bb] != ba
        assert mujoco.mj_geomDistance(m, d, int(a), int(b), 0.1, None) >= 0.005
        bodies |= {m.body(ba).name, m.body(bb).name}
    assert {"LARM_JOINT1_Link", "LARM_JOINT5_Link"} <= bodies  # the upper arm and the hand
    assert not any(n.startswith("RARM") for n in bodies)
    arm = ik.groups["left_arm"]
    assert apart_at(m, d.qpos, arm, arm, 1.0) == []  # nothing is a metre from the rest of its arm


def test_geoms_that_touch_at_home_are_left_out_of_a_pair_of_two_groups(robot: Robot) -> None:
    """A shoulder that touches the torso where it is mounted (a drafted PR2's, 6 cm inside it) would freeze the arm
    under an arm-torso pair: such geom pairs are left out, judged at home, the others kept."""
    pair = CollisionPairConfig(a="left_arm", b="torso", min_distance=0.15, detection_distance=0.2)
    ik = QPIK(robot, IKConfig(collision_pairs=(pair,)))
    m = ik.model
    d = mujoco.MjData(m)
    d.qpos[:] = ik.full(robot.keyframe_q("home"))
    mujoco.mj_kinematics(m, d)
    kept = list(zip(ik.collision.geom1, ik.collision.geom2, strict=True))
    assert kept and all(mujoco.mj_geomDistance(m, d, int(a), int(b), 1.0, None) >= 0.15 for a, b in kept)
    everything = QPIK(robot, IKConfig(collision_pairs=(pair.model_copy(update={"min_distance": 0.0}),)))
    assert everything.collision.geom1.size > len(kept)  # the near ones were there to leave out
