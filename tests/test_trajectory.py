import numpy as np
import pytest
from pydantic import ValidationError
from tests_support import NEXTAGE_JOINTS as JOINT_NAMES

from nextage_qp.errors import NextageQPError, TrajectoryError
from nextage_qp.loop.reference import JointTrajectory, TrajectoryLimits, chain_waypoints, plan_segment

N = len(JOINT_NAMES)
LIMITS = TrajectoryLimits(max_velocity=0.8, max_acceleration={"LARM_JOINT1": 2.0}, max_jerk=30.0)
TOL = 1e-6


def within_limits(qd, qdd, dt, limits=LIMITS):
    v, a, j = limits.arrays(JOINT_NAMES)
    jerk = np.diff(qdd, axis=0) / dt
    assert np.all(np.abs(qd) <= v + TOL)
    assert np.all(np.abs(qdd) <= a + TOL)
    # finite differences of a piecewise-linear acceleration never exceed the jerk bound
    assert np.all(np.abs(jerk) <= j * (1 + 1e-6) + TOL)


def test_limits_arrays_scalar_and_per_joint():
    v, a, j = LIMITS.arrays(JOINT_NAMES)
    assert v.shape == a.shape == j.shape == (N,)
    assert np.all(v == 0.8)
    assert a[JOINT_NAMES.index("LARM_JOINT1")] == 2.0 and a[0] == TrajectoryLimits().arrays(JOINT_NAMES)[1][0]


@pytest.mark.parametrize("kwargs", [{"max_velocity": -1.0}, {"max_jerk": float("nan")}, {"bogus": 1}])
def test_limits_rejects_bad_values(kwargs):
    with pytest.raises(ValidationError):
        TrajectoryLimits(**kwargs)


@pytest.mark.parametrize(
    "kwargs, words",
    [({"max_jerk": {"LARM_JOINT9": 1.0}}, "LARM_JOINT9"), ({"max_velocity": (1.0, 2.0)}, "needs 15 values")],
)
def test_limits_are_checked_against_the_robots_joints(kwargs, words):
    with pytest.raises(NextageQPError, match=words):
        TrajectoryLimits(**kwargs).arrays(JOINT_NAMES)


def test_online_reference_respects_limits_and_reaches_target():
    dt = 0.004
    gen = JointTrajectory(LIMITS, dt=dt, joint_names=JOINT_NAMES)
    q0 = np.zeros(N)
    target = np.linspace(-0.6, 0.9, N)
    gen.reset(q0)
    gen.set_target(target)
    states = []
    for _ in range(2000):
        states.append(gen.update())
        if gen.done:
            break
    assert gen.done and gen.is_at_target
    np.testing.assert_allclose(states[-1].q, target, atol=1e-9)
    qd = np.array([s.qd for s in states])
    qdd = np.array([s.qdd for s in states])
    within_limits(qd, qdd, dt)
    # the biggest move is limited by velocity: it needs at least distance / v_max
    assert len(states) * dt >= 0.9 / 0.8


def test_online_retargeting_every_tick_stays_within_limits():
    dt = 0.004
    gen = JointTrajectory(LIMITS, dt=dt, joint_names=JOINT_NAMES)
    gen.reset(np.zeros(N))
    states = []
    for k in range(600):
        gen.set_target(0.5 * np.sin(0.02 * k + np.arange(N)))  # a target that moves every tick
        states.append(gen.update())
    within_limits(np.array([s.qd for s in states]), np.array([s.qdd for s in states]), dt)
    # interpolation inside the last tick joins the previous and the new state
    np.testing.assert_allclose(gen.interpolate(dt).q, states[-1].q, atol=1e-9)
    np.testing.assert_allclose(gen.interpolate(0.0).q, states[-2].q, atol=1e-9)


