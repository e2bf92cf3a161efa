"""The compiled stage kernel (humanoid_sim.kernel) against Pinocchio and against the NumPy reference path.

Every check is independent of the kernel's own formulas:

- kinematics (placements, frame Jacobians, velocities, bias accelerations) against Pinocchio's algorithms at random
  configurations and velocities;
- SE(3) logarithm, quaternion <-> rotation conversions and the action matrix against Pinocchio's;
- one single-support stage (command accelerations, computed torque, actuator torques, logged quantities) against
  ``Simulator.evaluate`` / ``_stage0_record`` of a ``compiled=False`` simulator, at the states of real walks
  (sims 1-3) and at states pushed off the constraint manifold;
- the support projection against ``Simulator.project_on_support``;
- the fallbacks (saturated actuators, double support) and a whole walk against the reference walk.

Tolerances are absolute on the quantity divided by max(1, its largest reference entry) unless said otherwise.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import humanoid_sim.kernel as kernel_pkg
from humanoid_sim.analysis.summary import summarize
from humanoid_sim.dynamics.contact import record_anchors
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.simulate import BASIC, Simulator

ROOT = Path(__file__).resolve().parents[2]
PARAMS = ROOT / "scripts" / "params"
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
LOCAL = pin.ReferenceFrame.LOCAL
PHASE_OF_BASIC = {b: ph for ph, b in BASIC.items()}

assert kernel_pkg.AVAILABLE, "numba is a required dependency and is not importable"

# ----------------------------------------------------------------------------------------------- tolerances
# Placements: products of <= 10 rotations of O(1) entries, same operation order as Pinocchio's -> a few ulps.
TOL_PLACEMENT = 1e-14
# Jacobians / velocities / bias accelerations at |v| ~ 1 rad/s: O(10) magnitudes summed over ~30 columns, double
# round-off 1e-16 x 1e2.
TOL_MOTION = 1e-12
# log6 at |p| <= sqrt(3): a few ulps of the O(1) linear part; Pinocchio's small-angle branch (used up to theta ~
# 2.5e-3 rad) is itself accurate to ~theta^4/36 <= 3e-14 at the angles tested below it (1e-9, 1e-5, 1e-3 rad).
TOL_LOG6 = 1e-13
# Near pi the axis comes from vee(R - R^T) ~ sin(theta) = 0.14: round-off amplified by theta/sin(theta) ~ 20.
TOL_LOG6_LARGE = 1e-12
# Unit quaternions / rotation matrices: one or two ulps of O(1) numbers.
TOL_QUAT = 1e-15
# Stage outputs (a, lambda, theta_ddot_c, T, tau) relative to max(1, |reference|): double round-off 1e-16 times the
# condition of the cost normal equations and the inverse-dynamics solve (~1e3), measured ~5e-14; 200x margin.
TOL_STAGE = 1e-11
# Logged positions / orientations / weld errors (m, rad, m/s): same kinematics, a few ulps of O(1) quantities.
TOL_LOG_KIN = 1e-14
# Dynamics residual ||M a + h - tau - Jc^T lam||_inf: forces ~5e2 N x eps x ~1e4 (both paths report round-off).
TOL_RESIDUAL = 1e-9
# Projected q (m, unit quaternion) and v (m/s, rad/s): a few ulps of O(1) quantities through ~10 rotations.
TOL_PROJECT_Q = 1e-14
TOL_PROJECT_V = 1e-13
# Whole walk: the project's acceptance criterion ("same summary numbers to 1e-9").
TOL_SUMMARY = 1e-9
# Logged q of the compiled vs the reference walk: stage round-off ~1e-13 grown through ~700 ode3 steps and six
# touchdown resets of the closed loop (measured ~2e-12 m / rad).
TOL_WALK_Q = 1e-10

T_END = 2.0
"""s: the stage checks' walks cover LFFSSP, RFFDSP, RFFSSP, LFFDSP and the next LFFSSP in sims 1-3."""
PERTURBATIONS = {"on-manifold": (0.0, 0.0), "off-1e-7": (1e-7, 1e-2), "off-1e-4": (1e-4, 1e-2)}
"""Joint-angle (rad) and velocity (m/s, rad/s) offsets.  1e-7 rad keeps the weld orientation errors (~4e-7 rad) in
the small-angle branch of the kernel's log6, 1e-4 rad (~4e-4 rad errors) puts them above it."""


# ----------------------------------------------------------------------------------------------- 1. kinematics
@pytest.fixture(scope="module")
def tree(hm):
    from humanoid_sim.kernel.support import FRAMES
    from humanoid_sim.kernel.tree import TreeConstants

    return TreeConstants(hm.model, FRAMES)


