"""The object filter: converges, tracks, bridges dropouts, rejects outliers, restarts after a real jump."""

import numpy as np
import pytest

from nextage_qp.estimation.imm import PoseKalman
from nextage_qp.geometry import pose_vector, rot_of, rpy_of, vector_pose

SIGMA_POS, SIGMA_ROT, RATE = 0.002, 0.0175, 30.0


def measure(rng, truth):
    return truth + np.r_[rng.normal(0, SIGMA_POS, 3), rng.normal(0, SIGMA_ROT, 3)]


def settled(seed, truth, seconds=2.0):
    """A filter after ``seconds`` of measurements of an object resting at ``truth``, and its random stream."""
    rng = np.random.default_rng(seed)
    kf = PoseKalman(SIGMA_POS, SIGMA_ROT)
    for i in range(round(seconds * RATE)):
        kf.update(i / RATE, measure(rng, truth))
    return kf, rng


def test_rpy_round_trip():
    rng = np.random.default_rng(1)
    for rpy in rng.uniform([-0.5, -0.5, -3.0], [0.5, 0.5, 3.0], (20, 3)):
        np.testing.assert_allclose(rpy_of(rot_of(rpy)), rpy, atol=1e-12)
    pose = vector_pose(np.array([0.1, 0.2, 0.3, 0.05, -0.02, 1.0]))
    np.testing.assert_allclose(pose_vector(pose), [0.1, 0.2, 0.3, 0.05, -0.02, 1.0], atol=1e-12)


def test_converges_on_a_static_object():
    rng = np.random.default_rng(0)
    kf = PoseKalman(SIGMA_POS, SIGMA_ROT)
    truth = np.array([0.33, 0.0, 0.91, 0.0, 0.0, 0.4])
    errors = []
    for i in range(int(5 * RATE)):
        kf.update(i / RATE, measure(rng, truth))
        errors.append(np.linalg.norm(kf.estimate(i / RATE)[:3] - truth[:3]))
    late = np.sqrt(np.mean(np.square(errors[-60:])))  # the last 2 s
    assert late < 0.25 * SIGMA_POS * np.sqrt(3)  # the resting model averages: under a quarter of the raw noise
    assert abs(kf.estimate(5.0)[5] - 0.4) < 0.01
    assert kf.rejected == 0


def test_tracks_a_moving_object_with_latency_and_bridges_half_a_second_of_dropouts():
    rng = np.random.default_rng(2)
    kf = PoseKalman(SIGMA_POS, SIGMA_ROT)
    v, latency = np.array([0.08, -0.03, 0.0]), 0.02
    start = np.array([0.3, 0.1, 0.9])

    def truth(t):
        return np.r_[start + v * np.clip(t - 1.0, 0.0, None), 0.0, 0.0, 0.2]  # at rest, then moving at v

    errors = {}
    for i in range(int(6 * RATE)):
        t_sample = i / RATE
        gap = 4.0 <= t_sample < 4.5  # half a second without a single measurement
        if not gap:
            kf.update(t_sample, measure(rng, truth(t_sample)))  # it arrives latency later: applied at its stamp
        now = t_sample + latency
        errors[round(now, 4)] = np.linalg.norm(kf.estimate(now)[:3] - truth(now)[:3])
    moving = [e for t, e in errors.items() if 2.5 <= t < 4.0]
    bridged = [e for t, e in errors.items() if 4.0 <= t < 4.5 + latency]
    assert np.sqrt(np.mean(np.square(moving))) < 0.003
    assert max(bridged) < 0.006  # predicted through the gap at the estimated velocity
    np.testing.assert_allclose(kf.estimate(6.0)[:3], truth(6.0)[:3], atol=0.005)


def test_an_outlier_is_gated_and_a_real_jump_restarts_the_filter():
    truth = np.array([0.5, 0.0, 0.92, 0.0, 0.0, 0.0])
    kf, rng = settled(3, truth)
    before = kf.estimate(2.0).copy()
    assert not kf.update(2.0, truth + np.r_[0.05, 0, 0, 0, 0, 0])  # one 5 cm outlier
    np.testing.assert_allclose(kf.estimate(2.0), before, atol=1e-9)
    moved = truth + np.r_[0.0, 0.08, 0, 0, 0, 0]  # shoved 8 cm: every measurement from now on says so
    for i in range(10):
        kf.update(2.0 + (i + 1) / RATE, measure(rng, moved))
    assert kf.resets == 1
    np.testing.assert_allclose(kf.estimate(2.4)[:3], moved[:3], atol=0.006)


