"""humanoid_sim.dynamics.joint_loads: the wrench each joint transmits, checked four independent ways.

- against the thesis oracle's inter-body forces F (eq. 4.68) at the same states of the thesis gait;
- against MuJoCo's ``cfrc_int`` (mj_rnePostConstraint) on a MuJoCo walk, from MuJoCo's own qacc and contact forces;
- against each subtree's Newton-Euler balance summed body by body (pin.centerOfMass and the body inertias);
- its torsion about each joint's axis against the applied joint torque on the weld engine's walks.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.api import run_walk
from humanoid_sim.dynamics.joint_loads import (
    THESIS_FOOT_FRAMES,
    JointLoadsInputError,
    bearing_loads,
    fext_from_body_wrenches,
    joint_loads,
)
from humanoid_sim.paths import scenario_path
from humanoid_sim.robot.model import THETA_NAMES
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario import load_scenario
from humanoid_sim.sim.simulate import Simulator
from humanoid_sim.thesis import FootState
from humanoid_sim.thesis.engine import ThesisEngine
from humanoid_sim.thesis.forces import block
from humanoid_sim.thesis.frames import JOINT_GROUPS, JOINTS
from humanoid_sim.thesis.kinematics import origins

LOCAL = pin.ReferenceFrame.LOCAL
BASIC_PHASES = (Phase.LFFSSP, Phase.RFFDSP, Phase.RFFSSP, Phase.LFFDSP)   # the log's basic_phase order
TOE_FRAME = {"R": "O_1", "L": "O_2"}
_LOGS: dict[str, dict[str, np.ndarray]] = {}


def weld_log(name: str) -> dict[str, np.ndarray]:
    """The weld engine's log of ``name`` over its first 2 s (all four basic phases), run once per session."""
    if name not in _LOGS:
        _LOGS[name] = run_walk(name, until=2.0, verbose=False).result.log.arrays()
    return _LOGS[name]


def world(model: pin.Model, data: pin.Data, jid: int, w: np.ndarray) -> np.ndarray:
    """A joint-local wrench (about the joint origin) as [force; moment about the world origin], world frame
    (needs data.oMi of the state)."""
    return data.oMi[jid].act(pin.Force(w)).vector


# ---------------------------------------------------------------------------------------------------- unit checks
def test_foot_frames_are_the_logged_rows():
    from humanoid_sim.engines.weld import BODY_FRAMES

    assert THESIS_FOOT_FRAMES == BODY_FRAMES


def test_default_joints_are_the_thesis_joints(hm):
    m = hm.model
    q, v = pin.neutral(m)[None], np.zeros((1, m.nv))
    loads = joint_loads(m, q, v, v)
    assert sorted(loads.names) == sorted(THETA_NAMES) and loads.wrench.shape == (1, 26, 6)
    # at rest the root carries the robot's weight: the residual is m g (N), not zero
    weight = sum(i.mass for i in m.inertias) * np.linalg.norm(m.gravity.linear)
    assert abs(loads.residual[0] - weight) < 1e-9 * weight   # round-off of a sum of 13 weights
    ordered = joint_loads(m, q, v, v, joints=THETA_NAMES)
    assert ordered.names == THETA_NAMES
    assert np.array_equal(ordered.wrench[0], loads.wrench[0][[loads.names.index(n) for n in THETA_NAMES]])


def test_bearing_loads_split():
    w = np.array([[3.0, 4.0, 12.0, 1.0, 2.0, -5.0]])   # f, n; axis z
    b = bearing_loads(w, np.array([[0.0, 0.0, 2.0]]))  # not unit: normalised
    assert (b.axial[0], b.shear[0], b.torsion[0], b.bending[0]) == pytest.approx((12.0, 5.0, -5.0, np.sqrt(5.0)))
    rng = np.random.default_rng(1)
    w, u = rng.normal(size=(7, 4, 6)), rng.normal(size=(4, 3))
    b = bearing_loads(w, u)
    # Pythagoras along / across the axis; 1e-12: round-off on numbers of order 1
    assert np.allclose(b.axial**2 + b.shear**2, (w[..., :3] ** 2).sum(-1), atol=1e-12)
    assert np.allclose(b.torsion**2 + b.bending**2, (w[..., 3:] ** 2).sum(-1), atol=1e-12)


