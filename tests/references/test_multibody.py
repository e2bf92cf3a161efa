"""Multibody ZMP and Kajita's second pass (humanoid_sim/references/zmp/multibody.py).

Independent references: analytic velocities and accelerations of a motion given in closed form; RNEA's free-flyer
rows (the total external wrench, an algorithm that never forms the centroidal momentum); the cart-table law
p = c - z_c / g c'' of a rigidly translating body (no angular momentum about its CoM); forward kinematics."""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim import PACKAGE_DIR
from humanoid_sim.analysis.audit import FLAT, TOE, SoleGeometry, convex_hull, signed_distance, sole_polygons
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.references.initial import initial_configuration
from humanoid_sim.references.zmp.errors import GaitError
from humanoid_sim.references.zmp.multibody import (
    correct_hip,
    manifold_derivatives,
    multibody_zmp,
    path_derivatives,
    whole_body_com,
)
from humanoid_sim.references.zmp.posture import WalkPosture
from humanoid_sim.references.zmp.preview import CartTablePreview
from humanoid_sim.references.zmp.zmp_reference import intervals_from_trajectory, sample
from humanoid_sim.scenario.schema import load_scenario

PARAMS = PACKAGE_DIR.parent / "scripts" / "params"
G = 9.81


# ------------------------------------------------------------------------------------------------ a closed-form motion
def closed_form_motion(hm, t: np.ndarray):
    """q(t), v(t), a(t) of the humanoid: base position p(t), base rotation R0 Rz(phi(t)) Rx(psi(t)) and every
    joint theta_i(t) sinusoidal; v, a in Pinocchio's convention (base twist in the base frame)."""
    rng = np.random.default_rng(5)
    nj = hm.model.nv - 6
    amp_j, w_j, ph_j = rng.uniform(0.05, 0.3, nj), rng.uniform(2.0, 7.0, nj), rng.uniform(0, 6.0, nj)
    R0 = hm.initial_base().rotation
    q, v, a = [], [], []
    for s in t:
        p = np.array([0.05 * np.sin(3 * s), 0.3 * s + 0.02 * np.sin(5 * s), 0.9 + 0.01 * np.cos(4 * s)])
        pd = np.array([0.15 * np.cos(3 * s), 0.3 + 0.1 * np.cos(5 * s), -0.04 * np.sin(4 * s)])
        pdd = np.array([-0.45 * np.sin(3 * s), -0.5 * np.sin(5 * s), -0.16 * np.cos(4 * s)])
        phi, phid, phidd = 0.3 * np.sin(2 * s), 0.6 * np.cos(2 * s), -1.2 * np.sin(2 * s)
        psi, psid, psidd = 0.1 * np.sin(3 * s), 0.3 * np.cos(3 * s), -0.9 * np.sin(3 * s)
        Rz, Rx = pin.utils.rotate("z", phi), pin.utils.rotate("x", psi)
        R = R0 @ Rz @ Rx
        # body angular velocity of R0 Rz(phi) Rx(psi): Rx^T (phid e_z) + psid e_x, and its derivative
        w = Rx.T @ np.array([0.0, 0.0, phid]) + np.array([psid, 0.0, 0.0])
        Rxd = Rx @ pin.skew(np.array([psid, 0.0, 0.0]))
        wd = Rx.T @ np.array([0.0, 0.0, phidd]) + Rxd.T @ np.array([0.0, 0.0, phid]) + np.array([psidd, 0.0, 0.0])
        vb = R.T @ pd
        ab = R.T @ pdd - np.cross(w, vb)          # d/dt (R^T p') = R^T p'' - w x (R^T p')
        th = amp_j * np.sin(w_j * s + ph_j)
        qk = np.concatenate([p, pin.Quaternion(R).coeffs(), np.zeros(hm.model.nq - 7)])
        qk[7:] = th                                # every joint is 1-DOF revolute: q[7:] lines up with v[6:]
        q.append(qk)
        v.append(np.concatenate([vb, w, amp_j * w_j * np.cos(w_j * s + ph_j)]))
        a.append(np.concatenate([ab, wd, -amp_j * w_j ** 2 * np.sin(w_j * s + ph_j)]))
    return np.array(q), np.array(v), np.array(a)


def test_manifold_derivatives_match_the_closed_form_and_converge_at_second_order(hm):
    assert hm.model.nq - 7 == hm.model.nv - 6
    errs = []
    for T in (4e-3, 2e-3):
        t = np.arange(0.0, 0.4, T)
        q, v, a = closed_form_motion(hm, t)
        v_fd, a_fd = manifold_derivatives(hm, q, T)
        errs.append((np.abs(v_fd - v)[1:-1].max(), np.abs(a_fd - a)[1:-1].max(), np.abs(a_fd - a)[[0, -1]].max()))
    (ev1, ea1, ee1), (ev2, ea2, ee2) = errs
    # the central formulas are O(T^2): halving T divides the error by ~4 (3 to 5 allows the O(T^4) remainder);
    # the one-sided end accelerations are O(T): ~2
    assert 3.0 < ev1 / ev2 < 5.0 and 3.0 < ea1 / ea2 < 5.0 and 1.5 < ee1 / ee2 < 2.5
    # magnitudes: joint accelerations reach 0.3 * 7^2 = 15 rad/s^2; their O(T^2) error w^4 A T^2 / 12 ~ 2e-3
    assert ev2 < 1e-3 and ea2 < 5e-3


