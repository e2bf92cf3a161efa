"""Self-consistency of the thesis oracle's dynamics (4.3-4.5, 5.2), without pinocchio.

The comparison with pinocchio's constrained dynamics is in test_thesis_vs_pinocchio.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from humanoid_sim.thesis import PHASES, FootState, ThesisEngine
from humanoid_sim.thesis.dynamics import dynamic_terms
from humanoid_sim.thesis.forces import (
    CTC_ZERO,
    F_BLOCKS,
    N_F,
    T_F_INDEX,
    default_w_act,
    findex,
    phi,
    selector,
)
from humanoid_sim.thesis.frames import IDX, Q_LOWER, rot
from humanoid_sim.thesis.jacobians import full_jacobian
from humanoid_sim.thesis.joint_space import Q_from_F, T_from_Q, relative_angular_velocity_power
from humanoid_sim.thesis.kinematics import add_velocities, kinematics, positions
from humanoid_sim.thesis.params import load_params

P = load_params()
ENGINE = ThesisEngine(P)
LOCK = {"RFFSSP": "theta3", "RFFDSP": "theta3", "LFFSSP": "theta4", "LFFDSP": "theta4"}
TOTAL_MASS = sum(P.mass.values())


def random_state(phase: str, seed: int):
    """A state the phase admits: locked toe rate zero; in the DSPs the left toe data closes the chain and the
    rates satisfy the velocity closure (17_fR and 17_fL move together), built from the thesis's own relations."""
    rng = np.random.default_rng(seed)
    theta, thd = rng.uniform(-0.5, 0.5, 26), rng.uniform(-1, 1, 26)
    C = rot(3, rng.uniform(-np.pi, np.pi)) @ rot(1, rng.uniform(-0.2, 0.2))
    fixed = {"R": FootState(C, np.array([*rng.uniform(-1, 1, 2), 0.015])),
             "L": FootState(C, np.array([*rng.uniform(-1, 1, 2), 0.015]))}
    lock = np.eye(26)[IDX[LOCK[phase]]][None, :]
    if phase.endswith("DSP"):
        k = positions("RFFSSP", theta, {"R": fixed["R"]}, P)
        fixed["L"] = FootState(k.C[2], k.P["tpL"])
        kin = positions(phase, theta, fixed, P)
        G = np.vstack([full_jacobian(kin, "c17fR", "17fR", fixed, P) - full_jacobian(kin, "c17fL", "17fL", fixed, P),
                       lock])
    else:
        G = lock
    thd = thd - np.linalg.pinv(G) @ (G @ thd)
    return rng, theta, thd, fixed


def consistent_acceleration(phase, theta, thd, fixed, rng):
    """Random theta_ddot satisfying the phase's acceleration rows (toe lock; DSP closure eqs. 4.85/4.86)."""
    kin = add_velocities(positions(phase, theta, fixed, P), thd, fixed, P)
    terms = dynamic_terms(kin, thd, fixed, P)
    lock = np.eye(26)[IDX[LOCK[phase]]][None, :]
    if phase.endswith("DSP"):
        A, b = np.vstack([terms.A_closure, lock]), np.concatenate([terms.b_closure, [0.0]])
    else:
        A, b = lock, np.zeros(1)
    qdd = rng.uniform(-2, 2, 26)
    return qdd - np.linalg.pinv(A) @ (A @ qdd - b)


def test_force_vector_layout_and_actuator_extraction():
    """Eq. 4.68 has 32 blocks = 96 unknowns (L2808); eq. 4.69 with errata K-2; errata A-3 W_act reconstruction."""
    assert len(F_BLOCKS) == 32 and N_F == 96
    assert F_BLOCKS[12:16] == ("F12_17", "F17_20", "M12_17", "M17_20")    # errata K-12 interleaving
    assert T_F_INDEX[4] == findex("M9_11", 1) == 28                       # T9 = M_9,11y^(11) (errata K-2)
    errata_a3 = [10, 21, 22, 23, 28, 33, 34, 35, 42, 43, 44, 45, 46, 47, 52, 57, 58, 59, 70, 87, 88, 90, 91, 93,
                 94, 95]
    assert sorted(T_F_INDEX.tolist()) == errata_a3
    w = default_w_act()
    assert np.flatnonzero(w == 1000.0).tolist() == errata_a3 and np.all(w[w != 1000.0] == 1.0)
    assert phi().shape == (26, 96) and np.all(phi().sum(axis=1) == 1.0)


