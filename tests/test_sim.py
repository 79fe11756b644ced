import json

import numpy as np
import pytest
from pydantic import ValidationError
from tests_support import NEXTAGE_JOINTS as JOINT_NAMES

from nextage_qp.errors import SimulationError
from nextage_qp.loop.pd import Gains, PDController, load_gains
from nextage_qp.loop.reference import TrajectoryLimits
from nextage_qp.loop.simulation import Simulation, Timing
from nextage_qp.robots.model import Robot

N = len(JOINT_NAMES)


@pytest.fixture(scope="module")
def gains():
    return load_gains("default")


def test_holds_home_and_records_every_control_tick(push_robot, gains):
    sim = Simulation(push_robot, gains, frames=("left_wrist", "right_tool"))
    home = push_robot.keyframe_q()
    sim.reset(home)
    sim.set_target(home)
    sim.run(0.5)
    assert sim.time == pytest.approx(0.5)
    a = sim.recorder.arrays()
    assert len(a["t"]) == 125 and np.allclose(np.diff(a["t"]), 0.004)
    assert a["q"].shape == a["tau"].shape == (125, N)
    assert np.max(np.abs(a["q"] - home)) < 1e-3
    assert a["frame_left_wrist"].shape == (125, 7) and a["object_cube"].shape == (125, 7)
    assert sim.pd.ticks == 500  # the saturation counters see every physics step
    np.testing.assert_allclose(a["object_cube"][0, :3], [0.33, 0.0, 0.91], atol=1e-3)


def test_shaped_target_tracked_within_limits(robot, gains):
    limits = TrajectoryLimits(max_velocity=0.8, max_acceleration=3.0, max_jerk=30.0)
    sim = Simulation(robot, gains, limits, frames=())
    home = robot.keyframe_q()
    target = robot.q_from_names({"LARM_JOINT0": 0.4, "LARM_JOINT1": -0.9, "RARM_JOINT2": -0.5}, base=home)
    sim.reset(home)
    sim.set_target(target)
    sim.run(2.0)
    assert sim.traj.done
    a = sim.recorder.arrays()
    v, _, _ = limits.arrays(JOINT_NAMES)
    assert np.all(np.abs(a["qd_ref"]) <= v + 1e-9)
    assert np.max(np.abs(sim.q - target)) < 1e-3
    assert np.all(np.abs(a["tau"]) <= robot.torque_limit + 1e-9)


def test_hooks_run_every_tick_and_extra_signals_saved(robot, gains, tmp_path):
    sim = Simulation(robot, gains, frames=("left_wrist",))
    sim.reset(robot.keyframe_q())
    sim.hooks.append(lambda s: s.recorder.add("wrist_z", s.time, s.data.site_xpos[0][2:3]))
    sim.run(0.1)
    sim.recorder.meta["note"] = "hook test"
    js = sim.recorder.save(tmp_path / "run.npz")
    with np.load(tmp_path / "run.npz") as z:
        assert z["extra_wrist_z"].shape == (25, 1) and z["extra_wrist_z_t"][-1] == pytest.approx(0.1)
    summary = json.loads(js.read_text())
    assert summary["samples"] == 25 and summary["note"] == "hook test"


def test_stiff_damping_is_integrated_implicitly(robot):
    # kd * sim_dt / inertia >> 2 diverges when the PD law is explicit; in MuJoCo's actuators under the
    # implicitfast integrator the damping term is implicit and the joint settles.
    kd = np.full(N, 1.0)
    kd[JOINT_NAMES.index("LARM_JOINT5")] = 200.0
    sim = Simulation(robot, Gains(np.full(N, 10.0), kd, gravity_compensation=True), max_speed=5.0)
    sim.reset(robot.keyframe_q())
    target = robot.keyframe_q().copy()
    target[JOINT_NAMES.index("LARM_JOINT5")] = 0.1
    sim.set_target(target, shaped=False)
    sim.run(0.5)
    assert np.all(np.isfinite(sim.q)) and np.max(np.abs(sim.qd)) < 5.0


