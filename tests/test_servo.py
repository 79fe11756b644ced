"""The servo tick: joint and frame commands, the hold, the trust region that damps a cycling IK."""

from pathlib import Path

import numpy as np
import pytest

from nextage_qp.ik import QPIK, FrameTarget, IKConfig
from nextage_qp.kinematics.frames import Kinematics
from nextage_qp.loop.pd import load_gains
from nextage_qp.loop.servo import HOLD, Command, Servo
from nextage_qp.loop.simulation import Simulation

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
