"""The occupancy map from depth frames: seen-through space is free, hidden space unknown, the robot filtered out."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from nextage_qp.sensing.camera.occupancy import FREE, OCCUPIED_STATE, UNKNOWN, VoxelMap, self_filter
from nextage_qp.sensing.camera.pixels import backproject

SCENE = """
<mujoco>
  <worldbody>
    <geom name="table" type="plane" size="10 10 0.1"/>
    {boxes}
  </worldbody>
</mujoco>
"""
FRONT = '<geom name="front" type="box" pos="0.5 0 0.05" size="0.03 0.06 0.05"/>'
HIDDEN = '<geom name="hidden" type="box" pos="0.62 0 0.04" size="0.02 0.02 0.04"/>'
K = np.array([[60.0, 0.0, 40.0], [0.0, 60.0, 30.0], [0.0, 0.0, 1.0]])  # 80 x 60 pixels
LO, HI = np.array([0.3, -0.2, 0.0]), np.array([0.8, 0.2, 0.2])


def _looking(direction: np.ndarray) -> np.ndarray:
    """A camera rotation (MuJoCo's: x right, y up, looking along -z) looking level along ``direction``."""
    z = -direction / np.linalg.norm(direction)
    y = np.array([0.0, 0.0, 1.0])
    return np.stack([np.cross(y, z), y, z], axis=1)


def _depth(xml: str, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """A depth image (60 x 80, along the optical axis; NaN: no return) of a scene, ray by ray."""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    out = np.full((60, 80), np.nan)
    geom = np.zeros(1, dtype=np.int32)
    for r in range(60):
        for c in range(80):
            v = rot @ np.array([(c + 0.5 - K[0, 2]) / K[0, 0], -(r + 0.5 - K[1, 2]) / K[1, 1], -1.0])
            dist = mujoco.mj_ray(m, d, pos, v / np.linalg.norm(v), None, 1, -1, geom)
            if dist >= 0:
                out[r, c] = dist / np.linalg.norm(v)
    return out


def _above_table(depth: np.ndarray, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Pixels whose points stand over the table (z = 0) by more than 5 mm: what may be an obstacle."""
    from nextage_qp.sensing.camera.pixels import plane_height

    with np.errstate(invalid="ignore"):
        return plane_height(depth, K, pos, rot, np.array([0.0, 0.0, 1.0]), 0.0) > 0.005


def _state_at(vmap: VoxelMap, point) -> int:
    ijk, inside = vmap.index(np.array([point]))
    assert inside[0]
    return int(vmap.state()[tuple(ijk[0])])


@pytest.fixture(scope="module")
def side_view():
    xml = SCENE.format(boxes=FRONT + HIDDEN)
    pos, rot = np.array([0.2, 0.0, 0.06]), _looking(np.array([1.0, 0.0, 0.0]))
    return xml, pos, rot, _depth(xml, pos, rot)


def test_space_seen_through_is_free_a_surface_occupied_and_what_hides_behind_it_unknown(side_view):
    _, pos, rot, depth = side_view
    vmap = VoxelMap(LO, HI, cell=0.015)
    vmap.integrate(depth, K, pos, rot, _above_table(depth, pos, rot))
    assert _state_at(vmap, (0.40, 0.0, 0.05)) == FREE  # between the camera and the front box
    assert _state_at(vmap, (0.471, 0.0, 0.05)) == OCCUPIED_STATE  # the front box's face
    assert _state_at(vmap, (0.62, 0.0, 0.04)) == UNKNOWN  # the box behind it: not seen, so not free
    assert _state_at(vmap, (0.62, 0.15, 0.025)) == FREE  # beside the front box the view reaches the table beyond
    assert vmap.seen_share(np.array([0.6, -0.02, 0.0]), np.array([0.64, 0.02, 0.08])) == 0.0


def test_a_second_view_shows_the_hidden_box_and_the_boxes_cover_both(side_view):
    xml, pos, rot, depth = side_view
    vmap = VoxelMap(LO, HI, cell=0.015)
    vmap.integrate(depth, K, pos, rot, _above_table(depth, pos, rot))
    pos2, rot2 = np.array([0.62, -0.45, 0.06]), _looking(np.array([0.0, 1.0, 0.0]))  # from the side
    depth2 = _depth(xml, pos2, rot2)
    vmap.integrate(depth2, K, pos2, rot2, _above_table(depth2, pos2, rot2))
    assert _state_at(vmap, (0.62, -0.019, 0.04)) == OCCUPIED_STATE
    boxes = vmap.boxes(pad=0.01)
    for point in ((0.471, 0.0, 0.05), (0.62, -0.019, 0.04)):
        assert any(np.all(np.abs(np.array(point) - c) <= h) for c, h in boxes), point
    # unseen space counts when asked: what both boxes hide, from both views, comes back as boxes too
    shadow = (0.62, 0.05, 0.03)
    assert _state_at(vmap, shadow) == UNKNOWN
    behind = (np.array([0.57, 0.025, 0.0]), np.array([0.67, 0.09, 0.06]))
    unseen = vmap.boxes(pad=0.0, unknown_in=behind)
    assert any(np.all(np.abs(np.array(shadow) - c) <= h) for c, h in unseen)
    assert not any(np.all(np.abs(np.array(shadow) - c) <= h) for c, h in boxes)


def test_an_obstacle_taken_away_is_free_again_after_a_few_views(side_view):
    _, pos, rot, depth = side_view
    vmap = VoxelMap(LO, HI, cell=0.015)
    vmap.integrate(depth, K, pos, rot, _above_table(depth, pos, rot))
    face = (0.471, 0.0, 0.05)
    assert _state_at(vmap, face) == OCCUPIED_STATE
    gone = _depth(SCENE.format(boxes=""), pos, rot)
    mask = _above_table(gone, pos, rot)
    for _ in range(12):
        vmap.integrate(gone, K, pos, rot, mask)
    assert _state_at(vmap, face) == FREE


def test_the_self_filter_drops_the_robots_pixels_and_keeps_what_stands_in_front_of_it():
    depth = np.array([[0.5, 0.8, 0.8, np.nan]])
    robot = np.array([[np.nan, 0.81, 1.2, 0.5]])
    keep = self_filter(depth, robot, tolerance=0.02, pad=0)
    assert keep.tolist() == [[True, False, True, False]]  # no robot; the robot itself; in front of it; no depth


def test_over_a_run_the_self_filter_leaves_no_robot_voxel_in_the_map():
    """The default push seen by the head camera every 0.5 s: after the self-filter (the robot's own model rendered at
    its joints) and the table's removal, every point left is the cube's, and every occupied voxel lies at the cube."""
    from pathlib import Path

    from nextage_qp.manipulation.config import load_config
    from nextage_qp.manipulation.placement import table_top
    from nextage_qp.manipulation.runner import Runner
    from nextage_qp.sensing.camera.pixels import backproject, plane_height
    from nextage_qp.sensing.camera.render import RobotCamera, render_problem

    if render_problem() is not None:
        pytest.skip(render_problem())
    push = Path(__file__).resolve().parents[1] / "configs" / "push_cube.yaml"
    # the head follows the cube; without hand cameras the push stops to look, and the head sees the cube often
    runner = Runner(load_config(push, ["perception.source=camera", "perception.hand_cameras=[]"]), str(push))
    robot = runner.robot
    camera = RobotCamera(robot.model, "head_rgbd", robot.description.cameras["head_rgbd"], robot, seed=0)
    top = table_top(robot, runner.sim.data)[0]
    vmap = VoxelMap(np.array([0.1, -0.5, top - 0.02]), np.array([0.9, 0.5, top + 0.4]), cell=0.015)
    cube = robot.model.body("cube").id
    seen_at: list[np.ndarray] = []
    stray: list[float] = []
    robot_pixels = []

    def look(run, phase):
        if round(run.sim.time / 0.02) % 25:
            return
        pos, rot = camera.pose(robot.get_q(run.sim.data))
        depth, own = camera.depth(run.sim.data), camera.own()
        with np.errstate(invalid="ignore"):
            keep = self_filter(depth, own) & (plane_height(depth, camera.K, pos, rot, np.array([0.0, 0, 1]), top) > 0.01)
        robot_pixels.append(int((np.isfinite(own) & np.isfinite(depth)).sum()))
        centre = run.sim.data.xpos[cube].copy()
        seen_at.append(centre)
        r, c = np.nonzero(keep)
        points = backproject(depth, camera.K, pos, rot, r, c)
        if len(points):
            far = np.linalg.norm(points - centre, axis=1)
            stray.append(float(np.sort(far)[-3:].min()) if len(far) >= 3 else 0.0)  # a speck of one or two aside
        vmap.integrate(depth, camera.K, pos, rot, keep)

    try:
        result = runner.run(on_tick=look)
    finally:
        camera.close()
    assert result.success and len(seen_at) > 20
    assert max(robot_pixels) > 1000  # the arms were in view
    half = float(np.linalg.norm(robot.model.geom_size[robot.model.geom("cube").id]))  # 61 mm
    assert max(stray) < half + 0.02  # every point kept is the cube's (its half-diagonal, and the depth's noise)
    occupied = vmap.occupied_points()
    assert len(occupied) > 0
    nearest = np.min(np.linalg.norm(occupied[:, None, :] - np.array(seen_at)[None], axis=2), axis=1)
    assert nearest.max() < half + 2 * vmap.cell  # no voxel of the robot: all of them where the cube was


def test_the_camera_maps_the_clutter_it_sees_and_nothing_it_was_told_about():
    """perception.map: a few frames of the head camera over the clutter push's table, scored against the scene."""
    from pathlib import Path

    from test_vision import PROBLEM, aimed_scene

    if PROBLEM is not None:
        pytest.skip(PROBLEM)
    from nextage_qp.sensing.camera.source import CameraMeasurer

    clutter = Path(__file__).resolve().parents[1] / "configs" / "push_clutter.yaml"
    cfg, robot, data, q = aimed_scene("box", 0.33, 0.0, ("perception.source=camera", "perception.map=true",
                                                         "scene.clutter.seed=4", "scene.clutter.count=8"), clutter)
    camera = CameraMeasurer(cfg.perception, robot, data, lambda t: q, seed=0)
    try:
        for k in range(3):
            camera(k / 15, {"cube": None})  # untracked: whole frames, which the map takes
        report = camera.report()["map"]
    finally:
        camera.close()
    assert report["frames"] == 3
    assert report["obstacles_present"] >= 3  # the pieces in view
    assert report["obstacles_detected"] == report["obstacles_present"]
    assert report["false_occupied_cm3"] < 5.0  # neither the robot, the table nor the cube


def test_never_seen_space_comes_as_clusters_but_for_the_shadow_of_what_the_mask_holds(side_view):
    """What the front box hides is a never-seen cluster (an obstacle for planning); given the box's shadow as the mask
    (as the robot's links' and the tracked objects' are), it is not."""
    _, pos, rot, depth = side_view
    vmap = VoxelMap(LO, HI, cell=0.015)
    vmap.integrate(depth, K, pos, rot, _above_table(depth, pos, rot))
    lo, hi = np.array([0.3, -0.2, 0.02]), HI  # over the table, clear of the band a ray never carves
    hidden = (0.62, 0.0, 0.04)
    ijk, _ = vmap.index(np.array([hidden]))

    def holds(clusters) -> bool:
        return any(np.all(cells == ijk[0], axis=1).any() for cells in clusters)

    assert holds(vmap.unknown_clusters(vmap.region(lo, hi), np.zeros(vmap.shape, dtype=bool)))
    rows, cols = np.nonzero(np.isfinite(depth))
    points = backproject(depth, K, pos, rot, rows, cols)
    front = np.full(depth.shape, np.nan)  # the pixels that show the front box: its shadow is the mask
    on = points[:, 0] < 0.55
    front[rows[on], cols[on]] = depth[rows[on], cols[on]]
    shadow = vmap.behind(K, pos, rot, front)
    assert shadow[tuple(ijk[0])]
    assert not holds(vmap.unknown_clusters(vmap.region(lo, hi), shadow))
    box = vmap.oriented_box(next(c for c in vmap.unknown_clusters(vmap.region(lo, hi), np.zeros(vmap.shape, dtype=bool))
                                 if np.all(c == ijk[0], axis=1).any()))
    centre, half, yaw = box
    local = np.array(hidden) - centre
    turn = np.array([[np.cos(yaw), np.sin(yaw), 0.0], [-np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    assert np.all(np.abs(turn @ local) <= half + 1e-9)


def test_the_maps_voxels_land_on_the_pixels_a_pinhole_projection_gives_them() -> None:
    """The map's projection by the grid's axes: each voxel centre's pixel and depth as pixels.project gives them."""
    from nextage_qp.geometry import rot_of
    from nextage_qp.sensing.camera.pixels import project

    grid = VoxelMap(LO, HI, 0.02)
    rng = np.random.default_rng(3)
    for _ in range(5):
        pos = np.array([0.0, 0.0, 0.1]) + rng.normal(0.0, 0.02, 3)
        rot = _looking(np.array([1.0, 0.0, 0.0])) @ rot_of(rng.normal(0.0, 0.1, 3))
        depth = rng.uniform(0.2, 1.5, (60, 80))
        rows, cols, z = project(grid.centres, K, pos, rot)
        view = (z > 0.05) & (rows >= 0) & (rows < 60) & (cols >= 0) & (cols < 80)
        assert view.sum() > 100
        want = np.full(len(z), np.nan)
        want[view] = depth[rows[view], cols[view]]
        got_z, got = grid._along_rays(depth, K, pos, rot)
        np.testing.assert_allclose(got_z, z, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(got, want)
        assert grid._along_rays(depth, K, pos, rot)[1] is not got  # the same pose again: a new frame's depths
        lo, hi = LO + rng.uniform(0.0, 0.2, 3), HI - rng.uniform(0.0, 0.2, 3)
        inside = np.all((grid.centres >= lo) & (grid.centres <= hi), axis=1).reshape(grid.shape)
        np.testing.assert_array_equal(grid.region(lo, hi), inside)


def test_a_round_pieces_strip_boxes_hold_every_voxel_and_cut_the_single_boxs_corners() -> None:
    """A disc of voxels (a cylinder 9 cm across): its three strip boxes hold every voxel's corners, and the union
    reaches less far out from the piece than the one box around it."""
    vmap = VoxelMap(np.zeros(3), np.array([0.3, 0.3, 0.15]), cell=0.015)
    centre = np.array([0.15, 0.15])
    idx = np.argwhere(np.ones(vmap.shape, dtype=bool))
    xy = vmap.lo[:2] + (idx[:, :2] + 0.5) * vmap.cell
    cells = idx[(np.linalg.norm(xy - centre, axis=1) <= 0.045) & (idx[:, 2] >= 2) & (idx[:, 2] <= 5)]
    one = vmap.oriented_box(cells)
    strips = vmap.strip_boxes(cells, 3)
    assert len(strips) == 3

    def inside(box, points) -> np.ndarray:
        c, half, yaw = box
        turn = np.array([[np.cos(yaw), np.sin(yaw)], [-np.sin(yaw), np.cos(yaw)]])
        return np.all(np.abs((points - c[:2]) @ turn.T) <= half[:2] + 1e-9, axis=1)

    square = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])
    corners = (vmap.lo[:2] + ((cells[:, None, :2] + square[None]) * vmap.cell)).reshape(-1, 2)
    assert np.all(np.any([inside(b, corners) for b in strips], axis=0))  # every voxel held
    grid = np.stack(np.meshgrid(*[np.linspace(0.0, 0.3, 121)] * 2, indexing="ij"), axis=-1).reshape(-1, 2)
    held = np.any([inside(b, grid) for b in strips], axis=0)
    reach = np.linalg.norm(grid - centre, axis=1)
    assert reach[held].max() < reach[inside(one, grid)].max() - 0.008  # the corners cut by 8 mm or more
    assert held.sum() < inside(one, grid).sum()


def test_a_cluster_grows_into_the_hidden_space_beside_it_by_the_steps_given_and_nowhere_else() -> None:
    """A piece seen only up to an arm's edge: its cluster grows into the space the arm hides (three voxels on), not
    into seen space, and a cluster with no hidden space beside it stays as it is."""
    vmap = VoxelMap(np.zeros(3), np.array([0.3, 0.3, 0.15]), cell=0.015)
    solid = np.zeros(vmap.shape, dtype=bool)
    solid[5:7, 5:7, 2:5] = True  # a piece, seen up to y index 6
    solid[15:17, 15:17, 2:5] = True  # another, all of it seen
    hidden = np.zeros(vmap.shape, dtype=bool)
    hidden[3:9, 7:, 0:8] = True  # the arm's shadow beyond the first piece, on to the map's edge
    first, second = sorted(vmap.grown_clusters(solid, hidden, 3), key=lambda c: int(c[:, 0].min()))
    assert first[:, 1].max() == 6 + 3  # three voxels on into the shadow, not to its end
    assert first[:, 1].min() == 5 and first[:, 0].min() >= 3 and first[:, 0].max() <= 8  # not out of the shadow
    assert {tuple(c) for c in np.argwhere(solid[:10, :10])} <= {tuple(c) for c in first}
    assert len(second) == 2 * 2 * 3 and second[:, 0].min() == 15  # nothing hidden beside it