def test_divergence_is_caught_and_partial_log_written(robot, tmp_path):
    kp = np.full(N, 10.0)
    kp[JOINT_NAMES.index("LARM_JOINT5")] = 1e6  # kp * sim_dt**2 / inertia >> 1: the stiffness is explicit
    gains = Gains(kp, np.full(N, 1.0), gravity_compensation=True)
    sim = Simulation(robot, gains, frames=("left_wrist",), max_speed=5.0)
    home = robot.keyframe_q()
    sim.reset(home)
    target = home.copy()
    target[JOINT_NAMES.index("LARM_JOINT5")] = 0.1
    sim.set_target(target, shaped=False)
    with pytest.raises(SimulationError, match=r"t=\d+\.\d{3} s: joint LARM_JOINT5") as exc:
        sim.run(2.0)
    sim.recorder.save(tmp_path / "diverged.npz")
    summary = json.loads((tmp_path / "diverged.json").read_text())
    assert summary["error"] == str(exc.value)
    with np.load(tmp_path / "diverged.npz") as z:
        assert 0 < len(z["t"]) < 2000 and np.all(np.isfinite(z["q"][:4]))


def nan_velocity_from(t: float, dof: int):
    """A simulation hook that sets ``qvel[dof]`` to NaN from simulated time ``t`` on."""

    def corrupt(s):
        if s.time >= t:
            s.data.qvel[dof] = np.nan

    return corrupt


