"""Contact-constrained forward / inverse dynamics and ground reactions on the thesis humanoid (issue 5).

Oracles: the plain NumPy KKT of humanoid_sim.dynamics.contact.oracle (its own Jacobians, Jdot v from
getFrameJacobianTimeVariation, dense solve), pinocchio's legacy forwardDynamics(q, v, tau, J, gamma), and
pinocchio's constraintDynamics (its own constraint kinematics and Baumgarte corrector), plus momentum and
energy laws.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg as sla

from humanoid_sim.dynamics.contact import (
    AnchorError,
    Anchors,
    Baumgarte,
    ContactDynamics,
    ContactInputError,
    ContactSet,
    ContactSetError,
    SingularConstraintError,
    ground_reactions,
    record_anchors,
)
from humanoid_sim.dynamics.contact.oracle import kkt_forward, oracle_terms
from humanoid_sim.engines.impact import constraint_jacobian
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import FOOT_SPECS, Phase

PHASES = list(Phase)
FEET = list(FOOT_SPECS.values())
# Agreement tolerance of the brief.  Observed differences are 1e-12..3e-11: double round-off amplified by the
# KKT condition number (~1e4-1e5 here) on accelerations of O(10-100) rad/s^2 and multipliers of O(100) N.
TOL = 1e-9


def _random_q(hm: HumanoidModel, rng: np.random.Generator, scale: float = 0.3) -> np.ndarray:
    return pin.integrate(hm.model, hm.initial_q(), scale * rng.standard_normal(hm.model.nv))


def _random_tau(hm: HumanoidModel, rng: np.random.Generator, scale: float = 20.0) -> np.ndarray:
    tau = np.zeros(hm.model.nv)
    tau[6:] = scale * rng.standard_normal(hm.model.nv - 6)
    return tau


def _state(hm: HumanoidModel, rng: np.random.Generator, cs: ContactSet):
    """Random state with anchors recorded 1e-3 away, so the Baumgarte position terms are active."""
    q0 = _random_q(hm, rng)
    anchors = record_anchors(hm.model, q0, cs)
    q = pin.integrate(hm.model, q0, 1e-3 * rng.standard_normal(hm.model.nv))
    return q, anchors, rng.standard_normal(hm.model.nv), _random_tau(hm, rng)


def _rel(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.max(np.abs(x - y)) / max(1.0, np.max(np.abs(y))))


# ------------------------------------------------------------------------------------------- forward
@pytest.mark.parametrize("phase", PHASES, ids=lambda p: p.value)
def test_forward_agrees_with_numpy_kkt_and_legacy(hm: HumanoidModel, phase: Phase) -> None:
    rng = np.random.default_rng(100 + PHASES.index(phase))
    dyn = ContactDynamics(hm.model)
    cs = phase.contacts
    for _ in range(3):
        q, anchors, v, tau = _state(hm, rng, cs)
        res = dyn.forward(cs, anchors, q, v, tau)
        a_o, lam_o = kkt_forward(hm.model, cs, anchors, q, v, tau, dyn.gains)
        assert _rel(res.a, a_o) < TOL and _rel(res.lam, lam_o) < TOL
        t = oracle_terms(hm.model, cs, anchors, q, v)
        gamma = t.drift + dyn.gains.kd * t.velocity + dyn.gains.kp * t.error
        dl = hm.model.createData()
        a_l = pin.forwardDynamics(hm.model, dl, q, v, tau, t.J, gamma)
        assert _rel(res.a, a_l) < TOL and _rel(res.lam, dl.lambda_c) < TOL
        # Self-reported residuals: round-off level (1e-9 of O(1e3) entries of M a).
        assert res.dynamics_residual < 1e-9 and res.constraint_residual < 1e-9
        # Drift reports against an independent computation of the weld / lock errors.
        data = hm.model.createData()
        pin.framesForwardKinematics(hm.model, data, q)
        dist = [np.linalg.norm(data.oMf[hm.frame_id(f)].translation - anchors.placements[f].translation)
                for f in cs.welds]
        assert res.position_drift == pytest.approx(max(dist), rel=1e-12)
        lock = [abs(q[hm.model.idx_qs[hm.model.getJointId(j)]] - anchors.joint_positions[j]) for j in cs.locks]
        assert res.lock_drift == pytest.approx(max(lock), rel=1e-12)
        assert res.velocity_drift == pytest.approx(np.max(np.abs(t.J @ v)), rel=1e-12)


def _pin_constraints(hm: HumanoidModel, welds, anchors: Anchors, gains: Baumgarte):
    cms = []
    for f in welds:
        fr = hm.model.frames[hm.frame_id(f)]
        cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_6D, hm.model, fr.parentJoint, fr.placement, 0,
                                      anchors.placements[f], pin.ReferenceFrame.LOCAL)
        cm.m_baumgarte_parameters.Kp = gains.kp
        cm.m_baumgarte_parameters.Kd = gains.kd
        cms.append(cm)
    return cms


@pytest.mark.parametrize("phase", PHASES, ids=lambda p: p.value)
def test_forward_agrees_with_constraint_dynamics(hm: HumanoidModel, phase: Phase) -> None:
    """pin.constraintDynamics has no 1-row joint lock.  For constraint-consistent velocities, a locked toe
    on a welded foot is the same acceleration-level constraint as a second weld of the toe body (12 rows,
    rank 7, solved with proximal iterations).  Accelerations and the total ground wrench per foot agree."""
    rng = np.random.default_rng(200 + PHASES.index(phase))
    model = hm.model
    dyn = ContactDynamics(model)
    cs = phase.contacts
    toe_of = {s.toe_joint: s.toe_frame for s in FEET}
    welds = cs.welds + tuple(toe_of[j] for j in cs.locks)
    for _ in range(2):
        q = _random_q(hm, rng)
        N = sla.null_space(constraint_jacobian(model, model.createData(), q, cs))
        v = N @ rng.standard_normal(N.shape[1])
        tau = _random_tau(hm, rng)
        anchors = record_anchors(model, q, ContactSet(welds, cs.locks))
        res = dyn.forward(cs, anchors, q, v, tau)
        cms = _pin_constraints(hm, welds, anchors, dyn.gains)
        cds = [c.createData() for c in cms]
        data = model.createData()
        pin.initConstraintDynamics(model, data, cms, cds)
        prox = pin.ProximalSettings(1e-14, 1e-6, 100)
        a_cd = pin.constraintDynamics(model, data, q, v, tau, cms, cds, prox)
        assert _rel(res.a, a_cd) < TOL
        # Total ground wrench on each foot, world frame about the origin.
        pin.framesForwardKinematics(model, data, q)
        mult = res.multipliers()
        for spec in FEET:
            mine = sum((data.oMf[hm.frame_id(f)].act(pin.Force(mult[f"weld:{f}"])).vector
                        for f in (spec.main_frame, spec.toe_frame) if f in cs.welds), np.zeros(6))
            theirs = sum((data.oMf[hm.frame_id(f)].act(cd.contact_force).vector
                          for f, cd in zip(welds, cds) if f in (spec.main_frame, spec.toe_frame)), np.zeros(6))
            assert _rel(mine, theirs) < TOL, (spec.name, mine, theirs)


def test_baumgarte_matches_pinocchio_corrector(hm: HumanoidModel) -> None:
    """Weld-only set, position errors ~1e-2 and arbitrary (inconsistent) velocities: the stabilized law
    J a = -(Jdot v + Kd J v + Kp log6(anchor^-1 oMf)) is pinocchio's Baumgarte corrector."""
    rng = np.random.default_rng(3)
    cs = ContactSet(("O_3", "O_2"), name="two welds")
    for gains in (Baumgarte(20.0, 1.0), Baumgarte(50.0, 0.7)):
        dyn = ContactDynamics(hm.model, gains)
        q0 = _random_q(hm, rng)
        anchors = record_anchors(hm.model, q0, cs)
        q = pin.integrate(hm.model, q0, 1e-2 * rng.standard_normal(hm.model.nv))
        v, tau = rng.standard_normal(hm.model.nv), _random_tau(hm, rng)
        res = dyn.forward(cs, anchors, q, v, tau)
        cms = _pin_constraints(hm, cs.welds, anchors, gains)
        cds = [c.createData() for c in cms]
        data = hm.model.createData()
        pin.initConstraintDynamics(hm.model, data, cms, cds)
        a_cd = pin.constraintDynamics(hm.model, data, q, v, tau, cms, cds)
        assert _rel(res.a, a_cd) < TOL
        assert _rel(res.lam, np.concatenate([cd.contact_force.vector for cd in cds])) < TOL