# ------------------------------------------------------------------------------------------------ the ZMP
def _zmp_by_rnea(hm, q, v, a) -> np.ndarray:
    """Ground-plane point where the total external wrench (RNEA's free-flyer rows, base frame) has no horizontal
    moment."""
    data = hm.model.createData()
    out = []
    for qk, vk, ak in zip(q, v, a):
        tau = pin.rnea(hm.model, data, qk, vk, ak)
        Mb = pin.XYZQUATToSE3(qk[:7])
        f = Mb.rotation @ tau[:3]
        n = Mb.rotation @ tau[3:6] + np.cross(Mb.translation, f)
        out.append([-n[1] / f[2], n[0] / f[2]])
    return np.array(out)


def test_multibody_zmp_agrees_with_rnea(hm):
    T = 0.005
    t = np.arange(0.0, 0.6, T)
    q, _, _ = closed_form_motion(hm, t)
    v, a = manifold_derivatives(hm, q, T)
    # 1e-9 m: two exact algorithms on the same (q, v, a); the ZMP divides moments of ~500 N m by ~500 N
    np.testing.assert_allclose(multibody_zmp(hm, q, T), _zmp_by_rnea(hm, q, v, a), atol=1e-9)


def test_translating_rigid_body_obeys_the_cart_table_law(hm):
    """Every joint fixed, no rotation: the robot is one rigid body in translation, its angular momentum about the
    CoM is zero, and its ZMP is p = c - (c_z / (g + c_z'')) c'' exactly (here c_z is constant)."""
    T = 0.01
    t = np.arange(0.0, 2.0, T)
    q0 = hm.initial_q()
    c0 = whole_body_com(hm, q0[None, :])[0]
    A, w = np.array([0.06, 0.04]), np.array([2 * np.pi, 1.5 * np.pi])
    disp = A * np.sin(np.outer(t, w)) + np.outer(t, [0.0, 0.3])
    acc = -A * w ** 2 * np.sin(np.outer(t, w))
    q = np.tile(q0, (len(t), 1))
    q[:, :2] += disp
    zmp = multibody_zmp(hm, q, T)
    expected = c0[:2] + disp - c0[2] / G * acc
    # the central second difference errs by c_z/g A w^4 T^2 / 12 = 0.095 * 0.06 * 1559 * 1e-4 / 12 = 7.4e-5 m
    np.testing.assert_allclose(zmp[1:-1], expected[1:-1], atol=1e-4)
    # the one-sided ends are first order: error ~ c_z/g A w^3 T = 0.095 * 0.06 * 248 * 0.01 = 1.4e-2 m
    np.testing.assert_allclose(zmp[[0, -1]], expected[[0, -1]], atol=2e-2)


def test_path_derivatives_are_exact_for_a_cubic():
    T = 0.1
    t = T * np.arange(10)
    x = np.stack([t ** 3 - t, 2 * t ** 2], axis=1)
    v, a = path_derivatives(x, T)
    # first differences are exact for the quadratic; for the cubic (x''' = 6) the central ones err by
    # T^2 x'''/6 = 0.01 and the one-sided second-order ends by T^2 x'''/3 = 0.02, exactly
    np.testing.assert_allclose(v[:, 1], 4 * t, atol=1e-12)
    np.testing.assert_allclose(v[1:-1, 0] - (3 * t[1:-1] ** 2 - 1), 0.01, atol=1e-12)
    np.testing.assert_allclose(v[[0, -1], 0] - (3 * t[[0, -1]] ** 2 - 1), [-0.02, -0.02], atol=1e-12)
    # second differences (three-point inside, four-point at the ends) are exact for a cubic
    np.testing.assert_allclose(a, np.stack([6 * t, np.full_like(t, 4.0)], axis=1), atol=1e-10)


def test_bad_inputs_are_named(hm):
    with pytest.raises(GaitError, match=r"q: expected an \(N, 33\) array"):
        multibody_zmp(hm, np.zeros((5, 30)), 0.01)
    with pytest.raises(GaitError, match="q: expected at least 3 samples"):
        multibody_zmp(hm, np.tile(hm.initial_q(), (2, 1)), 0.01)
    with pytest.raises(GaitError, match="T: expected a finite sample time > 0 s"):
        manifold_derivatives(hm, np.tile(hm.initial_q(), (4, 1)), -0.01)
    with pytest.raises(GaitError, match="model: expected a pinocchio.Model"):
        multibody_zmp("robot", np.zeros((4, 33)), 0.01)


