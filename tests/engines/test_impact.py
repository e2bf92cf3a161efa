"""Touchdown laws (thesis s. 4.5, eqs. 4.95-4.100; errata K-11) and the inelastic impact."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg as sla

from humanoid_sim.dynamics.contact import ContactSet, SingularConstraintError
from humanoid_sim.dynamics.contact.oracle import kkt_impulse
from humanoid_sim.engines.impact import (
    ImpactError,
    constraint_jacobian,
    inelastic_impact,
    least_change_reset,
    thesis_adjustable_joints,
    touchdown,
)
from humanoid_sim.robot.model import THETA_NAMES, HumanoidModel
from humanoid_sim.robot.phases import FOOT_SPECS, TOE_POINT_FRAME, Phase, foot_held_flat

SSPS = [Phase.LFFSSP, Phase.RFFSSP]
# Wadj of Appendix B sets 1 and 3 (L4912-4918, L5213-5219; identical for both transitions, errata A-8).
W_ADJ = np.array([1, 1, 1, 3, 1.8, 1.8, 1.8, 1, 1, 1, 3, 1.8, 1.8, 1.8], dtype=float)
UPPER_BODY = THETA_NAMES[THETA_NAMES.index("theta18"):]  # theta18..theta27: waist, arms, neck


def _ssp_state(hm: HumanoidModel, rng: np.random.Generator, ssp: Phase):
    """Random posture; velocity that keeps the stance foot flat (the thesis's SSP state), landing foot moving."""
    model = hm.model
    q = pin.integrate(model, hm.initial_q(), 0.3 * rng.standard_normal(model.nv))
    N = sla.null_space(constraint_jacobian(model, model.createData(), q, ssp.contacts))
    return q, N @ rng.standard_normal(N.shape[1])


def _twist(hm: HumanoidModel, q, v, frame: str, rf=pin.LOCAL) -> np.ndarray:
    data = hm.model.createData()
    pin.forwardKinematics(hm.model, data, q, v)
    return pin.getFrameVelocity(hm.model, data, hm.frame_id(frame), rf).vector


def _v_idx(hm: HumanoidModel, names) -> np.ndarray:
    return np.array([hm.model.idx_vs[hm.model.getJointId(n)] for n in names], dtype=int)


def test_wadj_order_follows_errata_k11() -> None:
    assert thesis_adjustable_joints(Phase.RFFSSP) == (
        "theta5", "theta7", "theta9", "theta11", "theta13", "theta15", "theta17r",
        "theta6", "theta8", "theta10", "theta12", "theta14", "theta16", "theta17l")
    lf = thesis_adjustable_joints(Phase.LFFSSP)
    assert lf[:7] == thesis_adjustable_joints(Phase.RFFSSP)[7:] and lf[7:] == thesis_adjustable_joints(
        Phase.RFFSSP)[:7]
    with pytest.raises(ImpactError, match="LFFDSP"):
        thesis_adjustable_joints(Phase.LFFDSP)


@pytest.mark.parametrize("ssp", SSPS, ids=lambda p: p.value)
def test_thesis_reset(hm: HumanoidModel, ssp: Phase) -> None:
    rng = np.random.default_rng(10 + SSPS.index(ssp))
    model = hm.model
    stance, landing = FOOT_SPECS[ssp.support_foot], FOOT_SPECS[ssp.landing_foot]
    adjustable = thesis_adjustable_joints(ssp)
    for _ in range(3):
        q, v = _ssp_state(hm, rng, ssp)
        assert np.linalg.norm(_twist(hm, q, v, landing.main_frame)) > 0.1  # the foot lands with a velocity
        res = touchdown(model, q, v, ssp, "thesis", W_ADJ)
        vp = res.v_plus
        # Landing foot at rest (eq. 4.95/4.98): toe point velocity, w_2 (w_1), and the toe rate; 1e-10 is
        # round-off on O(1) velocities.
        for frame in (landing.main_frame, landing.toe_frame, TOE_POINT_FRAME[ssp.landing_foot]):
            assert np.max(np.abs(_twist(hm, q, vp, frame))) < 1e-10
        assert vp[_v_idx(hm, [landing.toe_joint])][0] == 0.0
        # The stance foot stays at rest.
        for frame in (stance.main_frame, stance.toe_frame):
            assert np.max(np.abs(_twist(hm, q, vp, frame))) < 1e-10
        assert res.constraint_residual < 1e-10
        # Upper-body joint velocities are unchanged (bit for bit); only base, 14 leg joints and the landing
        # toe change.
        assert np.array_equal(vp[_v_idx(hm, UPPER_BODY)], v[_v_idx(hm, UPPER_BODY)])
        changed = set(np.flatnonzero(vp != v))
        assert changed <= set(range(6)) | set(_v_idx(hm, adjustable)) | set(_v_idx(hm, [landing.toe_joint]))

        # Literal transcription of eq. 4.97 / 4.100 with the thesis's reduced Jacobian J_v,tp_r (6 x 14):
        # [V_tp; w] of the landing toe body (world) per unit rate of each adjustable joint, with the base
        # motion that keeps the stance foot welded (the thesis's kinematics start at the stance foot) and the
        # landing toe rate dropped.
        data = model.createData()
        pin.computeJointJacobians(model, data, q)
        Js = pin.getFrameJacobian(model, data, hm.frame_id(stance.main_frame), pin.LOCAL)
        Jtp = pin.getFrameJacobian(model, data, hm.frame_id(TOE_POINT_FRAME[ssp.landing_foot]),
                                   pin.LOCAL_WORLD_ALIGNED)
        idx = _v_idx(hm, adjustable)
        E = np.zeros((model.nv, idx.size))
        E[idx, np.arange(idx.size)] = 1.0
        E[:6] = -np.linalg.solve(Js[:, :6], Js @ E)   # base rates implied by the stance weld
        Jr = Jtp @ E
        Winv = np.diag(1.0 / W_ADJ)
        qd_end = v[idx]
        qd_ini = qd_end + Winv @ Jr.T @ np.linalg.solve(Jr @ Winv @ Jr.T, np.zeros(6) - Jr @ qd_end)
        # 1e-10: two different linear solves of a well-conditioned 14-unknown problem on O(1) rates.
        np.testing.assert_allclose(vp[idx], qd_ini, atol=1e-10)
        np.testing.assert_allclose(vp[:6], E[:6] @ qd_ini, atol=1e-10)


def test_thesis_reset_weights_and_fixed_point(hm: HumanoidModel) -> None:
    rng = np.random.default_rng(20)
    model = hm.model
    ssp = Phase.RFFSSP
    q, v = _ssp_state(hm, rng, ssp)
    idx = _v_idx(hm, thesis_adjustable_joints(ssp))
    base = touchdown(model, q, v, ssp, "thesis", W_ADJ)
    w = W_ADJ.copy()
    w[3] *= 1e4  # make the stance knee (theta11) expensive to change
    heavy = touchdown(model, q, v, ssp, "thesis", w)
    assert abs(heavy.delta_v[idx[3]]) < 1e-2 * abs(base.delta_v[idx[3]])
    # A velocity that already satisfies the touchdown constraints is left alone (1e-12: round-off).
    again = touchdown(model, q, base.v_plus, ssp, "thesis", W_ADJ)
    assert np.max(np.abs(again.delta_v)) < 1e-12


def _toe_push_z(hm: HumanoidModel, q, contacts: ContactSet, impulse: np.ndarray, frame: str) -> float:
    """World-z component of the impulse (N s) the weld on ``frame`` takes (its LOCAL force rotated to world)."""
    data = hm.model.createData()
    pin.framesForwardKinematics(hm.model, data, q)
    i = contacts.welds.index(frame)
    return float((data.oMf[hm.frame_id(frame)].rotation @ impulse[6 * i:6 * i + 3])[2])


@pytest.mark.parametrize("ssp", SSPS, ids=lambda p: p.value)
def test_inelastic_impact(hm: HumanoidModel, ssp: Phase) -> None:
    """The touchdown's inelastic impact against an independent KKT solve (contact.oracle.kkt_impulse): with the
    next DSP's contacts when the trailing toe pushes; when it would pull, the toe separates and the impact is the
    one on the landing foot alone (a unilateral contact pushes or leaves).  Both branches occur among the states."""
    rng = np.random.default_rng(30 + SSPS.index(ssp))
    model, data = hm.model, hm.model.createData()
    dsp = ssp.next
    toe = FOOT_SPECS[ssp.support_foot].toe_frame
    landing = FOOT_SPECS[ssp.landing_foot]
    branches = set()
    for _ in range(16):
        q, v = _ssp_state(hm, rng, ssp)
        res = touchdown(model, q, v, ssp, "inelastic")
        v_o, imp_o = kkt_impulse(model, dsp.contacts, q, v)
        pushes = _toe_push_z(hm, q, dsp.contacts, imp_o, toe) >= 0.0
        branches.add(pushes)
        if pushes:
            assert res.contacts == dsp.contacts
        else:
            assert res.contacts.welds == (landing.main_frame,) and res.contacts.locks == dsp.contacts.locks
            v_o, imp_o = kkt_impulse(model, res.contacts, q, v)
        # 1e-10 relative: two solves of the same (nv + m) KKT system.
        scale = max(1.0, np.max(np.abs(imp_o)))
        assert np.max(np.abs(res.v_plus - v_o)) < 1e-10 and np.max(np.abs(res.impulse - imp_o)) < 1e-10 * scale
        for frame in (landing.main_frame, landing.toe_frame) + ((toe,) if pushes else ()):
            assert np.max(np.abs(_twist(hm, q, res.v_plus, frame))) < 1e-10
        # Never gains energy; the loss is Carnot's: T- - T+ = 1/2 dv^T M dv for a perfectly inelastic impact.
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        dv = res.delta_v
        assert res.energy_change <= 0.0
        assert -res.energy_change == pytest.approx(0.5 * dv @ M @ dv, rel=1e-9)
    assert branches == {True, False}


def test_inelastic_with_caller_contacts_and_errors(hm: HumanoidModel) -> None:
    rng = np.random.default_rng(40)
    model = hm.model
    q, v = _ssp_state(hm, rng, Phase.RFFSSP)
    both_flat = foot_held_flat("R").union(foot_held_flat("L"))
    res = inelastic_impact(model, q, v, both_flat)
    assert res.constraint_residual < 1e-10 and res.energy_change <= 0.0
    with pytest.raises(ImpactError, match="bogus"):
        touchdown(model, q, v, Phase.RFFSSP, "bogus")
    with pytest.raises(ImpactError, match="W_adj"):
        touchdown(model, q, v, Phase.RFFSSP, "thesis")
    with pytest.raises(ImpactError, match="RFFDSP"):
        touchdown(model, q, v, Phase.RFFDSP, "inelastic")
    with pytest.raises(ImpactError, match=r"\(14,\)"):
        touchdown(model, q, v, Phase.RFFSSP, "thesis", np.ones(13))
    with pytest.raises(ImpactError, match="both adjustable and locked"):
        least_change_reset(model, q, v, both_flat, ("theta3",), np.ones(1))
    dependent = ContactSet(("O_3", "O_1"), ("theta3",), name="dependent")
    with pytest.raises(SingularConstraintError, match="dependent"):
        inelastic_impact(model, q, v, dependent)