# ------------------------------------------------------------------------------------------- inverse
@pytest.mark.parametrize("phase", PHASES, ids=lambda p: p.value)
def test_static_posture_round_trip(hm: HumanoidModel, phase: Phase) -> None:
    """Torques from the constrained inverse dynamics of a static posture hold it: forward gives a = 0."""
    rng = np.random.default_rng(300 + PHASES.index(phase))
    dyn = ContactDynamics(hm.model)
    cs = phase.contacts
    v = np.zeros(hm.model.nv)
    for _ in range(3):
        q = _random_q(hm, rng)
        anchors = record_anchors(hm.model, q, cs)
        inv = dyn.inverse(cs, anchors, q, v, np.zeros(hm.model.nv))
        assert inv.dynamics_residual < 1e-9 and inv.constraint_residual < 1e-12
        res = dyn.forward(cs, anchors, q, v, inv.tau)
        assert np.max(np.abs(res.a)) < TOL
        assert _rel(res.lam, inv.lam) < TOL
        assert np.all(inv.tau[:6] == 0.0) and np.all(inv.tau[dyn.rows(cs).lock_v] == 0.0)  # K-10
        k = 6 if phase.is_double_support else 0
        assert inv.null_space.shape == (hm.model.nv - 6 - len(cs.locks) + cs.n_rows, k)
        if k:
            tau2, lam2 = inv.with_null(50.0 * rng.standard_normal(k))
            res2 = dyn.forward(cs, anchors, q, v, tau2)
            assert np.max(np.abs(res2.a)) < TOL and _rel(res2.lam, lam2) < TOL
            assert np.max(np.abs(tau2 - inv.tau)) > 1.0  # it really is a different torque distribution


