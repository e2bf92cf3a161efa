"""One single-support stage in one compiled call: command accelerations, computed torque, actuator torques.

The compiled twin of ``Simulator.evaluate`` for the two single-support phases (LFFSSP, RFFSSP) when no actuator
saturates; see :mod:`humanoid_sim.kernel`.  Each function below mirrors a reference function, named in its
docstring, formula for formula:

- :func:`_body_task` = ``TaskKinematics.reduce_pair`` + ``CommandAccelerations._body_task`` (base eliminated
  through the stance-foot weld, thesis joint order and signs);
- :func:`_tracking_rows` / :func:`_normal` / :func:`_cholesky_solve` = ``command._tracking_rows``,
  ``_CostRows.normal`` and ``_solve_spd`` (thesis eqs. 5.1-5.23);
- :func:`_contact_rows` = ``ConstraintRows.evaluate`` for one weld and one lock (Baumgarte rows);
- :func:`_inverse_square` = ``contact.inverse._solve_square`` (the unique single-support computed torque);
- :func:`_thesis_torques` = ``Actuators.thesis_torques`` (T of eq. 4.69; shoulders from the arm's Newton-Euler
  equation, which is what RNEA's joint force of a leaf body is).

Double support (a few steps per phase change) and saturated stages (about 1 %) go to the reference path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.actuators import Actuators
from humanoid_sim.command import LAYOUTS, TASK_FRAMES, CommandAccelerations
from humanoid_sim.contact.constraints import Anchors, Baumgarte
from humanoid_sim.kernel import njit
from humanoid_sim.kernel.kinematics import (TreeConstants, action_matrix, cross, forward_kinematics,
                                           frame_motion_local, frame_motion_lwa, frame_placement, log6, mm, mtm,
                                           mtv, mv, quat_to_rot, rot_to_quat)
from humanoid_sim.model import HumanoidModel
from humanoid_sim.phases import FOOT_SPECS, Phase

FRAMES = list(TASK_FRAMES)
"""Frames the kernel evaluates: the controller's task frames (Pc_17, O_17, P_tpR, P_tpL, O_1, O_2, O_3, O_4)."""
F_PC17, F_O17, F_TPR, F_TPL, F_O1, F_O2, F_O3, F_O4 = range(8)
LOG_SIZE = 45
"""Floats of the per-stage log vector (see :class:`StageOutput`)."""