@pytest.fixture(scope="module")
def kin_states(hm):
    """25 random states: base anywhere in a 2 m cube with a random orientation (uniform unit quaternion), joint
    angles in +-1 rad, velocities (base twist included) in +-1; with Pinocchio's data for them:
    ``dj`` = computeJointJacobiansTimeVariation (J, dJ, oMi), ``df`` = computeJointJacobians, then
    forwardKinematics(q, v, 0) and updateFramePlacements (frame Jacobians, velocities, accelerations)."""
    model = hm.model
    rng = np.random.default_rng(20240611)
    out = []
    for _ in range(25):
        q = np.empty(model.nq)
        q[:3] = rng.uniform(-1.0, 1.0, 3)
        quat = rng.normal(size=4)
        q[3:7] = quat / np.linalg.norm(quat)
        q[7:] = rng.uniform(-1.0, 1.0, model.nq - 7)
        v = rng.uniform(-1.0, 1.0, model.nv)
        dj = model.createData()
        pin.computeJointJacobiansTimeVariation(model, dj, q, v)
        df = model.createData()
        pin.computeJointJacobians(model, df, q)
        pin.forwardKinematics(model, df, q, v, np.zeros(model.nv))
        pin.updateFramePlacements(model, df)
        out.append((q, v, dj, df))
    return out


def _fk(tree, q):
    from humanoid_sim.kernel.kinematics import forward_kinematics

    R = np.empty((tree.nj, 3, 3))
    p = np.empty((tree.nj, 3))
    forward_kinematics(q, tree.parents, tree.axis, tree.idx_q, tree.jR, tree.jp, R, p)
    return R, p


def test_forward_kinematics_matches_pinocchio_oMi(tree, kin_states):
    """forward_kinematics gives Pinocchio's oMi (rotation and translation) for every joint, universe included."""
    worst = 0.0
    for q, _, dj, _ in kin_states:
        R, p = _fk(tree, q)
        for j in range(tree.nj):
            worst = max(worst, np.abs(R[j] - dj.oMi[j].rotation).max(), np.abs(p[j] - dj.oMi[j].translation).max())
    assert worst <= TOL_PLACEMENT, worst


def test_frame_placements_match_pinocchio_oMf(hm, tree, kin_states):
    """frame_placement gives Pinocchio's oMf for every frame of stage.FRAMES."""
    from humanoid_sim.kernel.kinematics import frame_placement

    worst = 0.0
    for q, _, _, df in kin_states:
        R, p = _fk(tree, q)
        for i, name in enumerate(tree.frames):
            Rf, pf = frame_placement(R, p, tree.fparent[i], tree.fR[i], tree.fp[i])
            oMf = df.oMf[hm.model.getFrameId(name)]
            worst = max(worst, np.abs(Rf - oMf.rotation).max(), np.abs(pf - oMf.translation).max())
    assert worst <= TOL_PLACEMENT, worst


def test_frame_motion_lwa_matches_pinocchio(hm, tree, kin_states):
    """frame_motion_lwa: Jacobian = getFrameJacobian(LOCAL_WORLD_ALIGNED), last column =
    getFrameClassicalAcceleration(LWA) at zero joint acceleration, returned velocity = getFrameVelocity(LWA)."""
    from humanoid_sim.kernel.kinematics import frame_motion_lwa, frame_placement

    model = hm.model
    worst = {"J": 0.0, "acc": 0.0, "vel": 0.0}
    for q, v, dj, df in kin_states:
        R, p = _fk(tree, q)
        for i, name in enumerate(tree.frames):
            fid = model.getFrameId(name)
            _, pf = frame_placement(R, p, tree.fparent[i], tree.fR[i], tree.fp[i])
            out = np.full((6, model.nv + 1), np.nan)
            vel = frame_motion_lwa(dj.J, dj.dJ, v, tree.support[tree.fparent[i]], pf, out)
            worst["J"] = max(worst["J"], np.abs(out[:, :-1] - pin.getFrameJacobian(model, df, fid, LWA)).max())
            acc = pin.getFrameClassicalAcceleration(model, df, fid, LWA).vector
            worst["acc"] = max(worst["acc"], np.abs(out[:, -1] - acc).max())
            worst["vel"] = max(worst["vel"], np.abs(vel - pin.getFrameVelocity(model, df, fid, LWA).vector).max())
    assert max(worst.values()) <= TOL_MOTION, worst


def test_frame_motion_local_matches_pinocchio(hm, tree, kin_states):
    """frame_motion_local: Jacobian = getFrameJacobian(LOCAL), velocity = getFrameVelocity(LOCAL), acceleration
    at zero joint acceleration = getFrameAcceleration(LOCAL) (spatial, not classical)."""
    from humanoid_sim.kernel.kinematics import frame_motion_local, frame_placement

    model = hm.model
    worst = {"J": 0.0, "acc": 0.0, "vel": 0.0}
    for q, v, dj, df in kin_states:
        R, p = _fk(tree, q)
        for i, name in enumerate(tree.frames):
            fid = model.getFrameId(name)
            Rf, pf = frame_placement(R, p, tree.fparent[i], tree.fR[i], tree.fp[i])
            Jl = np.full((6, model.nv), np.nan)
            vel, acc = frame_motion_local(dj.J, dj.dJ, v, tree.support[tree.fparent[i]], Rf, pf, Jl)
            worst["J"] = max(worst["J"], np.abs(Jl - pin.getFrameJacobian(model, df, fid, LOCAL)).max())
            worst["vel"] = max(worst["vel"], np.abs(vel - pin.getFrameVelocity(model, df, fid, LOCAL).vector).max())
            worst["acc"] = max(worst["acc"],
                               np.abs(acc - pin.getFrameAcceleration(model, df, fid, LOCAL).vector).max())
    assert max(worst.values()) <= TOL_MOTION, worst