@pytest.mark.parametrize("phase", PHASES, ids=lambda p: p.value)
def test_inverse_then_forward_moving(hm: HumanoidModel, phase: Phase) -> None:
    rng = np.random.default_rng(400 + PHASES.index(phase))
    dyn = ContactDynamics(hm.model)
    cs = phase.contacts
    q, anchors, v, tau = _state(hm, rng, cs)
    a_des = 5.0 * rng.standard_normal(hm.model.nv)
    inv = dyn.inverse(cs, anchors, q, v, a_des)
    res = dyn.forward(cs, anchors, q, v, inv.tau)
    assert _rel(res.a, inv.a) < TOL and _rel(res.lam, inv.lam) < TOL
    free = inv.free
    if not phase.is_double_support:
        assert inv.acceleration_correction < 1e-9        # SSP: every free joint acceleration is realizable
        # Accelerations of a forward solve are reproduced, and so are its actuated torques (unique in SSP).
        fwd = dyn.forward(cs, anchors, q, v, tau)
        inv2 = dyn.inverse(cs, anchors, q, v, fwd.a)
        assert _rel(inv2.a, fwd.a) < TOL and _rel(inv2.tau[free], tau[free]) < TOL
    else:
        assert inv.acceleration_correction > 1e-3        # a random a_des violates the closed chain
        # The correction is the least-squares one: orthogonal to every constraint-compatible direction.
        N = sla.null_space(inv.J)
        assert np.max(np.abs(N[free].T @ (inv.a - a_des)[free])) < 1e-9
        fwd = dyn.forward(cs, anchors, q, v, tau)
        inv2 = dyn.inverse(cs, anchors, q, v, fwd.a)     # consistent desired accelerations: no correction
        assert inv2.acceleration_correction < 1e-8 and _rel(inv2.a, fwd.a) < TOL