def test_target_outside_joint_limits_names_joint():
    gen = JointTrajectory(LIMITS, dt=0.004, lower=-np.ones(N), upper=np.ones(N), joint_names=JOINT_NAMES)
    target = np.zeros(N)
    target[JOINT_NAMES.index("RARM_JOINT3")] = 1.5
    with pytest.raises(TrajectoryError, match="RARM_JOINT3"):
        gen.set_target(target)
    with pytest.raises(TrajectoryError, match="finite"):
        gen.set_target(np.full(N, np.nan))


def test_ruckig_input_error_is_typed_and_names_joint():
    bad = TrajectoryLimits.model_construct(max_velocity=1.0, max_acceleration=1.0, max_jerk=1.0)
    object.__setattr__(bad, "max_velocity", tuple([1.0] * 4 + [-1.0] + [1.0] * 10))
    with pytest.raises(TrajectoryError, match="LARM_JOINT1"):
        plan_segment(np.zeros(N), np.ones(N), bad, joint_names=JOINT_NAMES)


def test_chain_waypoints_passes_every_waypoint_within_limits():
    dt = 0.002
    wps = [np.zeros(N), np.full(N, 0.4), np.full(N, -0.2), np.zeros(N)]
    s = chain_waypoints(wps, LIMITS, dt=dt, joint_names=JOINT_NAMES)
    np.testing.assert_allclose(s.q[0], wps[0])
    np.testing.assert_allclose(s.q[-1], wps[-1], atol=1e-9)
    for wp in wps[1:-1]:  # each intermediate waypoint is visited (sampling at dt, so within one step)
        assert np.min(np.max(np.abs(s.q - wp), axis=1)) < 0.8 * dt + 1e-9
    assert np.all(np.diff(s.t) > 0) and np.allclose(np.diff(s.t)[:-1], dt)
    within_limits(s.qd, s.qdd, dt)


def test_chain_waypoints_needs_two():
    with pytest.raises(TrajectoryError, match="at least two"):
        chain_waypoints([np.zeros(N)], LIMITS, dt=0.01)


def test_a_state_ruckig_fails_on_numerically_is_stepped_with_the_target_a_picoradian_off():
    """A camera push's state (episode 97 of its sweep): Ruckig's profile search fails for joint 1 ("error in step 1"),
    synchronised or not; the step is solved with the target moved by 1e-12 rad."""
    q0 = [-0.2760662237123702, 0.283336304663246, 0.5745288260790065, -0.06311806678222627, -0.543650991415784,
          0.2144058656362579, 5.556524595524712e-06, 0.326814345989219, 0.389531522053482, 0.0, -0.4, 0.0, 0, 0, 0]
    v0 = [-0.243234885074084, 0.006609921144692034, -0.01329915464624131, 0.04325114303994779, -0.1545663387148554,
          0.1391124870830602, -9.819014214690293e-07, -0.04629669587106466, 0.07271818371120974, 0, 0, 0, 0, 0, 0]
    a0 = [-0.0875982128379329, -0.7271820209379238, 0, -0.1632665377704237, -1.868813111824615, 1.190172161908999,
          0, 0, -2.220446049250313e-16, 0, 0, 0, 0, 0, 0]
    target = [-0.6117005309115717, 0.3633763597950481, 0.5581129101786576, -0.0192969056216769, -0.6939503064134349,
              0.432947922721071, 4.125609640706765e-06, 0.2609198798685506, 1.518015006968197, 0, -0.4, 0, 0, 0, 0]
    gen = JointTrajectory(TrajectoryLimits(max_velocity=1.0, max_acceleration=4.0, max_jerk=40.0), dt=0.02,
                          joint_names=JOINT_NAMES)
    gen.reset(np.array(q0), np.array(v0))
    gen._inp.current_acceleration = a0  # the state mid-motion, as the last step left it
    gen.set_target(np.array(target))
    state = gen.update()
    assert np.isfinite(state.q).all() and abs(state.q[1] - 0.28337640001528) < 1e-12