# ----------------------------------------------------------------------------------------------- 2. SE(3) helpers
@pytest.mark.parametrize("angle, tol", [
    (1e-9, TOL_LOG6),    # tiny: Taylor branch of both
    (1e-5, TOL_LOG6),    # small: just above the kernel's Taylor threshold eps^(1/3) = 6.06e-6 rad
    (1e-3, TOL_LOG6),    # still below Pinocchio's switch (3 - tr R >= eps^(1/3), i.e. theta ~ 2.5e-3 rad)
    (0.5, TOL_LOG6),     # moderate
    (3.0, TOL_LOG6_LARGE),  # large, near pi
])
def test_log6_matches_pinocchio(angle, tol):
    """log6(R, p) = pin.log6(pin.SE3(R, p)).vector for rotations of the given angle about 20 random axes, with
    random translations in the unit cube."""
    from humanoid_sim.kernel.kinematics import log6

    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(20):
        axis = rng.normal(size=3)
        R = pin.exp3(angle * axis / np.linalg.norm(axis))
        p = rng.uniform(-1.0, 1.0, 3)
        worst = max(worst, np.abs(log6(R, p) - pin.log6(pin.SE3(R, p)).vector).max())
    assert worst <= tol, f"theta = {angle:g} rad: max |log6 - pin.log6| = {worst:.3e}"


def _branch_rotations():
    """Rotations covering every branch of rot_to_quat: random ones (mostly trace > 0), and rotations by pi, by
    pi - 1e-3 and by ~pi - 0.1 about perturbed axes near x, y and z (trace < 0, that diagonal entry largest)."""
    rng = np.random.default_rng(11)
    out = []
    for _ in range(100):
        a = rng.normal(size=3)
        out.append(pin.exp3(rng.uniform(0.0, np.pi) * a / np.linalg.norm(a)))
    for e in np.eye(3):
        for angle in (np.pi, -np.pi, np.pi - 1e-3, 2.5, -2.5):
            out.append(pin.exp3(angle * e))
        for _ in range(5):
            out.append(pin.exp3((np.pi - 0.1) * e + 0.2 * rng.normal(size=3)))
    return out


def test_rot_to_quat_matches_pinocchio_in_every_branch():
    """rot_to_quat = pin.SE3ToXYZQUAT's quaternion, sign included, for rotations hitting every branch (trace > 0,
    and each of R00, R11, R22 the largest diagonal entry with trace <= 0)."""
    from humanoid_sim.kernel.kinematics import rot_to_quat

    branches = set()
    worst = 0.0
    for R in _branch_rotations():
        tr = np.trace(R)
        branches.add("trace>0" if tr > 0.0 else f"R{int(np.argmax(np.diag(R)))}{int(np.argmax(np.diag(R)))}")
        out = np.full(4, np.nan)
        rot_to_quat(R, out)
        worst = max(worst, np.abs(out - pin.SE3ToXYZQUAT(pin.SE3(R, np.zeros(3)))[3:]).max())
    assert branches == {"trace>0", "R00", "R11", "R22"}, branches
    assert worst <= TOL_QUAT, worst


def test_quat_to_rot_matches_pinocchio():
    """quat_to_rot(x, y, z, w) = pin.XYZQUATToSE3(...).rotation for 100 random unit quaternions (both signs of w)
    and the quaternions of the branch rotations."""
    from humanoid_sim.kernel.kinematics import quat_to_rot

    rng = np.random.default_rng(13)
    quats = [x / np.linalg.norm(x) for x in rng.normal(size=(100, 4))]
    quats += [pin.SE3ToXYZQUAT(pin.SE3(R, np.zeros(3)))[3:] for R in _branch_rotations()]
    worst = max(np.abs(quat_to_rot(*qt) - pin.XYZQUATToSE3(np.r_[np.zeros(3), qt]).rotation).max() for qt in quats)
    assert worst <= TOL_QUAT, worst


def test_action_matrix_matches_pinocchio():
    """action_matrix(R, p) = pin.SE3(R, p).toActionMatrix() for 20 random placements (|p| up to ~3.5 m)."""
    from humanoid_sim.kernel.kinematics import action_matrix

    rng = np.random.default_rng(17)
    worst = 0.0
    for _ in range(20):
        R = pin.exp3(rng.normal(size=3))
        p = rng.uniform(-2.0, 2.0, 3)
        worst = max(worst, np.abs(action_matrix(R, p) - pin.SE3(R, p).toActionMatrix()).max())
    assert worst <= 4 * TOL_QUAT, worst  # entries [p]x R up to ~7: a few ulps of that


# ----------------------------------------------------------------------------------------------- walks
@pytest.fixture(scope="module")
def walks(hm):
    """Reference (compiled=False) walks of sims 1-3 up to T_END: {name: (simulator, scenario, log arrays)}."""
    out = {}
    for name in ("sim1", "sim2", "sim3"):
        sc = load_scenario(PARAMS / f"{name}.yaml")
        sim = Simulator(hm, sc, compiled=False)
        res = sim.run(t_end=T_END)
        arr = res.log.arrays()
        assert set(arr["basic_phase"].tolist()) == {0, 1, 2, 3}, f"{name}: the walk must cover all four phases"
        out[name] = (sim, sc, arr)
    return out


