"""Stereo depth from the head's two RGB cameras: static accuracy per shape, the pair's checks, the world's texture."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from test_vision import PROBLEM, PUSH, SHAPES, aimed_scene

from nextage_qp.errors import ConfigError
from nextage_qp.geometry import wrap
from nextage_qp.manipulation.config import load_config
from nextage_qp.manipulation.runner import Runner, build_robot
from nextage_qp.robots.cameras import CameraFile
from nextage_qp.scene.texture import MATERIAL
from nextage_qp.sensing.camera.stereo import check_pair

CV2 = importlib.util.find_spec("cv2") is not None
needs_stereo = pytest.mark.skipif(PROBLEM is not None or not CV2,
                                  reason=PROBLEM or "OpenCV missing: install the vision extra")
STEREO = ["perception.source=camera", "perception.depth=stereo"]


@needs_stereo
@pytest.mark.parametrize("shape", list(SHAPES))
@pytest.mark.parametrize("x", [0.3, 0.6])
def test_static_accuracy_stereo(shape: str, x: float) -> None:
    from nextage_qp.sensing.camera.source import CameraMeasurer

    yaw = 0.3 if x < 0.5 else -0.4
    cfg, robot, data, q = aimed_scene(shape, x, yaw, tuple(STEREO))
    camera = CameraMeasurer(cfg.perception, robot, data, lambda t: q, seed=0)
    try:
        pose = camera(0.0, {"cube": None})["cube"]
    finally:
        camera.close()
    assert pose is not None
    truth = data.xpos[robot.model.body("cube").id]
    dist = float(np.linalg.norm(truth - camera.camera.pose(q)[0]))
    assert 0.5 <= dist <= 1.1
    err = float(np.linalg.norm(pose[:3] - truth))
    assert err < 0.005, f"{shape} at {dist:.2f} m: {err * 1e3:.2f} mm"
    if shape not in ("cylinder", "capsule"):  # round: yaw unobservable and irrelevant
        yaw_err = abs(wrap(pose[5] - yaw, robot.yaw_symmetry("cube")))
        assert yaw_err < np.radians(5.0), f"{shape}: {np.degrees(yaw_err):.2f} deg"


@needs_stereo
def test_a_tracked_object_is_matched_in_a_window_as_in_the_whole_image() -> None:
    from nextage_qp.sensing.camera.source import CameraMeasurer
    from nextage_qp.sensing.camera.stereo import window

    cfg, robot, data, q = aimed_scene("box", 0.6, -0.4, tuple(STEREO))
    camera = CameraMeasurer(cfg.perception, robot, data, lambda t: q, seed=0)
    try:
        first = camera(0.0, {"cube": None})["cube"]  # not tracked yet: the whole image
        assert first is not None
        whole = camera.last[1]
        second = camera(1 / 15, {"cube": first})["cube"]  # tracked: a window around it
        part = camera.last[1]
        pos, rot = camera.camera.pose(q)
        win = camera.window({"cube": first}, pos, rot)
        report = camera.report()
    finally:
        camera.close()
    assert report["windowed_frames"] == 1 and win is not None
    r0, r1, c0, c1 = win
    assert (r1 - r0) * (c1 - c0) < 0.3 * whole.size
    inside = np.zeros(whole.shape, dtype=bool)
    inside[r0:r1, c0:c1] = True
    assert np.isnan(part[~inside]).all()
    both = inside & np.isfinite(whole) & np.isfinite(part)
    assert both.sum() > 0.8 * np.isfinite(whole[inside]).sum()
    assert np.mean(np.abs(whole[both] - part[both]) < 0.002) > 0.97  # the same matches, but near the window's edges
    truth = data.xpos[robot.model.body("cube").id]
    assert second is not None and np.linalg.norm(second[:3] - truth) < 0.005
    behind = pos + 0.2 * rot[:, 2] + 0.05 * np.array(list(np.ndindex(2, 2, 2))) - 0.025
    assert window(behind, camera.camera.K, pos, rot, whole.shape) is None  # behind it


def test_a_stereo_world_is_textured_beyond_the_robot_only() -> None:
    plain = build_robot(load_config(PUSH, []), str(PUSH)).model
    cfg = load_config(PUSH, STEREO)
    robot = build_robot(cfg, str(PUSH))
    model = robot.model
    mat = model.material(MATERIAL).id
    textured = {model.body(int(model.geom_bodyid[g])).name for g in range(model.ngeom) if model.geom_matid[g] == mat}
    assert {"table", "cube"} <= textured
    moved = {model.body(int(model.jnt_bodyid[model.joint(j).id])).name for j in robot.joint_names}
    assert moved and not textured & moved  # none of the robot's links
    # the physics is the same model's
    for attr in ("geom_size", "geom_friction", "body_mass", "geom_contype", "geom_conaffinity"):
        np.testing.assert_array_equal(getattr(model, attr), getattr(plain, attr))


def test_a_pair_that_is_not_rectified_is_one_line() -> None:
    left, right = CameraFile(body="b", pos=(0, 0.07, 0)), CameraFile(body="b", pos=(0, -0.07, 0))
    eye = np.eye(3)
    assert check_pair(left, right, eye, eye, np.array([0.14, 0.0, 0.0]), ("l", "r")) == pytest.approx(0.14)
    with pytest.raises(ConfigError, match=r"rectified as mounted .* name the cameras left first"):
        check_pair(left, right, eye, eye, np.array([-0.14, 0.0, 0.0]), ("r", "l"))  # swapped
    turned = np.array([[np.cos(0.1), 0, np.sin(0.1)], [0, 1, 0], [-np.sin(0.1), 0, np.cos(0.1)]])
    with pytest.raises(ConfigError, match=r"axes 5\.73 deg apart"):
        check_pair(left, right, eye, turned, np.array([0.14, 0.0, 0.0]), ("l", "r"))
    with pytest.raises(ConfigError, match=r"need the same width, height and fovx"):
        check_pair(left, right.model_copy(update={"width": 640}), eye, eye, np.array([0.14, 0, 0]), ("l", "r"))


@pytest.mark.skipif(PROBLEM is not None, reason=PROBLEM or "")
def test_stereo_config_errors_are_one_line() -> None:
    swapped = load_config(PUSH, [*STEREO, "perception.stereo=[head_right,head_left]"])
    with pytest.raises(ConfigError, match=r"perception.stereo \[head_right, head_left\]: the pair must be rectified"):
        Runner(swapped, str(PUSH))
    unknown = load_config(PUSH, [*STEREO, "perception.stereo=[head_left,eye]"])
    with pytest.raises(ConfigError, match=r"perception.stereo: 'eye' is not a camera of robot 'nextage'; valid: "):
        Runner(unknown, str(PUSH))
    apart = load_config(PUSH, [*STEREO, "perception.stereo=[head_left,head_rgbd]"])
    with pytest.raises(ConfigError, match=r"need the same width, height and fovx"):
        Runner(apart, str(PUSH))


def test_stereo_without_opencv_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    import builtins

    from nextage_qp.sensing.camera.stereo import StereoMatcher

    real = builtins.__import__

    def no_cv2(name: str, *args, **kwargs):
        if name == "cv2":
            raise ImportError("no cv2")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_cv2)
    with pytest.raises(ConfigError, match=r"stereo needs OpenCV; install the vision extra"):
        StereoMatcher(np.eye(3), 0.1)


def test_stereo_module_has_no_simulator_reads() -> None:
    import ast

    import nextage_qp.sensing.camera.stereo as stereo

    tree = ast.parse(Path(stereo.__file__).read_text())
    imported = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    imported |= {(n.module or "").split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert "mujoco" not in imported
