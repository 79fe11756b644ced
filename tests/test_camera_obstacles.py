"""``perception.obstacles: camera``: the controller knows the clutter only as the camera's map shows it."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner
from nextage_qp.planning.world import CollisionWorld
from nextage_qp.scene.seen_obstacles import PARK, SeenBoxes, clutter_geoms, pool_geoms
from nextage_qp.sensing.camera.occupancy import OCCUPIED_STATE, VoxelMap

CAMERA = ["perception.source=camera", "perception.obstacles=camera"]


def _camera_runner(task: str) -> Runner:
    """A run of ``configs/TASK.yaml`` with camera obstacles, or the test skipped without offscreen rendering."""
    try:
        return Runner(load_config(f"configs/{task}.yaml", CAMERA), task)
    except Exception as exc:  # no offscreen rendering on this machine
        if "offscreen rendering unavailable" in str(exc):
            pytest.skip(str(exc))
        raise


@pytest.fixture(scope="module")
def runner() -> Runner:
    pytest.importorskip("mujoco")
    return _camera_runner("push_clutter")


def _wrist(robot, qpos: np.ndarray) -> np.ndarray:
    """The left wrist's position [m] in a state of the scene."""
    m = robot.model
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(m, d)
    return d.xpos[m.body("LARM_JOINT5_Link").id].copy()


def test_the_controllers_models_hold_no_clutter_the_physics_all_of_it(runner):
    physics, controlled = runner.robot.model, runner.controlled.model
    clutter = clutter_geoms(physics)
    assert len(clutter) == 6
    assert all(physics.geom_contype[g] for g in clutter)  # the physics meets every piece
    for model in (controlled, runner.ik.model):  # the IK's kinematic copy is compiled anew: blinded too
        assert not model.geom_contype[clutter].any() and not model.geom_conaffinity[clutter].any()
        assert np.allclose(model.geom_pos[clutter], PARK)
    # The controller's clutter group is the pool; the physics' is the clutter (the pool collides with nothing there).
    assert set(runner.ik.groups["clutter"]) == set(pool_geoms(controlled).tolist())
    assert set(runner.robot.collision_geoms()["clutter"]) == set(clutter.tolist())


def test_a_robots_collision_groups_follow_its_geoms_collision_bits(runner):
    """Kept between calls (a dict of its own each time), and made anew when a geom's collision bits change."""
    physics, controlled = runner.robot, runner.controlled
    first = physics.collision_geoms()
    first["clutter"] = ()  # the caller's copy
    assert physics.collision_geoms()["clutter"] and controlled.collision_geoms()["clutter"] != \
        physics.collision_geoms()["clutter"]
    g = physics.collision_geoms()["clutter"][0]
    bits = physics.model.geom_contype[g], physics.model.geom_conaffinity[g]
    physics.model.geom_contype[g] = physics.model.geom_conaffinity[g] = 0
    try:
        assert g not in physics.collision_geoms()["clutter"]
    finally:
        physics.model.geom_contype[g], physics.model.geom_conaffinity[g] = bits
    assert g in physics.collision_geoms()["clutter"]


def test_a_state_inside_a_clutter_piece_is_valid_for_the_controller_until_the_map_shows_it(runner):
    """The planner's validity check never reads a clutter body: only the boxes the camera gives block a state."""
    physics = runner.robot.model
    q = runner.q0.copy()
    qpos = runner.sim.data.qpos.copy()
    wrist = _wrist(runner.robot, qpos)
    # Move a clutter piece onto the wrist in a copy of the physics: the physics' own world sees it, the controller's
    # world (made from the controller's model, as the run's planner is) does not.
    body = physics.body("clutter_0").id
    truth_world = CollisionWorld(runner.robot, 0.01)
    truth_world.model.body_pos[body] = wrist
    truth_world.set_world({}, q, qpos=qpos)
    assert truth_world.first_collision(q) is not None
    blind_world = CollisionWorld(runner.controlled, 0.01)
    blind_world.model.body_pos[body] = wrist  # the piece's pose read from anywhere would not matter: it is parked
    blind_world.set_world({}, q, qpos=qpos)
    assert blind_world.first_collision(q) is None
    seen = SeenBoxes()
    assert seen.set([(wrist, np.full(3, 0.03))])
    seen.sync(blind_world.model)
    hit = blind_world.first_collision(q)
    assert hit is not None and "seen_" in hit.body1 + hit.body2
    assert seen.set([(wrist + np.array([0.0, 0.0, 0.4]), np.full(3, 0.03))])  # the box moves away: free again
    seen.sync(blind_world.model)
    assert blind_world.first_collision(q) is None
    assert not seen.set([(wrist + np.array([0.0, 0.0, 0.4]), np.full(3, 0.03))])  # the same boxes: no new generation
    assert not seen.sync(blind_world.model)