def _state(hm, arr, i, dq, dv, rng):
    """(phase, k, t, q, v, anchors) of log row i; anchors recorded at the logged q, then q's joint angles and all of
    v offset by +-dq / +-dv (random signs)."""
    ph = PHASE_OF_BASIC[int(arr["basic_phase"][i])]
    q, v = arr["q"][i].copy(), arr["v"][i].copy()
    anchors = record_anchors(hm.model, q, ph.contacts)
    if dq or dv:
        q[7:] += dq * rng.choice([-1.0, 1.0], size=q.size - 7)
        v += dv * rng.choice([-1.0, 1.0], size=v.size)
    return ph, int(arr["phase"][i]), float(arr["t"][i]), q, v, anchors


def _pin_data(model, q, v):
    """A fresh Data with what StageKernel.stage expects: J, dJ, M (upper triangle), nle at (q, v)."""
    d = model.createData()
    pin.computeJointJacobiansTimeVariation(model, d, q, v)
    pin.crba(model, d, q)
    pin.nonLinearEffects(model, d, q, v)
    return d


def _dev(x, ref) -> float:
    """max |x - ref| / max(1, max |ref|)."""
    ref = np.asarray(ref, dtype=float)
    return float(np.max(np.abs(np.asarray(x, dtype=float) - ref)) / max(1.0, float(np.max(np.abs(ref)))))


# ----------------------------------------------------------------------------------------------- 3. stage
@pytest.fixture(scope="module")
def stage_deviations(hm, walks):
    """For every row of the three walks (all four phases) and every perturbation: the kernel stage (StageKernel
    built from the reference simulator's controller, actuators, gains and torque-split weights) against
    ``Simulator.evaluate`` + ``_stage0_record`` of that compiled=False simulator.  Returns {(sim, perturbation):
    {quantity: max deviation}} plus, per key, the number of stages compared, of saturated stages and of
    double-support stages."""
    from humanoid_sim.controllers.thesis.stage import StageKernel

    model = hm.model
    out = {}
    for name, (sim, _, arr) in walks.items():
        ker = StageKernel(hm, sim.cmd, sim.act, sim.dyn.gains, sim._w_tau, sim._w_lam)
        for seed, (pname, (dq, dv)) in enumerate(PERTURBATIONS.items()):
            rng = np.random.default_rng(seed)
            dev: dict[str, float] = {}
            n = nsat = ndsp = 0
            keep = []  # the kernel caches anchors by identity: keep every Anchors alive
            for i in range(len(arr["t"])):
                ph, k, t, q, v, anchors = _state(hm, arr, i, dq, dv, rng)
                keep.append(anchors)
                table = sim.traj.dsp_table(k) if ph.is_double_support else sim.traj.ssp_table(k)
                ko = ker.stage(ph, anchors, q, v, _pin_data(model, q, v), table, t)
                ndsp += ph.is_double_support
                ro = sim.evaluate(k, ph, anchors, t, q, v)
                rec = sim.engine._stage0_record(ph, q, v, ro["cmd"], ro["a"], ro["lam"])
                lg = ko.record
                n += 1
                sat = bool(ro["sat"].any())
                nsat += sat
                cmp = {
                    "saturation flag": float(lg.status != (1.0 if sat else 0.0)),
                    "theta_ddot_c": _dev(ko.thdd_c, ro["thdd_c"]),
                    "T_cmd": _dev(ko.T_cmd, ro["T_cmd"]),
                    "weld position error": abs(lg.weld_position_error - rec[7]),
                    "weld orientation error": abs(lg.weld_orientation_error - rec[8]),
                    "hip CoM p": _dev(lg.hip_p, rec[10]),
                    "hip CoM v": _dev(lg.hip_v, rec[11]),
                    "R_17": _dev(lg.R_17.ravel(), rec[12].ravel()),
                    "toe R p": _dev(lg.toe_R_p, rec[13]),
                    "toe L p": _dev(lg.toe_L_p, rec[14]),
                    "R_1": _dev(lg.R_1.ravel(), rec[15].ravel()),
                    "R_2": _dev(lg.R_2.ravel(), rec[16].ravel()),
                }
                if not sat:  # saturated: the reference solves the forward dynamics of the clipped torques instead
                    cmp.update({"a": _dev(ko.a, ro["a"]), "lam": _dev(ko.lam, ro["lam"]),
                                "tau": _dev(ko.tau, ro["tau"]),
                                "residual (kernel)": float(lg.residual), "residual (reference)": float(rec[9])})
                for key, val in cmp.items():
                    dev[key] = max(dev.get(key, 0.0), val)
            dev["_n"], dev["_sat"], dev["_dsp"] = n, nsat, ndsp
            out[(name, pname)] = dev
    return out


STAGE_TOL = {"saturation flag": 0.0, "theta_ddot_c": TOL_STAGE, "T_cmd": TOL_STAGE, "a": TOL_STAGE,
             "lam": TOL_STAGE, "tau": TOL_STAGE, "weld position error": TOL_LOG_KIN,
             "weld orientation error": TOL_LOG_KIN, "hip CoM p": TOL_LOG_KIN, "hip CoM v": TOL_LOG_KIN,
             "R_17": TOL_LOG_KIN, "toe R p": TOL_LOG_KIN, "toe L p": TOL_LOG_KIN, "R_1": TOL_LOG_KIN,
             "R_2": TOL_LOG_KIN, "residual (kernel)": TOL_RESIDUAL, "residual (reference)": TOL_RESIDUAL}


