import math

import numpy as np
import pytest

from nextage_qp.mobile import Bicycle, DiffDrive, Pose2, Twist, body_twist, integrate, relative


@pytest.mark.parametrize("r,half", [(0.1, 0.25), (0.075, 0.3), (0.2, 0.1)])
def test_diff_drive_round_trip(r: float, half: float) -> None:
    drive = DiffDrive(r, half)
    rng = np.random.default_rng(0)
    for right, left in rng.uniform(-20, 20, (200, 2)):
        tw = drive.forward(right, left)
        assert tw.vy == 0.0
        back = drive.inverse(tw.vx, tw.omega)
        assert back == pytest.approx((right, left), abs=1e-12)
    for vx, w in rng.uniform(-2, 2, (200, 2)):
        tw = drive.forward(*drive.inverse(vx, w))
        assert (tw.vx, tw.omega) == pytest.approx((vx, w), abs=1e-12)


def test_diff_drive_lecture_formula() -> None:
    drive = DiffDrive(0.1, 0.2)
    tw = drive.forward(3.0, 1.0)  # right faster: turns left
    assert tw == pytest.approx((0.1 * 4.0 / 2, 0.0, 0.1 * 2.0 / (2 * 0.2)))


@pytest.mark.parametrize("lf,lr", [(1.2, 1.4), (0.3, 0.0), (0.5, 0.2)])
def test_bicycle_round_trip(lf: float, lr: float) -> None:
    bike = Bicycle(lf, lr)
    for v in (-1.5, -0.2, 0.3, 2.0):
        for delta in np.linspace(-0.6, 0.6, 13):
            tw = bike.forward(v, float(delta))
            beta = math.atan(lr * math.tan(delta) / (lf + lr))
            assert tw.vx == pytest.approx(v * math.cos(beta), abs=1e-12)
            assert tw.vy == pytest.approx(v * math.sin(beta), abs=1e-12)
            assert bike.inverse(v, tw.omega) == pytest.approx(delta, abs=1e-12)
    assert bike.inverse(0.0, 1.0) == 0.0


def test_bicycle_refuses_a_turn_rate_beyond_its_steering() -> None:
    with pytest.raises(ValueError, match="beyond any steering"):
        Bicycle(0.5, 0.5).inverse(0.1, 10.0)


@pytest.mark.parametrize("vx,vy,w,dt", [(0.5, 0.0, 0.8, 2.0), (0.3, 0.1, -1.3, 3.7), (1.0, 0.0, 0.0, 5.0), (0.7, 0.0, 1e-4, 3.0),
                                        (0.0, 0.0, 2.0, 1.0), (-0.4, 0.0, 0.5, 4.0)])
def test_constant_twist_lands_on_the_closed_form_arc(vx: float, vy: float, w: float, dt: float) -> None:
    start = Pose2(0.3, -1.2, 0.7)
    # closed form: the point moves on a circle about the instantaneous centre of rotation
    end = integrate(start, Twist(vx, vy, w), dt)
    if abs(w) > 1e-6:
        c, s = math.cos(start.yaw), math.sin(start.yaw)
        # centre of rotation in the world: the body point (-vy/w, vx/w)
        cx, cy = start.x + c * (-vy / w) - s * (vx / w), start.y + s * (-vy / w) + c * (vx / w)
        a = w * dt
        px, py = start.x - cx, start.y - cy
        expect = (cx + math.cos(a) * px - math.sin(a) * py, cy + math.sin(a) * px + math.cos(a) * py)
    else:
        expect = (start.x + (math.cos(start.yaw) * vx - math.sin(start.yaw) * vy) * dt,
                  start.y + (math.sin(start.yaw) * vx + math.cos(start.yaw) * vy) * dt)
    assert (end.x, end.y) == pytest.approx(expect, abs=1e-9)
    assert end.yaw == pytest.approx(start.yaw + w * dt, abs=1e-12)


def test_integration_composes_exactly_and_never_drifts_sideways() -> None:
    """Many short arcs of one twist land where one long arc does; a diff drive's heading stays tangent."""
    tw, pose = Twist(0.4, 0.0, 0.9), Pose2(0.0, 0.0, 0.0)
    for _ in range(1000):
        pose = integrate(pose, tw, 0.005)
    one = integrate(Pose2(0.0, 0.0, 0.0), tw, 5.0)
    assert (pose.x, pose.y, pose.yaw) == pytest.approx((one.x, one.y, one.yaw), abs=1e-9)
    radius = 0.4 / 0.9  # the circle about (0, radius)
    assert math.hypot(pose.x, pose.y - radius) == pytest.approx(radius, abs=1e-9)


def test_straight_line() -> None:
    end = integrate(Pose2(1.0, 2.0, math.pi / 2), Twist(0.5, 0.0, 0.0), 4.0)
    assert (end.x, end.y, end.yaw) == pytest.approx((1.0, 4.0, math.pi / 2), abs=1e-12)


def test_body_twist_and_relative() -> None:
    pose = Pose2(1.0, 1.0, math.pi / 2)
    assert body_twist(pose, (0.0, 0.3, 0.1)) == pytest.approx((0.3, 0.0, 0.1), abs=1e-12)
    assert body_twist(pose, (0.2, 0.0, 0.0)) == pytest.approx((0.0, -0.2, 0.0), abs=1e-12)
    rel = relative(pose, Pose2(1.0, 2.0, math.pi))
    assert rel == pytest.approx((1.0, 0.0, math.pi / 2), abs=1e-12)