def test_the_iks_collision_rows_take_a_box_written_in_place_and_forget_its_old_distance(runner):
    """A pool geom resized where it stands: the IK measures its pairs anew (no stale distance bound)."""
    ik = runner.ik
    q = runner.q0.copy()
    wrist = _wrist(runner.robot, runner.sim.data.qpos.copy())
    seen = SeenBoxes()
    centre = wrist + np.array([0.0, 0.0, 0.2])
    clear = []
    for half in (0.01, 0.17):  # first 19 cm clear of the wrist's centre, then grown round it where it stands
        seen.set([(centre, np.full(3, half))])
        seen.sync(ik.model)
        ik.world_changed()
        ik.load(q)
        data = ik.configuration.data
        mujoco.mj_kinematics(ik.model, data)
        clear.append(ik.collision.clear(data))
    assert clear == [True, False]


def test_the_map_forgets_obstacle_evidence_where_a_tracked_object_stands():
    vmap = VoxelMap(np.zeros(3), np.full(3, 0.3), 0.015)
    vmap.logodds[:], vmap.seen[:] = 3.0, True  # everything occupied
    vmap.explain(np.full(3, 0.15), 0.05)
    state = vmap.state()
    ijk, _ = vmap.index(np.array([[0.15, 0.15, 0.15], [0.15, 0.15, 0.19], [0.05, 0.05, 0.05]]))
    assert state[tuple(ijk[0])] != OCCUPIED_STATE and state[tuple(ijk[1])] != OCCUPIED_STATE
    assert state[tuple(ijk[2])] == OCCUPIED_STATE


@pytest.mark.parametrize(("extra", "words"), [
    (["perception.source=truth"], "poses come from truth"),
    (["perception.depth=stereo"], "with stereo depth"),
])
def test_camera_obstacles_without_rendered_camera_depth_are_refused_in_one_line(extra, words):
    from nextage_qp.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        Runner(load_config("configs/push_clutter.yaml", [*CAMERA, *extra]), "push_clutter")
    message = str(err.value)
    assert "perception.obstacles: camera" in message and words in message and "\n" not in message


def test_a_free_spot_with_camera_obstacles_is_chosen_among_the_boxes_the_camera_gave():
    """The target is not placed before the run (nothing is seen yet) but at the start of the first phase naming it,
    among the seen boxes alone: a box where the spot was pushes it away by the clearance."""
    from nextage_qp.manipulation.runner import place_spot

    runner = Runner(load_config("configs/place_free_spot.yaml", CAMERA), "place_free_spot")
    assert not runner.free_spots and [r[0] for r in runner._unplaced] == ["box_target"]
    request = runner._unplaced[0]
    clearance = request[3].clearance
    blind = place_spot(runner.controlled, request, (), "place_free_spot")  # nothing seen
    seen = SeenBoxes()
    seen.set([(np.array([*blind.pos, 0.95]), np.array([0.02, 0.02, 0.05]))])
    seen.sync(runner.controlled.model)
    moved = place_spot(runner.controlled, request, (), "place_free_spot")
    assert moved.clearance >= clearance
    assert np.linalg.norm(moved.pos - blind.pos) >= clearance  # the box's half-size and the object's aside
    physics = runner.robot.model
    assert np.allclose(physics.body_pos[physics.geom_bodyid[pool_geoms(physics)]], PARK)  # the physics' pool parked


