import re

import numpy as np
import pytest
from tests_support import NEXTAGE_JOINTS as JOINT_NAMES

from nextage_qp.errors import ConfigError
from nextage_qp.loop.pd import Gains, PDController, load_gains

N = len(JOINT_NAMES)


def make_pd(kp=100.0, kd=10.0, comp=True, limit=50.0):
    return PDController(Gains(np.full(N, kp), np.full(N, kd), gravity_compensation=comp), np.full(N, limit))


def test_torque_is_zero_at_reference_with_zero_velocity():
    pd = make_pd()
    q = np.linspace(-1, 1, N)
    np.testing.assert_array_equal(pd.torque(q, np.zeros(N), q, np.zeros(N)), np.zeros(N))
    assert pd.ticks == 1 and pd.any_saturated_ticks == 0


def test_torque_law_and_bias_and_feedforward():
    pd = make_pd(kp=100.0, kd=10.0)
    q, qd = np.zeros(N), np.full(N, 0.1)
    q_ref, qd_ref = np.full(N, 0.2), np.zeros(N)
    bias, ff = np.full(N, 3.0), np.full(N, -1.0)
    expected = 100.0 * 0.2 + 10.0 * (-0.1) + 3.0 - 1.0
    np.testing.assert_allclose(pd.torque(q, qd, q_ref, qd_ref, bias, ff), expected)
    no_comp = make_pd(comp=False)
    np.testing.assert_allclose(no_comp.torque(q, qd, q_ref, qd_ref, bias), 100.0 * 0.2 - 1.0)


def test_torque_is_clamped_and_saturation_counted():
    pd = make_pd(kp=1000.0, limit=50.0)
    q_ref = np.zeros(N)
    q_ref[3] = 1.0
    q_ref[4] = -0.01
    tau = pd.torque(np.zeros(N), np.zeros(N), q_ref, np.zeros(N))
    assert tau[3] == 50.0 and tau[4] == pytest.approx(-10.0)
    pd.torque(np.zeros(N), np.zeros(N), -q_ref, np.zeros(N))
    assert pd.saturated_ticks[3] == 2 and pd.saturated_ticks.sum() == 2 and pd.any_saturated_ticks == 2


@pytest.mark.parametrize("name", ["default", "report", "stiff_wrist", "tuned"])
def test_bundled_gains_load(name):
    g = load_gains(name)
    assert g.kp.shape == g.kd.shape == (N,)
    assert np.all(g.kp > 0) and np.all(g.kd > 0)


def test_report_gains_match_table_2():
    g = load_gains("report")
    table = {"JOINT0": (30, 15), "JOINT1": (350, 40), "JOINT2": (215, 25), "JOINT3": (80, 5), "JOINT4": (60, 2.5)}
    for side in ("LARM", "RARM"):
        for joint, (p, d) in table.items():
            i = JOINT_NAMES.index(f"{side}_{joint}")
            assert (g.kp[i], g.kd[i]) == (p, d)
    assert (g.kp[0], g.kd[0]) == (30, 15) and not g.gravity_compensation


def _write(tmp_path, joints, extra=""):
    lines = ["gravity_compensation: true", extra, "joints:"]
    lines += [f"  {j}: {{kp: 10.0, kd: 1.0}}" for j in joints]
    path = tmp_path / "g.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_missing_joint_rejected_with_one_line_message(tmp_path):
    path = _write(tmp_path, [j for j in JOINT_NAMES if j != "LARM_JOINT3"])
    with pytest.raises(ConfigError) as exc:
        load_gains(path)
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg and "missing LARM_JOINT3" in msg and "CHEST_JOINT0" in msg


def test_unknown_joint_rejected_with_valid_list(tmp_path):
    path = _write(tmp_path, [*JOINT_NAMES, "LARM_JOINT6"])
    with pytest.raises(ConfigError, match=re.escape("joints: unknown joint 'LARM_JOINT6'; valid joints: CHEST_JOINT0")):
        load_gains(path)


@pytest.mark.parametrize(
    ("entry", "match"),
    [
        ("{kp: -1.0, kd: 1.0}", "joints.CHEST_JOINT0.kp: Input should be greater than or equal to 0 (got -1.0)"),
        ("{kp: 1.0}", "joints.CHEST_JOINT0.kd: required, but missing"),
        ("{kp: x, kd: 1}", "joints.CHEST_JOINT0.kp: Input should be a valid number"),
        ("{kp: .inf, kd: 1}", "joints.CHEST_JOINT0.kp: Input should be a finite number"),
        ("{kp: yes, kd: 1}", "joints.CHEST_JOINT0.kp: Input should be a valid number"),
        ("{kp: 1, kd: 1, ki: 0}", "joints.CHEST_JOINT0.ki: unknown key; valid: kd, kp"),
    ],
)
def test_bad_entry_rejected(tmp_path, entry, match):
    path = _write(tmp_path, JOINT_NAMES[1:], extra="")
    path.write_text(path.read_text() + f"  CHEST_JOINT0: {entry}\n")
    with pytest.raises(ConfigError, match=re.escape(match)):
        load_gains(path)


def test_unknown_top_level_key_and_missing_file(tmp_path):
    path = _write(tmp_path, JOINT_NAMES, extra="integral: 3")
    with pytest.raises(ConfigError, match="integral: unknown key; valid: gravity_compensation, joints"):
        load_gains(path)
    with pytest.raises(ConfigError, match="bundled: default"):
        load_gains(tmp_path / "nope.yaml")