@pytest.mark.parametrize("perturbation", list(PERTURBATIONS))
@pytest.mark.parametrize("name", ["sim1", "sim2", "sim3"])
def test_stage_matches_reference(stage_deviations, name, perturbation):
    """At every step state of the walk, single and double support (on the constraint manifold, or pushed off it so
    that the Baumgarte terms and weld errors are non-zero), StageKernel.stage gives the reference path's a, lambda,
    theta_ddot_c, T_cmd, tau, saturation decision and logged quantities (weld errors, hip CoM p and v, R_17, toe
    points, R_1, R_2); both dynamics residuals are at round-off."""
    dev = dict(stage_deviations[(name, perturbation)])
    n, nsat, ndsp = dev.pop("_n"), dev.pop("_sat"), dev.pop("_dsp")
    assert n > 150 and n - nsat > 150 and ndsp >= 2, (n, nsat, ndsp)  # DSPs end a step or two after touchdown
    bad = {k: f"{v:.3e} > {STAGE_TOL[k]:.0e}" for k, v in dev.items() if not v <= STAGE_TOL[k]}
    assert not bad, f"{name}, {perturbation} ({n} stages, {nsat} saturated): {bad}"


# ----------------------------------------------------------------------------------------------- 4. projection
@pytest.mark.parametrize("name", ["sim1", "sim2", "sim3"])
def test_projection_matches_reference(hm, walks, name):
    """StageKernel.project = Simulator.project_on_support at every step state of the walk (all four phases: in
    double support the projection uses the support foot) pushed off the manifold (1e-4 rad on the joints, 1e-2 on
    the velocities) and with the toe lock and weld anchors of the unperturbed state."""
    from humanoid_sim.controllers.thesis.stage import StageKernel

    sim, _, arr = walks[name]
    ker = StageKernel(hm, sim.cmd, sim.act, sim.dyn.gains)
    rng = np.random.default_rng(3)
    worst_q = worst_v = 0.0
    seen = set()
    keep = []
    for i in range(len(arr["t"])):
        ph, _, _, q, v, anchors = _state(hm, arr, i, 1e-4, 1e-2, rng)
        keep.append(anchors)
        seen.add(ph)
        qk, vk = ker.project(ph, anchors, q, v)
        qr, vr = sim.project_on_support(ph, anchors, q, v)
        worst_q = max(worst_q, np.abs(qk - qr).max())
        worst_v = max(worst_v, np.abs(vk - vr).max())
    assert seen == set(Phase)
    assert worst_q <= TOL_PROJECT_Q and worst_v <= TOL_PROJECT_V, (worst_q, worst_v)


@pytest.mark.parametrize("name", ["sim1", "sim3"])
def test_advance_matches_integrate_then_project(hm, walks, name):
    """StageKernel.advance(q, v, coeffs, vs, accs, h) = project_on_support(pin.integrate(q, h dq), v + h dv) with
    dq, dv the integrator's combinations (``integrator._combine``) of random stage rates (|v_j| ~ 0.3 rad/s,
    |a_j| ~ 3 rad/s^2) for ode3's rows (0.5), (0, 0.75) and its weights (2/9, 1/3, 4/9), h = 0.01 s, at the walk's
    step states in all four phases; the combinations themselves are bit-identical; the base quaternion stays unit."""
    from humanoid_sim.controllers.thesis.stage import StageKernel
    from humanoid_sim.dynamics.integrator import TABLEAUS, _combine

    sim, _, arr = walks[name]
    ker = StageKernel(hm, sim.cmd, sim.act, sim.dyn.gains)
    tab = TABLEAUS["ode3"]
    rng = np.random.default_rng(5)
    worst_q = worst_v = worst_n = 0.0
    keep = []
    for i in range(len(arr["t"])):
        ph, _, _, q, v, anchors = _state(hm, arr, i, 0.0, 0.0, None)
        keep.append(anchors)
        vs = [rng.normal(0.0, 0.3, hm.model.nv) for _ in range(3)]
        accs = [rng.normal(0.0, 3.0, hm.model.nv) for _ in range(3)]
        for coeffs, n in ((tab.a[1], 1), (tab.a[2], 2), (tab.b, 3)):
            qk, vk = ker.advance(ph, anchors, q, v, coeffs, vs[:n], accs[:n], 0.01)
            dq, dv = _combine(coeffs, vs[:n]), _combine(coeffs, accs[:n])
            qr, vr = sim.project_on_support(ph, anchors, pin.integrate(hm.model, q, 0.01 * dq), v + 0.01 * dv)
            worst_q = max(worst_q, np.abs(qk - qr).max())
            worst_v = max(worst_v, np.abs(vk - vr).max())
            worst_n = max(worst_n, abs(np.linalg.norm(qk[3:7]) - 1.0))
    assert worst_q <= TOL_PROJECT_Q and worst_v <= TOL_PROJECT_V, (worst_q, worst_v)
    assert worst_n <= 1e-15, worst_n  # normalised: one rounding of a unit vector


# ----------------------------------------------------------------------------------------------- 5. fallbacks
def _compiled_twin(hm, sim_ref, sc):
    """A compiled simulator reading the reference simulator's (landing-adjusted) trajectory."""
    sim = Simulator(hm, sc, compiled=True)
    sim.traj = sim_ref.traj
    return sim