def test_a_piece_standing_at_an_angle_gets_a_box_turned_with_it():
    """A 12 x 4 cm footprint at 30 deg: the oriented box holds every voxel's corner within a voxel of the piece's own
    footprint, a third smaller than the axis-aligned box of its voxels."""
    vmap = VoxelMap(np.zeros(3), np.full(3, 0.4), 0.01)
    yaw = np.radians(30.0)
    axes = np.array([[np.cos(yaw), np.sin(yaw)], [-np.sin(yaw), np.cos(yaw)]])
    local = (vmap.centres[:, :2] - 0.2) @ axes.T
    inside = (np.abs(local[:, 0]) <= 0.06) & (np.abs(local[:, 1]) <= 0.02) & (vmap.centres[:, 2] < 0.1)
    vmap.logodds.reshape(-1)[inside] = 3.0
    vmap.seen.reshape(-1)[inside] = True
    (centre, half, turned), = vmap.oriented_boxes()
    (_, aligned), = vmap.boxes(pad=0.0)
    assert abs(np.degrees(turned) - 30.0) <= 3.0
    assert np.all(half[:2] <= np.array([0.06, 0.02]) + vmap.cell)
    assert half[0] * half[1] < 0.75 * aligned[0] * aligned[1]
    cells = np.argwhere(vmap.state() == OCCUPIED_STATE)
    corners = np.array([(cells[:, :2] + [a, b]) * vmap.cell for a in (0, 1) for b in (0, 1)]).reshape(-1, 2)
    rel = (corners - centre[:2]) @ np.array([[np.cos(turned), np.sin(turned)], [-np.sin(turned), np.cos(turned)]]).T
    assert np.all(np.abs(rel) <= half[:2] + 1e-9)


def test_the_controller_keeps_what_it_saw_before_the_space_it_never_saw():
    """The pool holds the seen boxes first (largest first), then the never-seen space's, up to its size."""
    from nextage_qp.scene.seen_obstacles import POOL

    def box(x: float, half: float):
        return np.array([x, 0.0, 1.0]), np.full(3, half), 0.0

    seen = SeenBoxes()
    seen.set([box(0.1 * k, 0.01) for k in range(POOL - 2)], [box(-1.0 - k, 0.2) for k in range(5)])
    halves = [float(h[0]) for _, h, _ in seen.boxes]
    assert len(halves) == POOL and halves[: POOL - 2] == [0.01] * (POOL - 2) and halves[POOL - 2:] == [0.2, 0.2]
    assert seen.dropped == 3


def test_before_the_first_phase_the_head_looks_over_the_work_region_and_plans_see_what_they_sweep():
    """The scan turns the head to each of its points and leaves the map seeing more of the space over the table;
    never-seen space in the work region joins the controller's obstacles (unless ``perception.unknown: free``)."""
    runner = _camera_runner("push_clutter")
    runner._find_objects()
    q0 = runner.sim.data.qpos[runner.robot.qpos_idx].copy()
    runner._scan()
    scan = runner.scan
    assert scan is not None and scan["looked_at"] == scan["points"] == 9
    assert scan["seen_share_after"] > scan["seen_share_before"] + 0.1
    arms = [j for j, n in enumerate(runner.robot.joint_names) if "ARM" in n]
    assert np.allclose(runner.sim.data.qpos[runner.robot.qpos_idx][arms], q0[arms], atol=0.02)  # the arms held still
    mapper = runner.camera.mapper
    unseen = mapper.unknown_boxes()
    kept = {tuple(np.round(c, 9)) for c, _, _ in runner.seen.boxes}
    assert all(tuple(np.round(c, 9)) in kept for c, _, _ in unseen)
    lo, hi = mapper.work
    assert all(lo[0] - 0.02 <= c[0] <= hi[0] + 0.02 and lo[1] - 0.02 <= c[1] <= hi[1] + 0.02 for c, _, _ in unseen)
    right = [j for j, n in enumerate(runner.robot.joint_names) if n.startswith("RARM")][:3]
    goal = runner.q0 + np.where(np.isin(np.arange(len(runner.q0)), right), -0.2, 0.0)
    plan = runner.view.plan_path(runner.q0, goal, escape=True)  # (the map's boxes may graze a hand at home)
    assert plan.found and len(runner.view.swept_seen) == 1 and 0.0 < runner.view.swept_seen[0] <= 1.0
    assert len(runner.view.swept_met) == 1  # the obstacles in that space, scored for the report
    report = runner.summary()["swept_seen"]
    assert report["obstacles_met"] == len(runner.view.swept_met[0]) and report["legs"] == 1
    # A swept space holding one tall obstacle: met and detected once the map holds it; standing in never-seen space
    # over the work region, unknown (planned around as occupied); in seen free space, missed.
    model, data = runner.camera.world
    tall = max((b for b in range(model.nbody) if model.body(b).name.startswith("clutter_")),
               key=lambda b: float(data.xpos[b][2]))
    name, centre = model.body(tall).name, data.xpos[tall].copy()
    lo, hi = centre - 0.01, centre + 0.01
    [met] = [o for o in mapper.met(model, data, lo, hi) if o["name"] == name]
    assert met == {"name": name, "detected": True, "unknown": False}
    assert mapper.met(model, data, np.array([0.0, 0.0, -1.0]), np.array([0.1, 0.1, -0.9])) == []  # nothing there
    geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == tall]
    inside = np.zeros(len(mapper.map.centres), dtype=bool)
    for g in geoms:
        local = (mapper.map.centres - data.geom_xpos[g]) @ data.geom_xmat[g].reshape(3, 3)
        inside |= np.all(np.abs(local - model.geom_aabb[g, :3]) <= model.geom_aabb[g, 3:] + 0.015, axis=1)
    mapper.map.logodds.reshape(-1)[inside] = -1.0  # seen free: missed
    [met] = [o for o in mapper.met(model, data, lo, hi) if o["name"] == name]
    assert not met["detected"] and not met["unknown"]
    mapper.map.seen.reshape(-1)[inside] = False  # never seen: unknown in the work region, missed beyond it
    mapper.places = [(centre[:2] + 0.2, centre[:2] + 0.4)]
    [met] = [o for o in mapper.met(model, data, lo, hi) if o["name"] == name]
    assert not met["detected"] and not met["unknown"]
    mapper.places = [(centre[:2] - 0.2, centre[:2] + 0.2)]
    [met] = [o for o in mapper.met(model, data, lo, hi) if o["name"] == name]
    assert met == {"name": name, "detected": False, "unknown": True}
    runner.camera.close()


