"""The lever arms of the collision rows' broad phase bound every configuration's true lever arms."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from nextage_qp.ik.kinematic_model import lever_bounds
from nextage_qp.robots.model import Robot


@pytest.mark.parametrize("scene", ["dock_dumbbell", "push_cube"])
def test_lever_bounds_hold_in_random_configurations(scene):
    robot = Robot.from_scene(scene)
    m = robot.model
    lever = lever_bounds(m)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    jac = np.zeros((3, m.nv))
    for _ in range(20):
        robot.set_q(d, rng.uniform(robot.lower, robot.upper))
        mujoco.mj_kinematics(m, d)
        for g in range(m.ngeom):
            body = int(m.geom_bodyid[g])
            mujoco.mj_jacBody(m, d, jac, None, body)  # which dofs move the geom's body
            for dof in range(m.nv):
                jnt = int(m.dof_jntid[dof])
                moves = bool(np.any(jac[:, dof])) or _ancestor(m, int(m.jnt_bodyid[jnt]), body)
                if not moves:
                    assert lever[g, dof] == 0.0
                    continue
                if m.jnt_type[jnt] != mujoco.mjtJoint.mjJNT_HINGE:
                    assert lever[g, dof] == np.inf
                    continue
                reach = np.linalg.norm(d.geom_xpos[g] - d.xanchor[jnt]) + m.geom_rbound[g]
                assert reach <= lever[g, dof] + 1e-9


def _ancestor(m: mujoco.MjModel, a: int, b: int) -> bool:
    """Whether body ``a`` is ``b`` or one of its ancestors (its joints move ``b``)."""
    while b > 0:
        if b == a:
            return True
        b = int(m.body_parentid[b])
    return False
