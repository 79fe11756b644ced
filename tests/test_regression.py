"""End-to-end regression tests on the final object error of both YAML tasks and shifted variants."""

import json
from pathlib import Path

import pytest

from nextage_qp.cli import main
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner

ROOT = Path(__file__).resolve().parents[1]
PUSH = ROOT / "configs" / "push_cube.yaml"
DOCK = ROOT / "configs" / "dock_dumbbell.yaml"

# Object start and target moved by up to 3 cm and 15 deg (0.26 rad) of yaw.
PUSH_VARIANTS = [
    ["scene.poses.cube.pos=[0.36,0.03,0.91]", "scene.poses.cube.yaw=0.26", "scene.poses.cube_target.pos=[0.67,-0.03,0.91]"],
    ["scene.poses.cube.pos=[0.30,0.02,0.91]", "scene.poses.cube.yaw=-0.26", "scene.poses.cube_target.pos=[0.73,-0.01,0.91]"],
    ["scene.poses.cube.pos=[0.33,0.03,0.91]", "scene.poses.cube_target.pos=[0.70,-0.03,0.91]",
     "scene.poses.cube_target.yaw=2.88"],
    ["scene.poses.cube.pos=[0.35,-0.02,0.91]", "scene.poses.cube.yaw=0.15", "scene.poses.cube_target.pos=[0.69,0.03,0.91]"],
]
# Known limitation: a cube yawed by -15 deg that must travel towards +y is turned away by the flat push face and
# the re-pushes do not recover it. Kept as a strict xfail so a fix shows up.
PUSH_KNOWN_FAILURE = ["scene.poses.cube.pos=[0.31,-0.03,0.91]", "scene.poses.cube.yaw=-0.26",
                      "scene.poses.cube_target.pos=[0.72,0.03,0.91]"]
DOCK_VARIANTS = [
    ["scene.poses.dumbbell.pos=[0.53,0.02,1.015]", "scene.poses.dumbbell.yaw=0.26"],
    ["scene.poses.dumbbell.pos=[0.48,-0.03,1.015]", "scene.poses.dumbbell_target.pos=[0.37,0.40,1.0]",
     "scene.poses.dumbbell_target.yaw=0.52"],
    ["scene.poses.dumbbell.pos=[0.50,0.03,1.015]", "scene.poses.dumbbell.yaw=-0.26",
     "scene.poses.dumbbell_target.pos=[0.33,0.36,1.0]"],
]


def run(path: Path, overrides=()):
    cfg = load_config(path, list(overrides))
    return Runner(cfg, str(path)).run()


def assert_clean(result):
    assert result["error"] is None
    assert all(p["status"] == "done" for p in result["phases"])
    assert result["joint_limit_violations"] == 0
    assert result["torque_saturation_ticks"] == 0


@pytest.mark.slow
def test_push_cube_default_within_10mm():
    result = run(PUSH)
    assert_clean(result)
    assert result["object_error_m"] <= 0.010
    assert result["object_error_xy_m"] <= 0.002  # the aim, met by the closed-loop re-pushes
    assert result["success"]


@pytest.mark.slow
def test_dock_dumbbell_default_within_20mm_no_contact_no_drop():
    result = run(DOCK)
    assert_clean(result)
    assert result["object_error_m"] <= 0.020
    assert result["object_error_xy_m"] <= 0.008
    assert result["obstacle_contacts"] == 0
    assert result["min_obstacle_clearance_m"] > 0.0
    assert not result["object_dropped"]


@pytest.mark.slow
@pytest.mark.parametrize("overrides", PUSH_VARIANTS, ids=["shift+yaw", "shift-yaw", "target-yaw", "cross+yaw"])
def test_push_cube_shifted_variants_within_20mm(overrides):
    result = run(PUSH, overrides)
    assert_clean(result)
    assert result["object_error_m"] <= 0.020


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="yawed cube pushed towards +y turns away from the push face")
def test_push_cube_known_failure_yawed_cube_towards_left():
    result = run(PUSH, PUSH_KNOWN_FAILURE)
    assert result["error"] is None and result["object_error_m"] <= 0.020


@pytest.mark.slow
@pytest.mark.parametrize("overrides", DOCK_VARIANTS, ids=["object-shift+yaw", "target-shift+yaw", "both-shift"])
def test_dock_dumbbell_shifted_variants_within_20mm(overrides):
    result = run(DOCK, overrides)
    assert_clean(result)
    assert result["object_error_m"] <= 0.020
    assert result["obstacle_contacts"] == 0
    assert not result["object_dropped"]


@pytest.mark.slow
def test_run_cli_json_and_outputs(tmp_path, capsys):
    plot, log = tmp_path / "push.png", tmp_path / "push.npz"
    assert main(["run", str(PUSH), "--json", "--plot", str(plot), "--log", str(log)]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("task", "success", "object_error_m", "object_error_xy_m", "final_object_position", "target_position",
                "sim_time_s", "wall_time_s", "min_obstacle_clearance_m", "obstacle_contacts", "object_dropped",
                "joint_limit_violations", "max_abs_torque_nm", "torque_saturation_ticks", "phases"):
        assert key in out
    assert out["min_obstacle_clearance_m"] is None  # no obstacle in this scene
    assert out["wall_time_s"] < out["sim_time_s"]
    assert plot.stat().st_size > 10_000 and log.is_file()
