"""The thesis oracle (humanoid_sim.thesis, NumPy) against the pinocchio model: same system, every phase.

Pinocchio side (independent of the oracle): q from ``hm.q_on_foot``; v from theta_dot plus the base twist that
keeps the root toe body at rest (J_toe v = 0 solved for the 6 base components); a likewise with the drift.
Constrained dynamics: pinocchio's legacy KKT ``pin.forwardDynamics`` with the design.md section 4 constraints
(SSP: 6D weld of the stance main body 3/4 + lock of theta3/theta4; DSP: plus a 6D weld of the trailing toe).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.thesis import PHASES, FootState, ThesisEngine
from humanoid_sim.thesis.forces import fslice
from humanoid_sim.thesis.frames import IDX, skew
from humanoid_sim.thesis.jacobians import CDIAG_OF, JACOBIAN_DEFS, PHASE_JACOBIANS
from humanoid_sim.thesis.joint_space import Q_from_F, T_from_Q
from humanoid_sim.thesis.kinematics import kinematics, origins

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
LOCAL = pin.ReferenceFrame.LOCAL
TOE_FRAME = {"R": "O_1", "L": "O_2"}
LOCK = {"RFFSSP": "theta3", "RFFDSP": "theta3", "LFFSSP": "theta4", "LFFDSP": "theta4"}
WELDS = {"RFFSSP": ["O_3"], "LFFSSP": ["O_4"], "RFFDSP": ["O_3", "O_2"], "LFFDSP": ["O_4", "O_1"]}
REAL = (1, 2, 3, 4, 9, 10, 11, 12, 17, 20, 23, 24, 27)


class Pin:
    """Pinocchio evaluations on a private Data (the session model is shared and must not be mutated)."""

    def __init__(self, hm):
        self.hm, self.m, self.d = hm, hm.model, hm.model.createData()
        self.E = np.zeros((self.m.nv, 26))
        self.E[hm.theta_v_idx, np.arange(26)] = hm.theta_sign      # joint part of v from theta_dot

    def fid(self, name: str) -> int:
        return self.hm.frame_id(name)

    def base_map(self, q, root: str) -> np.ndarray:
        """N (nv x 26) with v = N theta_dot and toe body ``root`` at rest."""
        pin.computeJointJacobians(self.m, self.d, q)
        pin.updateFramePlacements(self.m, self.d)
        J1 = pin.getFrameJacobian(self.m, self.d, self.fid(TOE_FRAME[root]), LWA)
        N = self.E.copy()
        N[:6] = -np.linalg.solve(J1[:, :6], J1 @ self.E)
        return N

    def motion(self, q, thd, thdd, root: str) -> tuple[np.ndarray, np.ndarray]:
        """v, a for thesis rates with the root toe body at rest; leaves forward kinematics in self.d."""
        v = self.base_map(q, root) @ thd
        a = self.E @ thdd
        pin.forwardKinematics(self.m, self.d, q, v, a)
        pin.updateFramePlacements(self.m, self.d)
        drift = pin.getFrameAcceleration(self.m, self.d, self.fid(TOE_FRAME[root]), LOCAL).vector
        J1 = pin.getFrameJacobian(self.m, self.d, self.fid(TOE_FRAME[root]), LOCAL)
        a[:6] = -np.linalg.solve(J1[:, :6], drift)
        pin.forwardKinematics(self.m, self.d, q, v, a)
        pin.updateFramePlacements(self.m, self.d)
        return v, a


def random_state(hm, P: Pin, phase: str, seed: int):
    """q, fixed feet, theta, theta_dot, theta_ddot, root.  Toe-lock rate/acceleration zero where the dynamics need
    it (``locked``); in the DSPs the left toe data is read from pinocchio and the rates are projected so that both
    toe bodies are at rest (pinocchio Jacobians and drifts)."""
    rng = np.random.default_rng(seed)
    theta, thd, thdd = rng.uniform(-0.6, 0.6, 26), rng.uniform(-1, 1, 26), rng.uniform(-2, 2, 26)
    lock = IDX[LOCK[phase]]
    thd[lock] = thdd[lock] = 0.0
    C = pin.rpy.rpyToMatrix(*rng.uniform(-0.3, 0.3, 2), rng.uniform(-np.pi, np.pi))
    Ptp = np.array([*rng.uniform(-1, 1, 2), 0.015])
    root = "L" if phase == "LFFSSP" else "R"
    q = hm.q_on_foot(theta, root, Ptp, C)
    fixed = {root: FootState(C, Ptp)}
    if phase.endswith("DSP"):
        pin.framesForwardKinematics(P.m, P.d, q)
        M2 = P.d.oMf[P.fid("P_tpL")]
        fixed["L"] = FootState(M2.rotation.copy(), M2.translation.copy())
        N = P.base_map(q, "R")
        J2 = pin.getFrameJacobian(P.m, P.d, P.fid("O_2"), LWA)
        G = np.vstack([J2 @ N, np.eye(26)[lock]])
        Gp = np.linalg.pinv(G)
        thd = thd - Gp @ (G @ thd)
        P.motion(q, thd, np.zeros(26), "R")
        fid2 = P.fid("O_2")
        drift = np.concatenate([pin.getFrameClassicalAcceleration(P.m, P.d, fid2, LWA).linear,
                                pin.getFrameAcceleration(P.m, P.d, fid2, LWA).angular, [0.0]])
        thdd = thdd - Gp @ (G @ thdd + drift)
    return q, fixed, theta, thd, thdd, root


@pytest.fixture(scope="module")
def P(hm):
    return Pin(hm)


@pytest.fixture(scope="module")
def engine(hm):
    return ThesisEngine(hm.spec)


@pytest.mark.parametrize("phase", PHASES)
@pytest.mark.parametrize("seed", [1, 2])
def test_kinematics_equal_pinocchio(hm, P, engine, phase, seed):
    q, fixed, theta, thd, thdd, root = random_state(hm, P, phase, seed)
    thd[IDX[LOCK[phase]]] += 0.3 if phase.endswith("SSP") else 0.0   # kinematics need no toe lock in the SSPs
    kin = engine.kinematics(phase, theta, thd, fixed, theta_ddot=thdd)
    P.motion(q, thd, thdd, root)
    O = origins(kin, engine.params)
    pos_err = vel_err = acc_err = 0.0
    for k in range(1, 28):
        fid = P.fid(f"O_{k}")
        M = P.d.oMf[fid]
        pos_err = max(pos_err, np.abs(M.rotation - kin.C[k]).max(), np.abs(M.translation - O[k]).max())
        vel_err = max(vel_err, np.abs(pin.getFrameVelocity(P.m, P.d, fid, LWA).angular - kin.w[k]).max())
        acc_err = max(acc_err, np.abs(pin.getFrameAcceleration(P.m, P.d, fid, LWA).angular - kin.alpha[k]).max())
    points = [(f"Pc_{k}", f"c{k}") for k in REAL] + [("P_tpR", "tpR"), ("P_tpL", "tpL")]
    for frame, key in points:
        fid = P.fid(frame)
        pos_err = max(pos_err, np.abs(P.d.oMf[fid].translation - kin.P[key]).max())
        vel_err = max(vel_err, np.abs(pin.getFrameVelocity(P.m, P.d, fid, LWA).linear - kin.V[key]).max())
        acc_err = max(acc_err, np.abs(pin.getFrameClassicalAcceleration(P.m, P.d, fid, LWA).linear
                                      - kin.a[key]).max())
    # acceptance tolerances of the brief; measured ~1e-15 / 1e-14 / 3e-14 (float rounding along the chains)
    assert pos_err < 1e-12 and vel_err < 1e-10 and acc_err < 1e-10, (pos_err, vel_err, acc_err)


PIN_POINT = {"c17fR": "Pc_17", "c17fL": "Pc_17", "tpL": "P_tpL", "tpR": "P_tpR"}
PIN_FRAME = {"17fR": "O_17", "17fL": "O_17", 1: "O_1", 2: "O_2"}


def pin_thesis_jacobian(P: Pin, q, name: str, root: str) -> tuple[np.ndarray, np.ndarray]:
    """[V; w] per unit rate of the named columns, base eliminated through the root toe, and the rotation."""
    point, frame, cols = JACOBIAN_DEFS[name]
    N = P.base_map(q, root)
    Jl = pin.getFrameJacobian(P.m, P.d, P.fid(PIN_POINT[point]), LWA)[:3]
    Ja = pin.getFrameJacobian(P.m, P.d, P.fid(PIN_FRAME[frame]), LWA)[3:]
    idx = [IDX[c] for c in cols]
    return np.vstack([Jl, Ja]) @ N[:, idx], P.d.oMf[P.fid(PIN_FRAME[frame])].rotation.copy()


# Each Jacobian's chain is rooted at the toe whose data the thesis supplies for that chain (4.2.1.1-4.2.1.4).
JAC_ROOT = {"J_v,17_fR": "R", "J_v,tpL": "R", "J_v,17_fL": "L", "J_v,tpR": "L", "J_v,17_fL_all": "L",
            "J_v,17_fR_all": "R"}


@pytest.mark.parametrize("phase", PHASES)
def test_thesis_jacobians_equal_pinocchio(hm, P, engine, phase):
    q, fixed, theta, *_ = random_state(hm, P, phase, 11)
    Js = engine.jacobians(phase, theta, fixed)
    assert tuple(Js) == PHASE_JACOBIANS[phase]
    for name, J in Js.items():
        base = CDIAG_OF.get(name, name)
        Jp, R = pin_thesis_jacobian(P, q, base, JAC_ROOT[base])
        # Cdiag (eq. 4.9): d/dt diag(C^(0,k)) = diag(w~ C) per unit rate, with pinocchio's w and C
        ref = np.column_stack([np.diag(skew(Jp[3:, i]) @ R) for i in range(Jp.shape[1])]) if name in CDIAG_OF \
            else Jp
        assert np.abs(J - ref).max() < 1e-10, (name, np.abs(J - ref).max())   # measured ~1e-15


def test_numerical_jacobian_derivative_is_first_order(hm, P, engine):
    """Eq. 4.34 converges to pinocchio's analytic J_dot at first order: the error halves with the step."""
    q, fixed, theta, thd, _, _ = random_state(hm, P, "RFFSSP", 12)
    for name in ("J_v,17_fR", "J_v,tpL"):
        point, frame, cols = JACOBIAN_DEFS[name]
        N = P.base_map(q, "R")
        v = N @ thd
        pin.computeJointJacobiansTimeVariation(P.m, P.d, q, v)
        pin.updateFramePlacements(P.m, P.d)
        f1 = P.fid("O_1")
        J1, dJ1 = pin.getFrameJacobian(P.m, P.d, f1, LWA), pin.getFrameJacobianTimeVariation(P.m, P.d, f1, LWA)
        dN = np.zeros_like(N)       # d/dt of the base elimination N[:6] = -A^-1 J1 E, A = J1[:, :6]
        dN[:6] = -np.linalg.solve(J1[:, :6], dJ1[:, :6] @ N[:6] + dJ1 @ P.E)
        fl, fa = P.fid(PIN_POINT[point]), P.fid(PIN_FRAME[frame])
        JF = np.vstack([pin.getFrameJacobian(P.m, P.d, fl, LWA)[:3], pin.getFrameJacobian(P.m, P.d, fa, LWA)[3:]])
        dJF = np.vstack([pin.getFrameJacobianTimeVariation(P.m, P.d, fl, LWA)[:3],
                         pin.getFrameJacobianTimeVariation(P.m, P.d, fa, LWA)[3:]])
        idx = [IDX[c] for c in cols]
        dJ_analytic = (dJF @ N + JF @ dN)[:, idx]
        # the analytic reference itself against a central difference of pinocchio's Jacobian (O(h^2) ~ 1e-10)
        h = 1e-6
        Jp = pin_thesis_jacobian(P, hm.q_on_foot(theta + h * thd, "R", fixed["R"].P_tp, fixed["R"].C), name, "R")[0]
        Jm = pin_thesis_jacobian(P, hm.q_on_foot(theta - h * thd, "R", fixed["R"].P_tp, fixed["R"].C), name, "R")[0]
        assert np.abs((Jp - Jm) / (2 * h) - dJ_analytic).max() < 1e-7
        errs = [np.abs(engine.jacobian_derivatives("RFFSSP", theta, thd, fixed, dt, (name,))[name]
                       - dJ_analytic).max() for dt in (4e-3, 2e-3, 1e-3)]
        ratios = [errs[0] / errs[1], errs[1] / errs[2]]
        # first order: the ratio is 2 + O(dt); measured 1.9997-2.0017
        assert all(abs(r - 2.0) < 0.05 for r in ratios), (name, errs, ratios)
        assert errs[-1] < 1e-2          # and the error itself is O(dt |J_ddot|)