def test_nan_state_is_caught_with_time_and_joint(robot, gains, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo writes its warnings to MUJOCO_LOG.TXT in the working directory
    sim = Simulation(robot, gains, frames=())
    sim.reset(robot.keyframe_q())
    sim.hooks.append(nan_velocity_from(0.1, robot.dof_idx[JOINT_NAMES.index("RARM_JOINT2")]))
    with pytest.raises(SimulationError, match=r"t=0\.100 s: joint RARM_JOINT2 state is not finite"):
        sim.run(1.0)
    sim.recorder.save(tmp_path / "nan.npz")
    assert json.loads((tmp_path / "nan.json").read_text())["samples"] == 26


def test_ctrl_dt_must_be_multiple_of_sim_dt():
    with pytest.raises(ValidationError, match="must be a whole multiple of sim_dt"):
        Timing(ctrl_dt=0.0025)
    assert Timing(sim_dt=0.002, ctrl_dt=0.006).n_substeps == 3


def test_obstacle_contacts_are_counted_per_physics_step(gains):
    """With the wall moved onto the left wrist, every physics step in contact counts once."""
    from nextage_qp.manipulation.metrics import OutcomeMonitor
    from nextage_qp.scene.files import BodyPose, SceneOverrides

    wall = SceneOverrides(poses={"obstacle": BodyPose(pos=(0.505, 0.23, 1.03), yaw=0.0)})
    robot = Robot.from_scene("dock_dumbbell", wall)
    sim = Simulation(robot, gains)
    monitor = OutcomeMonitor(robot, "dumbbell")
    monitor.attach(sim)
    touching_steps = []

    def count(s: Simulation) -> None:
        obstacle = set(monitor.obstacle or ())
        d = s.data
        contacts = d.contact[: d.ncon]
        touching_steps.append(any((c.geom1 in obstacle) != (c.geom2 in obstacle) and c.dist < 0 for c in contacts))

    sim.substep_hooks.append(count)
    sim.run(0.048)
    assert len(touching_steps) == 48
    assert monitor.obstacle_contacts == sum(touching_steps) > 0
    assert monitor.min_clearance is not None and monitor.min_clearance < 0


def test_compiled_physics_loop_equals_the_python_loop(gains):
    """The compiled substep loop leaves the state, forces and obstacle-contact count of the Python loop, to the bit."""
    from nextage_qp.loop import stepping
    from nextage_qp.manipulation.metrics import OutcomeMonitor
    from nextage_qp.scene.files import BodyPose, SceneOverrides

    if not stepping.NATIVE:
        pytest.skip("MuJoCo's shared library not found: the simulation steps from Python only")
    wall = SceneOverrides(poses={"obstacle": BodyPose(pos=(0.505, 0.23, 1.03), yaw=0.0)})
    runs = []
    for python_loop in (False, True):
        robot = Robot.from_scene("dock_dumbbell", wall)
        sim = Simulation(robot, gains)
        monitor = OutcomeMonitor(robot, "dumbbell")
        monitor.attach(sim)
        if python_loop:
            sim.substep_hooks.append(lambda s: None)  # any Python hook takes the Python loop
        sim.set_target(robot.keyframe_q("home") + 0.05)
        sim.run(0.1)
        runs.append((sim.recorder.arrays(), monitor.obstacle_contacts, sim.physics_s, sim.data.qpos.copy()))
    (a, contacts_a, physics_a, q_a), (b, contacts_b, physics_b, q_b) = runs
    assert contacts_a == contacts_b > 0
    assert np.array_equal(q_a, q_b) and all(np.array_equal(a[k], b[k]) for k in a)
    assert physics_a > 0 and physics_b > 0


def test_actuators_apply_the_documented_pd_law(robot):
    # The law runs in MuJoCo's actuators; the torque they applied matches PDController.torque (numpy) on the
    # recorded state, saturation included.
    gains = Gains(np.full(N, 300.0), np.full(N, 20.0), gravity_compensation=False)
    sim = Simulation(robot, gains)
    sim.reset(robot.keyframe_q())
    target = robot.keyframe_q() + 0.3  # a raw step far enough for some joints to saturate at first
    sim.set_target(target, shaped=False)
    sim.run(0.2)
    a = sim.recorder.arrays()
    law = PDController(gains, robot.torque_limit)
    rows = zip(a["q"], a["qd"], a["q_ref"], a["qd_ref"], strict=True)
    expected = np.array([law.torque(q, qd, qr, qdr) for q, qd, qr, qdr in rows])
    np.testing.assert_allclose(a["tau"], expected, atol=1e-6)
    # the counters see every physics step, the log one per tick
    assert sim.pd.ticks == 4 * len(a["t"]) and sim.pd.any_saturated_ticks >= law.any_saturated_ticks > 0


def test_frames_recorded_raw_read_back_as_unit_quaternions():
    import mujoco

    from nextage_qp.geometry import mats_to_quats

    rng = np.random.default_rng(0)
    quats = rng.normal(size=(200, 4))
    quats[:4] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]  # every pivot branch
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    mats = np.empty((len(quats), 9))
    for q, m in zip(quats, mats, strict=True):
        mujoco.mju_quat2Mat(m, q)
    got = mats_to_quats(mats)
    np.testing.assert_allclose(got, quats * np.sign(quats[:, :1] + 1e-300), atol=1e-9)


def test_object_nan_fails_with_mujocos_warning_and_writes_no_log_file(gains, tmp_path, monkeypatch):
    import mujoco

    from nextage_qp.native.mj_warnings import capture_mujoco_warnings
    from nextage_qp.robots.model import Robot

    monkeypatch.chdir(tmp_path)
    previous = mujoco.get_mju_user_warning()
    capture_mujoco_warnings()
    try:
        robot = Robot.from_scene("push_cube")
        sim = Simulation(robot, gains, frames=())
        sim.reset(robot.keyframe_q())
        sim.hooks.append(nan_velocity_from(0.05, robot.model.jnt_dofadr[robot.model.body("cube").jntadr[0]]))
        with pytest.raises(SimulationError, match=r"not finite.*\(MuJoCo: Nan, Inf or huge value in QVEL"):
            sim.run(0.5)
    finally:
        mujoco.set_mju_user_warning(previous)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
