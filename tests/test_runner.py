"""The servo tick, the runner's sequencing (stale-pose case, plug-in kinds), the metrics, and the layer's shape."""

import ast
from pathlib import Path
from typing import Literal

import mujoco
import numpy as np
import pytest
import yaml

from nextage_qp.control import load_gains
from nextage_qp.errors import ConfigError
from nextage_qp.ik import QPIK, FrameTarget, IKConfig
from nextage_qp.kinematics import Kinematics
from nextage_qp.manipulation.config import SuccessCriteria, load_config
from nextage_qp.manipulation.context import View
from nextage_qp.manipulation.metrics import OutcomeMonitor, PhaseRecord, summarize
from nextage_qp.manipulation.phases import Phase, Spec, register, unregister
from nextage_qp.manipulation.phases.base import name_field
from nextage_qp.manipulation.runner import Runner
from nextage_qp.robot import Robot
from nextage_qp.servo import HOLD, Command, Servo
from nextage_qp.sim import Simulation

ROOT = Path(__file__).resolve().parents[1]
PUSH = ROOT / "configs" / "push_cube.yaml"


@pytest.fixture
def servo(push_robot):
    sim = Simulation(push_robot, load_gains("default"))
    q0 = push_robot.keyframe_q("home")
    sim.reset(q0)
    return Servo(QPIK(push_robot, IKConfig()), sim, q0)


def test_servo_joint_goal_is_clipped_and_the_commanded_pose_follows_at_once(servo):
    robot = servo.robot
    kin = Kinematics(robot)
    q = servo.step(Command(joints={"LARM_JOINT0": 0.5, "LARM_JOINT1": -9.0}))
    j0, j1 = robot.joint_index("LARM_JOINT0"), robot.joint_index("LARM_JOINT1")
    assert q[j0] == 0.5 and q[j1] == robot.lower[j1]
    assert np.allclose(servo.sim.traj.target, q)
    assert np.allclose(servo.commanded_pose("left_tool").pos, kin.fk("left_tool", q).pos, atol=1e-12)


def test_servo_frame_command_integrates_one_ik_step_and_hold_keeps_q(servo):
    q0 = np.array(servo.q_cmd)
    start = servo.commanded_pose("left_tool").pos
    goal = start + np.array([0.0, 0.0, 0.05])
    q1 = servo.step(Command((FrameTarget("left_tool", pos=goal),)))
    moved = servo.commanded_pose("left_tool").pos
    assert 0 < np.max(np.abs(q1 - q0)) <= 3.0 * servo.sim.ctrl_dt + 1e-12  # the default velocity limit x dt
    assert np.linalg.norm(goal - moved) < np.linalg.norm(goal - start)
    assert np.array_equal(servo.step(HOLD), q1)
    with pytest.raises(ValueError):
        servo.q_cmd[0] = 1.0  # read-only view


class _CyclingIK:
    """An IK whose full-speed step flips sign every call: the limit cycle the servo's trust region must damp."""

    def __init__(self, box) -> None:
        self.box, self.sign, self.v = box, 1.0, box.vmax.copy()
        self.config = IKConfig(trust_region=True)
        self.nb = 0  # a fixed robot: no base variables

    def step(self, q, targets, dt, **_):
        self.sign = -self.sign
        return self.sign * self.v


def test_servo_trust_region_damps_a_cycle_only_under_an_unchanged_command(servo):
    servo.ik = _CyclingIK(servo.ik.box)
    hold_here = Command((FrameTarget("left_tool", pos=np.array([0.3, 0.2, 1.0])),))
    swings = []
    for _ in range(8):
        q0 = np.array(servo.q_cmd)
        swings.append(float(np.max(np.abs(servo.step(hold_here) - q0))))
    assert swings[0] == pytest.approx(np.max(servo.ik.v) * servo.sim.ctrl_dt)  # the first step is taken whole
    assert swings[-1] == pytest.approx(swings[0] / 64)  # each reversal halves the step, down to 1/64
    assert servo.scale == pytest.approx(1 / 64)
    moving = [Command((FrameTarget("left_tool", pos=np.array([0.3, 0.2, 1.0 + 0.001 * (k + 1)])),)) for k in range(7)]
    scales = []
    for command in moving:  # a target that moves: reversals are the target's, not a cycle; the scale regrows
        servo.step(command)
        scales.append(servo.scale)
    assert scales == [1 / 32, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 1.0]
    servo.ik.v *= 0.4  # slow steps that turn back (a converged IK's small back-and-forth) are left alone
    for _ in range(3):
        servo.step(hold_here)
        assert servo.scale == 1.0
    servo.ik.config = IKConfig()  # off (the default): every step is taken whole
    servo.ik.v /= 0.4
    for _ in range(3):
        q0 = np.array(servo.q_cmd)
        assert np.max(np.abs(servo.step(hold_here) - q0)) == pytest.approx(swings[0])


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


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
    return found


def test_layering_tools_and_phases():
    pkg = ROOT / "nextage_qp"
    for tool in (ROOT / "tools").glob("*.py"):
        assert not any(m.startswith("nextage_qp.commands") for m in _imports(tool)), tool
    for module in (pkg / "manipulation" / "phases").glob("*.py"):
        assert "mink" not in _imports(module), module
    for module in pkg.rglob("*.py"):
        assert not any(m.startswith("nextage_qp.commands") for m in _imports(module)) or "commands" in module.parts \
            or module.name == "cli.py", module


def test_no_module_over_about_250_lines():
    long = {str(p.relative_to(ROOT)): n for p in (ROOT / "nextage_qp").rglob("*.py")
            if (n := len(p.read_text().splitlines())) > 275}
    assert not long


class _TwoStepCyclingIK(_CyclingIK):
    """An IK whose full-speed step turns back every second call: two steps each way, a cycle of four ticks."""

    def __init__(self, box) -> None:
        super().__init__(box)
        self.calls = 0

    def step(self, q, targets, dt, **_):
        self.calls += 1
        return (1.0 if self.calls % 4 in (1, 2) else -1.0) * self.v


def test_servo_trust_region_keeps_a_slower_cycle_damped_until_the_command_changes(servo):
    servo.ik = _TwoStepCyclingIK(servo.ik.box)
    hold_here = Command((FrameTarget("left_tool", pos=np.array([0.3, 0.2, 1.0])),))
    scales = []
    for _ in range(12):
        servo.step(hold_here)
        scales.append(servo.scale)
    # each reversal halves the scale and the ticks between do not grow it back: the swing keeps shrinking
    assert scales == [1.0, 1.0, 0.5, 0.5, 0.25, 0.25, 0.125, 0.125, 1 / 16, 1 / 16, 1 / 32, 1 / 32]
    servo.step(Command((FrameTarget("left_tool", pos=np.array([0.3, 0.2, 1.01])),)))  # a new command
    assert servo.scale == pytest.approx(1 / 16)  # grows back again (doubling, up to 1)