def test_partial_views_confirm_a_resting_object_never_move_it_and_clear_views_still_restart_the_filter():
    truth = np.array([0.5, 0.0, 0.92, 0.0, 0.0, 0.0])
    kf, rng = settled(3, truth)
    before = kf.estimate(2.5).copy()
    biased = truth + np.r_[0.05, 0, 0, 0, 0, 0]  # the hand in front: every partial view's fit 5 cm off, alike
    for i in range(6):
        assert not kf.update(2.0 + i / RATE, measure(rng, biased), partial=True)
    assert kf.resets == 0 and kf.rejected == 6
    np.testing.assert_allclose(kf.estimate(2.5), before, atol=1e-9)
    assert kf.update(2.5, measure(rng, truth), partial=True)  # a partial view where the object rests: it confirms
    moved = truth + np.r_[0.0, 0.08, 0, 0, 0, 0]  # then shoved: the clear views move it, partial ones between them
    for i in range(8):
        kf.update(2.5 + (i + 1) / RATE, measure(rng, moved if i % 2 == 0 else biased), partial=i % 2 == 1)
    np.testing.assert_allclose(kf.estimate(2.5 + 8 / RATE)[:3], moved[:3], atol=0.006)


def test_a_run_of_agreeing_partial_views_restarts_the_filter_at_rest_where_they_put_the_object():
    """A hand parked beside an object it nudged 15 mm covers it in every view: a second of partial views that agree
    with each other moves the estimate there (at rest: it stays), fewer do not, and partial views that disagree never
    do."""
    from nextage_qp.estimation.imm import PARTIAL_RUN

    truth = np.array([0.5, 0.0, 0.92, 0.0, 0.0, 0.3])
    nudged = truth + np.r_[0.012, 0.009, 0, 0, 0, 0.05]
    kf, rng = settled(4, truth)
    t = 2.0
    for _ in range(PARTIAL_RUN - 1):
        t += 1 / RATE
        assert not kf.update(t, measure(rng, nudged), partial=True)
    assert kf.resets == 0 and np.linalg.norm(kf.estimate(t)[:3] - truth[:3]) < 0.002
    t += 1 / RATE
    kf.update(t, measure(rng, nudged), partial=True)
    assert kf.resets == 1
    for dt in (0.0, 1.0):  # restarted at rest: where the views put it, not flying on
        assert np.linalg.norm(kf.estimate(t + dt)[:3] - nudged[:3]) < 0.002
    assert kf.update(t + 1 / RATE, measure(rng, nudged))  # and the clear views that follow confirm it
    kf, rng = settled(5, truth)
    for i in range(5 * PARTIAL_RUN):  # fits 3 cm apart from frame to frame: no restart, however many
        kf.update(2.0 + i / RATE, measure(rng, truth + np.r_[0.015 * (-1) ** i, 0.03, 0, 0, 0, 0]), partial=True)
    assert kf.resets == 0 and np.linalg.norm(kf.estimate(2.0 + 5 * PARTIAL_RUN / RATE)[:3] - truth[:3]) < 0.002


def test_each_axis_keeps_its_own_model_a_pushed_object_s_height_stays_averaged():
    rng = np.random.default_rng(5)
    kf = PoseKalman(SIGMA_POS, SIGMA_ROT)
    z_err, x_err = [], []
    for i in range(int(6 * RATE)):
        t = i / RATE
        truth = np.r_[0.3 + 0.04 * max(t - 1.0, 0.0) + 0.002 * np.sin(6.0 * t), 0.0, 0.91, 0.0, 0.0, 0.0]  # pushed
        kf.update(t, measure(rng, truth))
        if t > 3.0:
            est = kf.estimate(t)
            z_err.append(est[2] - truth[2])
            x_err.append(est[0] - truth[0])
    assert np.sqrt(np.mean(np.square(z_err))) < 0.3 * SIGMA_POS  # resting axis: averaged although x moves
    assert np.sqrt(np.mean(np.square(x_err))) < 0.8 * SIGMA_POS  # moving axis: tracked
    assert kf.mode[0, 2] > 0.5 and kf.mode[0, 0] < 0.5  # height resting, x not


