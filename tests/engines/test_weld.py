"""The weld engine (humanoid_sim.engines.weld) against Pinocchio directly: the support-foot projection, the
constrained motion (a KKT system solved here with NumPy), one integration step, and the yaw helpers."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.dynamics.contact import record_anchors
from humanoid_sim.engines.weld import WeldEngine, unwrap_to, yaw_of
from humanoid_sim.interfaces.controller import Command
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.references.zmp.zmp_walk import initial_state
from humanoid_sim.robot.phases import Phase

LOCAL = pin.ReferenceFrame.LOCAL
PHASE = Phase.LFFSSP              # left foot flat: body 4 (O_4) welded, toe joint theta4 locked
NO_CHECKS = SimpleNamespace(check_stage=lambda *a: None, check_acceleration=lambda *a: None, plan_delay=0.0)


def rz(a: float) -> np.ndarray:
    return pin.utils.rotate("z", a)


def test_yaw_is_the_heading_of_the_body_x_axis() -> None:
    for a in (0.0, 0.3, -2.0, np.pi - 1e-9):
        assert yaw_of(rz(a)) == pytest.approx(a, abs=1e-12)
        assert yaw_of(rz(a) @ pin.utils.rotate("x", 0.4)) == pytest.approx(a, abs=1e-12)  # a roll keeps the heading


def test_unwrap_to_lands_within_pi_of_the_reference() -> None:
    assert unwrap_to(1.5 * np.pi, 0.0) == pytest.approx(-0.5 * np.pi)
    assert unwrap_to(0.1, 4 * np.pi) == pytest.approx(4 * np.pi + 0.1)
    assert unwrap_to(-3.0, 3.0) == pytest.approx(2 * np.pi - 3.0)


@pytest.fixture(scope="module")
def setup(hm, sim1):
    sc = sim1
    traj = ReferenceTrajectory(sc.path)
    eng = WeldEngine(hm, sc, traj, compiled=False)
    q0 = initial_state(hm, sc)
    return eng, q0, record_anchors(hm.model, q0, PHASE.contacts)


def _disturbed(hm, q0, seed=0):
    rng = np.random.default_rng(seed)
    q = q0.copy()
    q[:3] += rng.normal(0, 0.02, 3)                     # base moved off the weld
    q[7:] += rng.normal(0, 0.05, hm.model.nq - 7)       # every joint moved
    return q, rng.normal(0, 0.5, hm.model.nv)


def _foot_state(model, q, v, a=None):
    d = model.createData()
    fid = model.getFrameId("O_4")
    pin.forwardKinematics(model, d, q, v, np.zeros(model.nv) if a is None else a)
    oMf = pin.updateFramePlacement(model, d, fid)
    return oMf, pin.getFrameVelocity(model, d, fid, LOCAL), pin.getFrameAcceleration(model, d, fid, LOCAL)


def test_projection_puts_the_support_foot_back_at_rest_on_its_anchor(hm, setup) -> None:
    eng, q0, anchors = setup
    model = hm.model
    q, v = _disturbed(hm, q0)
    qp, vp = eng.project_on_support(PHASE, anchors, q, v)
    oMf, vel, _ = _foot_state(model, qp, vp)
    assert oMf.isApprox(anchors.placements["O_4"], 1e-12)
    np.testing.assert_allclose(vel.vector, 0.0, atol=1e-12)           # Pinocchio's own foot twist
    jid = model.getJointId("theta4")
    assert qp[model.idx_qs[jid]] == anchors.joint_positions["theta4"] and vp[model.idx_vs[jid]] == 0.0
    others = np.ones(model.nq, bool)
    others[:7] = False
    others[model.idx_qs[jid]] = False
    np.testing.assert_array_equal(qp[others], q[others])              # only the base and the locked toe move
    assert np.linalg.norm(qp[3:7]) == pytest.approx(1.0, abs=1e-12)  # a unit quaternion


def _kkt(model, q, v, tau, J):
    """Constrained accelerations from M, h (Pinocchio crba / rnea) and J a = -Jdot v, solved here with NumPy."""
    d = model.createData()
    M = pin.crba(model, d, q)
    M = np.triu(M) + np.triu(M, 1).T
    h = pin.rnea(model, d, q, v, np.zeros(model.nv))
    pin.forwardKinematics(model, d, q, v, np.zeros(model.nv))
    fid = model.getFrameId("O_4")
    jdotv = np.concatenate([pin.getFrameAcceleration(model, d, fid, LOCAL).vector, [0.0]])
    nc = J.shape[0]
    K = np.block([[M, J.T], [J, np.zeros((nc, nc))]])
    return np.linalg.solve(K, np.concatenate([tau - h, -jdotv]))[:model.nv]


def _jacobian(model, q):
    d = model.createData()
    J6 = pin.computeFrameJacobian(model, d, q, model.getFrameId("O_4"), LOCAL)
    lock = np.zeros((1, model.nv))
    lock[0, model.idx_vs[model.getJointId("theta4")]] = 1.0
    return np.vstack([J6, lock])


def test_motion_is_the_constrained_dynamics(hm, setup) -> None:
    eng, q0, anchors = setup
    model = hm.model
    q, v = eng.project_on_support(PHASE, anchors, *_disturbed(hm, q0, seed=1))
    anchors_here = record_anchors(model, q, PHASE.contacts)   # no drift: the Baumgarte terms vanish
    tau = np.concatenate([np.zeros(6), np.random.default_rng(2).normal(0, 20, model.nv - 6)])
    a, lam = eng._motion(PHASE, anchors_here, q, v, Command(tau=tau.copy()))
    np.testing.assert_allclose(a, _kkt(model, q, v, tau, _jacobian(model, q)), atol=1e-8)
    _, _, acc = _foot_state(model, q, v, a)
    np.testing.assert_allclose(acc.vector, 0.0, atol=1e-9)             # the welded foot does not accelerate
    # Newton-Euler: M a + h - tau is a pure constraint force, in the range of J^T
    r = pin.rnea(model, model.createData(), q, v, a) - tau
    J = _jacobian(model, q)
    x = np.linalg.lstsq(J.T, r, rcond=None)[0]
    np.testing.assert_allclose(J.T @ x, r, atol=1e-8)


def test_one_step_keeps_the_weld_and_logs_the_stage_zero_state(hm, setup) -> None:
    eng, q0, _ = setup
    model = hm.model
    tau = np.concatenate([np.zeros(6), np.random.default_rng(3).normal(0, 5, model.nv - 6)])
    eng.start(q0, PHASE)
    calls = []
    control = lambda obs: calls.append(obs.stage) or Command(tau=tau.copy())  # noqa: E731
    rec = eng.step(0.0, 1e-3, 0, control, NO_CHECKS)
    assert calls == [0, 1, 2]                                          # ode3: three stages, one call each
    q1, v1 = eng.state_vectors()
    oMf, vel, _ = _foot_state(model, q1, v1)
    assert oMf.isApprox(record_anchors(model, q0, PHASE.contacts).placements["O_4"], 1e-12)
    np.testing.assert_allclose(vel.vector, 0.0, atol=1e-12)
    q_log, v_log, a_log = rec.q, rec.v, rec.stage.a
    np.testing.assert_array_equal(q_log, q0)
    np.testing.assert_array_equal(v_log, 0.0)
    np.testing.assert_allclose(a_log, _kkt(model, q0, np.zeros(model.nv), tau, _jacobian(model, q0)), atol=1e-8)
    # from rest, v(h) = h a(0) + O(h^2): within a few percent of the stage-0 acceleration for h = 1 ms
    dv = (v1 - v_log) / 1e-3
    assert np.linalg.norm(dv - a_log) < 0.05 * np.linalg.norm(a_log)
    np.testing.assert_array_equal(rec.stage.tau, tau)
    d = model.createData()
    pin.framesForwardKinematics(model, d, q0)
    hip_p = rec.stage.hip_p
    np.testing.assert_allclose(hip_p, d.oMf[model.getFrameId("Pc_17")].translation, atol=1e-14)


def test_enter_keeps_held_anchors_and_adds_new_ones(hm, setup) -> None:
    eng, q0, _ = setup
    eng.start(q0, PHASE)
    held = eng.anchors.placements["O_4"].copy()
    eng.q = eng.q.copy()
    eng.q[2] += 0.001                                   # the state moved: a held foot keeps its anchor
    eng.enter(PHASE.next)                               # RFFDSP: right flat (O_3, theta3), left toe (O_2)
    assert set(eng.anchors.placements) == {"O_3", "O_2"} and set(eng.anchors.joint_positions) == {"theta3"}
    d = hm.model.createData()
    pin.framesForwardKinematics(hm.model, d, eng.q)
    assert eng.anchors.placements["O_3"].isApprox(d.oMf[hm.model.getFrameId("O_3")], 1e-14)
    assert held.isApprox(record_anchors(hm.model, q0, PHASE.contacts).placements["O_4"])
    assert eng.phase is Phase.RFFDSP


@pytest.mark.parametrize("compiled", [False, None])
def test_a_control_period_calls_the_controller_once_per_period_and_holds_its_torque(hm, sim1, compiled) -> None:
    """With ``control_period_s`` = 1 ms, a 10 ms step calls the controller 10 times, at the period's starts (stage
    = the update's index), and every ode3 stage within a period integrates the torque of that period's call."""
    eng = WeldEngine(hm, sim1, ReferenceTrajectory(sim1.path), compiled=compiled)
    eng.control_period_s = 0.001
    q0 = initial_state(hm, sim1)
    eng.start(q0, PHASE)
    calls, applied = [], []
    forward = eng.dyn.forward_prepared

    def spy(rows, tau):
        applied.append(tau.copy())
        return forward(rows, tau)

    eng.dyn.forward_prepared = spy
    rng = np.random.default_rng(1)

    def control(obs):
        calls.append((obs.t, obs.stage))
        return Command(tau=np.r_[np.zeros(6), rng.normal(0.0, 1.0, 26)])

    for n in range(2):
        rec = eng.step(0.01 * n, 0.01, 0, control, NO_CHECKS)
        assert rec.q is not None
    assert len(calls) == 20
    np.testing.assert_allclose([t for t, _ in calls], 0.001 * np.arange(20), atol=1e-15)
    assert [s for _, s in calls] == list(range(10)) * 2
    stages = len(eng.rk.tab.c)
    assert len(applied) == 20 * stages
    for i in range(20):   # the torque is held over the period: every stage of period i applies call i's torque
        for j in range(1, stages):
            np.testing.assert_array_equal(applied[i * stages + j], applied[i * stages])
        if i:
            assert not np.array_equal(applied[i * stages], applied[(i - 1) * stages])
    with pytest.raises(Exception, match="whole number of control periods"):
        eng.step(0.02, 0.0015, 0, control, NO_CHECKS)
