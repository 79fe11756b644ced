"""Hand cameras: which cameras they are, when they are rendered, and what they see past the tool."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from nextage_qp.errors import ConfigError
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner, build_robot
from nextage_qp.sensing.camera.frame import Detection
from nextage_qp.sensing.camera.hands import UNSEEN, HandCameras, hand_camera_names
from nextage_qp.sensing.camera.render import render_problem
from nextage_qp.sensing.camera.shapes import ShapeModel

ROOT = Path(__file__).resolve().parents[1]
PUSH = ROOT / "configs" / "push_cube.yaml"
PROBLEM = render_problem()
needs_gl = pytest.mark.skipif(PROBLEM is not None, reason=PROBLEM or "")


def _scene(ahead: float):
    """The push scene at home with the cube on the table ``ahead`` [m] of the left tool: robot, world, joints."""
    cfg = load_config(PUSH)
    robot = build_robot(cfg, str(PUSH))
    data = mujoco.MjData(robot.model)
    q = robot.keyframe_q("home")
    robot.set_q(data, q)
    mujoco.mj_forward(robot.model, data)
    tool = data.site_xpos[robot.model.site("left_tool").id]
    s = robot.object_qpos_slice("cube")
    data.qpos[s.start:s.start + 3] = [tool[0] + ahead, tool[1], data.qpos[s.start + 2]]
    mujoco.mj_forward(robot.model, data)
    return robot, data, q


def _truth(robot, data) -> np.ndarray:
    body = robot.model.body("cube").id
    quat = data.xquat[body]
    yaw = np.arctan2(2 * (quat[0] * quat[3] + quat[1] * quat[2]), 1 - 2 * (quat[2] ** 2 + quat[3] ** 2))
    return np.array([*data.xpos[body], 0.0, 0.0, yaw])


def test_the_hand_cameras_are_the_robot_files_cameras_on_a_wrist_unless_named() -> None:
    robot = build_robot(load_config(PUSH), str(PUSH))
    assert hand_camera_names(robot, None, "t.yaml") == ("left_hand", "right_hand")  # head_* are on the head
    assert hand_camera_names(robot, ("right_hand",), "t.yaml") == ("right_hand",)
    assert hand_camera_names(robot, (), "t.yaml") == ()
    with pytest.raises(ConfigError, match=r"perception.hand_cameras: 'wrist_cam' is not a camera of robot 'nextage'; "
                                          r"valid: head_left, head_rgbd, head_right, left_hand, right_hand"):
        hand_camera_names(robot, ("wrist_cam",), "t.yaml")


@needs_gl
def test_a_hand_camera_fits_the_object_ahead_of_its_tool_that_the_head_did_not_see() -> None:
    robot, data, q = _scene(0.25)  # the hand 9 cm over the table: nearer, it covers the cube
    shapes = {"cube": ShapeModel.of_body(robot.model, "cube", robot.yaw_symmetry("cube"))}
    hands = HandCameras(("left_hand", "right_hand"), robot, shapes, seed=0)
    truth = _truth(robot, data)
    prior = truth + np.array([0.006, -0.004, 0.0, 0.0, 0.0, 0.05])
    head_plane = (np.array([0.0, 0.0, 1.0]), float(data.geom_xpos[robot.model.geom("table_top").id][2]
                                                   + robot.model.geom("table_top").size[2]))
    try:
        found = hands.measure(data, q, {"cube": prior}, {"cube": UNSEEN}, (), head_plane)
        assert set(found) == {"cube"}
        assert np.linalg.norm(found["cube"].pose[:3] - truth[:3]) < 0.002
        assert hands.frames == {"left_hand": 1, "right_hand": 0}  # the right hand's view does not hold it
        assert hands.used == {"left_hand": 1, "right_hand": 0}
        # the head saw it clearly: no hand camera is rendered
        seen = Detection(truth, "ok", rms=0.001, points=400, occluded=0.0, support=1.0)
        assert hands.measure(data, q, {"cube": prior}, {"cube": seen}, (), head_plane) == {}
        # an object behind the hands is in no hand camera's view: none is rendered
        behind = prior + np.array([-0.5, 0.0, 0.0, 0.0, 0.0, 0.0])
        assert hands.measure(data, q, {"cube": behind}, {"cube": UNSEEN}, (), head_plane) == {}
        assert hands.frames == {"left_hand": 1, "right_hand": 0}
        # not tracked yet (no prediction to look at): the head's job
        assert hands.measure(data, q, {"cube": None}, {"cube": UNSEEN}, (), head_plane) == {}
    finally:
        hands.close()


def test_an_unknown_hand_camera_in_a_config_is_one_line() -> None:
    cfg = load_config(PUSH, ["perception.source=camera", "perception.hand_cameras=[palm_cam]"])
    if PROBLEM is not None:
        pytest.skip(PROBLEM)
    with pytest.raises(ConfigError, match=r"perception.hand_cameras: 'palm_cam' is not a camera of robot 'nextage'"):
        Runner(cfg, str(PUSH))


@needs_gl
@pytest.mark.slow
def test_the_default_push_from_the_cameras_sees_the_cube_past_the_hand_and_never_stops_to_look() -> None:
    """The head's view of the cube is hidden by the pushing hand; the left hand's camera sees it, so the push goes on
    without stopping to look, and the head renders only every WHOLE_EVERY-th frame while it does."""
    result = Runner(load_config(PUSH, ["perception.source=camera"]), PUSH).run()
    assert result["success"], result["error"]
    hands = result["estimation"]["camera"]["hand_cameras"]
    assert hands["used"]["left_hand"] > 50 and hands["head_skipped"] > 50
    assert all(p.get("looks", 0) == 0 for p in result["phases"])
    errors = result["estimation"]["objects"]["cube"]
    assert errors["estimate_max_m"] < 0.01


@needs_gl
def test_while_every_object_is_held_the_head_takes_every_held_every_th_frame() -> None:
    from nextage_qp.sensing.camera.source import CameraMeasurer
    from nextage_qp.sensing.perception_config import PerceptionConfig

    robot, data, q = _scene(0.25)
    resting = _truth(robot, data)
    aloft = resting + np.array([0.0, 0.0, 0.05, 0.0, 0.0, 0.0])  # predicted 5 cm up: held in the air
    cfg = PerceptionConfig(source="camera", held_every=3, hand_cameras=())  # the head alone
    source = CameraMeasurer(cfg, robot, data, lambda t: q, seed=0)
    try:
        taken = [bool(source(0.1 * k, {"cube": aloft}, held={"cube"})) for k in range(6)]
        # the first frame: nothing seen yet (nor the table); then every third (no frame: nothing measured, no dropout)
        assert taken == [True, False, True, False, False, True]
        assert source.report()["frames"] == 3 and source.report()["held_skipped"] == 3
        assert all(source(0.7 + 0.1 * k, {"cube": aloft}) for k in range(3))  # not held: every period
        assert all(source(1.0 + 0.1 * k, {"cube": resting}, held={"cube"}) for k in range(3))  # on the table: every
        assert source.report()["frames"] == 9
    finally:
        source.close()


@needs_gl
def test_while_every_object_rests_away_from_the_robot_the_head_takes_every_rest_every_th_frame() -> None:
    from nextage_qp.sensing.camera.source import CameraMeasurer
    from nextage_qp.sensing.perception_config import PerceptionConfig

    cfg = PerceptionConfig(source="camera", rest_every=3, hand_cameras=())  # the head alone
    robot, data, q = _scene(0.25)
    resting = _truth(robot, data)
    source = CameraMeasurer(cfg, robot, data, lambda t: q, seed=0)
    try:
        taken = [bool(source(0.1 * k, {"cube": resting})) for k in range(9)]
        # two fits before it is known still, then every third period (no frame: nothing measured, no dropout)
        assert taken == [True, True, True, False, False, True, False, False, True]
        assert source.report()["rest_skipped"] == 4
        assert all(source(1.0 + 0.1 * k, {"cube": resting}, held={"cube"}) for k in range(3))  # held: every period
    finally:
        source.close()
    robot, data, q = _scene(0.03)  # a hand beside it
    source = CameraMeasurer(cfg, robot, data, lambda t: q, seed=0)
    try:
        near = _truth(robot, data)
        assert all(source(0.1 * k, {"cube": near}) for k in range(6))
        assert source.report()["rest_skipped"] == 0
    finally:
        source.close()
