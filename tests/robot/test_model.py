"""The Pinocchio model of the thesis humanoid against the thesis's own numbers (issue 2)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.linalg import expm

from humanoid_sim.robot.model import REAL_BODIES, THETA_NAMES, HumanoidModel, ModelError

# Appendix B.1 initial CoM positions Pc_k, world frame, m (thesis L4938-4962; identical in B.2/B.3).
APPENDIX_PC = {
    1: (0.16, 0.1505, 0.015), 2: (-0.16, 0.1505, 0.015), 3: (0.16, 0.0286, 0.0351), 4: (-0.16, 0.0286, 0.0351),
    9: (0.16, 0.0, 0.2487), 10: (-0.16, 0.0, 0.2487), 11: (0.16, 0.0, 0.6212), 12: (-0.16, 0.0, 0.6212),
    17: (0.0, 0.0, 0.9588), 20: (0.0, 0.0, 1.2524), 23: (0.29, 0.0, 1.0452), 24: (-0.29, 0.0, 1.0452),
    27: (0.0, 0.0, 1.4997),
}
# Table 2.6 (L858-883): theta rotates frame `child` relative to frame `parent` about u_axis of `parent`.
TABLE_2_6 = {
    "theta3": (1, 3, 1), "theta4": (2, 4, 1), "theta5": (3, 5, 1), "theta6": (4, 6, 1), "theta7": (5, 7, 2),
    "theta8": (6, 8, 2), "theta9": (7, 9, 0), "theta10": (8, 10, 0), "theta11": (9, 11, 1),
    "theta12": (10, 12, 1), "theta13": (11, 13, 1), "theta14": (12, 14, 1), "theta15": (13, 15, 0),
    "theta16": (14, 16, 0), "theta17r": (15, 17, 2), "theta17l": (16, 17, 2), "theta18": (17, 18, 1),
    "theta19": (18, 19, 2), "theta20": (19, 20, 0), "theta21": (20, 21, 0), "theta22": (20, 22, 0),
    "theta23": (21, 23, 1), "theta24": (22, 24, 1), "theta25": (20, 25, 2), "theta26": (25, 26, 1),
    "theta27": (26, 27, 0),
}


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def _placements(hm: HumanoidModel, q: np.ndarray) -> pin.Data:
    data = hm.model.createData()
    pin.framesForwardKinematics(hm.model, data, q)
    return data


def test_dimensions_and_mass(hm: HumanoidModel) -> None:
    m = hm.model
    assert (m.nq, m.nv) == (33, 32)
    revolute = [j for j in m.joints[2:] if j.shortname().startswith("JointModelR")]
    assert len(revolute) == 26 and m.njoints == 28  # universe + free flyer + 26 revolute joints
    # 55.044 kg: sum of Table 2.4 masses (errata P-4); 1e-9 is float round-off on a sum of 13 numbers.
    assert abs(sum(I.mass for I in m.inertias) - 55.044) < 1e-9
    assert abs(pin.computeTotalMass(m) - 55.044) < 1e-9


def test_initial_posture_matches_appendix(hm: HumanoidModel) -> None:
    data = _placements(hm, hm.initial_q())
    for k in REAL_BODIES:
        p = data.oMf[hm.frame_id(f"Pc_{k}")].translation
        # The appendix prints 4 decimals: 1e-4 m is its rounding.
        np.testing.assert_allclose(p, APPENDIX_PC[k], atol=1e-4, err_msg=f"Pc_{k}")
        # Every body frame has orientation C0 = Rz(+90 deg) at the zero posture (L838, L4964).
        np.testing.assert_allclose(data.oMf[hm.frame_id(f"O_{k}")].rotation, hm.spec.C0, atol=1e-15)
    np.testing.assert_allclose(data.oMf[hm.frame_id("P_tpR")].translation, (0.16, 0.1876, 0.015), atol=1e-12)
    np.testing.assert_allclose(data.oMf[hm.frame_id("P_tpL")].translation, (-0.16, 0.1876, 0.015), atol=1e-12)
    # Head top O_27: 0.015 + l3z + l9 + l11 + l17z + l20z + l27 = 1.6002 m (errata P-3).
    assert abs(data.oMf[hm.frame_id("O_27")].translation[2] - 1.6002) < 1e-12
    # Both feet flat: the soles (0.078 m below the ankles O_3/O_4) lie on z = 0.
    for k in (3, 4):
        assert abs(data.oMf[hm.frame_id(f"O_{k}")].translation[2] - 0.078) < 1e-12


@pytest.mark.parametrize("name", THETA_NAMES)
def test_each_joint_turns_as_table_2_6(hm: HumanoidModel, name: str) -> None:
    """theta_k alone turns frame k relative to its thesis parent by exp(u_i theta_k), u_i of the parent."""
    parent, child, axis = TABLE_2_6[name]
    theta = np.zeros(26)
    angle = 0.3  # large enough that a sign or axis error shows far above round-off
    theta[hm.theta_index(name)] = angle
    data = _placements(hm, hm.q_from_theta(theta))
    R_p = data.oMf[hm.frame_id(f"O_{parent}")].rotation
    R_c = data.oMf[hm.frame_id(f"O_{child}")].rotation
    expected = expm(_skew(np.eye(3)[axis]) * angle)  # C^(parent, child), Ozgoren exponential rotation
    np.testing.assert_allclose(R_p.T @ R_c, expected, atol=1e-14)


def test_coordinate_maps_round_trip(hm: HumanoidModel) -> None:
    rng = np.random.default_rng(0)
    theta = rng.uniform(-1, 1, 26)
    base = pin.SE3.Random()
    q = hm.q_from_theta(theta, base)
    np.testing.assert_allclose(hm.theta_from_q(q), theta, atol=0)
    assert hm.base_from_q(q).isApprox(base, 1e-12)
    thd = rng.normal(size=26)
    tw = rng.normal(size=6)
    v = hm.v_from_theta_dot(thd, tw)
    np.testing.assert_array_equal(hm.theta_dot_from_v(v), thd)
    np.testing.assert_array_equal(v[:6], tw)
    with pytest.raises(ModelError, match="shape"):
        hm.q_from_theta(np.zeros(25))
    with pytest.raises(ModelError, match="unknown frame"):
        hm.frame_id("O_99")


def test_leg_joint_power_is_conjugate(hm: HumanoidModel) -> None:
    """tau_from_joint_torques: generalized force conjugate to theta (virtual power tau.v == T.theta_dot)."""
    rng = np.random.default_rng(1)
    T, thd = rng.normal(size=26), rng.normal(size=26)
    assert abs(hm.tau_from_joint_torques(T) @ hm.v_from_theta_dot(thd) - T @ thd) < 1e-12


@pytest.mark.parametrize("foot", ["R", "L"])
def test_q_on_foot_places_the_toe_body(hm: HumanoidModel, foot: str) -> None:
    rng = np.random.default_rng(2)
    theta = rng.uniform(-0.5, 0.5, 26)
    R = pin.rpy.rpyToMatrix(0.0, 0.0, rng.uniform(-3, 3))
    p = np.array([0.3, -0.2, 0.015])
    data = _placements(hm, hm.q_on_foot(theta, foot, p, R))
    toe = {"R": "P_tpR", "L": "P_tpL"}[foot]
    body = {"R": "O_1", "L": "O_2"}[foot]
    np.testing.assert_allclose(data.oMf[hm.frame_id(toe)].translation, p, atol=1e-12)
    np.testing.assert_allclose(data.oMf[hm.frame_id(body)].rotation, R, atol=1e-12)