# ------------------------------------------------------------------------------------------------ second pass
@pytest.fixture(scope="module")
def straight_walk(hm):
    """Sim 3 (straight, 0.93 m hip, 8 steps) planned by preview control after a 1 s shift, then corrected."""
    path = load_scenario(PARAMS / "sim3.yaml").path
    traj = ReferenceTrajectory(path)
    q0 = initial_configuration(hm, path)
    com0 = whole_body_com(hm, q0[None, :])[0]
    T = 0.01
    sole = SoleGeometry.from_model(hm)
    times, ref = sample(intervals_from_trajectory(traj, sole, lead_in_s=1.0, start_xy=com0[:2]), T)
    preview = CartTablePreview(T, com0[2])        # z_c: the whole-body CoM height of the initial posture
    plan = preview.run(ref)
    posture = WalkPosture.from_trajectory(hm, traj, times, q0)
    t0 = time.perf_counter()
    res = correct_hip(preview, hm, ref, plan, posture, passes=2)
    elapsed = time.perf_counter() - t0
    ssp = np.array([0 <= t < traj.duration and traj.phases[traj.phase_at(t)].is_ssp for t in times])
    return dict(traj=traj, times=times, ref=ref, plan=plan, res=res, ssp=ssp, com0=com0, elapsed=elapsed)


def test_initial_posture_com_height(straight_walk):
    # the cart-table height: 0.929 m, 0.9 mm below the Body-17 CoM (0.93 m): legs bent ~32 deg, arms down
    assert straight_walk["com0"][2] == pytest.approx(0.92914, abs=1e-5)


def test_second_pass_reduces_the_multibody_zmp_error(straight_walk):
    res, ssp = straight_walk["res"], straight_walk["ssp"]
    e = [np.linalg.norm(p.zmp_error, axis=1) for p in res.passes]
    rms = [float(np.sqrt(np.mean(x[ssp] ** 2))) for x in e]
    peak = [float(x[ssp].max()) for x in e]
    print(f"\nsim 3 multibody ZMP error in single support, before / after 1 / after 2 corrections: "
          f"RMS {[round(1e3 * r, 1) for r in rms]} mm, max {[round(1e3 * p, 1) for p in peak]} mm; "
          f"all samples max {[round(1e3 * float(x.max()), 1) for x in e]} mm; {straight_walk['elapsed']:.1f} s")
    # the whole-body CoM follows the cart-table plan, yet the multibody ZMP misses by ~25 mm RMS (swing leg,
    # angular momentum, heel rise); each pass must cut the single-support RMS, the first one by at least half
    assert rms[1] < 0.5 * rms[0] and rms[2] < rms[1]
    assert peak[2] < 0.5 * peak[0]
    np.testing.assert_array_equal(res.zmp_error, res.passes[-1].zmp_error)


def test_corrected_hip_path_is_consistent(hm, straight_walk):
    res = straight_walk["res"]
    data = hm.model.createData()
    hip17, com = [], []
    for q in res.q:
        pin.framesForwardKinematics(hm.model, data, q)
        hip17.append(data.oMf[hm.frame_id("Pc_17")].translation[:2].copy())
        com.append(pin.centerOfMass(hm.model, data, q)[:2].copy())
    np.testing.assert_allclose(np.array(hip17), res.hip_xy, atol=1e-9)      # the posture's promise (IK tolerance)
    np.testing.assert_allclose(np.array(com), res.com_plan, atol=1e-5)     # match_com's tolerance
    v, a = path_derivatives(res.hip_xy, 0.01)
    np.testing.assert_array_equal(res.hip_v, v)
    np.testing.assert_array_equal(res.hip_a, a)
    # Body 17 sits behind and outside the whole-body CoM by up to a couple of centimetres (swing leg, arms)
    assert 0.005 < np.abs(res.hip_xy - res.com_plan).max() < 0.05


def test_corrected_multibody_zmp_stays_in_the_support_polygon(hm, straight_walk):
    """The contact audit's ZMP criterion on the planned motion: the multibody ZMP of the corrected postures against
    the support polygon of the thesis's contacts (audit.sole_polygons on those postures)."""
    traj, times, res = straight_walk["traj"], straight_walk["times"], straight_walk["res"]
    kinds = np.zeros((len(times), 2), dtype=int)
    for k, t in enumerate(times):
        if t < 0:
            kinds[k] = FLAT
            continue
        ph = traj.phases[traj.phase_at(t)]
        if ph.is_ssp:
            kinds[k, 0 if ph.swing_foot == "L" else 1] = FLAT
        else:
            kinds[k, 0 if ph.landed_foot == "R" else 1] = FLAT
            kinds[k, 1 if ph.landed_foot == "R" else 0] = TOE
    polys = sole_polygons(hm, res.q, kinds)
    margin = np.array([signed_distance(res.zmp_mb[k], convex_hull(np.vstack([p for p in polys[k] if p is not None])))
                       for k in range(len(times))])
    print(f"\nsim 3 corrected multibody ZMP: min margin {1e3 * margin.min():.1f} mm, in single support "
          f"{1e3 * margin[straight_walk['ssp']].min():.1f} mm")
    assert margin.min() > 0.0
