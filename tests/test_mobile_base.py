"""Mobile bases: the base built under a robot, its wheels and odometry, its rows in the IK, driving and parking."""

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from nextage_qp.cli import main
from nextage_qp.errors import ConfigError
from nextage_qp.geometry import rot_z
from nextage_qp.ik import QPIK, FrameTarget, IKConfig
from nextage_qp.ik.kinematic_model import kinematic_model
from nextage_qp.loop.simulation import Simulation
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner
from nextage_qp.mobile import Twist
from nextage_qp.mobile.build import BASE_BODY, PLANAR_JOINTS
from nextage_qp.mobile.drive_paths import around
from nextage_qp.robots.description import load_robot
from nextage_qp.robots.gains import robot_gains
from nextage_qp.robots.model import Robot

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def mobile() -> Robot:
    return Robot.from_scene("fetch_push", robot="nextage_mobile")


@pytest.fixture(scope="module")
def floor() -> Robot:
    """The mobile Nextage on an empty floor."""
    return Robot.from_scene("scene", robot="nextage_mobile")


def test_the_base_goes_under_the_robot_file_it_extends(mobile: Robot) -> None:
    desc = load_robot("nextage_mobile")
    assert desc.base is not None and desc.base.type == "diff_drive"
    assert mobile.joint_names == Robot.from_scene("push_cube").joint_names  # the Nextage's joints, driven as before
    assert BASE_BODY not in mobile.object_names and "cube" in mobile.object_names
    groups = mobile.collision_geoms()  # the base's own group (its body and wheels) and the Nextage's
    assert BASE_BODY in groups and "torso" in groups
    wheels = {mobile.model.body(int(mobile.model.geom_bodyid[g])).name for g in groups[BASE_BODY]}
    assert wheels >= {"mobile_base_wheel_right", "mobile_base_wheel_left"} and not set(groups[BASE_BODY]) & set(groups["torso"])
    model = kinematic_model(mobile)
    assert tuple(model.joint(i).name for i in range(model.njnt)) == (*PLANAR_JOINTS, *mobile.joint_names)


def test_wheels_drive_on_the_floor_without_sliding_and_odometry_follows(floor: Robot) -> None:
    sim = Simulation(floor, robot_gains(floor))
    assert sim.base is not None
    start = sim.base.base.pose(sim.data)
    for k in range(1000):  # 4 s at 250 Hz: 1.5 s straight, then an arc
        sim.base.command(sim.data, Twist(0.3, 0.0, 0.0 if k < 375 else 0.5))
        sim.tick()
    true, believed = sim.base.base.pose(sim.data), sim.measured.base
    assert believed is not None
    assert math.dist(true[:2], start[:2]) > 1.0  # it drove
    assert math.dist(true[:2], believed[:2]) < 0.02 and abs(true.yaw - believed.yaw) < 0.01
    lateral = np.array(sim.base.log)[:, 8]
    assert np.max(np.abs(lateral)) < 0.01  # a differential drive never slides sideways


def test_a_standing_base_holds_its_place_under_a_push(floor: Robot) -> None:
    sim = Simulation(floor, robot_gains(floor))
    assert sim.base is not None
    start = sim.base.base.pose(sim.data)
    body = floor.model.body("nextage_base").id
    for _ in range(500):  # 2 s of a 60 N shove on the robot, the base told to stand
        sim.data.xfrc_applied[body, :3] = (60.0, 20.0, 0.0)
        sim.base.command(sim.data, Twist(0.0, 0.0, 0.0))
        sim.tick()
    assert math.dist(sim.base.base.pose(sim.data)[:2], start[:2]) < 0.005


def test_ik_base_step_never_slides_sideways_and_respects_the_wheels(mobile: Robot) -> None:
    ik = QPIK(mobile, IKConfig())
    base = mobile.base
    assert base is not None
    rng = np.random.default_rng(0)
    dt, q = 0.02, mobile.keyframe_q("home")
    for _ in range(60):
        ik.base_pose = np.array([*rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi)])
        goal = ik.base_pose + np.array([*rng.uniform(-2, 2, 2), rng.uniform(-2, 2)])
        target = FrameTarget(BASE_BODY, pos=np.array([goal[0], goal[1], 0.0]), rot=rot_z(goal[2]),
                             position_cost=20.0, orientation_cost=20.0)
        ik.step(q, [target], dt, base=True)
        xd, yd, w = ik.base_velocity
        yaw = ik.base_pose[2]
        forward, lateral = math.cos(yaw) * xd + math.sin(yaw) * yd, -math.sin(yaw) * xd + math.cos(yaw) * yd
        assert abs(lateral) < 1e-9
        right, left = base.drive.inverse(forward, w)
        assert max(abs(right), abs(left)) <= base.limits.wheel_speed * (1 + 1e-6)
    ik.step(q, [target], dt)  # without base=True the base stays
    assert np.abs(ik.base_velocity).max() < 1e-9


def test_path_around_an_obstacle_keeps_its_clearance() -> None:
    points = around(np.array([0.0, 0.0]), np.array([4.0, 0.2]), [(2.0, 0.1, 0.8)])
    assert points is not None and len(points) > 2
    for a, b in itertools.pairwise(points):
        for s in np.linspace(0, 1, 50):
            assert math.dist(a + s * (b - a), (2.0, 0.1)) >= 0.8 - 1e-9
    assert around(np.array([0.0, 0.0]), np.array([2.0, 0.1]), [(2.0, 0.1, 0.8)]) is None  # the goal inside


def _run(config: str) -> tuple[Runner, dict]:
    path = ROOT / "configs" / config
    runner = Runner(load_config(path), str(path))
    result = runner.run()
    assert result["success"], result["error"]
    return runner, result