@pytest.mark.parametrize("extra", [["perception.source=truth"], ["perception.source=camera", "perception.look_at=false"],
                                   ["perception.source=camera"]])
def test_a_scan_with_no_map_to_scan_for_or_no_head_to_look_with_is_refused_in_one_line(extra):
    from nextage_qp.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        Runner(load_config("configs/push_cube.yaml", ["perception.scan=true", *extra]), "push_cube")
    message = str(err.value)
    assert "perception.scan" in message and "perception.map: true" in message and "\n" not in message


def test_a_free_spots_region_beyond_the_work_region_is_mapped_and_its_unseen_space_occupied():
    """The free-spot task's region reaches past the work region (and the map's margin round it): the map covers it,
    and before anything is seen its space is occupied for the free-spot choice and the planner, as the work region's."""
    runner = _camera_runner("place_free_spot")
    mapper = runner.camera.mapper
    (x0, y0), (x1, y1) = runner.cfg.scene.poses["box_target"].free_spot.region
    top = mapper.map.lo + np.array(mapper.map.shape) * mapper.map.cell
    assert y1 > mapper.work[1][1] + 0.15  # beyond the work region and the margin a map has round it
    assert mapper.map.lo[0] <= x0 and mapper.map.lo[1] <= y0 and top[0] >= x1 and top[1] >= y1
    unseen = mapper.unknown_boxes()  # nothing seen yet: over the work region and the spot's region
    for x, y in ((x0 + 0.01, y1 - 0.01), (x1 - 0.01, y1 - 0.01), (0.5 * (x0 + x1), 0.5 * (y0 + y1))):
        assert any(np.all(np.abs(np.array([x, y]) - c[:2]) <= h[:2] + 1e-6) for c, h, _ in unseen), (x, y)
    runner.camera.close()


def test_the_map_covers_the_table_within_the_arms_reach_not_only_the_work_region(runner):
    """An elbow swings past the work region: a piece of clutter it may meet there is mapped (an obstacle the map does
    not cover is never in the controller's world). The map covers the table as far as the arms' reach spheres go."""
    from nextage_qp.kinematics.frames import Kinematics

    mapper = runner.camera.mapper
    lo, top = mapper.map.lo, mapper.map.lo + np.array(mapper.map.shape) * mapper.map.cell
    kin, q = Kinematics(runner.robot), runner.robot.keyframe_q("zero")
    centre, radius, _ = kin.reach("left_wrist", q)
    assert top[1] >= min(centre[1] + radius, 1.0) and lo[1] <= max(centre[1] - radius, -1.0)
    assert mapper.work[1][1] + 0.15 < 0.55 < top[1]  # where such an elbow met a piece the old bounds left out
    assert lo[0] >= 0.1 - 1e-9  # not beyond the table's near edge