def constrained_dynamics(P: Pin, phase, q, v, tau):
    """pinocchio legacy KKT with the design.md section 4 constraints; returns (ddq, lambda)."""
    pin.computeJointJacobians(P.m, P.d, q)
    pin.forwardKinematics(P.m, P.d, q, v, np.zeros(P.m.nv))
    pin.updateFramePlacements(P.m, P.d)
    Js, gs = [], []
    for w in WELDS[phase]:
        Js.append(pin.getFrameJacobian(P.m, P.d, P.fid(w), LOCAL))
        gs.append(pin.getFrameAcceleration(P.m, P.d, P.fid(w), LOCAL).vector)
    row = np.zeros((1, P.m.nv))
    row[0, P.hm.theta_v_idx[IDX[LOCK[phase]]]] = 1.0
    Js.insert(1, row)
    gs.insert(1, np.zeros(1))
    J, g = np.vstack(Js), np.concatenate(gs)
    ddq = pin.forwardDynamics(P.m, P.d, q, v, tau, J, g)
    assert np.abs(J @ ddq + g).max() < 1e-9
    return ddq, P.d.lambda_c.copy()


def thesis_wrench(kin, O, F, bodies, about) -> tuple[np.ndarray, np.ndarray]:
    """Sum of F_0,k / M_0,k (frame k, about CoM k) over ``bodies``, world frame, moment about O_about."""
    f, n = np.zeros(3), np.zeros(3)
    for k in bodies:
        Fk, Mk = kin.C[k] @ F[fslice(f"F0_{k}")], kin.C[k] @ F[fslice(f"M0_{k}")]
        f, n = f + Fk, n + Mk + np.cross(kin.P[f"c{k}"] - O[about], Fk)
    return f, n