def _assert_same_result(out, ref):
    assert "kernel_log" not in out
    assert out.keys() == ref.keys()
    for key in ref:
        if key != "cmd":  # the Command object behind the other entries
            np.testing.assert_array_equal(out[key], ref[key], err_msg=key)


def test_saturated_stages_fall_back_to_reference(hm, walks):
    """Where an actuator saturates along the walks, the kernel flags it (log status 1) and Simulator.evaluate on a
    compiled simulator returns exactly the reference path's result (no kernel_log, same numbers as compiled=False);
    where none saturates it returns the kernel's result."""
    n_sat = n_free = 0
    for sim_ref, sc, arr in walks.values():
        sim_c = _compiled_twin(hm, sim_ref, sc)
        rng = np.random.default_rng(0)
        for i in np.flatnonzero(np.isin(arr["basic_phase"], [BASIC[Phase.LFFSSP], BASIC[Phase.RFFSSP]])):
            ph, k, t, q, v, anchors = _state(hm, arr, i, 0.0, 0.0, rng)
            ref = sim_ref.evaluate(k, ph, anchors, t, q, v)
            out = sim_c.evaluate(k, ph, anchors, t, q, v)
            if ref["sat"].any():
                n_sat += 1
                ko = sim_c.kernel.stage(ph, anchors, q, v, _pin_data(hm.model, q, v), sim_c.traj.ssp_table(k), t)
                assert ko.status == 1.0 and ko.saturated
                _assert_same_result(out, ref)
            else:
                n_free += 1
                assert "kernel_log" in out
    assert n_sat >= 1 and n_free > 400, (n_sat, n_free)  # the walks saturate at 6 step states (1 %)


