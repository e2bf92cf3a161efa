"""The StateMap between Pinocchio and MuJoCo (issue 15): both ways, and against each engine's own kinematics and
dynamics (placements, velocities, forward dynamics under the mapped forces)."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.engines.mujoco import MujocoModelError, StateMap, build_model
from humanoid_sim.robot.model import REAL_BODIES, HumanoidModel

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@pytest.fixture(scope="module")
def setup(hm: HumanoidModel):
    mm = build_model(hm)
    return mm.model, mujoco.MjData(mm.model), StateMap.from_models(hm, mm.model)


def _random_state(hm: HumanoidModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    model = hm.model
    q = pin.randomConfiguration(model, -np.pi * np.ones(model.nq), np.pi * np.ones(model.nq))
    q[:3] = rng.normal(size=3) + [0.0, 0.0, 3.0]  # base 3 m up: no ground contact
    return q, rng.normal(size=model.nv)


def test_round_trips(hm: HumanoidModel, setup) -> None:
    _, _, smap = setup
    rng = np.random.default_rng(0)
    for _ in range(20):
        q, v = _random_state(hm, rng)
        tau, ctrl = rng.normal(size=32) * 50, rng.normal(size=26) * 50
        qpos = smap.qpos_from_q(q)
        np.testing.assert_array_equal(smap.q_from_qpos(qpos), q)  # a permutation: exact
        np.testing.assert_array_equal(qpos[3:7], [q[6], q[3], q[4], q[5]])  # (w, x, y, z)
        # 1e-12: one rotation and its transpose (round-off ~1e-15 on values of order 1-100).
        np.testing.assert_allclose(smap.v_from_qvel(qpos, smap.qvel_from_v(q, v)), v, atol=1e-12, rtol=0)
        np.testing.assert_allclose(smap.tau_from_qfrc(q, smap.qfrc_from_tau(q, tau)), tau, atol=1e-12, rtol=0)
        np.testing.assert_array_equal(smap.ctrl_from_tau(smap.tau_from_ctrl(ctrl)), ctrl)
        tau_j = tau.copy()
        tau_j[:6] = 0.0
        np.testing.assert_array_equal(smap.tau_from_ctrl(smap.ctrl_from_tau(tau)), tau_j)
        # Same power in both conventions (1e-9 on |tau.v| ~ 1e3: round-off).
        assert abs(smap.qfrc_from_tau(q, tau) @ smap.qvel_from_v(q, v) - tau @ v) < 1e-9


def test_joints_matched_by_name(hm: HumanoidModel, setup) -> None:
    m, _, smap = setup
    for pq, mq in zip(smap.pin_q, smap.mj_q):
        jid = [j for j in range(2, hm.model.njoints) if hm.model.idx_qs[j] == pq][0]
        assert m.joint(hm.model.names[jid]).qposadr[0] == mq
    for pv, a in zip(smap.pin_u, smap.mj_u):
        jid = [j for j in range(2, hm.model.njoints) if hm.model.idx_vs[j] == pv][0]
        assert m.actuator(int(a)).name == hm.model.names[jid]
    # MuJoCo orders the right leg first, Pinocchio the left: the map is not the identity.
    assert not np.array_equal(smap.pin_q, smap.mj_q)


def test_placements_and_velocities(hm: HumanoidModel, setup) -> None:
    """Body frames, CoMs and CoM velocities from MuJoCo equal Pinocchio's at the mapped state."""
    m, d, smap = setup
    model, data = hm.model, hm.model.createData()
    rng = np.random.default_rng(1)
    res = np.zeros(6)
    for _ in range(5):
        q, v = _random_state(hm, rng)
        d.qpos[:], d.qvel[:] = smap.qpos_from_q(q), smap.qvel_from_v(q, v)
        mujoco.mj_forward(m, d)
        pin.forwardKinematics(model, data, q, v)
        pin.updateFramePlacements(model, data)
        # Base quaternion: MuJoCo's body orientation is q's (w, x, y, z).
        base = m.body("lower_trunk").id
        np.testing.assert_allclose(d.xquat[base], [q[6], q[3], q[4], q[5]], atol=1e-12)
        for b in range(1, m.nbody):
            fid = model.getFrameId(m.body(b).name, pin.FrameType.BODY)
            # 1e-12 m / 1e-12: two forward-kinematics recursions over <= 8 joints, round-off only.
            np.testing.assert_allclose(d.xpos[b], data.oMf[fid].translation, atol=1e-12)
            np.testing.assert_allclose(d.xmat[b].reshape(3, 3), data.oMf[fid].rotation, atol=1e-12)
        for k in REAL_BODIES:
            fid = hm.frame_id(f"Pc_{k}")
            # CoM position: MuJoCo xipos of the body (URDF link) carrying Pc_k.
            link = model.frames[fid]
            while model.frames[link.parentFrame].type != pin.FrameType.JOINT:
                link = model.frames[link.parentFrame]
            body = m.body(link.name).id
            np.testing.assert_allclose(d.xipos[body], data.oMf[fid].translation, atol=1e-12, err_msg=f"Pc_{k}")
            # CoM velocity (angular; linear at the CoM), world frame: mj_objectVelocity returns [w; v].
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, body, res, 0)
            vel = pin.getFrameVelocity(model, data, fid, LWA)
            # 1e-11: velocities up to ~30 m/s from random joint rates; round-off of two recursions.
            np.testing.assert_allclose(res[3:], vel.linear, atol=1e-11, err_msg=f"Pc_{k} linear")
            np.testing.assert_allclose(res[:3], vel.angular, atol=1e-11, err_msg=f"Pc_{k} angular")