@pytest.mark.parametrize("phase", PHASES)
def test_direct_dynamics_equal_constrained_dynamics(hm, P, engine, phase):
    q, fixed, theta, thd, thdd, root = random_state(hm, P, phase, 21)
    rng = np.random.default_rng(5)
    T = engine.computed_torque(phase, theta, thd, thdd, fixed).T
    T = T + rng.uniform(-1, 1, 26) * np.where(np.isin(np.arange(26), [0, 8]), 0.01, 1.0)   # off the CTC solution
    res = engine.forward_dynamics(phase, theta, thd, T, fixed)
    kin = kinematics(phase, theta, thd, None, fixed, engine.params)
    tau = hm.tau_from_joint_torques(Q_from_F(kin, res.F))     # full shoulder moments (errata P-8)
    v, _ = P.motion(q, thd, np.zeros(26), root)
    ddq, lam = constrained_dynamics(P, phase, q, v, tau)
    err = np.abs(hm.theta_dot_from_v(ddq) - res.theta_ddot).max()
    assert err < 1e-8, err                                     # measured ~2e-11 (|theta_ddot| up to ~100)
    O = origins(kin, engine.params)
    stance = [1, 3] if WELDS[phase][0] == "O_3" else [2, 4]
    f, n = thesis_wrench(kin, O, res.F, stance, stance[1])
    R = P.d.oMf[P.fid(WELDS[phase][0])].rotation
    # per-foot totals (F_0,1 + F_0,3 about O_3); measured ~1e-12 N on ~500 N
    assert np.abs(R @ lam[:3] - f).max() < 1e-6 and np.abs(R @ lam[3:6] - n).max() < 1e-6
    if len(WELDS[phase]) == 2:
        toe = 2 if WELDS[phase][1] == "O_2" else 1
        f, n = thesis_wrench(kin, O, res.F, [toe], toe)
        R = P.d.oMf[P.fid(WELDS[phase][1])].rotation
        assert np.abs(R @ lam[7:10] - f).max() < 1e-6 and np.abs(R @ lam[10:13] - n).max() < 1e-6