def test_a_shoved_object_is_followed_at_its_new_velocity_within_three_camera_periods():
    rest = np.array([0.4, 0.0, 0.91, 0.0, 0.0, 0.0])
    kf, rng = settled(6, rest)
    v = np.r_[0.0, 2.0, 0.0, 0.0, 0.0, 0.0]  # shoved just after the last measurement: sliding at 2 m/s
    t0 = 59 / RATE
    stamps = [t0 + (i + 1) / RATE for i in range(3)]
    for t in stamps:
        kf.update(t, rest + v * (t - t0) + np.r_[rng.normal(0, 1e-4, 6)])
    assert kf.rejected >= 1 and kf.resets <= 1  # the first alone looks like an outlier
    assert kf.mode[2, 1] > 0.5  # manoeuvring
    ahead = stamps[-1] + 0.02  # predicted through the latency at the velocity the measurements showed
    assert abs(kf.estimate(ahead)[1] - 2.0 * (ahead - t0)) < 0.01


def test_yaw_wraps_across_pi():
    rng = np.random.default_rng(4)
    kf = PoseKalman(SIGMA_POS, SIGMA_ROT)
    for i in range(90):
        yaw = np.pi - 0.01 + 0.02 * (i % 2)  # measurements alternate either side of +-pi
        z = np.r_[0.3, 0.0, 0.9, 0.0, 0.0, (yaw + np.pi) % (2 * np.pi) - np.pi]
        kf.update(i / RATE, z + np.r_[rng.normal(0, 1e-4, 3), 0, 0, 0])
    assert kf.rejected == 0
    assert abs(np.cos(kf.estimate(3.0)[5]) + 1.0) < 1e-3


@pytest.mark.parametrize("noise", [0.0, 0.002])
def test_noiseless_and_noisy_cameras_both_accepted(noise):
    kf = PoseKalman(noise, 0.0)
    kf.update(0.0, np.zeros(6))
    assert kf.update(1 / RATE, np.zeros(6)) and kf.initialised


def _carrier(t):
    """A pad moving on a curve and turning: 0.1 m/s, 0.5 rad/s about z."""
    from nextage_qp.geometry import Pose, rot_z

    return Pose(np.array([0.3 + 0.1 * t, 0.05 * np.sin(t), 1.1]), rot_z(0.5 * t) @ rot_of(np.array([0.3, -0.2, 0.0])))


def test_a_held_object_is_estimated_relative_to_its_moving_carrier():
    from nextage_qp.estimation.held import HeldEstimate
    from nextage_qp.geometry import Pose

    rng = np.random.default_rng(5)
    offset = Pose(np.array([0.0, -0.06, -0.1]), rot_of(np.array([0.1, 0.0, 0.7])))  # object in the pad frame

    def truth(t):
        c = _carrier(t)
        return pose_vector(Pose(c.pos + c.rot @ offset.pos, c.rot @ offset.rot))

    world = PoseKalman(SIGMA_POS, SIGMA_ROT)
    dt, latency = 0.004, 0.02
    held = HeldEstimate(0.0, _carrier(0.0), truth(0.0), np.full(6, SIGMA_POS**2), PoseKalman(SIGMA_POS, SIGMA_ROT))
    pending, errors, world_errors = [], [], []
    for k in range(int(6.0 / dt)):
        t = k * dt
        held.observe(t, _carrier(t))
        if k % round(1 / (RATE * dt)) == 0:
            pending.append((t + latency, t, measure(rng, truth(t))))
        while pending and pending[0][0] <= t + 1e-9:
            _, stamp, z = pending.pop(0)
            held.update(stamp, z)
            world.update(stamp, z)
        if t > 2.0:
            errors.append(np.linalg.norm(held.estimate(t)[:3] - truth(t)[:3]))
            world_errors.append(np.linalg.norm(world.estimate(t)[:3] - truth(t)[:3]))
    rms, world_rms = np.sqrt(np.mean(np.square(errors))), np.sqrt(np.mean(np.square(world_errors)))
    assert rms < 0.5 * SIGMA_POS * np.sqrt(3)  # the hold averages the noise although the object moves
    assert rms < 0.6 * world_rms  # and beats the world-frame filter on the same measurements (about 0.5)