def test_forward_dynamics_under_mapped_forces(hm: HumanoidModel, setup) -> None:
    """MuJoCo's qacc under qfrc_applied = map(tau), mapped back, equals Pinocchio's ABA(q, v, tau) (the force, the
    velocity and the acceleration maps together); the motors give the same joint forces as qfrc_applied."""
    m, d, smap = setup
    # M's condition number reaches ~1e7 here (toe 1.3e-4 kg m^2 vs the trunk), so the ~1e-13 differences of
    # the inertias (MuJoCo's 2e-13 mass bound, its principal axes) move accelerations by ~1e-9 relative.  Give
    # Pinocchio MuJoCo's inertias (test_mujoco_model compares them) to compare the maps at round-off.
    model = hm.model.copy()
    for b in range(1, m.nbody):
        jid = model.frames[model.getFrameId(m.body(b).name, pin.FrameType.BODY)].parentJoint
        R = pin.Quaternion(*m.body_iquat[b]).toRotationMatrix()
        model.inertias[jid] = pin.Inertia(float(m.body_mass[b]), m.body_ipos[b].copy(),
                                          R @ np.diag(m.body_inertia[b]) @ R.T)
    data = model.createData()
    rng = np.random.default_rng(2)
    for _ in range(5):
        q, v = _random_state(hm, rng)
        tau = rng.normal(size=model.nv) * 20
        d.qpos[:], d.qvel[:] = smap.qpos_from_q(q), smap.qvel_from_v(q, v)
        d.ctrl[:] = 0.0
        d.qfrc_applied[:] = smap.qfrc_from_tau(q, tau)
        mujoco.mj_forward(m, d)
        a_mj = smap.a_from_qacc(q, v, d.qacc)
        a_pin = pin.aba(model, data, q, v, tau)
        # Two backward-stable factorizations of M (MuJoCo's LDL, Pinocchio's ABA) each solve to a forward error of
        # about cond(M) * eps of the largest acceleration; 10 cond(M) eps bounds their difference (cond up to ~1e7
        # here; measured 2e-14 .. 3.5e-12 relative in one environment, 1.9e-11 in a fresh install whose
        # libraries differ, against a bound of ~1e-9).
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        bound = 10.0 * np.linalg.cond(M) * np.finfo(float).eps
        np.testing.assert_allclose(a_mj, a_pin, atol=bound * np.abs(a_pin).max(), rtol=0)
        # Motors: ctrl_from_tau gives qfrc_actuator = the joint rows of map(tau), exactly (gear 1, a permutation).
        d.qfrc_applied[:] = 0.0
        d.ctrl[:] = smap.ctrl_from_tau(tau)
        mujoco.mj_forward(m, d)
        tau_j = tau.copy()
        tau_j[:6] = 0.0
        np.testing.assert_array_equal(d.qfrc_actuator, smap.qfrc_from_tau(q, tau_j))
    d.ctrl[:] = 0.0


def test_bad_shapes(setup) -> None:
    _, _, smap = setup
    with pytest.raises(MujocoModelError, match=r"q: expected shape \(33,\), got \(32,\)"):
        smap.qpos_from_q(np.zeros(32))
    with pytest.raises(MujocoModelError, match=r"tau: expected shape \(32,\), got \(26,\)"):
        smap.ctrl_from_tau(np.zeros(26))


def test_gathers_are_the_written_out_maps(hm: HumanoidModel, setup) -> None:
    """Each map is one gather (q_gather, v_gather, ctrl_gather): the same numbers as the maps written out from the
    index pairs, to the bit; a map that is not one-to-one is refused."""
    _, _, smap = setup
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, v = _random_state(hm, rng)
        qpos, qvel, tau = smap.qpos_from_q(q), rng.normal(size=32), rng.normal(size=32) * 50
        expect_q = np.empty(33)
        expect_q[:3], expect_q[3:6], expect_q[6] = qpos[:3], qpos[4:7], qpos[3]
        expect_q[smap.pin_q] = qpos[smap.mj_q]
        np.testing.assert_array_equal(smap.q_from_qpos(qpos), expect_q)
        R = pin.Quaternion(qpos[3], qpos[4], qpos[5], qpos[6]).normalized().toRotationMatrix()
        for got, x in ((smap.v_from_qvel(qpos, qvel), qvel), (smap.tau_from_qfrc(expect_q, qvel), qvel)):
            expect = np.empty(32)
            expect[:3], expect[3:6] = R.T @ x[:3], x[3:6]
            expect[smap.pin_v] = x[smap.mj_v]
            np.testing.assert_array_equal(got, expect)
        expect_ctrl = np.empty(26)
        expect_ctrl[smap.mj_u] = tau[smap.pin_u]
        np.testing.assert_array_equal(smap.ctrl_from_tau(tau), expect_ctrl)
    bad = smap.pin_q.copy()
    bad[0] = bad[1]
    with pytest.raises(MujocoModelError, match="the q index maps are not a one-to-one map of 33 entries"):
        StateMap(smap.nq, smap.nv, smap.nu, bad, smap.mj_q, smap.pin_v, smap.mj_v, smap.pin_u, smap.mj_u)
