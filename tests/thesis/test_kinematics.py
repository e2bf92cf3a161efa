"""Self-consistency of the thesis oracle's kinematics (sections 4.1-4.2), without pinocchio.

The comparison with the pinocchio model is in test_thesis_vs_pinocchio.py; here the transcription is checked
against the thesis's own printed numbers and against calculus (finite differences).
"""

from __future__ import annotations

import numpy as np
import pytest

from humanoid_sim.thesis import PHASES, FootState
from humanoid_sim.thesis.frames import IDX, JOINTS, THETA_NAMES, PhaseError, rot
from humanoid_sim.thesis.jacobians import CDIAG_OF, PHASE_JACOBIANS, point_jacobian, thesis_jacobians
from humanoid_sim.thesis.kinematics import kinematics, origins, positions
from humanoid_sim.thesis.params import load_params

P = load_params()
C0 = P.C0

# Appendix B.1, L4938-4962: mass centres at the initial posture (printed to 4 decimals).
APPENDIX_PC = {
    1: (0.16, 0.1505, 0.015), 2: (-0.16, 0.1505, 0.015), 3: (0.16, 0.0286, 0.0351), 4: (-0.16, 0.0286, 0.0351),
    9: (0.16, 0.0, 0.2487), 10: (-0.16, 0.0, 0.2487), 11: (0.16, 0.0, 0.6212), 12: (-0.16, 0.0, 0.6212),
    17: (0.0, 0.0, 0.9588), 20: (0.0, 0.0, 1.2524), 23: (0.29, 0.0, 1.0452), 24: (-0.29, 0.0, 1.0452),
    27: (0.0, 0.0, 1.4997),
}
# toe point = P_c,1 + (l1 - c1) u1^(1) (inverse of L1972)
INITIAL_FEET = {"R": FootState(C0, np.array(APPENDIX_PC[1]) + (P["l1"] - P["c1"]) * C0[:, 0]),
                "L": FootState(C0, np.array(APPENDIX_PC[2]) + (P["l2"] - P["c2"]) * C0[:, 0])}


def random_fixed(rng: np.random.Generator) -> dict[str, FootState]:
    C = rot(3, rng.uniform(-np.pi, np.pi)) @ rot(1, rng.uniform(-0.3, 0.3)) @ rot(2, rng.uniform(-0.3, 0.3))
    return {"R": FootState(C, np.array([*rng.uniform(-1, 1, 2), 0.015])),
            "L": FootState(C, np.array([*rng.uniform(-1, 1, 2), 0.015]))}


def consistent_dsp_feet(theta: np.ndarray, fixed_R: FootState) -> dict[str, FootState]:
    """Left toe data that closes the chain: the left toe pose the RFFSSP recursion gives for theta."""
    kin = positions("RFFSSP", theta, {"R": fixed_R}, P)
    return {"R": fixed_R, "L": FootState(kin.C[2], kin.P["tpL"])}


@pytest.mark.parametrize("phase", PHASES)
def test_initial_posture_reproduces_appendix_mass_centres(phase):
    kin = positions(phase, np.zeros(26), INITIAL_FEET, P)
    for k, pc in APPENDIX_PC.items():
        # 6e-5 m: the appendix prints 4 decimals (half a unit of the last digit is 5e-5) plus float noise.
        assert np.allclose(kin.P[f"c{k}"], pc, atol=6e-5), (phase, k, kin.P[f"c{k}"], pc)
    for k in range(1, 28):
        # every frame has orientation C0 at the zero posture (L838, L4964); exact up to rounding.
        assert np.allclose(kin.C[k], C0, atol=1e-15), (phase, k)


def test_joint_table_matches_model_yaml():
    """frames.JOINTS (Table 2.6 transcription) agrees with the axes and bodies of models/thesis_humanoid.yaml."""
    from urdf_gen.spec import load_spec

    spec = load_spec(Path_yaml())
    by_theta = {j.theta: j for j in spec.joints}
    names = {b.name: k for k, b in spec.bodies.items()}
    assert tuple(spec.theta_order) == THETA_NAMES
    for theta, (a, b, j) in JOINTS.items():
        js = by_theta[theta]
        assert "xyz"[j - 1] == js.axis, theta
        assert {names[js.parent], names[js.child]} == {a, b}, theta


def Path_yaml():
    from pathlib import Path

    return Path(__file__).resolve().parents[2] / "models" / "thesis_humanoid.yaml"


