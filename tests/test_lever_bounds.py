"""The lever arms of the collision rows' broad phase bound every configuration's true lever arms."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from nextage_qp.ik.kinematic_model import lever_bounds
from nextage_qp.robots.model import Robot

# A lift (a TIAGo's torso): a slide joint between a hinge below it and an arm's hinge above it.
LIFT = """<mujoco><worldbody><body name="column"><joint name="pan" axis="0 0 1" range="-1 1"/>
  <geom type="box" size="0.1 0.1 0.4" pos="0 0 0.4"/>
  <body name="lift" pos="0 0 0.8"><joint name="lift" type="slide" axis="0 0 1" range="0 0.35"/>
    <geom type="box" size="0.08 0.08 0.05"/>
    <body name="arm" pos="0.1 0.2 0.05"><joint name="shoulder" axis="0 1 0" range="-2 2"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/></body></body></body></worldbody></mujoco>"""


@pytest.mark.parametrize("scene", ["dock_dumbbell", "push_cube", "lift"])
def test_lever_bounds_hold_in_random_configurations(scene):
    if scene == "lift":
        m = mujoco.MjModel.from_xml_string(LIFT)
        qpos, lower, upper = np.arange(m.nq), m.jnt_range[:, 0], m.jnt_range[:, 1]
    else:
        robot = Robot.from_scene(scene)
        m, qpos, lower, upper = robot.model, robot.qpos_idx, robot.lower, robot.upper
    lever = lever_bounds(m)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    jac = np.zeros((3, m.nv))
    for _ in range(20):
        d.qpos[qpos] = rng.uniform(lower, upper)
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
                if m.jnt_type[jnt] == mujoco.mjtJoint.mjJNT_SLIDE:
                    assert lever[g, dof] == 1.0  # a slide moves every point by its own travel
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
