import mujoco
import numpy as np
import pytest

from nextage_qp.errors import ConfigError
from nextage_qp.kinematics.dh import PUMA560, PUMA560_A2, PUMA560_A3, PUMA560_D3, PUMA560_D4, DHRow, dh_fk, dh_transform


def puma_closed_form(q):
    """Craig's closed-form 0T6 of the PUMA 560 (Introduction to Robotics, eq. 3.14)."""
    a2, a3, d3, d4 = PUMA560_A2, PUMA560_A3, PUMA560_D3, PUMA560_D4
    c1, s1 = np.cos(q[0]), np.sin(q[0])
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    c4, s4 = np.cos(q[3]), np.sin(q[3])
    c5, s5 = np.cos(q[4]), np.sin(q[4])
    c6, s6 = np.cos(q[5]), np.sin(q[5])
    c23, s23 = np.cos(q[1] + q[2]), np.sin(q[1] + q[2])
    r11 = c1 * (c23 * (c4 * c5 * c6 - s4 * s6) - s23 * s5 * c6) + s1 * (s4 * c5 * c6 + c4 * s6)
    r21 = s1 * (c23 * (c4 * c5 * c6 - s4 * s6) - s23 * s5 * c6) - c1 * (s4 * c5 * c6 + c4 * s6)
    r31 = -s23 * (c4 * c5 * c6 - s4 * s6) - c23 * s5 * c6
    r12 = c1 * (c23 * (-c4 * c5 * s6 - s4 * c6) + s23 * s5 * s6) + s1 * (c4 * c6 - s4 * c5 * s6)
    r22 = s1 * (c23 * (-c4 * c5 * s6 - s4 * c6) + s23 * s5 * s6) - c1 * (c4 * c6 - s4 * c5 * s6)
    r32 = -s23 * (-c4 * c5 * s6 - s4 * c6) + c23 * s5 * s6
    r13 = -c1 * (c23 * c4 * s5 + s23 * c5) - s1 * s4 * s5
    r23 = -s1 * (c23 * c4 * s5 + s23 * c5) + c1 * s4 * s5
    r33 = s23 * c4 * s5 - c23 * c5
    px = c1 * (a2 * c2 + a3 * c23 - d4 * s23) - d3 * s1
    py = s1 * (a2 * c2 + a3 * c23 - d4 * s23) + d3 * c1
    pz = -a3 * s23 - a2 * s2 - d4 * c23
    return np.array([[r11, r12, r13, px], [r21, r22, r23, py], [r31, r32, r33, pz], [0, 0, 0, 1]])


def puma_mujoco_model() -> mujoco.MjModel:
    """An equivalent MuJoCo model: each body placed by R_x(alpha) D_x(a) D_z(d), hinge about its local z."""
    spec = mujoco.MjSpec()
    parent = spec.worldbody
    for i, row in enumerate(PUMA560):
        body = parent.add_body(name=f"link{i + 1}")
        ca, sa = np.cos(row.alpha), np.sin(row.alpha)
        body.pos = [row.a, -sa * row.d, ca * row.d]
        body.quat = [np.cos(row.alpha / 2), np.sin(row.alpha / 2), 0, 0]
        body.add_joint(name=f"j{i + 1}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
        body.add_geom(size=[0.01, 0, 0], mass=1)
        parent = body
    return spec.compile()


def test_dh_fk_matches_craig_closed_form():
    rng = np.random.default_rng(0)
    for _ in range(200):
        q = rng.uniform(-np.pi, np.pi, 6)
        np.testing.assert_allclose(dh_fk(PUMA560, q), puma_closed_form(q), atol=1e-12)


def test_dh_fk_matches_equivalent_mujoco_model():
    model = puma_mujoco_model()
    data = mujoco.MjData(model)
    rng = np.random.default_rng(1)
    for _ in range(200):
        q = rng.uniform(-np.pi, np.pi, 6)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        t = dh_fk(PUMA560, q)
        np.testing.assert_allclose(data.xpos[6], t[:3, 3], atol=1e-12)
        np.testing.assert_allclose(data.xmat[6].reshape(3, 3), t[:3, :3], atol=1e-12)


def test_dh_transform_of_zero_row_is_identity():
    np.testing.assert_allclose(dh_transform(DHRow(0, 0, 0), 0.0), np.eye(4))


def test_dh_fk_partial_chain_and_shape_check():
    q = np.zeros(6)
    t3 = dh_fk(PUMA560, q, upto=3)
    np.testing.assert_allclose(t3[:3, 3], [PUMA560_A2, PUMA560_D3, 0.0], atol=1e-12)
    with pytest.raises(ConfigError, match="6 rows"):
        dh_fk(PUMA560, np.zeros(5))