def test_static_stance_carries_the_weight():
    """Zero posture, at rest, RFFSSP computed torque for zero acceleration: the right foot carries m g and T1 = 0."""
    C0 = P.C0
    fixed = {"R": FootState(C0, np.array([0.16, 0.1876, 0.015]))}
    res = ENGINE.computed_torque("RFFSSP", np.zeros(26), np.zeros(26), np.zeros(26), fixed)
    kin = positions("RFFSSP", np.zeros(26), fixed, P)
    f_total = kin.C[1] @ res.F[0:3] + kin.C[3] @ res.F[12:15]
    # relative 1e-12 of the 540 N weight: a 96x96 solve of well-scaled data
    assert np.allclose(f_total, [0, 0, TOTAL_MASS * P.g], rtol=0, atol=1e-9)
    assert abs(res.T[0]) < 1e-12                    # T1 = M_1,3y = 0 by K_c (L3810), up to solver rounding
    # body 1 carries only its own weight (errata K-10)
    assert np.allclose(kin.C[1] @ res.F[0:3], [0, 0, P.mass[1] * P.g], atol=1e-12)
    assert res.residual < 1e-9


@pytest.mark.parametrize("phase", PHASES)
def test_computed_torque_then_direct_dynamics_round_trip(phase):
    """T from 5.2 fed to the 122 x 122 system of 4.4 returns the commanded acceleration and the same F."""
    rng, theta, thd, fixed = random_state(phase, 40 + PHASES.index(phase))
    qdd_c = consistent_acceleration(phase, theta, thd, fixed, rng)
    ctc = ENGINE.computed_torque(phase, theta, thd, qdd_c, fixed)
    fd = ENGINE.forward_dynamics(phase, theta, thd, ctc.T, fixed)
    # 1e-8 rad/s^2 and 1e-7 N: conditioning of the 122 x 122 system (~1e5) times float eps times |F| ~ 1e3
    assert np.allclose(fd.theta_ddot, qdd_c, atol=1e-8), np.abs(fd.theta_ddot - qdd_c).max()
    assert np.allclose(fd.F, ctc.F, atol=1e-7), np.abs(fd.F - ctc.F).max()
    assert fd.residual < 1e-8 and ctc.residual < 1e-8
    for name, comp in CTC_ZERO[phase]:
        assert np.allclose(selector([(name, comp)]) @ fd.F, 0.0, atol=1e-9), name


@pytest.mark.parametrize("phase", ["RFFDSP", "LFFDSP"])
def test_double_support_torque_is_the_weighted_minimum_norm(phase):
    """KKT of eq. 5.96/5.98: W_act F lies in the row space of K_T, so no feasible direction lowers the cost."""
    rng, theta, thd, fixed = random_state(phase, 50)
    qdd_c = consistent_acceleration(phase, theta, thd, fixed, rng)
    res = ENGINE.computed_torque(phase, theta, thd, qdd_c, fixed)
    kin = add_velocities(positions(phase, theta, fixed, P), thd, fixed, P)
    terms = dynamic_terms(kin, thd, fixed, P)
    KT = np.vstack([terms.K, selector(CTC_ZERO[phase])])
    _, s, Vt = np.linalg.svd(KT)
    null = Vt[np.sum(s > 1e-9 * s[0]):]                   # feasible directions K_T dF = 0
    assert null.shape[0] >= 6                              # 96 unknowns, at most 90 independent rows
    grad = default_w_act() * res.F
    # projection of the cost gradient on the feasible directions vanishes (relative to |W F| ~ 1e5)
    assert np.abs(null @ grad).max() < 1e-8 * np.abs(grad).max()
    # and the unweighted solution is a different (higher-torque) one: the weights matter
    other = ENGINE.computed_torque(phase, theta, thd, qdd_c, fixed, W_act=np.ones(96))
    assert np.linalg.norm(other.T) > np.linalg.norm(res.T)