def test_faulty_sensors_hand_a_held_object_over_without_a_jump():
    from nextage_qp.sensing.faults import EstimationConfig, FaultsConfig
    from nextage_qp.sensing.faulty import FaultySensors

    faults = FaultsConfig.model_validate({"object_pose": {"rate_hz": 30, "latency_s": 0.02, "noise_pos_m": SIGMA_POS,
                                                          "noise_rot_rad": SIGMA_ROT}})
    sensors = FaultySensors(faults, EstimationConfig(), seed=3)
    offset = np.array([0.0, -0.06, -0.1])
    dt, ests, truth = 0.004, [], []
    for k in range(int(4.0 / dt)):
        t = k * dt
        held = 1.0 <= t < 3.0
        c = _carrier(max(min(t, 3.0) - 1.0, 0.0))  # the object rests, is carried for 2 s, rests again
        obj = vector_pose(pose_vector(type(c)(c.pos + c.rot @ offset, c.rot)))
        sensors.carry("obj" if held else None, (lambda c=c: c) if held else None)
        ests.append(sensors.objects(t, {"obj": obj})["obj"].pos)
        truth.append(obj.pos)
    for handover in (1.0, 3.0):  # the estimate does not jump when the hold starts or ends
        k = round(handover / dt)
        assert np.linalg.norm(ests[k] - ests[k - 1]) < 0.001
    held = slice(round(1.5 / dt), round(3.0 / dt))  # carried, after the first half second of the hold
    err = np.linalg.norm(np.array(ests[held]) - np.array(truth[held]), axis=1)
    assert np.sqrt(np.mean(err**2)) < 0.5 * SIGMA_POS * np.sqrt(3)


def test_a_long_gap_coasts_at_most_coast_s_and_its_variance_grows():
    """An object unseen for longer than COAST_S stops where the prediction put it (a bad measurement's speed does not
    fly it off the table), and the filter's variance grows over the gap."""
    from nextage_qp.estimation.imm import COAST_S

    kf = PoseKalman(SIGMA_POS, SIGMA_ROT)
    v = np.array([0.1, 0.0, 0.0])
    for i in range(round(2 * RATE)):  # moving at 0.1 m/s, then no measurement after 2 s
        t = i / RATE
        kf.update(t, np.r_[v * t, 0.0, 0.0, 0.0])
    last = kf.t
    assert last is not None
    np.testing.assert_allclose(kf.estimate(last + 0.5)[0], 0.1 * (last + 0.5), atol=0.003)  # bridged at its speed
    stop = kf.estimate(last + COAST_S)
    np.testing.assert_array_equal(kf.estimate(last + 5.0), stop)  # and no further
    assert np.all(kf.variance(last + 3.0) > kf.variance())


def test_a_speed_that_wrong_measurements_gave_coasts_at_most_coast_m():
    """Measurements that jump 2.5 cm a frame (the hand taken for the object) then stop: the estimate flies no further
    than COAST_M past the last of them, however long the object stays unseen."""
    from nextage_qp.estimation.imm import COAST_M

    kf, _ = settled(3, np.array([0.5, 0.0, 0.92, 0.0, 0.0, 0.0]))
    t = kf.t
    assert t is not None
    for k in range(1, 6):
        kf.update(t + k / RATE, np.r_[0.5 + 0.025 * k, 0.0, 0.92, 0.0, 0.0, 0.0])
    last = kf.estimate(kf.t)
    assert np.linalg.norm(kf.estimate(kf.t + 0.1)[:3] - last[:3]) > 0.02  # it does coast at the speed it has
    for gap in (0.5, 1.0, 5.0):  # the speed would take it 30 cm in a second: it stops at COAST_M
        assert np.linalg.norm(kf.estimate(kf.t + gap)[:3] - last[:3]) == pytest.approx(COAST_M, abs=1e-12)