@pytest.mark.slow
def test_fetch_push_drives_around_the_crate_and_pushes_the_cube() -> None:
    _, result = _run("fetch_push.yaml")
    assert result["object_error_xy_m"] < 0.005 and result["obstacle_contacts"] == 0
    base = result["base"]
    assert base["max_lateral_speed_m_s"] < 0.01 and base["sliding_ticks"] == 0
    assert base["odometry_drift_m"] < 0.02 and base["distance_m"] > 3.0
    drive = result["phases"][0]
    assert drive["kind"] == "drive" and drive["waypoints"] > 2  # around the crate, not through it


@pytest.mark.slow
def test_car_parks_within_5cm_and_5deg_never_turning_tighter_than_it_can() -> None:
    runner, result = _run("park_car.yaml")
    assert result["object_error_xy_m"] <= 0.05 and result["object_yaw_error_rad"] <= math.radians(5)
    base = runner.robot.base
    assert base is not None and base.bicycle is not None and runner.sim.base is not None
    least = base.bicycle.wheelbase / math.tan(base.limits.steer)  # the least turning radius [m]
    log = np.array(runner.sim.base.log)
    xy, yaw, forward = log[:, 1:3], np.unwrap(log[:, 3]), log[:, 7]
    assert forward.min() > -0.02  # forward only
    # curvature over stretches of at least 5 cm of travel
    travelled = np.r_[0.0, np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]
    i, checked = 0, 0
    for j in range(len(log)):
        if travelled[j] - travelled[i] >= 0.05:
            assert abs(yaw[j] - yaw[i]) / (travelled[j] - travelled[i]) <= 1.05 / least
            i, checked = j, checked + 1
    assert checked > 40


def test_bad_base_sections_and_drive_phases_are_one_line_errors(tmp_path: Path, capsys) -> None:
    cases = {
        "bad type": "base: {type: tank}\n",
        "bicycle without wheelbase": "base: {type: bicycle}\n",
        "wheelbase on a diff drive": "base: {type: diff_drive, wheelbase: 0.5}\n",
        "negative radius": "base: {type: diff_drive, wheel_radius: -0.1}\n",
        "nan track": "base: {type: diff_drive, track: .nan}\n",
        "unknown key": "base: {type: diff_drive, wheels: 3}\n",
    }
    for name, extra in cases.items():
        robot = tmp_path / f"{name.replace(' ', '_')}.yaml"
        robot.write_text(f"extends: {ROOT / 'robots' / 'nextage.yaml'}\nname: x\n{extra}")
        with pytest.raises(ConfigError) as err:
            load_robot(robot)
        assert "base" in str(err.value) and "\n" not in str(err.value), name
    circle = tmp_path / "a.yaml"
    circle.write_text(f"extends: {circle}\nname: a\n")
    with pytest.raises(ConfigError, match="circle"):
        load_robot(circle)
    fetch = str(ROOT / "configs" / "fetch_push.yaml")
    for item in ("phases[0].frame=wheel", "phases[0].avoid=[nothing]", "phases[0].speed=-1", "mount.yaw=99",
                 "phases[0].relative_to=nowhere", "mount.pos=[1, 2]"):
        assert main(["run", fetch, "--set", item]) == 2, item
        err = capsys.readouterr().err
        assert len([ln for ln in err.splitlines() if ln.strip()]) == 1 and "Traceback" not in err, err
    # a start inside the crate's clearance: refused before anything moves, naming the obstacle
    assert main(["run", fetch, "--set", "mount.pos=[-1.5, 0.2, 0.0]"]) == 2
    assert "obstacle" in capsys.readouterr().err
    # a robot without a base cannot drive
    push = str(ROOT / "configs" / "push_cube.yaml")
    assert main(["run", push, "--set", "phases=[{kind: drive, offset: [0.1, 0.0]}]"]) == 2
    assert "no base" in capsys.readouterr().err


def test_a_holonomic_base_parks_too(tmp_path: Path) -> None:
    robot = tmp_path / "omni.yaml"
    robot.write_text(f"extends: {ROOT / 'robots' / 'nextage.yaml'}\nname: omni\n"
                     "base: {type: holonomic, axle_x: -0.19, limits: {speed: 0.4, turn_rate: 0.8}}\n")
    path = ROOT / "configs" / "park_car.yaml"
    cfg = load_config(path, [f"robot={robot}", "phases[0].timeout=60", "scene.poses.parking_spot.pos=[1.0, -0.8, 0]"])
    result = Runner(cfg, str(path)).run()
    assert result["success"], result["error"]
    assert result["base"]["type"] == "holonomic" and result["object_error_xy_m"] < 0.01


def test_a_pair_of_the_moving_base_and_a_crate_in_the_world_gets_rows() -> None:
    """The base moves on its own joints from the world and the crate is welded to it: no parent and child, so the
    config's mobile_base-obstacle pair keeps them apart (mink's own test takes the world for the base's parent)."""
    from nextage_qp.manipulation.config import load_config
    from nextage_qp.manipulation.runner import build_robot

    cfg = load_config(ROOT / "configs" / "fetch_push.yaml")
    ik = QPIK(build_robot(cfg, "fetch_push"), cfg.ik)
    crate = {int(g) for g in ik.groups["obstacle"]}
    base = {int(g) for g in ik.groups["mobile_base"]}
    pairs = {(int(a), int(b)) for a, b in zip(ik.collision.geom1, ik.collision.geom2, strict=True)}
    assert any((a in crate and b in base) or (b in crate and a in base) for a, b in pairs)