@pytest.mark.parametrize("phase", ["RFFSSP", "LFFSSP"])
def test_single_support_computed_torque_equals_inverse_dynamics(hm, P, engine, phase):
    """5.2.1/5.2.2 against pinocchio: RNEA, stance wrench from the 6 base rows, theta3/4 row = toe lock (T1 = 0),
    then tau -> T with the arms' shoulder z moments from pinocchio's joint wrenches."""
    q, fixed, theta, thd, thdd, root = random_state(hm, P, phase, 31)
    ctc = engine.computed_torque(phase, theta, thd, thdd, fixed)
    v, a = P.motion(q, thd, thdd, root)
    tau_total = pin.rnea(P.m, P.d, q, v, a)
    shoulder_z = []
    kin = kinematics(phase, theta, None, None, fixed, engine.params)
    for joint, body in (("theta23", 23), ("theta24", 24)):
        jid = P.m.getJointId(joint)
        m_world = P.d.oMi[jid].rotation @ P.d.f[jid].angular       # moment on the arm about its joint, world
        shoulder_z.append(float((kin.C[body].T @ m_world)[2]))
    pin.computeJointJacobians(P.m, P.d, q)
    Jw = pin.getFrameJacobian(P.m, P.d, P.fid(WELDS[phase][0]), LOCAL)
    lam = np.linalg.solve(Jw[:6, :6].T, tau_total[:6])
    tau = tau_total - Jw.T @ lam
    assert np.abs(tau[:6]).max() < 1e-9
    tau[hm.theta_v_idx[IDX[LOCK[phase]]]] = 0.0               # the toe lock takes it: T1 (T2) = 0 (L3810)
    T_pin = T_from_Q(kin, hm.theta_dot_from_v(tau), tuple(shoulder_z))
    err = np.abs(T_pin - ctc.T).max()
    assert err < 1e-8, err                                     # measured ~1e-13 on |T| ~ 100 N m