@pytest.mark.parametrize("phase", PHASES)
def test_velocities_and_accelerations_are_time_derivatives(phase):
    """V = dP/dt and a = dV/dt along theta(t) = theta + theta_dot t + theta_ddot t^2 / 2 (central differences)."""
    rng = np.random.default_rng(10 + PHASES.index(phase))
    theta, thd, thdd = rng.uniform(-0.5, 0.5, 26), rng.uniform(-1, 1, 26), rng.uniform(-2, 2, 26)
    fixed = random_fixed(rng)
    # (in the DSPs the two chains are independent recursions from fixed toes, so each is differentiated as is)
    h = 1e-5

    def state(t):
        return theta + thd * t + 0.5 * thdd * t * t, thd + thdd * t

    kin = kinematics(phase, theta, thd, thdd, fixed, P)
    kp = kinematics(phase, *state(h), None, fixed, P)
    km = kinematics(phase, *state(-h), None, fixed, P)
    for key in kin.P:
        # central difference error ~ h^2 |d3P/dt3| ~ 1e-10 * O(10); 1e-7 m/s leaves a wide margin
        assert np.allclose((kp.P[key] - km.P[key]) / (2 * h), kin.V[key], atol=1e-7), key
        assert np.allclose((kp.V[key] - km.V[key]) / (2 * h), kin.a[key], atol=1e-6), key
    for k in kin.C:
        dC = (kp.C[k] - km.C[k]) / (2 * h)
        wk = kin.w[k]
        W = np.array([[0, -wk[2], wk[1]], [wk[2], 0, -wk[0]], [-wk[1], wk[0], 0]])
        assert np.allclose(dC, W @ kin.C[k], atol=1e-7), k           # C_dot = w~ C
        assert np.allclose((kp.w[k] - km.w[k]) / (2 * h), kin.alpha[k], atol=1e-6), k


@pytest.mark.parametrize("phase", ["RFFDSP", "LFFDSP"])
def test_two_chains_meet_at_body_17(phase):
    """With the left toe data taken from the same configuration, 17_fR and 17_fL coincide (L1725-1734)."""
    rng = np.random.default_rng(3)
    theta = rng.uniform(-0.5, 0.5, 26)
    fixed = consistent_dsp_feet(theta, random_fixed(rng)["R"])
    kin = positions(phase, theta, fixed, P)
    assert np.allclose(kin.P["c17fR"], kin.P["c17fL"], atol=1e-14)   # two float chains of ~10 products
    assert np.allclose(kin.C["17fR"], kin.C["17fL"], atol=1e-14)


def test_origins_are_joint_points():
    """O_3 from the foot side equals O_3 = O_9 + C^(0,9) l_9,3 from the shank side (errata P-2 layout)."""
    rng = np.random.default_rng(5)
    theta = rng.uniform(-0.5, 0.5, 26)
    kin = positions("LFFSSP", theta, random_fixed(rng), P)
    O = origins(kin, P)
    assert np.allclose(O[9] + kin.C[9] @ np.array([0, 0, -P["l9"]]), O[3], atol=1e-14)
    assert np.allclose(O[3] + kin.C[3] @ np.array([P["l3x"], 0, -P["l3z"]]), O[1], atol=1e-14)
    assert np.allclose(O[1] + kin.C[1] @ np.array([P["l1"], 0, 0]), kin.P["tpR"], atol=1e-14)


@pytest.mark.parametrize("phase", PHASES)
def test_thesis_jacobians_shapes_and_definition(phase):
    """Each phase builds the Jacobians its section lists (4.2.1.1-4.2.1.4), with the column counts of eqs. 4.6,
    4.8, 4.16, 4.18, 4.25, 4.29 (values are compared with pinocchio in test_thesis_vs_pinocchio.py)."""
    rng = np.random.default_rng(20)
    theta = rng.uniform(-0.5, 0.5, 26)
    fixed = consistent_dsp_feet(theta, random_fixed(rng)["R"]) if phase.endswith("DSP") else random_fixed(rng)
    kin = positions(phase, theta, fixed, P)
    Js = thesis_jacobians(kin, fixed, P)
    assert tuple(Js) == PHASE_JACOBIANS[phase]
    expected_cols = {"J_v,17_fR": 7, "J_v,17_fL": 7, "J_v,tpL": 15, "J_v,tpR": 15, "J_v,17_fL_all": 8,
                     "J_v,17_fR_all": 8}
    for name, J in Js.items():
        base = CDIAG_OF.get(name, name)
        assert J.shape[1] == expected_cols[base], name
        assert J.shape[0] == (3 if "Cdiag" in name else 6), name


def test_missing_stance_data_and_unknown_phase_raise():
    with pytest.raises(PhaseError, match="foot 'L'"):
        positions("LFFSSP", np.zeros(26), {"R": INITIAL_FEET["R"]}, P)
    with pytest.raises(PhaseError, match="unknown phase"):
        positions("RFSSP", np.zeros(26), INITIAL_FEET, P)
    with pytest.raises(ValueError, match="shape"):
        positions("RFFSSP", np.zeros(25), INITIAL_FEET, P)


def test_jacobian_column_is_velocity_of_unit_rate():
    """4.2.2 (L2605): column i of J_v,tpL is [V_tpL; w_2] for q_dot = e_i (checked on theta13)."""
    rng = np.random.default_rng(7)
    theta = rng.uniform(-0.5, 0.5, 26)
    fixed = random_fixed(rng)
    qd = np.zeros(26)
    qd[IDX["theta13"]] = 1.0
    kin = kinematics("RFFSSP", theta, qd, None, fixed, P)
    J = point_jacobian(kin, "tpL", 2, ("theta13",), fixed, P)
    assert np.allclose(J[:, 0], np.concatenate([kin.V["tpL"], kin.w[2]]), atol=1e-15)