def test_a_turn_rate_that_the_last_views_gave_coasts_at_most_coast_rad():
    """The last views before a gap turn the object 7 deg in a frame (a fit of a cube the hand comes down beside): the
    estimate turns on at that rate for a moment, and never more than COAST_RAD past the last view, however long the
    object stays unseen (a 45 deg coast made a push take a cube's face for its corner)."""
    from nextage_qp.estimation.imm import COAST_RAD

    kf, _ = settled(3, np.array([0.5, 0.0, 0.92, 0.0, 0.0, 1.6]))
    t = kf.t
    assert t is not None
    for k in range(1, 4):
        kf.update(t + k / RATE, np.array([0.5, 0.0, 0.92, 0.0, 0.0, 1.6 + 0.12 * k]))
    last = kf.estimate(kf.t)
    assert abs(kf.estimate(kf.t + 0.05)[5] - last[5]) > 0.02  # it does coast at the rate it has
    for gap in (0.5, 1.0, 5.0):  # the rate would turn it by radians in a second: it stops at COAST_RAD
        assert abs(kf.estimate(kf.t + gap)[5] - last[5]) == pytest.approx(COAST_RAD, abs=1e-12)
        assert np.all(np.abs(kf.estimate(kf.t + gap)[3:5] - last[3:5]) <= COAST_RAD + 1e-12)  # every axis is bounded


def test_a_pushed_object_held_without_extrapolation_stays_where_the_tool_holds_it():
    from nextage_qp.estimation.held import HeldEstimate
    from nextage_qp.geometry import Pose

    carrier = Pose(np.array([0.4, 0.0, 0.95]), np.eye(3))
    world = np.array([0.45, 0.0, 0.91, 0.0, 0.0, 0.0])
    held = HeldEstimate(0.0, carrier, world, np.full(6, SIGMA_POS**2), PoseKalman(SIGMA_POS, SIGMA_ROT),
                        pushed=True)
    for k, t in enumerate((0.05, 0.10)):  # two measurements that drift 1 cm/s relative to the tool
        held.update(t, world + np.r_[0.0, 0.0005 * (k + 1), 0.0, 0.0, 0.0, 0.0])
    at_last = held.estimate(0.10)
    moved = Pose(carrier.pos + np.array([0.2, 0.0, 0.0]), carrier.rot)  # then the tool pushes on, unseen, 20 cm
    held.observe(3.0, moved)
    np.testing.assert_allclose(held.estimate(3.0)[:3], at_last[:3] + np.array([0.2, 0.0, 0.0]), atol=1e-12)


def test_a_pushed_object_follows_the_tool_along_the_table_only():
    """A tool that rides up the pushed object's face and tilts while it is unseen moves it in x, y and yaw only."""
    from nextage_qp.estimation.held import HeldEstimate
    from nextage_qp.geometry import Pose, axis_angle, rot_z

    carrier = Pose(np.array([0.4, 0.0, 0.95]), rot_z(0.1))
    world = np.array([0.45, 0.01, 0.91, 0.0, 0.0, 0.2])
    held = HeldEstimate(0.0, carrier, world, np.full(6, SIGMA_POS**2), PoseKalman(SIGMA_POS, SIGMA_ROT), pushed=True)
    held.update(0.05, world)
    turn = rot_z(0.3) @ axis_angle(np.array([0.0, 1.0, 0.0]), 0.4)  # turned 0.2 rad further, pitched 0.4 rad
    moved = Pose(carrier.pos + np.array([0.1, 0.05, 0.03]), turn)  # and 3 cm higher
    held.observe(2.0, moved)
    est = held.estimate(2.0)
    assert est[2] == pytest.approx(0.91, abs=1e-9)  # the height, roll and pitch stay
    np.testing.assert_allclose(est[3:5], 0.0, atol=1e-9)
    assert est[5] == pytest.approx(0.4, abs=1e-9)  # the yaw turns with the tool's heading
    offset = rot_z(0.2)[:2, :2] @ np.array([0.05, 0.01])  # the object's place relative to the tool, turned with it
    np.testing.assert_allclose(est[:2], moved.pos[:2] + offset, atol=1e-9)