@pytest.mark.parametrize("phase_from", ["RFFSSP", "LFFSSP"])
def test_touchdown_reset_stops_the_landing_foot(hm, P, engine, phase_from):
    q, fixed, theta, thd, _, root = random_state(hm, P, phase_from, 41)
    w_adj = np.array([1, 1, 1, 3, 1.8, 1.8, 1.8, 1, 1, 1, 3, 1.8, 1.8, 1.8])   # Appendix B L4912-4918
    res = engine.touchdown_reset(phase_from, theta, thd, fixed, w_adj)
    P.motion(q, res.theta_dot, np.zeros(26), root)
    landing = "O_2" if phase_from == "RFFSSP" else "O_1"
    point = "P_tpL" if phase_from == "RFFSSP" else "P_tpR"
    V = pin.getFrameVelocity(P.m, P.d, P.fid(point), LWA).linear
    w = pin.getFrameVelocity(P.m, P.d, P.fid(landing), LWA).angular
    assert np.abs(V).max() < 1e-10 and np.abs(w).max() < 1e-10      # rest to rounding (rates ~1 rad/s)
    changed = np.flatnonzero(res.theta_dot != thd)
    assert changed.size > 0 and changed.max() < 16                  # only q_lower (eq. 4.4) changes


# ------------------------------------------------------------------ the fast path itself
# (humanoid_sim.dynamics.contact)
@pytest.mark.parametrize("phase", PHASES)
def test_fast_contact_solver_equals_the_122x122_solution(hm, P, engine, phase):
    """Issue 5: the simulator's own solver (ContactDynamics.forward with the phase's contact set) against the
    thesis's direct dynamic solution, same q, q_dot and actuator torques.  The state lies on the constraint
    manifold and the anchors are recorded at q, so the Baumgarte terms vanish and both solve the same system."""
    from humanoid_sim.dynamics.contact import ContactDynamics, record_anchors
    from humanoid_sim.robot.phases import Phase

    q, fixed, theta, thd, thdd, root = random_state(hm, P, phase, 41)
    rng = np.random.default_rng(6)
    T = engine.computed_torque(phase, theta, thd, thdd, fixed).T + rng.uniform(-1, 1, 26)
    T[[0, 8]] = 0.0                       # both toe actuators off: the held one is a lock by K-10
    res = engine.forward_dynamics(phase, theta, thd, T, fixed)
    kin = kinematics(phase, theta, thd, None, fixed, engine.params)
    tau = hm.tau_from_joint_torques(Q_from_F(kin, res.F))
    v, _ = P.motion(q, thd, np.zeros(26), root)
    cs = Phase(phase).contacts
    fwd = ContactDynamics(hm.model).forward(cs, record_anchors(hm.model, q, cs), q, v, tau)
    # the bound; measured ~1e-11 on |theta_ddot| ~ 1e1-1e2
    assert np.abs(hm.theta_dot_from_v(fwd.a) - res.theta_ddot).max() < 1e-8
    O = origins(kin, engine.params)
    stance = [1, 3] if WELDS[phase][0] == "O_3" else [2, 4]
    f, n = thesis_wrench(kin, O, res.F, stance, stance[1])
    R = P.d.oMf[P.fid(WELDS[phase][0])].rotation
    lam = fwd.lam
    assert np.abs(R @ lam[:3] - f).max() < 1e-6 and np.abs(R @ lam[3:6] - n).max() < 1e-6


@pytest.mark.parametrize("phase", ["RFFSSP", "LFFSSP"])
def test_fast_computed_torque_equals_thesis_5_2(hm, P, engine, phase):
    """Issue 4: in single support the simulator's computed torque (ContactDynamics.inverse, then
    Actuators.thesis_torques to the thesis's Cartesian components) equals eq. 5.92 / 5.93 of the oracle."""
    from humanoid_sim.dynamics.contact import ContactDynamics, record_anchors
    from humanoid_sim.robot.actuators import Actuators
    from humanoid_sim.robot.phases import Phase

    q, fixed, theta, thd, thdd, root = random_state(hm, P, phase, 51)
    ctc = engine.computed_torque(phase, theta, thd, thdd, fixed)
    v, a = P.motion(q, thd, thdd, root)
    cs = Phase(phase).contacts
    inv = ContactDynamics(hm.model).inverse(cs, record_anchors(hm.model, q, cs), q, v, a)
    T = Actuators(hm).thesis_torques(q, v, inv.a, inv.tau)
    # the bound; measured ~1e-12 on |T| ~ 1e2 N m
    assert np.abs(T - ctc.T).max() < 1e-8
