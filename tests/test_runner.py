"""The runner: its sequencing (the stale-pose case, plug-in kinds) and the metrics of a run."""

from pathlib import Path
from typing import Literal

import mujoco
import numpy as np
import pytest
import yaml

from nextage_qp.errors import ConfigError
from nextage_qp.ik import FrameTarget
from nextage_qp.kinematics.frames import Kinematics
from nextage_qp.loop.pd import load_gains
from nextage_qp.loop.servo import Command
from nextage_qp.loop.simulation import Simulation
from nextage_qp.manipulation.config import SuccessCriteria, load_config
from nextage_qp.manipulation.context import View
from nextage_qp.manipulation.metrics import OutcomeMonitor, PhaseRecord, summarize
from nextage_qp.manipulation.phases import Phase, Spec, register, unregister
from nextage_qp.manipulation.phases.base import name_field
from nextage_qp.manipulation.runner import Runner
from nextage_qp.robots.model import Robot

ROOT = Path(__file__).resolve().parents[1]
PUSH = ROOT / "configs" / "push_cube.yaml"


def test_stale_pose_after_a_joints_phase(tmp_path):
    """A move after a joints phase starts at the tool's real pose and never outruns its speed by 20 %.

    The IK's posture target is the joints phase's own, so the move's null space does not swing the arm back to
    home (that swing would be the posture task at work, not a stale pose).
    """
    robot = Robot.from_scene("push_cube")
    q = robot.keyframe_q("home")
    q[robot.joint_index("LARM_JOINT0")] = 0.5
    tool = Kinematics(robot).fk("left_tool", q).pos
    goal = (tool + np.array([0.06, -0.04, 0.03])).round(4).tolist()
    doc = yaml.safe_load(PUSH.read_text())
    doc["ik"]["posture_target"] = {"LARM_JOINT0": 0.5}
    doc["phases"] = [
        {"kind": "joints", "positions": {"LARM_JOINT0": 0.5}, "tolerance": 0.0005},
        {"kind": "move", "name": "move", "speed": 0.1, "tolerance": 0.002,
         "targets": [{"frame": "left_tool", "offset": goal}]},
    ]
    path = tmp_path / "stale.yaml"
    path.write_text(yaml.safe_dump(doc))
    runner = Runner(load_config(path), str(path))
    first, seen = {}, {}

    def on_tick(r, phase):
        if phase is not None and phase.name == "move" and not first:
            first["setpoint"] = phase.points[0].pos.copy()  # the setpoint of the move's first tick
            first["commanded_at_start"] = seen["commanded"]
            first["measured"] = seen["tool"]  # the tool as the move saw it when it started
            first["t"] = r.sim.time
        seen["tool"] = r.view.frame_pose("left_tool").pos
        seen["commanded"] = r.view.commanded_pose("left_tool").pos

    result = runner.run(on_tick)
    assert result["error"] is None, result["error"]
    assert np.linalg.norm(first["setpoint"] - first["measured"]) < 1e-3
    # the move started from the pose at the commanded joints of that tick (one step from rest: accel x dt^2)
    assert np.linalg.norm(first["setpoint"] - first["commanded_at_start"]) == pytest.approx(1.0 * runner.sim.ctrl_dt**2)
    rec = runner.sim.recorder.arrays()
    during = rec["t"] >= first["t"] - runner.sim.ctrl_dt
    p = rec["frame_left_tool"][during, :3]  # one row per control tick
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / runner.sim.ctrl_dt
    assert speed.max() <= 1.2 * 0.1


class NudgeSpec(Spec):
    """Raise a tool frame by ``dz`` from where it is commanded."""

    kind: Literal["nudge"]
    frame: str = name_field("frame")
    dz: float = 0.02


class Nudge(Phase):
    spec: NudgeSpec

    def start(self, view: View) -> None:
        self.goal = view.commanded_pose(self.spec.frame).pos + np.array([0.0, 0.0, self.spec.dz])

    def update(self, view: View) -> Command:
        err = float(np.linalg.norm(view.frame_pose(self.spec.frame).pos - self.goal))
        self.info["error_m"] = err
        return Command((FrameTarget(self.spec.frame, pos=self.goal),), done=err < 0.002 and view.settled())


@pytest.fixture
def nudge_kind():
    register(NudgeSpec, Nudge)
    yield
    unregister("nudge")


def test_a_phase_kind_added_from_a_test_module_runs_from_yaml(tmp_path, nudge_kind):
    doc = yaml.safe_load(PUSH.read_text())
    doc["phases"] = [{"kind": "nudge", "frame": "left_tool", "dz": 0.03, "timeout": 5.0}]
    path = tmp_path / "nudge.yaml"
    path.write_text(yaml.safe_dump(doc))
    result = Runner(load_config(path), str(path)).run()
    assert result["phases"][0]["kind"] == "nudge" and result["phases"][0]["status"] == "done"
    assert result["phases"][0]["error_m"] < 0.002
    doc["phases"][0]["frame"] = "left_toll"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match=r"phases\[0\]\.frame: 'left_toll' is not valid; valid: left_wrist"):
        Runner(load_config(path), str(path))
    doc["phases"][0]["kind"] = "nudg"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match="unknown kind; valid: move, push, grasp, carry, place, release, joints, wait, drive, nudge"):
        load_config(path)


def test_metrics_flag_a_drop_and_success_needs_every_criterion(dock_robot):
    from tests_support import held_grip_at

    sim = Simulation(dock_robot, load_gains("default"), frames=("left_pad", "right_pad"))
    sim.reset(dock_robot.keyframe_q("home"))
    monitor = OutcomeMonitor(dock_robot, "dumbbell")
    monitor.attach(sim)
    grip = held_grip_at(sim, dock_robot, "dumbbell", shift=0.05)  # offsets 5 cm off, as from a wrong estimate
    monitor.check_hold(sim, grip)
    assert not monitor.dropped  # measured on the truth: the object has not moved in the pads
    model, data = dock_robot.model, sim.data
    adr = int(model.jnt_qposadr[model.body_jntadr[model.body("dumbbell").id]])
    data.qpos[adr] += 0.05  # the object falls away from the pads
    mujoco.mj_kinematics(model, data)
    monitor.check_hold(sim, grip)
    assert monitor.dropped
    data.qpos[adr] -= 0.05
    mujoco.mj_kinematics(model, data)
    sim.tick()
    records = [PhaseRecord("a", "wait", "done", 0.0, 0.004, {"x": 1})]
    out = summarize(task="t", robot=dock_robot, sim=sim, monitor=monitor, records=records, obj="dumbbell",
                    target="dumbbell_target", criteria=SuccessCriteria(planar_error=1.0), error=None, wall_s=0.1)
    assert out["criteria"]["object_error"]["ok"] and not out["criteria"]["not_dropped"]["ok"]
    assert out["success"] is False and out["failed_criteria"] == ["not_dropped"]
    assert out["phases"] == [{"name": "a", "kind": "wait", "status": "done", "start_s": 0.0, "duration_s": 0.004,
                              "x": 1}]
    assert out["min_obstacle_clearance_m"] > 0.0
