"""Pushes aimed so that their error stays on a side an arm reaches (nextage_qp/manipulation/phases/push/sides.py)."""

from pathlib import Path

import numpy as np
import pytest

from nextage_qp.geometry import angle2, rotate2
from nextage_qp.manipulation.phases.push.sides import SIDE_STEP, SIDE_STEPS, middle, side_directions, split

X = np.array([1.0, 0.0])


def test_side_directions_fan_out_evenly_either_way_of_the_line():
    line = rotate2(X, 0.3)
    dirs = side_directions(line)
    assert len(dirs) == 2 * SIDE_STEPS + 1
    angles = [angle2(line, d) for d in dirs]
    assert angles == pytest.approx([k * SIDE_STEP for k in range(-SIDE_STEPS, SIDE_STEPS + 1)])


def test_middle_is_the_mean_direction_of_the_longest_reachable_run():
    dirs = side_directions(X)
    reach = [False] * len(dirs)
    for k in (1, 2, 6, 7, 8, 9):  # a run of two, and one of four from 0 to +45 deg
        reach[k] = True
    found = middle(dirs, reach)
    assert found is not None
    direction, length = found
    assert length == 4
    assert angle2(X, direction) == pytest.approx(np.radians(22.5))
    assert middle(dirs, [False] * len(dirs)) is None


def test_split_leaves_the_rest_of_the_error_along_a_reachable_side_beyond_it():
    error = 0.01 * rotate2(X, np.radians(40.0))
    along = X  # the side reached nearest the error, 40 deg off it
    sides = [rotate2(X, np.radians(a)) for a in (-30.0, 0.0, 60.0, 75.0)]
    rest = split(error, along, sides)
    assert rest is not None
    assert angle2(X, rest) == pytest.approx(np.radians(60.0))  # the nearest side beyond the error
    pushed = error - rest  # what the push along `along` does
    assert abs(angle2(along, pushed)) < 1e-9 and float(pushed @ along) > 0


def test_split_pushes_the_whole_way_when_it_is_straight_or_nothing_lies_beyond():
    error = 0.01 * rotate2(X, np.radians(40.0))
    assert split(error, rotate2(X, np.radians(38.0)), [X]) is None  # within STRAIGHT of the error
    assert split(error, X, [X, rotate2(X, np.radians(-30.0))]) is None  # no reachable side beyond the error
    assert split(np.zeros(2), X, [X]) is None


def test_in_clutter_the_first_push_aims_short_along_the_sides_reachable_at_the_target():
    """A scene whose tall cylinder beside the target's right leaves no arm a side to push the cube left from there:
    the sides reachable at the target are found, and the first push stops short along their middle."""
    from nextage_qp.manipulation.config import load_config
    from nextage_qp.manipulation.phases.push.approach import reachable_sides
    from nextage_qp.manipulation.phases.push.phase import Push
    from nextage_qp.manipulation.runner import Runner

    config = Path(__file__).resolve().parents[1] / "configs" / "push_clutter.yaml"
    runner = Runner(load_config(config, [
        "scene.poses.cube.pos=[0.2833,0.0430,0.91]", "scene.poses.cube.yaw=0.0749",
        "scene.poses.cube_target.pos=[0.6700,0.0192,0.91]", "scene.clutter.count=5", "seed=1484405855"]))
    view, spec = runner.view, runner.cfg.phases[0]
    push = Push(spec, "push")
    push.start(view)
    assert push.sides is not None and push.info["reachable_sides"] == len(push.sides)
    tgt = view.body_pose("cube_target").pos[:2]
    line = (tgt - view.body_pose("cube").pos[:2]) / np.linalg.norm(tgt - view.body_pose("cube").pos[:2])
    left = rotate2(line, np.radians(75.0))  # pushing the cube left at the target: the arm meets the cylinder
    reach = reachable_sides(view, spec, (spec.frame, *spec.other_frames), [left, line], tgt, push._target, push.raised)
    assert reach == [False, True]
    assert np.linalg.norm(push.aim) == pytest.approx(spec.correction_room)
    angles = [angle2(line, s) for s in push.sides]
    assert min(angles) < angle2(line, push.aim) < max(angles)  # among the reachable sides