def test_bad_inputs_name_the_shapes(hm):
    m = hm.model
    q = pin.neutral(m)[None]
    with pytest.raises(JointLoadsInputError, match=r"\(1, 32\)"):
        joint_loads(m, q, np.zeros((1, 31)), np.zeros((1, 32)))
    with pytest.raises(JointLoadsInputError, match="fext"):
        joint_loads(m, q, np.zeros((1, 32)), np.zeros((1, 32)), fext=np.zeros((1, 4, 6)))
    with pytest.raises(JointLoadsInputError, match="theta99"):
        joint_loads(m, q, np.zeros((1, 32)), np.zeros((1, 32)), joints=["theta3", "theta99"])
    with pytest.raises(JointLoadsInputError, match="O_99"):
        fext_from_body_wrenches(m, np.zeros((1, 1, 3)), np.zeros((1, 1, 3)), frames=["O_99"])
    with pytest.raises(JointLoadsInputError, match=r"\(2, 3\)"):
        fext_from_body_wrenches(m, np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(JointLoadsInputError, match="norms"):
        bearing_loads(np.zeros((1, 6)), np.zeros(3))


# ---------------------------------------------------------------------------------------------------- subtree balance
def test_each_subtree_balances_its_newton_euler_wrench(hm):
    """W_j = sum over the subtree of (momentum rate - gravity - external wrench), summed body by body with the
    body inertias and pin.centerOfMass, at random states and random ground wrenches (thesis convention)."""
    m = hm.model
    d = m.createData()
    rng = np.random.default_rng(7)
    n = 5
    Q = np.array([pin.randomConfiguration(m, -np.ones(m.nq), np.ones(m.nq)) for _ in range(n)])
    V, A = rng.normal(size=(n, m.nv)), rng.normal(size=(n, m.nv))
    BF, BM = 100.0 * rng.normal(size=(n, 4, 3)), 10.0 * rng.normal(size=(n, 4, 3))
    loads = joint_loads(m, Q, V, A, fext_from_body_wrenches(m, BF, BM), joints=THETA_NAMES)
    g = m.gravity.linear
    foot = [(m.frames[hm.frame_id(f)].parentJoint, hm.frame_id(f)) for f in THESIS_FOOT_FRAMES]
    worst = 0.0
    for i in range(n):
        pin.forwardKinematics(m, d, Q[i], V[i], A[i])
        pin.updateFramePlacements(m, d)
        pin.centerOfMass(m, d, Q[i], V[i], A[i])   # subtree masses and CoM accelerations (joint frame for j > 0)
        body = np.zeros((m.njoints, 6))            # per body: [m (a_c - g); c x m (a_c - g) + dL_c/dt], world
        for b in range(1, m.njoints):
            I, M = m.inertias[b], d.oMi[b]
            if I.mass == 0.0:
                continue
            R, c = M.rotation, I.lever
            v, w = d.v[b].linear, d.v[b].angular
            a_c = R @ (d.a[b].linear + np.cross(w, v) + np.cross(d.a[b].angular, c) + np.cross(w, np.cross(w, c)))
            Iw, ww, alw = R @ I.inertia @ R.T, R @ w, R @ d.a[b].angular
            f = I.mass * (a_c - g)
            body[b] = np.r_[f, np.cross(M.act(c), f) + Iw @ alw + np.cross(ww, Iw @ ww)]
        for k, (jid, fid) in enumerate(foot):      # ground wrench: F_0,k in frame k, M_0,k about CoM k
            R = d.oMf[fid].rotation
            f = R @ BF[i, k]
            body[jid] -= np.r_[f, R @ BM[i, k] + np.cross(d.oMi[jid].act(m.inertias[jid].lever), f)]
        for k, name in enumerate(THETA_NAMES):
            jid = m.getJointId(name)
            sub = list(m.subtrees[jid])
            expect = body[sub].sum(axis=0)
            ext = sum((d.oMf[fid].rotation @ BF[i, r] for r, (j, fid) in enumerate(foot) if j in sub), np.zeros(3))
            # Newton with Pinocchio's subtree CoM (the same force summed another way); 1e-9 N: round-off on 1e2 N
            assert np.allclose(expect[:3], d.mass[jid] * (d.oMi[jid].rotation @ d.acom[jid] - g) - ext, atol=1e-9)
            worst = max(worst, np.abs(world(m, d, jid, loads.wrench[i, k]) - expect).max())
        # the root joint's wrench: the whole robot's balance (the residual of inconsistent inputs)
        worst = max(worst, np.abs(world(m, d, 1, loads.root_wrench[i]) - body.sum(axis=0)).max())
    # measured 1.4e-13: forces and moments of order 1e2 N, N m summed over <= 13 bodies; 1e-9 is round-off's bound
    assert worst < 1e-9, worst


# ---------------------------------------------------------------------------------------------------- thesis oracle
def _pin_state(hm, phase: Phase, fixed: dict, theta, theta_dot, theta_ddot):
    """Pinocchio (q, v, a) of a thesis state: the support foot's toe body (the chain root) at its placement, at
    rest and not accelerating."""
    m, d = hm.model, hm.model.createData()
    root = phase.support_foot
    q = hm.q_on_foot(theta, root, fixed[root].P_tp, fixed[root].C)
    fid = hm.frame_id(TOE_FRAME[root])
    J = pin.computeFrameJacobian(m, d, q, fid, LOCAL)
    v, a = hm.v_from_theta_dot(theta_dot), hm.v_from_theta_dot(theta_ddot)
    v[:6] = -np.linalg.solve(J[:, :6], J @ v)
    pin.forwardKinematics(m, d, q, v, a)
    a[:6] = -np.linalg.solve(J[:, :6], pin.getFrameAcceleration(m, d, fid, LOCAL).vector)
    return q, v, a


def _closed_chain_rates(hm, phase: Phase, fixed: dict, theta, theta_dot):
    """theta_dot with the trailing toe at rest (DSP): the weld engine holds it by Baumgarte only (drift ~1e-6
    rad/s), the thesis assumes it exactly; SSP: unchanged."""
    if not phase.is_double_support:
        return theta_dot
    m, d = hm.model, hm.model.createData()
    root = phase.support_foot
    q = hm.q_on_foot(theta, root, fixed[root].P_tp, fixed[root].C)
    Jr = pin.computeFrameJacobian(m, d, q, hm.frame_id(TOE_FRAME[root]), LOCAL)
    Jt = pin.computeFrameJacobian(m, d, q, hm.frame_id(TOE_FRAME[phase.trailing_toe]), LOCAL)
    E = np.array([hm.v_from_theta_dot(e) for e in np.eye(26)]).T
    E[:6] = -np.linalg.solve(Jr[:, :6], Jr @ E)
    P = Jt @ E
    return theta_dot - np.linalg.pinv(P) @ (P @ theta_dot)


def test_matches_the_thesis_oracle_inter_body_forces(hm):
    """At weld-engine states of Simulation 1 (every basic phase), the oracle's 122 x 122 solution F gives the
    inter-body wrenches F_{a,b} / M_{a,b} (body a on body b, frame b, moment about the joint point); joint_loads
    with the oracle's own theta_ddot and ground wrenches F_0,k / M_0,k gives the same wrench at every joint of the
    pair (virtual bodies are massless and share the joint point), with the sign of the tree's direction."""
    log = weld_log("sim1")
    m, d = hm.model, hm.model.createData()
    eng = ThesisEngine(hm.spec)
    group = {n: g for g, names in JOINT_GROUPS.items() for n in names}
    rows = []
    for p in range(4):
        idx = np.flatnonzero(log["basic_phase"] == p)
        rows += sorted({int(idx[0]), int(idx[len(idx) // 2]), int(idx[-1])})
    worst = 0.0
    for r in rows:
        phase = BASIC_PHASES[int(log["basic_phase"][r])]
        fixed = {f: FootState(log[f"foot_{f}_R"][r], log[f"toe_{f}_p"][r]) for f in phase.stance_feet}
        theta = log["theta"][r]
        thd = _closed_chain_rates(hm, phase, fixed, theta, log["theta_dot"][r])
        fd = eng.forward_dynamics(phase.value, theta, thd, log["T"][r], fixed)
        q, v, a = _pin_state(hm, phase, fixed, theta, thd, fd.theta_ddot)
        BF = np.array([[fd.ground[k][0] for k in (1, 2, 3, 4)]])
        BM = np.array([[fd.ground[k][1] for k in (1, 2, 3, 4)]])
        loads = joint_loads(m, q[None], v[None], a[None], fext_from_body_wrenches(m, BF, BM), joints=THETA_NAMES)
        kin = eng.kinematics(phase.value, theta, thd, fixed, theta_ddot=fd.theta_ddot)
        O = origins(kin, eng.params)
        pin.forwardKinematics(m, d, q)
        for k, name in enumerate(THETA_NAMES):
            a_, b_ = group[name]
            point = O[JOINTS[JOINT_GROUPS[(a_, b_)][-1]][0]]   # the joint point: origin of the pair's last joint
            f = kin.C[b_] @ block(fd.F, f"F{a_}_{b_}")
            thesis = np.r_[f, kin.C[b_] @ block(fd.F, f"M{a_}_{b_}") + np.cross(point, f)]
            jid = m.getJointId(name)
            on_b = m.frames[hm.frame_id(f"O_{b_}")].parentJoint in m.subtrees[jid]   # child side holds body b
            diff = world(m, d, jid, loads.wrench[0, k]) - (thesis if on_b else -thesis)
            worst = max(worst, np.abs(diff).max())
    # measured 3.6e-12 N / N m (world frame, moments about the origin): one model through two formulations (a
    # 122 x 122 solve and Pinocchio's RNEA) at one state; 1e-8 leaves a 1000x margin over that round-off
    assert worst <= 1e-8, worst


# ---------------------------------------------------------------------------------------------------- torsion
@pytest.mark.parametrize("name", ["sim1", "sim3", pytest.param("sim1_zmp", marks=pytest.mark.slow),
                                  pytest.param("sim3_zmp", marks=pytest.mark.slow)])
def test_torsion_is_the_applied_joint_torque(hm, name):
    """With the logged ground wrenches, the moment about each joint's axis is the applied generalized torque,
    toe joints included (on the zmp gait the locked support toe is driven, up to ~22 N m, and the ground under
    the toe box takes it); without them it is not."""
    log = weld_log(name)
    m = hm.model
    fext = fext_from_body_wrenches(m, log["body_force"], log["body_moment"])
    loads = joint_loads(m, log["q"], log["v"], log["a"], fext, joints=THETA_NAMES)
    tau = log["tau"][:, hm.theta_v_idx]
    miss = np.abs(loads.bearing().torsion - tau)
    # measured <= 2e-11 N m (sim1) and 1e-13 N m (the others): the KKT solve's residual (the logged
    # dynamics_residual, the same size); 1e-6 N m leaves room for other controllers' solves
    assert miss.max() <= 1e-6, {THETA_NAMES[k]: float(miss[:, k].max()) for k in np.argsort(-miss.max(0))[:3]}
    # the free robot balances its ground wrenches: the same KKT residual (measured <= 5e-11 N, N m)
    assert loads.residual.max() <= 1e-6
    bare = joint_loads(m, log["q"], log["v"], log["a"], None, joints=THETA_NAMES)
    assert np.abs(bare.bearing().torsion - tau).max() > 10.0   # N m: the ground wrenches matter
    if name.endswith("_zmp"):
        locked = np.where(np.isin(log["basic_phase"], (1, 2)), tau[:, 0], tau[:, 1])   # support toe, N m
        assert np.abs(locked).max() > 1.0   # the check covers a driven locked toe


# ---------------------------------------------------------------------------------------------------- MuJoCo
def _mujoco_fext(hm, mj: mujoco.MjModel, md: mujoco.MjData, d: pin.Data, body_joint: list[int]) -> np.ndarray:
    """Every contact force (mj_contactForce, contact frame) as Pinocchio fext: on geom2's body, its negative on
    geom1's, applied at the contact point; local frame of the body's joint, about the joint origin."""
    fext = np.zeros((hm.model.njoints, 6))
    f6 = np.zeros(6)
    for i in range(md.ncon):
        c = md.contact[i]
        mujoco.mj_contactForce(mj, md, i, f6)
        frame = c.frame.reshape(3, 3)        # rows: normal, tangents (world)
        f, t = frame.T @ f6[:3], frame.T @ f6[3:]
        for geom, s in ((c.geom2, 1.0), (c.geom1, -1.0)):
            jid = body_joint[mj.geom_bodyid[geom]]
            if jid > 0:
                fext[jid] += d.oMi[jid].actInv(pin.Force(s * f, s * (np.cross(c.pos, f) + t))).vector
    return fext


@pytest.mark.slow
def test_matches_mujoco_cfrc_int(hm):
    """On a MuJoCo walk of sim3_zmp: at logged states, MuJoCo's qacc and contact forces fed to joint_loads give
    MuJoCo's own interaction forces cfrc_int (mj_rnePostConstraint: [torque; force] at subtree_com[0], world
    orientation, the parent's wrench on the body's subtree)."""
    sim = Simulator(hm, load_scenario(scenario_path("sim3_zmp")), engine="mujoco")
    log = sim.run(t_end=0.6).log.arrays()
    ms = sim.engine.sim
    mj, md = ms.model, ms.data
    m, d = hm.model, hm.model.createData()
    body_joint = []
    for body in range(mj.nbody):   # MuJoCo body -> the Pinocchio joint that moves it (0: the world)
        b = body
        while b > 0 and mj.body_jntnum[b] == 0:
            b = mj.body_parentid[b]
        jnt = mj.body_jntadr[b] if b > 0 else -1
        body_joint.append(0 if jnt < 0 else 1 if mj.jnt_type[jnt] == mujoco.mjtJoint.mjJNT_FREE
                          else m.getJointId(mj.joint(jnt).name))
    hinge_body = [mj.jnt_bodyid[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in THETA_NAMES]
    diff, scale, contacts = np.zeros(2), np.zeros(2), 0
    for r in range(0, len(log["t"]), 5):
        q, v = log["q"][r], log["v"][r]
        ms.set_state(q, v)
        md.ctrl[:] = ms.map.ctrl_from_tau(log["tau"][r])
        mujoco.mj_forward(mj, md)
        mujoco.mj_rnePostConstraint(mj, md)
        contacts += md.ncon
        a = ms.map.a_from_qacc(q, v, md.qacc)
        pin.forwardKinematics(m, d, q)
        fext = _mujoco_fext(hm, mj, md, d, body_joint)
        loads = joint_loads(m, q[None], v[None], a[None], fext[None], joints=THETA_NAMES)
        for k, name in enumerate(THETA_NAMES):
            torque, force = md.cfrc_int[hinge_body[k]][:3], md.cfrc_int[hinge_body[k]][3:]
            theirs = np.r_[force, torque + np.cross(md.subtree_com[0], force)]   # moment about the world origin
            ours = world(m, d, m.getJointId(name), loads.wrench[0, k])
            for c, sl in enumerate((slice(0, 3), slice(3, 6))):
                diff[c] = max(diff[c], np.abs(ours[sl] - theirs[sl]).max())
                scale[c] = max(scale[c], np.abs(theirs[sl]).max())
    assert contacts > 0
    # measured 6.4e-13 (force) and 1.2e-10 (moment) of the largest value: one formula in two codes on two copies
    # of the model (MuJoCo's bodies carry its 1e-13 kg bound on the virtual bodies' masses); 1e-6 relative is the
    # brief's bound
    assert np.all(diff <= 1e-6 * scale), (diff, scale)
