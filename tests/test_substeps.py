"""A tick's physics steps as one MuJoCo rollout give the loop's state, forces and contact counts to the last bit."""

import mujoco
import numpy as np
import pytest

from nextage_qp.control import load_gains
from nextage_qp.manipulation.metrics import OutcomeMonitor
from nextage_qp.robot import Robot
from nextage_qp.scene import BodyPose, SceneOverrides
from nextage_qp.sim import Simulation
from nextage_qp.substeps import force_sensor_addresses


def _walk(sim: Simulation, ticks: int, seed: int = 0) -> list[np.ndarray]:
    """Random shaped targets around home; every tick's (qpos, qvel, forces, sensor rows)."""
    rng = np.random.default_rng(seed)
    home = sim.robot.keyframe_q()
    sim.reset(home)
    out = []
    for k in range(ticks):
        if k % 25 == 0:
            sim.set_target(np.clip(home + rng.normal(0.0, 0.3, home.size), sim.robot.lower, sim.robot.upper))
        sim.tick()
        d = sim.data
        out.append(np.concatenate([d.qpos, d.qvel, sim.substeps.force.ravel(), sim.substeps.sensordata.ravel()]))
    return out


def test_every_actuator_of_a_composed_scene_has_a_force_sensor(push_robot):
    lo, hi = int(push_robot.actuator_ids.min()), int(push_robot.actuator_ids.max()) + 1
    adr = force_sensor_addresses(push_robot.model, range(lo, hi))
    assert adr is not None and len(adr) == push_robot.nq


def test_a_rollout_and_the_python_loop_step_to_the_same_bits(push_robot):
    gains = load_gains("default")
    rolled = Simulation(push_robot, gains)
    looped = Simulation(Robot.from_scene("push_cube"), gains)
    looped.substeps._rollout = None  # the loop only
    a, b = _walk(rolled, 150), _walk(looped, 150)
    assert rolled.substeps.rolled and not looped.substeps.rolled
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    # The forces the rollout reports are MuJoCo's applied actuator forces of the last step.
    np.testing.assert_array_equal(rolled.substeps.force[-1], rolled.data.actuator_force[push_robot.actuator_ids])
    assert rolled.pd.ticks == looped.pd.ticks == 150 * rolled.n_substeps


def test_an_applied_force_or_a_step_hook_runs_the_loop(push_robot):
    sim = Simulation(push_robot, load_gains("default"))
    sim.reset(push_robot.keyframe_q())
    sim.tick()
    assert sim.substeps.rolled
    body = push_robot.model.body("cube").id
    sim.data.xfrc_applied[body, :3] = [0.0, 0.5, 0.0]  # a shove: the rollout's reset of the data would clear it
    sim.tick()
    assert not sim.substeps.rolled and sim.data.xfrc_applied[body, 1] == 0.5
    sim.data.xfrc_applied[:] = 0.0
    steps = []
    sim.substep_hooks.append(lambda s: steps.append(s.time))
    sim.tick()
    assert not sim.substeps.rolled
    assert steps == pytest.approx(sim.time - sim.ctrl_dt + sim.sim_dt * np.arange(1, sim.n_substeps + 1))


def test_the_obstacles_touching_steps_are_counted_alike_rolled_or_looped():
    """With the wall moved onto the left wrist, the sensor rows of a rollout count the contact list's steps."""
    wall = SceneOverrides(poses={"obstacle": BodyPose(pos=(0.505, 0.23, 1.03), yaw=0.0)})
    counts = []
    for loop in (False, True):
        robot = Robot.from_scene("dock_dumbbell", wall)
        sim = Simulation(robot, load_gains("default"))
        if loop:
            sim.substeps._rollout = None
        monitor = OutcomeMonitor(robot, "dumbbell")
        monitor.attach(sim)
        assert not sim.substep_hooks  # the contact sensor counts: no per-step hook
        sim.reset(robot.keyframe_q())
        sim.set_target(robot.keyframe_q())
        sim.run(0.2)
        counts.append(monitor.obstacle_contacts)
    assert counts[0] == counts[1] > 0


def test_a_model_without_force_sensors_runs_the_loop():
    spec = mujoco.MjSpec.from_string("""<mujoco><worldbody><body><joint name="j"/><geom size=".1" mass="1"/></body>
        </worldbody><actuator><motor name="m" joint="j"/></actuator></mujoco>""")
    model = spec.compile()
    assert force_sensor_addresses(model, [0]) is None