@pytest.mark.parametrize("phase", [Phase.RFFDSP, Phase.LFFDSP], ids=lambda p: p.value)
def test_weighted_minimum_norm(hm: HumanoidModel, phase: Phase) -> None:
    rng = np.random.default_rng(500 + PHASES.index(phase))
    dyn = ContactDynamics(hm.model)
    cs = phase.contacts
    q, anchors, v, _ = _state(hm, rng, cs)
    a_des = dyn.forward(cs, anchors, q, v, _random_tau(hm, rng)).a
    w_tau = rng.uniform(0.5, 2.0, hm.model.nv)
    w_lam = rng.uniform(0.5, 2.0, cs.n_rows)
    inv = dyn.inverse(cs, anchors, q, v, a_des, w_tau, w_lam)
    assert inv.dynamics_residual < 1e-9
    N = inv.null_space
    assert N.shape[1] == 6 and np.max(np.abs(inv.A @ N)) < 1e-12
    W = np.concatenate([w_tau[inv.actuated], w_lam])
    # Optimality of min x^T W x on the affine solution set: W x is orthogonal to the null space.  The scale is
    # |W x| ~ 1e3, so 1e-8 is round-off.
    assert np.max(np.abs(N.T @ (W * inv.x))) < 1e-8
    # Penalizing the trailing toe's wrench shifts the load to the support foot.
    toe_rows = cs.row_slices()[f"weld:{cs.welds[1]}"]
    heavy = np.ones(cs.n_rows)
    heavy[toe_rows] = 1e4
    base = dyn.inverse(cs, anchors, q, v, a_des)
    shifted = dyn.inverse(cs, anchors, q, v, a_des, w_lambda=heavy)
    assert np.linalg.norm(shifted.lam[toe_rows]) < 0.5 * np.linalg.norm(base.lam[toe_rows])
    assert _rel(dyn.forward(cs, anchors, q, v, shifted.tau).a, a_des) < TOL


