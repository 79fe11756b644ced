"""Goal points computed from the obstacles: a target placed on the free spot nearest a point (``free_spot``)."""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from nextage_qp.cli import main
from nextage_qp.errors import InfeasibleError
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.placement import (
    FREE_SPOT_APART,
    FREE_SPOT_MARGIN,
    FREE_SPOT_STEP,
    free_spots,
    obstacle_clearance,
)
from nextage_qp.manipulation.runner import Runner

ROOT = Path(__file__).resolve().parents[1]
FREE = ROOT / "configs" / "place_free_spot.yaml"
REGION = ((0.22, 0.20), (0.50, 0.56))  # the config's
ASKED = 0.09  # the config's clearance [m]


@pytest.fixture(scope="module")
def runner():
    return Runner(load_config(FREE, ["scene.clutter.count=6", "scene.clutter.seed=7"]), str(FREE))


def _box_at(robot, xy, yaw):
    """The box standing on the table at ``xy`` and ``yaw``, in a fresh data: its clearance from the obstacles."""
    data = mujoco.MjData(robot.model)
    mujoco.mj_forward(robot.model, data)
    sl = robot.object_qpos_slice("box")
    z = data.qpos[sl][2]
    data.qpos[sl] = [xy[0], xy[1], z, np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    mujoco.mj_kinematics(robot.model, data)
    return obstacle_clearance(robot, data, "box")


def test_the_target_goes_to_the_nearest_spot_that_keeps_the_clearance(runner):
    robot, m = runner.robot, runner.robot.model
    spot = runner.free_spots["box_target"]
    xy = m.body("box_target").pos[:2]
    assert np.allclose(xy, spot.pos) and spot.clearance >= ASKED + FREE_SPOT_MARGIN
    yaw = float(2 * np.arctan2(m.body("box_target").quat[3], m.body("box_target").quat[0]))
    assert _box_at(robot, xy, yaw) >= ASKED - 1e-6  # measured again, independently of the search
    near = np.array([0.35, 0.38])
    # no grid point nearer `near` keeps the clearance: the spot is the nearest one
    (x0, y0), (x1, y1) = REGION
    grid = np.stack(np.meshgrid(np.arange(x0, x1 + 1e-9, FREE_SPOT_STEP), np.arange(y0, y1 + 1e-9, FREE_SPOT_STEP),
                                indexing="ij"), axis=-1).reshape(-1, 2)
    nearer = grid[np.linalg.norm(grid - near, axis=1) < np.linalg.norm(xy - near) - 1e-9]
    assert len(nearer) > 0  # the clutter occupies the point asked for: the search had to move away
    assert all(_box_at(robot, p, yaw) < ASKED + FREE_SPOT_MARGIN for p in nearer[:: max(1, len(nearer) // 40)])


def test_later_spots_keep_the_clearance_and_lie_apart(runner):
    robot = runner.robot
    spots = list(free_spots(robot, "box", 0.785398, REGION, (0.35, 0.38), 0.06, "test"))
    assert len(spots) >= 3
    for k, (xy, room) in enumerate(spots):
        assert room >= 0.06 + FREE_SPOT_MARGIN and _box_at(robot, xy, 0.785398) >= 0.06 + FREE_SPOT_MARGIN - 1e-6
        assert all(np.linalg.norm(xy - other) >= FREE_SPOT_APART - 1e-9 for other, _ in spots[:k])
    dists = [np.linalg.norm(xy - np.array([0.35, 0.38])) for xy, _ in spots]
    assert dists == sorted(dists)  # nearest first


def test_a_spot_the_first_phase_refuses_is_replaced_by_the_next(runner):
    spot = runner.free_spots["box_target"]
    first = spot.pos.copy()
    m = runner.robot.model
    try:
        assert spot.take_next((m,), "out of reach")
        assert np.linalg.norm(spot.pos - first) >= FREE_SPOT_APART - 1e-9
        assert np.allclose(m.body("box_target").pos[:2], spot.pos)
        assert spot.report()["spots_refused"] == 1
    finally:  # the module's runner again as it was
        m.body("box_target").pos[:2] = first


def test_a_spot_judged_again_moves_to_the_nearest_that_keeps_the_clearance_or_stays(runner):
    """A spot a later phase judges again on a fuller map moves to the nearest spot of a new search that keeps the
    clearance, the reason kept; a search with no spot leaves it where it is."""
    spot = runner.free_spots["box_target"]
    first, refused = spot.pos.copy(), len(spot.refused)
    m = runner.robot.model
    try:
        again = free_spots(runner.robot, "box", 0.785398, REGION, tuple(first), 0.06, "test")
        assert spot.move(again, (m,), "the map now keeps box 80 mm from an obstacle")
        assert np.linalg.norm(spot.pos - first) <= FREE_SPOT_STEP + 1e-9  # the nearest: the spot or beside it
        assert np.allclose(m.body("box_target").pos[:2], spot.pos)
        assert spot.report()["spots_refused"] == refused + 1
        x, y = m.body("clutter_0").pos[:2]
        none = free_spots(runner.robot, "box", 0.0, ((x - 0.01, y - 0.01), (x + 0.01, y + 0.01)), (x, y), 0.03, "t")
        before = spot.pos.copy()
        assert not spot.move(none, (m,), "no room")
        assert np.allclose(spot.pos, before) and spot.report()["spots_refused"] == refused + 1
    finally:  # the module's runner again as it was
        m.body("box_target").pos[:2] = first


def test_a_region_with_no_room_is_refused_naming_the_roomiest_spot(runner):
    x, y = runner.robot.model.body("clutter_0").pos[:2]
    around = ((x - 0.01, y - 0.01), (x + 0.01, y + 0.01))  # on a piece of clutter: nowhere to stand
    with pytest.raises(InfeasibleError, match=r"no spot of the region .* keeps box 30 mm from the obstacles \(the "
                                              r"roomiest, .* keeps -?\d+ mm\)"):
        next(free_spots(runner.robot, "box", 0.0, around, (x, y), 0.03, "test"))


@pytest.mark.parametrize(("override", "says"), [
    ("scene.poses.box_target.free_spot.clearance=-0.01", "scene.poses.box_target.free_spot.clearance"),
    ("scene.poses.box_target.free_spot.region=[[0.4, 0.2], [0.3, 0.5]]", "region"),
    ("scene.poses.box_target.free_spot.near=[nan, 0.3]", "near"),
    ("scene.poses.box_target.pos=[0.3, 0.3, 0.9]", "give pos or free_spot, not both"),
    ("scene.poses.box_target.free_spot.clearance=0.2", "scene.poses.box_target.free_spot.clearance"),
    ("scene.poses.box_target.free_spot.region=[[0.3, 0.3], [0.31, 0.31]]", "no spot of the region"),
    ("scene.poses.box.free_spot={region: [[0.3, 0.3], [0.4, 0.4]]}", "is no object's target"),
    ("success.obstacle_clearance=-1", "success.obstacle_clearance"),
])
def test_every_free_spot_key_is_validated_in_one_line(override, says, capsys):
    assert main(["run", str(FREE), "--set", override]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err