def test_generalized_forces_by_virtual_power():
    """Q . theta_dot equals the power of the 12 joint moments, sum M_{a,b} . (w_b - w_a)."""
    rng, theta, thd, fixed = random_state("LFFSSP", 60)
    kin = kinematics("LFFSSP", theta, thd, None, fixed, P)
    F = rng.normal(size=96) * 10.0
    Q = Q_from_F(kin, F)
    power = relative_angular_velocity_power(kin, F)
    assert abs(Q @ thd - power) < 1e-12 * np.abs(F).sum() * np.abs(thd).sum()   # float rounding only


def test_torque_components_from_generalized_forces():
    """T_from_Q inverts Q_from_F on the actuator components, given the shoulder reaction z-components (P-8)."""
    rng, theta, thd, fixed = random_state("RFFSSP", 61)
    kin = positions("RFFSSP", theta, fixed, P)
    F = rng.normal(size=96) * 10.0
    Q = Q_from_F(kin, F)
    T = T_from_Q(kin, Q, (F[findex("M20_23", 2)], F[findex("M20_24", 2)]))
    assert np.allclose(T, phi() @ F, atol=1e-11)
    # P-8: the shoulder z moment does work through theta21 when theta23 != 0
    F2 = F.copy()
    F2[findex("M20_23", 2)] += 1.0
    dQ = Q_from_F(kin, F2) - Q
    assert abs(dQ[IDX["theta21"]]) > 0.1 * abs(np.sin(theta[IDX["theta23"]]))
    assert np.allclose(np.delete(dQ, IDX["theta21"]), 0.0, atol=1e-14)


@pytest.mark.parametrize("phase_from", ["RFFSSP", "LFFSSP"])
def test_touchdown_reset(phase_from):
    """Eq. 4.97/4.100: landing toe at rest, dropped toe rate zero, upper body and stance toe rates unchanged, and
    the change is the W_adj-weighted least change (optimality: W dq is orthogonal to the constraint null space)."""
    rng, theta, thd, fixed = random_state(phase_from, 70)
    w_adj = np.array([1, 1, 1, 3, 1.8, 1.8, 1.8, 1, 1, 1, 3, 1.8, 1.8, 1.8])  # Appendix B L4912-4918
    res = ENGINE.touchdown_reset(phase_from, theta, thd, fixed, w_adj)
    assert np.abs(res.V_landing).max() < 1e-12 and np.abs(res.w_landing).max() < 1e-12  # float rounding
    dropped, stance = ("theta4", "theta3") if phase_from == "RFFSSP" else ("theta3", "theta4")
    assert res.theta_dot[IDX[dropped]] == 0.0
    assert res.theta_dot[IDX[stance]] == thd[IDX[stance]]
    assert np.array_equal(res.theta_dot[16:], thd[16:])                      # upper body untouched (L3036)
    assert set(res.columns) == set(Q_LOWER) - {dropped, stance} and len(res.columns) == 14
    # optimality of the weighted least change
    from humanoid_sim.thesis.jacobians import point_jacobian
    kin = positions(phase_from, theta, fixed, P)
    point, body = ("tpL", 2) if phase_from == "RFFSSP" else ("tpR", 1)
    J = point_jacobian(kin, point, body, res.columns, fixed, P)
    idx = [IDX[c] for c in res.columns]
    dq = res.theta_dot[idx] - thd[idx]
    _, s, Vt = np.linalg.svd(J)
    null = Vt[6:]
    assert np.abs(null @ (w_adj * dq)).max() < 1e-12 * max(1.0, np.abs(w_adj * dq).max())
    with pytest.raises(ValueError, match="14 positive"):
        ENGINE.touchdown_reset(phase_from, theta, thd, fixed, w_adj[:13])