# ------------------------------------------------------------------------------------------- reactions
def _centroidal_wrench(hm: HumanoidModel, q, v, a) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Total external (ground) wrench from the momentum law: f = dP/dt - m g, n_G = dL_G/dt."""
    data = hm.model.createData()
    dh = pin.computeCentroidalMomentumTimeVariation(hm.model, data, q, v, a)
    mass = sum(I.mass for I in hm.model.inertias)
    return dh.linear - mass * hm.model.gravity.linear, dh.angular, data.com[0].copy()


@pytest.mark.parametrize("phase", PHASES, ids=lambda p: p.value)
def test_ground_reactions_thesis_split_and_momentum(hm: HumanoidModel, phase: Phase) -> None:
    rng = np.random.default_rng(600 + PHASES.index(phase))
    model = hm.model
    dyn = ContactDynamics(model)
    cs = phase.contacts
    q, anchors, v, tau = _state(hm, rng, cs)
    res = dyn.forward(cs, anchors, q, v, tau)
    gr = ground_reactions(model, q, v, res.a, cs, res.lam, FEET)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    point = rng.standard_normal(3)
    total_f, total_n = np.zeros(3), np.zeros(3)
    for spec in FEET:
        # Foot total straight from the weld multipliers (LOCAL at the frame origin), moved to `point`.
        f_raw, n_raw = np.zeros(3), np.zeros(3)
        for frame in (spec.main_frame, spec.toe_frame):
            if frame in cs.welds:
                M = data.oMf[hm.frame_id(frame)]
                lam = res.multipliers()[f"weld:{frame}"]
                f_w = M.rotation @ lam[:3]
                f_raw += f_w
                n_raw += M.rotation @ lam[3:] + np.cross(M.translation - point, f_w)
        # Sum of the thesis per-body wrenches (F_0,k, M_0,k about Pc_k in frame k), moved to `point` with the
        # model's Pc_k frames and O_k rotations.
        f_sum, n_sum = np.zeros(3), np.zeros(3)
        for frame in (spec.main_frame, spec.toe_frame):
            bw = gr.bodies[frame]
            R = data.oMf[hm.frame_id(frame)].rotation
            com = data.oMf[hm.frame_id(frame.replace("O_", "Pc_"))].translation
            f_sum += R @ bw.force
            n_sum += R @ bw.moment + np.cross(com - point, R @ bw.force)
        fw = gr.feet[spec.name]
        for x, y in ((f_sum, f_raw), (n_sum, n_raw), (fw.force, f_raw), (fw.moment_about(point), n_raw)):
            assert _rel(x, y) < 1e-10  # transforms of O(100) N values: round-off
        total_f += f_raw
        total_n += n_raw
    # K-10 split on the foot held flat, while moving (random v, Baumgarte active): the toe body's ground
    # wrench is its own Newton-Euler wrench, m (a_c - g) and J alpha + w x J w about Pc (eqs. 4.42-4.43 with
    # F_13 = M_13 = 0), from pinocchio's classical CoM acceleration and the body's rotational inertia.
    spec = FOOT_SPECS[phase.support_foot]
    jt = model.frames[hm.frame_id(spec.toe_frame)].parentJoint
    pin.forwardKinematics(model, data, q, v, res.a)
    pin.updateFramePlacements(model, data)
    pc = hm.frame_id(spec.toe_frame.replace("O_", "Pc_"))
    a_c = pin.getFrameClassicalAcceleration(model, data, pc, pin.LOCAL_WORLD_ALIGNED).linear
    w = pin.getFrameVelocity(model, data, pc, pin.LOCAL_WORLD_ALIGNED).angular
    alpha = pin.getFrameAcceleration(model, data, pc, pin.LOCAL_WORLD_ALIGNED).angular
    R_j = data.oMi[jt].rotation
    I_w = R_j @ model.inertias[jt].inertia @ R_j.T
    R_t = data.oMf[hm.frame_id(spec.toe_frame)].rotation
    toe = gr.bodies[spec.toe_frame]
    assert _rel(R_t @ toe.force, model.inertias[jt].mass * (a_c - model.gravity.linear)) < 1e-10
    assert _rel(R_t @ toe.moment, I_w @ alpha + np.cross(w, I_w @ w)) < 1e-10
    f_c, n_g, com = _centroidal_wrench(hm, q, v, res.a)
    assert _rel(total_f, f_c) < 1e-9
    assert _rel(total_n, n_g + np.cross(com - point, f_c)) < 1e-9
    if phase.is_double_support:  # eq. 4.83 / 4.89: the trailing foot's main body has no ground wrench
        trailing = FOOT_SPECS[phase.trailing_toe].main_frame
        assert np.all(gr.bodies[trailing].force == 0.0) and np.all(gr.bodies[trailing].moment == 0.0)
    else:
        swing = FOOT_SPECS[phase.swing_foot]
        assert not np.any(gr.feet[swing.name].force) and np.all(np.isnan(gr.feet[swing.name].cop))


@pytest.mark.parametrize("phase", [Phase.RFFSSP, Phase.LFFSSP], ids=lambda p: p.value)
def test_static_toe_carries_own_weight_and_cop_is_zmp(hm: HumanoidModel, phase: Phase) -> None:
    """Errata K-10: with the toe locked the toe body carries only its own weight (at rest: F_0,1 = m_1 g up,
    M_0,1 = 0 about its CoM).  In a static single support the CoP is below the CoM."""
    rng = np.random.default_rng(700)
    model = hm.model
    dyn = ContactDynamics(model)
    cs = phase.contacts
    q = _random_q(hm, rng, 0.1)
    anchors = record_anchors(model, q, cs)
    v = np.zeros(model.nv)
    inv = dyn.inverse(cs, anchors, q, v, np.zeros(model.nv))
    res = dyn.forward(cs, anchors, q, v, inv.tau)
    gr = ground_reactions(model, q, v, res.a, cs, res.lam, FEET)
    spec = FOOT_SPECS[phase.support_foot]
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    toe = gr.bodies[spec.toe_frame]
    m_toe = model.inertias[model.frames[hm.frame_id(spec.toe_frame)].parentJoint].mass
    R = data.oMf[hm.frame_id(spec.toe_frame)].rotation
    # 1e-9: the residual acceleration of the round trip (< 1e-9 m/s^2) times a 0.13 kg body, plus round-off.
    np.testing.assert_allclose(toe.force, R.T @ np.array([0.0, 0.0, m_toe * 9.81]), atol=1e-9)
    np.testing.assert_allclose(toe.moment, np.zeros(3), atol=1e-9)
    com = pin.centerOfMass(model, data, q)
    cop = gr.feet[spec.name].cop
    np.testing.assert_allclose(cop[:2], com[:2], atol=1e-9)  # static: ZMP = ground projection of the CoM
    assert abs(gr.feet[spec.name].free_moment) < 1e-8  # static: no vertical moment; round-off on O(100) N m
    # The stance foot carries the whole weight: 55.044 kg (Table 2.4 sum) * 9.81 m/s^2; 1e-12 is round-off.
    assert gr.feet[spec.name].force[2] == pytest.approx(55.044 * 9.81, rel=1e-12)


# ------------------------------------------------------------------------------------------- energy
def _ode3_step(f, model: pin.Model, q: np.ndarray, v: np.ndarray, h: float):
    """Bogacki-Shampine 3rd order (Simulink ode3), fixed step; configuration via pin.integrate."""
    a1 = f(q, v)
    q2, v2 = pin.integrate(model, q, 0.5 * h * v), v + 0.5 * h * a1
    a2 = f(q2, v2)
    q3, v3 = pin.integrate(model, q, 0.75 * h * v2), v + 0.75 * h * a2
    a3 = f(q3, v3)
    return (pin.integrate(model, q, h * (2 / 9 * v + 1 / 3 * v2 + 4 / 9 * v3)),
            v + h * (2 / 9 * a1 + 1 / 3 * a2 + 4 / 9 * a3))


def test_energy_conservation_double_support(hm: HumanoidModel) -> None:
    """tau = 0, gravity on, RFFDSP welds, 2 s of ode3 at h = 1e-3.

    Upright, the passive robot collapses through closed-chain singularities and Euler-angle gimbal locks
    within ~1.7 s (measured: joint rates > 150 rad/s), which no fixed-step integrator follows.  So the robot
    hangs from its welded feet (turned upside down, gravity pulls the body away from the feet): it is first
    settled near its stable hanging equilibrium with joint damping, then released from rest with the waist,
    neck and both arms displaced, and swings (kinetic energy range ~5 J)."""
    model = hm.model
    th = np.zeros(26)
    for name, val in (("theta11", 0.2), ("theta12", 0.2), ("theta15", 0.4), ("theta16", -0.4),
                      ("theta9", -0.4), ("theta10", 0.4), ("theta21", np.pi), ("theta22", -np.pi)):
        th[hm.theta_index(name)] = val
    R_flip = pin.utils.rotate("x", np.pi) @ hm.spec.C0
    q = hm.q_on_foot(th, "R", np.array([0.16, 0.1876, 0.015]), R_flip)
    cs = Phase.RFFDSP.contacts
    anchors = record_anchors(model, q, cs)
    dyn = ContactDynamics(model)
    zero = np.zeros(model.nv)

    def damped(qq, vv):
        tau = np.zeros(model.nv)
        tau[6:] = -5.0 * vv[6:]  # N m s/rad joint damping, only for settling
        return dyn.forward(cs, anchors, qq, vv, tau).a

    v = np.zeros(model.nv)
    for _ in range(2000):  # 4 s at 2 ms
        q, v = _ode3_step(damped, model, q, v, 2e-3)
    dq = np.zeros(model.nv)
    for name, val in (("theta21", 0.4), ("theta22", -0.4), ("theta18", 0.3), ("theta25", 0.3)):
        dq[model.idx_vs[model.getJointId(name)]] = val  # upper-body joints: the welds are unaffected
    q, v = pin.integrate(model, q, dq), np.zeros(model.nv)
    anchors = record_anchors(model, q, cs)

    def free(qq, vv):
        return dyn.forward(cs, anchors, qq, vv, zero).a

    data = model.createData()

    def energy(qq, vv):
        return pin.computeKineticEnergy(model, data, qq, vv), pin.computePotentialEnergy(model, data, qq)

    ke0, pe0 = energy(q, v)
    kes, es, drift_p, drift_r = [ke0], [ke0 + pe0], 0.0, 0.0
    for _ in range(2000):
        q, v = _ode3_step(free, model, q, v, 1e-3)
        ke, pe = energy(q, v)
        kes.append(ke)
        es.append(ke + pe)
        r = dyn.forward(cs, anchors, q, v, zero)
        drift_p, drift_r = max(drift_p, r.position_drift), max(drift_r, r.orientation_drift)
    ke_range = max(kes) - min(kes)
    assert ke_range > 1.0  # it really moves (measured ~4.9 J)
    # Brief: energy change < 1e-4 of the kinetic range (measured 7.5e-6; ode3 error scales as h^3 -- measured
    # factor 8 per halving of h on a harder run).
    assert max(abs(e - es[0]) for e in es) < 1e-4 * ke_range
    assert drift_p < 1e-6 and drift_r < 1e-6  # m, rad (measured ~1e-7)


# ------------------------------------------------------------------------------------------- errors, speed
def test_errors_carry_the_offending_value(hm: HumanoidModel) -> None:
    dyn = ContactDynamics(hm.model)
    q, v = hm.initial_q(), np.zeros(hm.model.nv)
    cs = Phase.RFFSSP.contacts
    anchors = record_anchors(hm.model, q, cs)
    tau = np.zeros(hm.model.nv)
    tau[2] = 3.5
    with pytest.raises(ContactInputError, match="3.5"):
        dyn.forward(cs, anchors, q, v, tau)
    with pytest.raises(ContactInputError, match=r"\(31,\)"):
        dyn.forward(cs, anchors, q, v, np.zeros(31))
    with pytest.raises(AnchorError, match="O_3"):
        dyn.forward(cs, Anchors(), q, v, np.zeros(hm.model.nv))
    with pytest.raises(ContactSetError, match="O_99"):
        dyn.forward(ContactSet(("O_99",)), anchors, q, v, np.zeros(hm.model.nv))
    with pytest.raises(ContactSetError, match="root_joint"):
        ContactDynamics(hm.model).rows(ContactSet(locks=("root_joint",)))
    redundant = ContactSet(("O_3", "O_1"), ("theta3",), name="dependent rows")
    with pytest.raises(SingularConstraintError, match="dependent rows"):
        dyn.forward(redundant, record_anchors(hm.model, q, redundant), q, v, np.zeros(hm.model.nv))
    with pytest.raises(ContactSetError, match="duplicate"):
        ContactSet(("O_3", "O_3"))


@pytest.mark.parametrize("phase", [Phase.LFFSSP, Phase.RFFSSP], ids=lambda p: p.value)
def test_single_support_closed_form_equals_general_solution(hm: HumanoidModel, phase: Phase, monkeypatch) -> None:
    """The single-support elimination (one weld + locks) returns the general KKT/minimum-norm solution."""
    from humanoid_sim.dynamics.contact import inverse as inv_mod

    rng = np.random.default_rng(500 + PHASES.index(phase))
    dyn = ContactDynamics(hm.model)
    cs = phase.contacts
    q, anchors, v, _ = _state(hm, rng, cs)
    a_des = 5.0 * rng.standard_normal(hm.model.nv)
    fast = dyn.inverse(cs, anchors, q, v, a_des)
    monkeypatch.setattr(inv_mod, "_square_support", lambda rows: False)
    general = dyn.inverse(cs, anchors, q, v, a_des)
    # two exact solves of the same unique problem: round-off relative to torques of order 1e2-1e3 N m
    assert _rel(fast.a, general.a) < 1e-10 and _rel(fast.tau, general.tau) < 1e-10
    assert _rel(fast.lam, general.lam) < 1e-10
    assert fast.dynamics_residual < 1e-8 and fast.constraint_residual < 1e-9


@pytest.mark.parametrize("phase", PHASES, ids=lambda p: p.value)
def test_log_arrays_equal_the_ground_reaction_objects(hm: HumanoidModel, phase: Phase) -> None:
    """GroundReactionLog (what the simulator logs) fills the same numbers as ground_reactions (tested above
    against the momentum law and the thesis split); bodies without ground contact keep their zero rows."""
    from humanoid_sim.dynamics.contact.wrenches import GroundReactionLog

    rng = np.random.default_rng(600 + PHASES.index(phase))
    cs = phase.contacts
    q, anchors, v, tau = _state(hm, rng, cs)
    res = ContactDynamics(hm.model).forward(cs, anchors, q, v, tau)
    frames = ("O_1", "O_2", "O_3", "O_4")
    bf, bm = np.zeros((4, 3)), np.zeros((4, 3))
    fw, cop = np.zeros((2, 6)), np.zeros((2, 3))
    GroundReactionLog(hm.model, FEET, frames)(q, v, res.a, cs, res.lam, bf, bm, fw, cop)
    gr = ground_reactions(hm.model, q, v, res.a, cs, res.lam, FEET)
    for i, frame in enumerate(frames):
        expected = (gr.bodies[frame].force, gr.bodies[frame].moment) if frame in gr.bodies else (np.zeros(3),) * 2
        # the same helpers on the same data: identical up to round-off of forces of order 1e2-1e3 N
        np.testing.assert_allclose(bf[i], expected[0], atol=1e-9)
        np.testing.assert_allclose(bm[i], expected[1], atol=1e-9)
    for i, foot in enumerate(FEET):
        w = gr.feet[foot.name]
        np.testing.assert_allclose(fw[i], np.concatenate([w.force, w.moment]), atol=1e-9)
        np.testing.assert_allclose(cop[i], w.cop, atol=1e-12, equal_nan=True)
