"""The collision rows' compiled loops (nextage_qp.native.kernels) against the Python loop they replace."""

import numpy as np
import pytest

from nextage_qp.ik import QPIK, CollisionPairConfig, FrameTarget, IKConfig
from nextage_qp.kinematics.frames import Kinematics
from nextage_qp.manipulation.config import load_config
from nextage_qp.native import kernels
from nextage_qp.robots.model import Robot

pytestmark = pytest.mark.skipif(not kernels.NATIVE, reason="MuJoCo's shared library not found next to its package")


@pytest.fixture(scope="module")
def robot() -> Robot:
    return Robot.from_scene("dock_dumbbell")


def _walk(robot: Robot, ik: QPIK, native: bool, monkeypatch: pytest.MonkeyPatch) -> list[tuple]:
    """Rows, bounds, active pairs and counters of an IK step at each state of a seeded random walk."""
    monkeypatch.setattr(kernels, "NATIVE", native)
    limit = ik.collision
    assert limit is not None
    rng, q, out = np.random.default_rng(3), robot.keyframe_q("home"), []
    for k in range(400):
        q = np.clip(q + rng.normal(0.0, 0.3 if k % 40 == 0 else 0.02, robot.nq), robot.lower, robot.upper)
        ik.configuration.update(q)
        rows = limit.compute_qp_inequalities(ik.configuration, 0.004)
        out.append((None if rows.G is None else rows.G.copy(), None if rows.h is None else rows.h.copy(),
                    list(limit.active), limit.slack, limit.queries))
    return out


def test_compiled_rows_are_the_python_loops_to_the_bit(robot: Robot, monkeypatch: pytest.MonkeyPatch) -> None:
    pairs = load_config("configs/dock_dumbbell.yaml").ik.collision_pairs
    native = _walk(robot, QPIK(robot, IKConfig(collision_pairs=pairs)), True, monkeypatch)
    python = _walk(robot, QPIK(robot, IKConfig(collision_pairs=pairs)), False, monkeypatch)
    rows = 0
    for (g1, h1, a1, s1, n1), (g2, h2, a2, s2, n2) in zip(native, python, strict=True):
        assert (a1, s1, n1) == (a2, s2, n2)
        assert (g1 is None) == (g2 is None)
        if g1 is not None:
            assert np.array_equal(g1, g2) and np.array_equal(h1, h2)
            rows += len(h1)
    assert rows > 1000, rows  # pairs were within detection distance along the walk


def test_an_ik_step_compiles_nothing(robot: Robot) -> None:
    """The kernels are loaded when the IK is built, with the argument types its steps pass (one signature each)."""
    pairs = (CollisionPairConfig(a="left_arm", b="table", min_distance=0.005, detection_distance=0.05),
             CollisionPairConfig(a="left_arm", b="right_arm", min_distance=0.005, detection_distance=0.05))
    ik = QPIK(robot, IKConfig(collision_pairs=pairs))
    before = {k: len(getattr(kernels, k).signatures) for k in ("near_pairs", "remember", "narrow_rows")}
    home, kin = robot.keyframe_q("home"), Kinematics(robot)
    goal = kin.fk("left_wrist", home).pos + np.array([0.1, -0.1, -0.15])
    q = home.copy()
    for _ in range(50):
        q = q + 0.004 * ik.step(q, [FrameTarget("left_wrist", pos=goal)], 0.004)
    assert ik.collision is not None and ik.collision.queries > 0
    assert {k: len(getattr(kernels, k).signatures) for k in before} == before


def test_compiled_obstacle_clearance_is_the_python_loops(robot: Robot) -> None:
    """The outcome monitor's clearance: the same smallest distances, and the argument types warmed up."""
    import mujoco

    from nextage_qp.manipulation.metrics import OutcomeMonitor

    monitor = OutcomeMonitor(robot, "dumbbell")
    kernels.warm_up(robot.model.nv, True)
    signatures = len(kernels.clearance.signatures)
    model, data = robot.model, mujoco.MjData(robot.model)
    rng, near = np.random.default_rng(11), 0
    for _ in range(300):
        robot.set_q(data, rng.uniform(robot.lower, robot.upper))
        mujoco.mj_kinematics(model, data)
        best = float(rng.uniform(0.0, 0.2))
        args = (monitor._pair1, monitor._pair2, monitor._pair_rsum, best, 0.04, np.zeros(6))
        compiled = kernels.clearance(kernels.GEOM_DISTANCE, model._address, data._address, data.geom_xpos, *args)
        assert compiled == kernels.clearance_python(model, data, *args)
        near += compiled[1] < 0.04
    assert near > 10, near
    assert len(kernels.clearance.signatures) == signatures
