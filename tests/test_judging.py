"""Scenes with many objects, judged honestly: bystanders knocked, several objects judged, fixed obstacles."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from nextage_qp.errors import ConfigError
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.placement import clearance_at
from nextage_qp.manipulation.runner import Runner, build_robot

PUSH = "configs/push_cube.yaml"


def run(path: str, *overrides: str) -> dict:
    return dict(Runner(load_config(path, list(overrides)), path).run().record)


def test_a_bystander_knocked_off_its_place_fails_the_run_one_left_alone_does_not():
    knocked = run(PUSH, "scene.objects.mug={shape: cylinder, size: [0.02, 0.04], mass: 0.05, pos: [0.55, 0.0]}")
    assert not knocked["success"] and "knocked" in knocked["failed_criteria"]
    assert knocked["criteria"]["knocked"]["detail"].startswith("mug moved")
    assert knocked["knocked_m"]["mug"] > 0.02
    spared = run(PUSH, "scene.objects.mug={shape: cylinder, size: [0.02, 0.04], mass: 0.05, pos: [0.55, 0.25]}")
    assert spared["success"] and spared["knocked_m"]["mug"] < 0.002


def test_success_judges_every_object_it_names_against_its_target():
    two = ("scene.objects.cube2={shape: box, size: [0.02, 0.02, 0.02], mass: 0.1, pos: [0.45, 0.3]}",)
    off = run(PUSH, *two, "scene.poses.cube2_target={pos: [0.45, 0.25, 0.9]}", "success.objects={cube2: cube2_target}")
    assert not off["success"] and off["failed_criteria"] == ["cube2:object_error"]  # the first cube made it
    assert off["objects"]["cube2"]["error_xy_m"] == pytest.approx(0.05, abs=0.002)
    on = run(PUSH, *two, "scene.poses.cube2_target={pos: [0.45, 0.3, 0.9]}", "success.objects={cube2: cube2_target}")
    assert on["success"] and "cube2:object_error" in on["criteria"]


def test_success_objects_must_name_objects_and_bodies():
    with pytest.raises(ConfigError, match=r"success.objects: unknown object 'cube9'; valid: cube"):
        run(PUSH, "success.objects={cube9: cube_target}")
    with pytest.raises(ConfigError, match=r"success.objects: unknown target 'nowhere'"):
        run(PUSH, "success.objects={cube: nowhere}")


def test_a_fixed_object_is_a_static_obstacle_the_planner_and_the_ik_keep_clear_of():
    cfg = load_config(PUSH, ["scene.objects.crate={shape: box, size: [0.03, 0.1, 0.06], fixed: true, "
                             "pos: [0.7, 0.3]}"])
    runner = Runner(cfg, PUSH)
    robot = runner.robot
    assert "crate" in robot.fixed_objects and "crate" not in robot.object_names  # no joint: it cannot move
    assert "crate" in robot.collision_geoms()  # a collision group by its name
    assert "crate_target" not in robot.body_names  # no marker
    from nextage_qp.manipulation.placement import obstacle_top

    runner.sim.reset(runner.sim.data.qpos[robot.qpos_idx])
    assert obstacle_top(robot, runner.sim.data) == pytest.approx(0.875 + 0.12, abs=1e-6)  # the carry clears it


def test_a_fixed_object_cannot_take_a_free_objects_name():
    with pytest.raises(ConfigError, match=r"scene.objects.cube: 'cube' is a free object of the scene"):
        Runner(load_config(PUSH, ["scene.objects.cube={shape: box, size: [0.02, 0.02, 0.02], fixed: true}"]), PUSH)


def test_clearance_at_measures_an_object_against_the_wall_and_points_away_from_it():
    path = "configs/dock_dumbbell.yaml"
    robot = build_robot(load_config(path), path)
    data = mujoco.MjData(robot.model)
    mujoco.mj_forward(robot.model, data)
    normal = np.array([-1.0, 1.0, 0.0]) / np.sqrt(2.0)  # the wall runs along (1, 1) through (0.43, 0.275)
    far, away = clearance_at(robot, data, "dumbbell", np.array([0.35, 0.40, 1.015]), 0.785398, ["obstacle"])
    near, away = clearance_at(robot, data, "dumbbell", np.array([0.40, 0.40, 1.015]), 0.785398, ["obstacle"])
    assert 0.0 < near < far and away @ normal > 0.9  # nearer as it moves towards the wall, which it is off
    inside, into = clearance_at(robot, data, "dumbbell", np.array([0.43, 0.29, 1.015]), 0.785398, ["obstacle"])
    assert inside < 0.0 and np.linalg.norm(into) == pytest.approx(1.0)


def test_a_dock_target_touching_the_wall_is_aimed_off_it_and_set_down_within_the_tolerance():
    # The wall's face is 0.3 mm from the plate at this target: aimed 2.7 mm off it, along the wall's normal.
    record = run("configs/dock_dumbbell.yaml", "scene.poses.dumbbell_target.pos=[0.3526,0.3646,1.0]",
                 "scene.poses.dumbbell_target.yaw=1.0468")
    place = record["phases"][1]
    assert place["target_room_m"] < 0.003 and 0.0 < place["aim_off_m"] <= 0.003
    assert record["success"] and record["object_error_xy_m"] < 0.005 and record["obstacle_contacts"] == 0