# ----------------------------------------------------------------------------------------------- small algebra
@njit
def _cholesky_solve(Z: np.ndarray, g: np.ndarray) -> np.ndarray:
    """x with Z x = g for symmetric positive definite Z (lower Cholesky factor, as LAPACK posv); NaNs when Z is
    not positive definite (the caller reports it)."""
    n = g.size
    L = np.zeros((n, n))
    for j in range(n):
        s = Z[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return np.full(n, np.nan)
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            s = Z[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    y = np.empty(n)
    for i in range(n):
        s = g[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x


@njit
def _solve3(B: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with B x = b for a 3 x 3 B (Gaussian elimination, partial pivoting)."""
    A = B.copy()
    x = b.copy()
    for c in range(3):
        piv = c
        for r in range(c + 1, 3):
            if abs(A[r, c]) > abs(A[piv, c]):
                piv = r
        if piv != c:
            for k in range(3):
                A[c, k], A[piv, k] = A[piv, k], A[c, k]
            x[c], x[piv] = x[piv], x[c]
        for r in range(c + 1, 3):
            f = A[r, c] / A[c, c]
            for k in range(c, 3):
                A[r, k] -= f * A[c, k]
            x[r] -= f * x[c]
    for c in range(2, -1, -1):
        s = x[c]
        for k in range(c + 1, 3):
            s -= A[c, k] * x[k]
        x[c] = s / A[c, c]
    return x


# ----------------------------------------------------------------------------------------------- controller
@njit
def _body_task(motion: np.ndarray, vel: np.ndarray, fpos: np.ndarray, fparent: np.ndarray, point: int, body: int,
               weld: int, jcols: np.ndarray, jsign: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(J (6 x 26), drift (6,), velocity (6,)) of [linear motion of frame ``point``; angular motion of frame
    ``body``] in thesis joint space, the base eliminated through the weld of frame ``weld``."""
    nv = jcols.size + 6
    W = motion[weld]
    T = motion[point].copy()
    v6 = vel[point].copy()
    if fparent[point] != fparent[body]:
        T[3:] = motion[body][3:]
        v6[3:] = vel[body][3:]
    D = T - W
    d = fpos[weld] - fpos[point]  # S = [d]x: S x = d x x
    for c in range(nv + 1):
        wx, wy, wz = W[3, c], W[4, c], W[5, c]
        D[0, c] -= d[1] * wz - d[2] * wy
        D[1, c] -= d[2] * wx - d[0] * wz
        D[2, c] -= d[0] * wy - d[1] * wx
    J = np.empty((6, jcols.size))
    for i in range(jcols.size):
        J[:, i] = D[:, jcols[i]] * jsign[i]
    return J, D[:, nv].copy(), v6


@njit
def _tracking_rows(A: np.ndarray, r: np.ndarray, J6: np.ndarray, drift6: np.ndarray, p: np.ndarray,
                   v6: np.ndarray, R: np.ndarray, ref_p: np.ndarray, ref_v: np.ndarray, ref_R: np.ndarray,
                   dt: float) -> None:
    """The 12 rows (position 3, velocity 6, C_diag orientation 3) of one task body (eqs. 5.1-5.3, errata C-1)."""
    h2 = 0.5 * dt * dt
    A[0:3] = J6[:3] * h2
    r[0:3] = ref_p - (p + v6[:3] * dt + drift6[:3] * h2)
    A[3:9] = J6 * dt
    r[3:9] = ref_v - (v6 + drift6 * dt)
    w = v6[3:]
    L = np.zeros((3, 3))  # d/dt C_diag = L w (taskspace.cdiag_rate_matrix)
    L[0, 1], L[0, 2] = R[2, 0], -R[1, 0]
    L[1, 0], L[1, 2] = -R[2, 1], R[0, 1]
    L[2, 0], L[2, 1] = R[1, 2], -R[0, 2]
    diag = np.empty(3)
    for i in range(3):
        diag[i] = R[i, i]
    bias = w * mtv(R, w) - (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * diag  # diag([w]x [w]x C)
    A[9:12] = mm(L, J6[3:]) * h2
    pred = diag + mv(L, w) * dt + (mv(L, drift6[3:]) + bias) * h2
    for i in range(3):
        r[9 + i] = ref_R[i, i] - pred[i]


@njit
def _normal(A: np.ndarray, r: np.ndarray, w: np.ndarray, dZ: np.ndarray, dg: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """(Z, g) = (A^T W A + diag(dZ), A^T W r + dg) (``_CostRows.normal``)."""
    WA = A * w[:, None]
    Z = mtm(A, WA)
    for i in range(dZ.size):
        Z[i, i] += dZ[i]
    return Z, mtv(WA, r) + dg


@njit
def _controller(motion, vel, fpos, fR, fparent, th, thd, jcols, jsign, ref_a_p, ref_a_v, ref_a_R, ref_b_p,
                ref_b_v, ref_b_R, ip, fp_) -> np.ndarray:
    """Command accelerations theta_ddot_c (26,) of a single-support phase (``CommandAccelerations.compute``, SSP
    branch).  ``ip`` (int64): root weld frame, other toe point frame, other weld frame, stance toe, other toe,
    k_toe, n_s, n_o, then xs (n_s), xo (n_o), upper joints (10).  ``fp_`` (float64): dt_a, dt_b, ha, hb, s_p, w_p,
    s_v, w_v, theta0_toe, then wa_rows (12), wb_rows (12), dZ_a (n_s), dZ_b (n_o), W_q_a (n_s), W_q_b (n_o),
    upper Wp, Wv, dt, den, dt2, dt3 (10 each)."""
    root, toe_pt, other_weld, stance_toe, other_toe, k_toe, ns, no = (ip[0], ip[1], ip[2], ip[3], ip[4], ip[5],
                                                                      ip[6], ip[7])
    xs = ip[8:8 + ns]
    xo = ip[8 + ns:8 + ns + no]
    qu = ip[8 + ns + no:18 + ns + no]
    dta, dtb, ha, hb, s_p, w_p, s_v, w_v, theta0_toe = (fp_[0], fp_[1], fp_[2], fp_[3], fp_[4], fp_[5], fp_[6],
                                                        fp_[7], fp_[8])
    o = 9
    wa_rows = fp_[o:o + 12]
    wb_rows = fp_[o + 12:o + 24]
    o += 24
    dZ_a = fp_[o:o + ns]
    dZ_b = fp_[o + ns:o + ns + no]
    Wq_a = fp_[o + ns + no:o + 2 * ns + no]
    Wq_b = fp_[o + 2 * ns + no:o + 2 * ns + 2 * no]
    o += 2 * (ns + no)
    uWp, uWv, udt, uden, udt2, udt3 = (fp_[o:o + 10], fp_[o + 10:o + 20], fp_[o + 20:o + 30], fp_[o + 30:o + 40],
                                       fp_[o + 40:o + 50], fp_[o + 50:o + 60])
    qdd = np.zeros(26)
    # step 1: stance-leg joints for Body 17 and its CoM (5.1.1.1.1)
    J, drift, v6 = _body_task(motion, vel, fpos, fparent, F_PC17, F_O17, root, jcols, jsign)
    Aa = np.zeros((12, ns))
    ra = np.zeros(12)
    Js = np.empty((6, ns))
    for i in range(ns):
        Js[:, i] = J[:, xs[i]]
    _tracking_rows(Aa, ra, Js, drift, fpos[F_PC17], v6, fR[F_O17], ref_a_p, ref_a_v, ref_a_R, dta)
    dg = np.empty(ns)
    for i in range(ns):
        dg[i] = Wq_a[i] * ha * -(th[xs[i]] + thd[xs[i]] * dta)
    Z, g = _normal(Aa, ra, wa_rows, dZ_a, dg)
    qdd_s = _cholesky_solve(Z, g)
    for i in range(ns):
        qdd[xs[i]] = qdd_s[i]
    # step 2: swing-leg joints for the swing toe point and toe body, given step 1 (5.1.1.1.2)
    J, drift, v6 = _body_task(motion, vel, fpos, fparent, toe_pt, other_weld, root, jcols, jsign)
    drift = drift + Js_times(J, xs, qdd_s)
    Ab = np.zeros((12, no))
    rb = np.zeros(12)
    Jo = np.empty((6, no))
    for i in range(no):
        Jo[:, i] = J[:, xo[i]]
    _tracking_rows(Ab, rb, Jo, drift, fpos[toe_pt], v6, fR[other_weld], ref_b_p, ref_b_v, ref_b_R, dtb)
    dg = np.empty(no)
    for i in range(no):
        dg[i] = Wq_b[i] * hb * -(th[xo[i]] + thd[xo[i]] * dtb)
    th_toe = th[other_toe] + theta0_toe
    dg[k_toe] += (w_p * s_p * -(th_toe + thd[other_toe] * s_v)) + (w_v * s_v * -thd[other_toe])
    Z, g = _normal(Ab, rb, wb_rows, dZ_b, dg)
    qdd_o = _cholesky_solve(Z, g)
    for i in range(no):
        qdd[xo[i]] = qdd_o[i]
    qdd[stance_toe] = 0.0
    for i in range(10):  # eq. 5.90 per upper-body joint
        k = qu[i]
        num = uWp[i] * th[k] * udt2[i] / 2 + uWp[i] * thd[k] * udt3[i] / 2 + uWv[i] * thd[k] * udt[i]
        qdd[k] = -num / uden[i]
    return qdd


@njit
def Js_times(J: np.ndarray, cols: np.ndarray, x: np.ndarray) -> np.ndarray:
    """J[:, cols] @ x."""
    out = np.zeros(J.shape[0])
    for i in range(cols.size):
        out += J[:, cols[i]] * x[i]
    return out


# ----------------------------------------------------------------------------------------------- dynamics
@njit
def _contact_rows(J, dJ, v, q, support_w, Rf, pf, Ra, pa, lock_q, lock_v, lock_anchor, kp, kd
                  ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Constraint Jacobian Jc (7 x nv: LOCAL weld rows, then the lock row), rhs shift r = Jdot v + Kd Jc v + Kp e
    (7,), weld position and orientation errors (m, rad) (``ConstraintRows.evaluate``, one weld + one lock)."""
    nv = v.size
    Jc = np.zeros((7, nv))
    vel, acc = frame_motion_local(J, dJ, v, support_w, Rf, pf, Jc[:6])
    Jc[6, lock_v] = 1.0
    e = log6(mtm(Ra, Rf), mtv(Ra, pf - pa))
    r = np.empty(7)
    for i in range(6):
        r[i] = kd * vel[i]
        r[i] += acc[i]
        r[i] += kp * e[i]
    r[6] = kd * v[lock_v]  # the lock row has no drift (its Jacobian is constant)
    r[6] += kp * (q[lock_q] - lock_anchor)
    dp = pf - pa
    return Jc, r, np.sqrt(dp[0] * dp[0] + dp[1] * dp[1] + dp[2] * dp[2]), np.sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5])


@njit
def _inverse_square(Jc, r, M, h, a_des, Rb, pb, Rf, pf, lock_v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, tau, lam) of the single-support computed torque (``contact.inverse._solve_square``): free joints take
    the desired accelerations, the weld fixes the base (J_Wb^-1 = Ad(bMf)), the lock row the locked joint."""
    nv = a_des.size
    a = a_des.copy()
    a[lock_v] = -r[6]
    Jb_inv = action_matrix(mtm(Rb, Rf), mtv(Rb, pf - pb))
    a[:6] = mv(Jb_inv, -r[:6] - mv(Jc[:6, 6:], a[6:]))
    b = mv(M, a) + h
    lam_w = mtv(Jb_inv, b[:6])
    g = b - mtv(Jc[:6], lam_w)
    tau = np.zeros(nv)
    tau[6:] = g[6:]
    tau[lock_v] = 0.0
    lam = np.empty(7)
    lam[:6] = lam_w
    lam[6] = g[lock_v]
    return a, tau, lam


@njit
def _thesis_torques(J, dJ, v, a, tau, R, p, support, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity
                    ) -> np.ndarray:
    """T (26,, T-bar order) (``Actuators.thesis_torques``).  g1 (n1, 5) int: T row, v index, sign (+-1),
    higher-joint slot, component of the one-component groups; g3 (n3, 10) int: 3 T rows, 3 v indices, 3 signs,
    higher-joint slot; gs (2, 6) int: 2 T rows, 2 components, tree joint, higher-joint slot of the shoulders,
    with ``arm_mass`` (2,), ``arm_lever`` (2, 3), ``arm_I`` (2, 3, 3) (inertia about the CoM, joint frame);
    hj: joint ids of the higher bodies (slots)."""
    T = np.zeros(26)
    for i in range(g1.shape[0]):
        row, vi, sg, slot, comp = g1[i, 0], g1[i, 1], g1[i, 2], g1[i, 3], g1[i, 4]
        Rh = R[hj[slot]]
        b = sg * (J[3, vi] * Rh[0, comp] + J[4, vi] * Rh[1, comp] + J[5, vi] * Rh[2, comp])
        T[row] = tau[vi] / b
    B = np.empty((3, 3))
    rhs = np.empty(3)
    for i in range(g3.shape[0]):
        Rh = R[hj[g3[i, 9]]]
        for k in range(3):
            vi, sg = g3[i, 3 + k], g3[i, 6 + k]
            for c in range(3):
                B[k, c] = sg * (J[3, vi] * Rh[0, c] + J[4, vi] * Rh[1, c] + J[5, vi] * Rh[2, c])
            rhs[k] = tau[vi]
        x = _solve3(B, rhs)
        for k in range(3):
            T[g3[i, k]] = x[k]
    for i in range(gs.shape[0]):  # the arm (a leaf body): its Newton-Euler wrench about the shoulder point
        tj, slot = gs[i, 4], gs[i, 5]
        Rt, pt = R[tj], p[tj]
        V = np.zeros(6)
        A = np.zeros(6)
        for c in range(v.size):
            if support[tj, c]:
                for k in range(6):
                    V[k] += J[k, c] * v[c]
                    A[k] += J[k, c] * a[c] + dJ[k, c] * v[c]
        w, alpha = V[3:], A[3:]
        com = pt + mv(Rt, arm_lever[i])
        vc = V[:3] + cross(w, com)
        ac = A[:3] + cross(alpha, com) + cross(w, vc)
        f = arm_mass[i] * (ac - gravity)
        Iw = mm(mm(Rt, arm_I[i]), Rt.T)
        n = mv(Iw, alpha) + cross(w, mv(Iw, w)) + cross(com - pt, f)  # moment on the arm from the trunk, about pt
        m = mtv(R[hj[slot]], n)
        T[gs[i, 0]] = m[gs[i, 2]]
        T[gs[i, 1]] = m[gs[i, 3]]
    return T


# ----------------------------------------------------------------------------------------------- the stage
@njit
def ssp_stage(q, v, J, dJ, M_upper, h, ref_a_p, ref_a_v, ref_a_R, ref_b_p, ref_b_v, ref_b_R, anchor_R, anchor_p,
              lock_anchor, parents, axis, idx_q, jR, jp, support, fparent, fRp, fpp, jcols, jsign, theta_q, theta0,
              ip, fp_, weld, lock_q, lock_v, kp, kd, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity, limits):
    """One single-support stage: (a (nv,), lam (7,), theta_ddot_c (26,), T_cmd (26,), tau (nv,), log (LOG_SIZE,)).

    Inputs: the state (q, v); Pinocchio's WORLD joint Jacobians J, dJ and M (upper triangle), h = nle at that
    state; the two task references; the support anchors; and the constant arrays of :class:`SSPKernel`."""
    nj = parents.size
    R = np.empty((nj, 3, 3))
    p = np.empty((nj, 3))
    forward_kinematics(q, parents, axis, idx_q, jR, jp, R, p)
    nf = fparent.size
    nv = v.size
    fR = np.empty((nf, 3, 3))
    fpos = np.empty((nf, 3))
    motion = np.empty((nf, 6, nv + 1))
    vel = np.empty((nf, 6))
    for i in range(nf):
        fR[i], fpos[i] = frame_placement(R, p, fparent[i], fRp[i], fpp[i])
        vel[i] = frame_motion_lwa(J, dJ, v, support[fparent[i]], fpos[i], motion[i])
    th = np.empty(26)
    thd = np.empty(26)
    for i in range(26):
        th[i] = jsign[i] * q[theta_q[i]] - theta0[i]
        thd[i] = jsign[i] * v[jcols[i]]
    qdd = _controller(motion, vel, fpos, fR, fparent, th, thd, jcols, jsign, ref_a_p, ref_a_v, ref_a_R, ref_b_p,
                      ref_b_v, ref_b_R, ip, fp_)
    a_des = np.zeros(nv)
    for i in range(26):
        a_des[jcols[i]] = jsign[i] * qdd[i]
    M = M_upper.copy()
    for i in range(nv):
        for k in range(i):
            M[i, k] = M_upper[k, i]
    Jc, r, pos_err, ori_err = _contact_rows(J, dJ, v, q, support[fparent[weld]], fR[weld], fpos[weld], anchor_R,
                                            anchor_p, lock_q, lock_v, lock_anchor, kp, kd)
    a, tau, lam = _inverse_square(Jc, r, M, h, a_des, R[1], p[1], fR[weld], fpos[weld], lock_v)
    T = _thesis_torques(J, dJ, v, a, tau, R, p, support, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity)
    log = np.zeros(LOG_SIZE)
    log[0] = 0.0
    for i in range(26):
        if T[i] > limits[i] or T[i] < -limits[i] or not np.isfinite(T[i]):
            log[0] = 1.0
    if not np.isfinite(qdd).all():
        log[0] = -1.0  # a cost's normal matrix was not positive definite
    res = mv(M, a) + h - tau - mtv(Jc, lam)
    log[1], log[2], log[3] = pos_err, ori_err, np.max(np.abs(res))
    log[4:7] = fpos[F_PC17]
    log[7:10] = vel[F_PC17][:3]
    log[10:19] = fR[F_O17].ravel()
    log[19:22] = fpos[F_TPR]
    log[22:25] = fpos[F_TPL]
    log[25:34] = fR[F_O1].ravel()
    log[34:43] = fR[F_O2].ravel()
    return a, lam, qdd, T, tau, log


@njit
def project_on_support(q, v, anchor_R, anchor_p, lock_q, lock_v, lock_anchor, parents, axis, idx_q, idx_v, jR, jp,
                       support, f_parent, f_R, f_p) -> tuple[np.ndarray, np.ndarray]:
    """(q, v) with the support foot at its anchor and at rest (``Simulator.project_on_support``): toe lock at its
    anchor angle with zero rate, base placement re-derived from the foot's anchor, base twist from the joint
    rates through the foot's LOCAL Jacobian."""
    q = q.copy()
    v = v.copy()
    q[lock_q] = lock_anchor
    v[lock_v] = 0.0
    nj = parents.size
    R = np.empty((nj, 3, 3))
    p = np.empty((nj, 3))
    forward_kinematics(q, parents, axis, idx_q, jR, jp, R, p)
    Rf, pf = frame_placement(R, p, f_parent, f_R, f_p)
    Rb = quat_to_rot(q[3], q[4], q[5], q[6])
    pb = q[:3].copy()
    X = mm(anchor_R, Rf.T)
    Rn = mm(X, Rb)
    q[:3] = anchor_p + mv(X, pb - pf)
    quat = np.empty(4)
    rot_to_quat(Rn, quat)
    q[3:7] = quat
    # LOCAL Jacobian of the foot frame times the joint rates (the joint columns do not depend on the base)
    vj = np.zeros(3)
    wj = np.zeros(3)
    for j in range(2, nj):
        iv = idx_v[j]
        if support[f_parent, iv] and v[iv] != 0.0:
            u = R[j][:, axis[j]]
            wj += u * v[iv]
            vj += cross(u, pf - p[j]) * v[iv]
    lin = mtv(Rf, vj)
    ang = mtv(Rf, wj)
    Ad = action_matrix(mtm(Rb, Rf), mtv(Rb, pf - pb))
    tw = np.empty(6)
    tw[:3] = lin
    tw[3:] = ang
    v[:6] = -mv(Ad, tw)
    return q, v


# ----------------------------------------------------------------------------------------------- Python side
@dataclass
class StageOutput:
    """What one kernel stage returns (SI units; see ``Simulator.evaluate``)."""

    a: np.ndarray
    lam: np.ndarray
    thdd_c: np.ndarray
    T_cmd: np.ndarray
    tau: np.ndarray
    log: np.ndarray  # [saturated flag, weld position error, weld orientation error, dynamics residual,
    #                  hip CoM p (3), hip CoM v (3), R_17 (9), toe R p (3), toe L p (3), R_1 (9), R_2 (9), pad]

    @property
    def saturated(self) -> bool:
        return self.log[0] > 0.0

    @property
    def failed(self) -> bool:
        """A cost's normal matrix was not positive definite (the reference path then raises its error)."""
        return self.log[0] < 0.0


class SSPKernel:
    """The constant arrays of the compiled single-support stage and projection, built once per simulator from the
    reference objects (so both paths use the same weights, layouts and actuator groups)."""

    def __init__(self, hm: HumanoidModel, cmd: CommandAccelerations, act: Actuators,
                 gains: Baumgarte | None = None) -> None:
        model = hm.model
        self.hm = hm
        self.tree = TreeConstants(model, FRAMES)
        tr = self.tree
        gains = gains if gains is not None else Baumgarte()
        self.kp, self.kd = float(gains.kp), float(gains.kd)
        self.jcols = np.asarray(hm.theta_v_idx, dtype=np.int64)
        self.jsign = np.asarray(hm.theta_sign, dtype=float)
        self.theta_q = np.asarray(hm.theta_q_idx, dtype=np.int64)
        self.theta0 = cmd.theta0.copy()
        self.phase = {}
        fi = tr.frame_index
        for ph in (Phase.LFFSSP, Phase.RFFSSP):
            lay = LAYOUTS[ph.value]
            P = cmd._problems[ph.value]
            wa, wb = cmd.params.steps[ph.value]
            ns, no = P.xs.size, P.xo.size
            ip = np.concatenate([[fi[lay.root_weld], fi[lay.other_toe_point], fi[lay.other_weld], lay.stance_toe,
                                  lay.other_toe, P.k_toe, ns, no], P.xs, P.xo, cmd._q_upper]).astype(np.int64)
            up = cmd.params
            fp_ = np.concatenate([[wa.dt, wb.dt, P.ha, P.hb, P.toe_p[0], P.toe_p[1], P.toe_v[0], P.toe_v[1],
                                   P.theta0_toe], P.a.w[:, 0], P.b.w[:, 0], P.dZ_a, P.dZ_b, wa.W_q, wb.W_q,
                                  up.upper_Wp, up.upper_Wv, up.upper_dt, cmd._upper_den, cmd._upper_dt2,
                                  cmd._upper_dt3]).astype(float)
            spec = FOOT_SPECS[ph.support_foot]
            jid = model.getJointId(spec.toe_joint)
            self.phase[ph] = (ip, fp_, fi[spec.main_frame], int(model.idx_qs[jid]), int(model.idx_vs[jid]),
                              spec.main_frame, spec.toe_joint)
        # actuator groups (Actuators._groups / _batches in flat integer tables)
        g1, g3, gs = [], [], []
        hj = np.array(act._hj_unique, dtype=np.int64)
        for gi, (rows, comps, hjid, sl, tj, higher_is_parent) in enumerate(act._groups):
            slot = act._hj_unique.index(hjid)
            vidx = act._vidx[sl]
            sg = act._signs[sl].astype(np.int64)
            if len(rows) == 1:
                g1.append([rows[0], vidx[0], sg[0], slot, comps[0]])
            elif len(rows) == 3:
                if list(comps) != [0, 1, 2]:
                    raise ValueError(f"actuator group {gi}: three components must be x, y, z")
                g3.append(list(rows) + list(vidx) + list(sg) + [slot])
            else:
                if higher_is_parent:
                    raise ValueError(f"actuator group {gi}: the two-component (universal) joint must carry a "
                                     "leaf body on its child side")
                gs.append(list(rows) + list(comps) + [tj, slot])
        self.g1 = np.array(g1, dtype=np.int64)
        self.g3 = np.array(g3, dtype=np.int64)
        self.gs = np.array(gs, dtype=np.int64)
        self.hj = hj
        self.arm_mass = np.array([model.inertias[g[4]].mass for g in gs], dtype=float)
        self.arm_lever = np.array([model.inertias[g[4]].lever for g in gs], dtype=float)
        self.arm_I = np.array([model.inertias[g[4]].inertia for g in gs], dtype=float)
        for g in gs:
            if any(model.parents[j] == g[4] for j in range(model.njoints)):
                raise ValueError(f"joint {model.names[g[4]]!r} of a universal actuator is not a leaf")
        self.gravity = np.array(model.gravity.linear, dtype=float)
        self.limits = act.limits.astype(float)
        self._anchor_key: tuple | None = None
        self._anchor_val: tuple = ()

    def _anchor(self, phase: Phase, anchors: Anchors) -> tuple[np.ndarray, np.ndarray, float]:
        key = (id(anchors), phase)
        if self._anchor_key != key:
            _, _, _, _, _, frame, toe = self.phase[phase]
            M = anchors.placements[frame]
            self._anchor_val = (M.rotation.copy(), M.translation.copy(), float(anchors.joint_positions[toe]))
            self._anchor_key = key
        return self._anchor_val

    def stage(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, data: pin.Data, ref_a, ref_b
              ) -> StageOutput:
        """Evaluate one single-support stage; ``data`` holds computeJointJacobiansTimeVariation, crba and
        nonLinearEffects at (q, v)."""
        tr = self.tree
        ip, fp_, weld, lock_q, lock_v, _, _ = self.phase[phase]
        aR, ap, alock = self._anchor(phase, anchors)
        out = ssp_stage(q, v, data.J, data.dJ, data.M, data.nle, ref_a.p, ref_a.v, ref_a.R, ref_b.p, ref_b.v, ref_b.R,
                        aR, ap, alock, tr.parents, tr.axis, tr.idx_q, tr.jR, tr.jp, tr.support, tr.fparent, tr.fR,
                        tr.fp, self.jcols, self.jsign, self.theta_q, self.theta0, ip, fp_, weld, lock_q, lock_v,
                        self.kp, self.kd, self.g1, self.g3, self.gs, self.hj, self.arm_mass, self.arm_lever,
                        self.arm_I, self.gravity, self.limits)
        return StageOutput(*out)

    def project(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The compiled ``Simulator.project_on_support`` for the support foot of ``phase``."""
        tr = self.tree
        _, _, weld, lock_q, lock_v, _, _ = self.phase[_ssp_of(phase)]
        aR, ap, alock = self._anchor(_ssp_of(phase), anchors)
        return project_on_support(q, v, aR, ap, lock_q, lock_v, alock, tr.parents, tr.axis, tr.idx_q, tr.idx_v,
                                  tr.jR, tr.jp, tr.support, tr.fparent[weld], tr.fR[weld], tr.fp[weld])


def _ssp_of(phase: Phase) -> Phase:
    """The single-support phase with the same support foot (the projection only needs the support foot)."""
    return Phase.LFFSSP if phase.support_foot == "L" else Phase.RFFSSP