@pytest.mark.parametrize("phase", [Phase.LFFSSP, Phase.RFFSSP])
def test_constructed_saturation_falls_back_to_reference(hm, walks, phase):
    """With every actuator limit scaled so that the most loaded actuator of an unsaturated single-support state
    gets half its torque, the kernel flags saturation and the compiled evaluate equals the reference evaluate
    (same scaled limits) exactly."""
    sim_ref0, sc, arr = walks["sim1"]
    rows = np.flatnonzero((arr["basic_phase"] == BASIC[phase]) & ~arr["saturated"].any(axis=1))
    i = int(rows[len(rows) // 2])
    ph, k, t, q, v, anchors = _state(hm, arr, i, 0.0, 0.0, None)
    sim_ref = Simulator(hm, sc, compiled=False)
    sim_ref.traj = sim_ref0.traj
    sim_c = _compiled_twin(hm, sim_ref0, sc)
    T = sim_c.kernel.stage(ph, anchors, q, v, _pin_data(hm.model, q, v), sim_c.traj.ssp_table(k), t).T_cmd
    scale = 0.5 * np.max(np.abs(T) / sim_ref.act.limits)
    assert scale < 1.0  # the original limits hold here
    for s in (sim_ref, sim_c):
        s.act.limits = s.act.limits * scale  # replaced on the Actuators: the kernel follows (StageKernel.limits)
    ko = sim_c.kernel.stage(ph, anchors, q, v, _pin_data(hm.model, q, v), sim_c.traj.ssp_table(k), t)
    assert ko.status == 1.0
    ref = sim_ref.evaluate(k, ph, anchors, t, q, v)
    assert ref["sat"].any()
    _assert_same_result(sim_c.evaluate(k, ph, anchors, t, q, v), ref)
    # an in-place change of the limits reaches the kernel as well (the same array): back to no saturation
    sim_c.act.limits /= scale
    assert sim_c.kernel.stage(ph, anchors, q, v, _pin_data(hm.model, q, v), sim_c.traj.ssp_table(k), t).status == 0.0


def test_double_support_stage_matches_reference(hm, walks):
    """Double support in more states than the walks' few DSP steps: every DSP step state of the three walks with 12
    random perturbations each (joint angles up to 1e-3 rad, rates up to 0.05 rad/s: larger ones saturate the
    actuators, and saturated stages leave the kernel): the kernel's command
    accelerations (closed chain by KKT), realised accelerations, weighted minimum-norm torques and multipliers,
    thesis torques and weld errors equal the reference path's."""
    from humanoid_sim.controllers.thesis.stage import StageKernel

    worst: dict[str, float] = {}
    n = 0
    keep = []
    for sim, _, arr in walks.values():
        ker = StageKernel(hm, sim.cmd, sim.act, sim.dyn.gains, sim._w_tau, sim._w_lam)
        rng = np.random.default_rng(11)
        for i in np.flatnonzero(np.isin(arr["basic_phase"], [BASIC[Phase.LFFDSP], BASIC[Phase.RFFDSP]])):
            for _ in range(12):
                ph, k, t, q, v, anchors = _state(hm, arr, i, rng.uniform(0, 1e-3), rng.uniform(0, 0.05), rng)
                keep.append(anchors)
                ko = ker.stage(ph, anchors, q, v, _pin_data(hm.model, q, v), sim.traj.dsp_table(k), t)
                ro = sim.evaluate(k, ph, anchors, t, q, v)
                if bool(ro["sat"].any()) or ko.status != 0.0:
                    assert bool(ro["sat"].any()) == (ko.status == 1.0)
                    continue
                rec = sim.engine._stage0_record(ph, q, v, ro["cmd"], ro["a"], ro["lam"])
                for key, x, y in (("theta_ddot_c", ko.thdd_c, ro["thdd_c"]), ("a", ko.a, ro["a"]),
                                  ("tau", ko.tau, ro["tau"]), ("lam", ko.lam, ro["lam"]),
                                  ("T_cmd", ko.T_cmd, ro["T_cmd"])):
                    worst[key] = max(worst.get(key, 0.0), _dev(x, y))
                worst["weld errors"] = max(worst.get("weld errors", 0.0), abs(ko.record.weld_position_error - rec[7]),
                                              abs(ko.record.weld_orientation_error - rec[8]))
                n += 1
    assert n >= 30, n
    bad = {k: v for k, v in worst.items() if not v <= (TOL_LOG_KIN if k == "weld errors" else TOL_STAGE)}
    assert not bad, (bad, worst)


# ----------------------------------------------------------------------------------------------- 6. whole walk
def _flatten(x, path=""):
    if isinstance(x, dict):
        for k, v in x.items():
            yield from _flatten(v, f"{path}.{k}")
    elif isinstance(x, (list, tuple)):
        for i, v in enumerate(x):
            yield from _flatten(v, f"{path}[{i}]")
    else:
        yield path, x


@pytest.fixture(scope="module", params=["sim1", "sim2", "sim3"])
def full_walks(hm, request):
    """A shipped scenario walked to the end with the compiled kernel (counting kernel stages and fallbacks) and
    without."""
    sc = load_scenario(PARAMS / f"{request.param}.yaml")
    sim_c = Simulator(hm, sc, compiled=True)
    calls = {"stage": 0, "fallback": 0}
    stage = sim_c.kernel.stage

    def counting_stage(*args, **kwargs):
        out = stage(*args, **kwargs)
        calls["stage"] += 1
        calls["fallback"] += out.status != 0.0
        return out

    sim_c.kernel.stage = counting_stage
    res_c = sim_c.run()
    res_r = Simulator(hm, sc, compiled=False).run()
    return res_c, res_r, calls


@pytest.mark.slow
def test_whole_walk_compiled_equals_reference(full_walks):
    """Sims 1-3 compiled vs reference: same completion, phase sequence and switch steps; every numeric summary entry
    within 1e-9 (wall-time entries excepted), strings equal; logged q within TOL_WALK_Q; the compiled run did
    evaluate its single-support stages with the kernel."""
    res_c, res_r, calls = full_walks
    assert res_r.completed and res_c.completed == res_r.completed and res_c.reason == res_r.reason
    assert res_c.steps == res_r.steps
    assert [(p.name, p.t_start, p.t_end) for p in res_c.phases] == [(p.name, p.t_start, p.t_end) for p in res_r.phases]
    a_c, a_r = res_c.log.arrays(), res_r.log.arrays()
    np.testing.assert_array_equal(a_c["phase"], a_r["phase"])
    np.testing.assert_array_equal(a_c["basic_phase"], a_r["basic_phase"])
    # ~3 stages per SSP step go through the kernel; saturated ones (a few %) fall back
    assert calls["stage"] > 0.9 * 3 * res_c.steps and calls["fallback"] < 0.05 * calls["stage"], calls
    s_c = dict(_flatten(summarize(res_c, "sim1", "pinocchio")))
    s_r = dict(_flatten(summarize(res_r, "sim1", "pinocchio")))
    assert s_c.keys() == s_r.keys()
    # the stage counts of summary.json: what the kernel computed, and none on the reference path
    assert s_c[".compiled_stages"] == calls["stage"] - calls["fallback"] and s_r[".compiled_stages"] == 0
    assert s_c[".compiled_stages"] + s_c[".reference_stages"] == res_c.stage_evaluations
    worst, bad = 0.0, {}
    for key, ref in s_r.items():
        if key in (".wall_time_s", ".real_time_factor", ".compiled_stages", ".reference_stages"):
            continue
        val = s_c[key]
        if isinstance(ref, (bool, str)) or ref is None or val is None:
            if val != ref:
                bad[key] = (val, ref)
        else:
            worst = max(worst, abs(val - ref))
            if not abs(val - ref) <= TOL_SUMMARY:
                bad[key] = (val, ref)
    assert not bad, bad
    dq = float(np.abs(a_c["q"] - a_r["q"]).max())
    assert dq <= TOL_WALK_Q, dq
    # the compiled advance normalises the base quaternion as Pinocchio's integrate does: no drift over the walk
    assert np.abs(np.linalg.norm(a_c["q"][:, 3:7], axis=1) - 1.0).max() <= 1e-15


# ----------------------------------------------------------------------------------------------- 7. no numba
def test_compiled_without_numba_raises(hm, monkeypatch):
    """With numba unavailable, compiled=True raises a RuntimeError naming numba; compiled=None falls back to the
    reference path."""
    monkeypatch.setattr(kernel_pkg, "AVAILABLE", False)
    sc = load_scenario(PARAMS / "sim1.yaml")
    with pytest.raises(RuntimeError, match="numba"):
        Simulator(hm, sc, compiled=True)
    assert Simulator(hm, sc).kernel is None


# ----------------------------------------------------------------------------------------------- 8. self-check
@pytest.mark.parametrize("name", ["sim1", "sim2", "sim3"])
def test_self_check_passes_on_the_shipped_scenarios(hm, name):
    """Simulator's start-up comparison of the kernel with the reference path finds no difference above round-off,
    in all four phases."""
    sim = Simulator(hm, load_scenario(PARAMS / f"{name}.yaml"), compiled=True)
    assert sim.kernel is not None
    # single support agrees to ~1e-15; double support's weighted minimum-norm torque split (weights 1000 : 1, so
    # a normal matrix of condition ~1e6) to ~2e-12: 1e-10 is far below any real formula change (the default
    # check tolerance is 1e-8)
    assert sim.check_kernel(tol=1e-10) is None


def test_self_check_passes_on_a_robot_variant(variant_hm):
    """The kernel reads the robot from the model it is given, not from constants: on a variant (every segment,
    mass and the sole changed, a payload) its stages equal the reference path's as on the thesis robot."""
    sim = Simulator(variant_hm, load_scenario(PARAMS / "sim1.yaml"), compiled=True)
    assert sim.kernel is not None
    assert sim.check_kernel(tol=1e-10) is None   # the thesis robot's bound (above)


@pytest.mark.parametrize("target", ["controller", "actuators"])
def test_self_check_catches_an_edited_reference_formula(hm, monkeypatch, target):
    """A reference formula changed by 0.1 % without its compiled twin (the upper-body law of eq. 5.90, or the
    actuator torque map) makes the default simulator warn and run on the reference path, and an explicit
    compiled=True refuse to start."""
    from humanoid_sim.controllers.thesis import command
    from humanoid_sim.robot import actuators

    if target == "controller":
        orig = command.CommandAccelerations.upper
        monkeypatch.setattr(command.CommandAccelerations, "upper", lambda self, th, thd: 1.001 * orig(self, th, thd))
    else:
        orig_t = actuators.Actuators.thesis_torques
        monkeypatch.setattr(actuators.Actuators, "thesis_torques",
                            lambda self, *a, **k: 1.001 * orig_t(self, *a, **k))
    sc = load_scenario(PARAMS / "sim1.yaml")
    with pytest.warns(RuntimeWarning, match="disagrees with the reference path"):
        sim = Simulator(hm, sc)
    assert sim.kernel is None
    with pytest.raises(RuntimeError, match="disagrees with the reference path"):
        Simulator(hm, sc, compiled=True)


# ----------------------------------------------------------------------------------------------- 9. references
def test_ssp_references_equal_the_trajectory_queries(walks):
    """ssp_references from ReferenceTrajectory.ssp_table equals hip_reference / toe_reference (swing foot) bit for
    bit (same formulas, same operation order), in every single-support phase of sims 1-3 after their walks (so the
    landing-adjusted swings too), at times before, inside and after the phase window (clamping) and on both sides of
    the swing's t_z switch."""
    from humanoid_sim.references.chapter3.compiled import ssp_references

    n = 0
    for sim, _, _ in walks.values():
        tr = sim.traj
        for k, ph in enumerate(tr.phases):
            if not ph.is_ssp:
                continue
            tab = tr.ssp_table(k)
            for t in np.linspace(ph.t_start - 0.1, ph.t_end + 0.1, 61):
                out = [np.empty(3), np.empty(6), np.empty((3, 3)), np.empty(3), np.empty(6), np.empty((3, 3))]
                ssp_references(tab, t, t + 0.013, *out)
                ref = list(tr.hip_reference(k, t)) + list(tr.toe_reference(k, t + 0.013, ph.swing_foot))
                for x, y in zip(out, ref):
                    np.testing.assert_array_equal(x, y)
                n += 1
    assert n > 1000


def test_ssp_table_refuses_a_double_support_phase(walks):
    """ssp_table names the phase when asked for a double support phase."""
    from humanoid_sim.references.chapter3.generator import TrajectoryError

    sim = next(iter(walks.values()))[0]
    k = next(i for i, ph in enumerate(sim.traj.phases) if not ph.is_ssp)
    with pytest.raises(TrajectoryError, match="not a single support phase"):
        sim.traj.ssp_table(k)


def test_split_stage_equals_fused_stage(hm, walks):
    """StageKernel.split (the controller and dynamics halves as two calls, for profiling) gives the fused call's
    results bit for bit at single-support states of sim 1: the same compiled functions run in the same order."""
    from humanoid_sim.controllers.thesis.stage import StageKernel

    sim, _, arr = walks["sim1"]
    ker = StageKernel(hm, sim.cmd, sim.act, sim.dyn.gains)
    rows = np.flatnonzero(np.isin(arr["basic_phase"], [BASIC[Phase.LFFSSP], BASIC[Phase.RFFSSP]]))[::5]
    assert rows.size >= 30
    for i in rows:
        ph, k, t, q, v, anchors = _state(hm, arr, i, 0.0, 0.0, None)
        d = _pin_data(hm.model, q, v)
        outs = []
        for split in (False, True):
            ker.split = split
            outs.append(ker.stage(ph, anchors, q, v, d, sim.traj.ssp_table(k), t))
        for name in ("a", "lam", "thdd_c", "T_cmd", "tau", "log"):
            np.testing.assert_array_equal(getattr(outs[0], name), getattr(outs[1], name), err_msg=name)
