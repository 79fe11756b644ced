"""Objects of other shapes and new tasks from YAML alone, end to end: each shape pushed, pick-and-place, stacking,
and a task config written here (no code of its own) run through the CLI."""

import json
from pathlib import Path

import pytest
import yaml

from nextage_qp.cli import main
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner

ROOT = Path(__file__).resolve().parents[1]
PUSH = ROOT / "configs" / "push_cube.yaml"


def run(path: Path, overrides=()):
    return Runner(load_config(path, list(overrides)), str(path)).run()


def assert_clean(result):
    assert result["error"] is None, result["error"]
    assert all(p["status"] == "done" for p in result["phases"])
    assert result["joint_limit_violations"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("shape", [
    "{shape: box, size: [0.045, 0.015, 0.035]}",           # oblong 1:3, 3 x 9 cm
    "{shape: box, size: [0.02, 0.02, 0.035]}",             # a 4 cm square box
    "{shape: cylinder, size: [0.03, 0.035]}",              # rolls its contact point around the face
    "{shape: prism, sides: 6, size: [0.03, 0.035]}",       # hexagonal
    "{shape: prism, sides: 3, size: [0.04, 0.03]}",        # triangular: the face pushed is not the one opposite
    "{shape: compound, parts: [{shape: box, size: [0.03, 0.03, 0.02], pos: [0, 0, -0.015]},"
    " {shape: cylinder, size: [0.02, 0.015], pos: [0, 0, 0.02]}]}",   # a box with a boss on top
])
def test_each_shape_is_pushed_onto_its_target(shape):
    result = run(PUSH, [f"scene.objects.cube={shape}"])
    assert_clean(result)
    assert result["success"]
    assert result["object_error_xy_m"] <= 0.005


@pytest.mark.slow
def test_a_low_cylinder_is_pushed_with_the_tool_raised_to_reach_it():
    """5 cm tall: at the config's height the hand would meet the table, so the push goes higher, every approach."""
    result = run(PUSH, ["scene.objects.cube.shape=cylinder", "scene.objects.cube.size=[0.03,0.025]"])
    assert_clean(result)
    assert result["success"] and result["object_error_xy_m"] <= 0.005


@pytest.mark.slow
def test_pick_place_box_default_sets_the_box_down_on_its_target():
    result = run(ROOT / "configs" / "pick_place_box.yaml")
    assert_clean(result)
    assert result["success"]
    assert result["object_error_xy_m"] <= 0.005 and result["obstacle_contacts"] == 0


@pytest.mark.slow
def test_stack_boxes_default_centres_box_b_on_box_a():
    result = run(ROOT / "configs" / "stack_boxes.yaml")
    assert_clean(result)
    assert result["success"] and result["object_resting"]
    assert result["object_error_xy_m"] <= 0.005
    assert result["object_yaw_error_rad"] <= 0.0873
    assert result["final_object_position"][2] > 0.875 + 0.08  # on box_a's top, not on the table


@pytest.mark.slow
def test_a_task_written_here_runs_from_yaml_alone(tmp_path, capsys):
    """A puck pushed across the bare table: scene, object, target and phase all declared in the config."""
    config = {
        "task": "push_puck",
        "scene": {
            "file": "tabletop",
            "objects": {"puck": {"shape": "cylinder", "size": [0.035, 0.03], "mass": 0.15, "pos": [0.34, 0.02]}},
            "poses": {"puck_target": {"pos": [0.62, -0.03, 0.905], "yaw": 0.0}},
        },
        "object": "puck",
        "target": "puck_target",
        "success": {"planar_error": 0.005},
        "gains": "stiff_wrist",
        "ik": {"trust_region": True, "collision_pairs": [
            {"a": "left_hand", "b": "table", "min_distance": 0.008, "detection_distance": 0.05},
            {"a": "right_arm", "b": "table", "min_distance": 0.01, "detection_distance": 0.05}]},
        "timing": {"ctrl_dt": 0.02},
        "phases": [{"kind": "push", "frame": "left_tool", "object": "puck", "target": "puck_target",
                    "height": 0.008, "clearance": 0.05, "timeout": 60.0}],
    }
    path = tmp_path / "push_puck.yaml"
    path.write_text(yaml.safe_dump(config))
    assert main(["run", str(path), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["success"] and result["object_error_xy_m"] <= 0.005


@pytest.mark.slow
def test_a_target_out_of_the_clamps_reach_is_refused_before_anything_moves(capsys):
    code = main(["run", str(ROOT / "configs" / "pick_place_box.yaml"),
                 "--set", "scene.objects.box.size=[0.03,0.16,0.12]",  # 32 cm long: the clamp turns it
                 "--set", "scene.poses.box_target.pos=[-0.15,0.5,0.03]"])  # workspace
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "cannot reach box_target's pose" in err[0] and "out of the arms' reach" in err[0]
