import json

import pytest

from nextage_qp.cli import main
from nextage_qp.ik import FrameTarget
from nextage_qp.ik.baselines import dls_ik, lm_ik, pinv_ik
from nextage_qp.kinematics.frames import Kinematics
from nextage_qp.robots.model import Robot


@pytest.fixture(scope="module")
def robot() -> Robot:
    return Robot.from_scene("scene")


@pytest.mark.parametrize("method", [pinv_ik, dls_ik, lm_ik])
def test_baselines_reach_easy_target(robot: Robot, method) -> None:  # type: ignore[no-untyped-def]
    kin = Kinematics(robot)
    goal = robot.q_from_names({"LARM_JOINT1": -0.7, "LARM_JOINT2": 0.2, "LARM_JOINT4": -0.3})
    pose = kin.fk("left_wrist", goal)
    res = method(robot, [FrameTarget("left_wrist", pos=pose.pos, rot=pose.rot)], robot.keyframe_q("home"))
    assert res.converged and res.pos_err_m <= 1e-4 and res.rot_err_rad <= 1e-3
    assert robot.within_limits(res.q)


def test_pinv_averages_chest_of_two_arm_solves(robot: Robot) -> None:
    kin = Kinematics(robot)
    goal = robot.q_from_names({"CHEST_JOINT0": 0.5, "LARM_JOINT1": -0.6, "RARM_JOINT1": -0.6})
    targets = [FrameTarget(f, pos=kin.fk(f, goal).pos) for f in ("left_wrist", "right_wrist")]
    res = pinv_ik(robot, targets, robot.keyframe_q("home"))
    # Each arm solve has its own chest angle; the mean generally misses both wrists.
    assert res.q[0] != 0.0
    assert robot.within_limits(res.q)


def test_cli_json(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["ik", "--frame", "LARM_JOINT5_Link", "--pos", "0.45", "0.2", "1.0", "--axis", "0", "0", "1", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["converged"]
    assert set(out["q"]) >= {"CHEST_JOINT0", "RARM_JOINT5"} and len(out["q"]) == 15
    assert out["pos_err_m"] <= 1e-4 and out["iters"] >= 1 and out["time_s"] > 0


def test_cli_two_frames_table_and_method(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["ik", "--frame", "left_wrist", "--pos", "0.45", "0.2", "1.0", "--frame2", "right_wrist", "--pos2", "0.45",
            "-0.2", "1.0", "--method", "lm", "--from", "zero"]  # fmt: skip
    assert main(argv) == 0
    assert "LARM_JOINT0" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--frame", "left_hnd", "--pos", "0.4", "0.2", "1"], "unknown frame"),
        (["--frame", "left_wrist", "--pos", "0.4", "0.2", "1", "--solver", "nosuch"], "not installed"),
        (["--frame", "left_wrist", "--pos", "0.4", "0.2", "1", "--from", "up"], "--from"),
        (["--frame", "left_wrist", "--pos", "0.4", "0.2", "1", "--frame2", "right_wrist"], "--pos2"),
        (["--frame", "left_wrist", "--pos", "0.4", "0.2", "1", "--pos2", "0.4", "0.2", "1"], "--frame2"),
        (
            [
                "--frame",
                "left_wrist",
                "--pos",
                "0.4",
                "0.2",
                "1",
                "--axis",
                "0",
                "0",
                "1",
                "--quat",
                "1",
                "0",
                "0",
                "0",
            ],
            "exclude",
        ),
        (["--frame", "left_wrist", "--pos", "0.4", "0.2", "1", "--dir", "0", "0", "1"], "--axis"),
    ],
)
def test_cli_errors_exit_2(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ik", *argv]) == 2
    assert message in capsys.readouterr().err


def test_cli_unreachable_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    """Within the wrist's reach sphere but out of its reach (above the head): solved, not converged, exit 1."""
    assert main(["ik", "--frame", "left_wrist", "--pos", "0", "0", "2.05", "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["converged"] is False


def test_cli_beyond_the_reach_sphere_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    """Beyond every configuration's reach: refused before solving, one line, exit 2."""
    assert main(["ik", "--frame", "left_wrist", "--pos", "2", "0", "1", "--json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "out of reach: 2.003 m from CHEST_JOINT0" in err[0], err