def test_the_estimate_error_while_the_camera_sees_the_object_counts_the_ticks_after_clear_frames_only():
    from nextage_qp.estimation.report import EstimateErrors

    errors = EstimateErrors()
    for k in range(10):  # 1 mm off while the object is in view (ticks 0.3-0.6 s), 10 mm while hidden
        t = 0.1 * k
        errors.tick(t, (0.001 if 0.3 <= t < 0.65 else 0.01) ** 2, 0.0, 0.0)
    report = errors.report((), [(0.0, False), (0.3, True), (0.65, False)])
    assert report["unoccluded_ticks"] == 4 and report["estimate_unoccluded_rms_m"] == pytest.approx(0.001)
    assert "estimate_unoccluded_rms_m" not in errors.report()  # no camera frames: not reported


def test_a_restart_at_rest_takes_a_jump_in_the_next_measurement_for_where_it_is_not_for_a_speed():
    kf = PoseKalman(SIGMA_POS, SIGMA_ROT)
    start = np.array([0.5, 0.0, 0.91, 0.0, 0.0, 0.0])
    kf.start(0.0, start, np.full(6, 0.01**2))  # as a hold ends: 10 mm uncertain, at rest
    kf.update(1.0 / RATE, start + np.r_[0.01, 0.0, 0.0, 0.0, 0.0, 0.0])  # the camera sees it 10 mm away
    now = kf.estimate(kf.t)
    assert np.linalg.norm(kf.estimate(kf.t + 0.5)[:3] - now[:3]) < 1e-3  # no coasting on a made-up speed


def test_a_view_with_a_spread_moves_the_estimate_by_as_much_less_as_its_variance_is_larger():
    """``spread``: a fit to part of an object errs more than a clear view; it weighs less, not nothing."""
    truth = np.array([0.5, 0.0, 0.92, 0.0, 0.0, 0.0])
    for off in (0.006, 0.02):
        shifts = {}
        for spread in (1.0, 3.0):
            kf, _ = settled(5, truth)
            before = kf.estimate(2.0)[0]
            assert kf.update(2.0, truth + np.r_[off, 0, 0, 0, 0, 0], spread=spread)
            shifts[spread] = kf.estimate(2.0)[0] - before
        assert 0 < shifts[3.0] < shifts[1.0] / 5, (off, shifts)
    kf, rng = settled(5, truth)  # the gate stays the filter's own: an object moved 6 cm is followed, spread or not
    moved = truth + np.r_[0.0, 0.06, 0, 0, 0, 0]
    assert not kf.update(2.0, measure(rng, moved), spread=4.0)  # an outlier under the filter's own noise
    for i in range(1, 6):
        kf.update(2.0 + i / RATE, measure(rng, moved), spread=4.0)
    np.testing.assert_allclose(kf.estimate(2.0 + 5 / RATE)[:3], moved[:3], atol=0.006)


def _drift_lag(assumed: float) -> float:
    """Largest sideways lag [m], over 50 draws, of a filter assuming ``assumed`` of a 0.5 mm camera at 15 Hz, after
    1.5 s of a pushed object sliding across the tool's face at 3 mm/s (its pose relative to the tool, from rest)."""
    lags = []
    for seed in range(50):
        rng = np.random.default_rng(seed)
        kf = PoseKalman(assumed, 0.02)
        kf.start(0.0, np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0]), np.full(6, 1e-6))
        for i in range(1, 31):
            t = i / 15.0
            truth = np.array([0.05, -0.003 * max(t - 0.5, 0.0), 0.0, 0.0, 0.0, 0.0])
            kf.update(t, truth + np.r_[rng.normal(0, 0.0005, 3), rng.normal(0, 0.005, 3)])
        lags.append(abs(kf.estimate(t)[1] - truth[1]))
    return max(lags)


def test_a_slow_drift_is_followed_when_the_assumed_noise_is_the_camera_s_own():
    """The rendered-depth default (1 mm, :data:`~nextage_qp.sensing.camera.source.FIT_NOISE`) keeps a slow slide within
    a millimetre; assuming 2 mm of a 0.5 mm camera, the resting model takes the slide for noise and lags it further."""
    from nextage_qp.sensing.camera.source import FIT_NOISE

    assert _drift_lag(FIT_NOISE["rendered"]) < 0.001 < _drift_lag(0.002)
