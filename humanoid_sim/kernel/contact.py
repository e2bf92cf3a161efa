"""Compiled twin of :mod:`humanoid_sim.dynamics.contact` for the weld model (numba): the constraint rows of a
phase's welds and toe lock (``ConstraintRows.evaluate``) and the computed torque under them
(``contact.inverse._solve_square`` in single support, ``contact.inverse.solve_inverse`` in double support), formula
for formula.  Compared with the reference in ``tests/test_kernel.py``.  SI units; LOCAL weld rows.
"""

from __future__ import annotations

import numpy as np

from humanoid_sim.jit import njit
from humanoid_sim.kernel.kinematics import action_matrix, frame_motion_local, log6
from humanoid_sim.kernel.linalg import cholesky_solve, mtm, mtv, mv, put, solve_dense


@njit
def contact_rows(st, tree, work, contact, anchor) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Constraint Jacobian Jc (6 n_w + 1 x nv: the LOCAL rows of each weld of frame rows ``contact.welds`` with
    anchors ``anchor.R`` (n_w, 3, 3), ``anchor.p`` (n_w, 3), then the lock row), rhs shift r = Jdot v + Kd Jc v + Kp e,
    and the largest weld position and orientation errors (m, rad) (``ConstraintRows.evaluate``: welds + one lock).
    ``st``: ``records.State``; ``tree``: ``Tree``; ``work``: ``Work`` with the frame placements filled;
    ``contact``: ``Contact``; ``anchor``: ``Anchor``."""
    J, dJ, v, q = st.J, st.dJ, st.v, st.q
    support, fparent, fR, fpos = tree.support, tree.fparent, work.fR, work.fpos
    welds, lock_q, lock_v, kp, kd = contact.welds, contact.lock_q, contact.lock_v, contact.kp, contact.kd
    anchor_R, anchor_p, lock_anchor = anchor.R, anchor.p, anchor.lock
    nv = v.size
    nw = welds.size
    m = 6 * nw + 1
    Jc = np.zeros((m, nv))
    r = np.empty(m)
    pos_err = 0.0
    ori_err = 0.0
    for w in range(nw):
        f = welds[w]
        Rf, pf = fR[f], fpos[f]
        vel, acc = frame_motion_local(J, dJ, v, support[fparent[f]], Rf, pf, Jc[6 * w:6 * w + 6])
        Ra, pa = anchor_R[w], anchor_p[w]
        e = log6(mtm(Ra, Rf), mtv(Ra, pf - pa))
        for i in range(6):
            r[6 * w + i] = kd * vel[i]
            r[6 * w + i] += acc[i]
            r[6 * w + i] += kp * e[i]
        dp = pf - pa
        pos_err = max(pos_err, np.sqrt(dp[0] * dp[0] + dp[1] * dp[1] + dp[2] * dp[2]))
        ori_err = max(ori_err, np.sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5]))
    Jc[m - 1, lock_v] = 1.0
    r[m - 1] = kd * v[lock_v]  # the lock row has no drift (its Jacobian is constant)
    r[m - 1] += kp * (q[lock_q] - lock_anchor)
    return Jc, r, pos_err, ori_err


@njit
def inverse_square(Jc, r, M, h, a_des, Rb, pb, Rf, pf, lock_v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, tau, lam) of the single-support computed torque (``contact.inverse._solve_square``): free joints take
    the desired accelerations, the weld fixes the base (J_Wb^-1 = Ad(bMf)), the lock row the locked joint."""
    nv = a_des.size
    a = a_des.copy()
    a[lock_v] = -r[6]
    Jb_inv = action_matrix(mtm(Rb, Rf), mtv(Rb, pf - pb))
    put(a, 0, mv(Jb_inv, -r[:6] - mv(Jc[:6, 6:], a[6:])))
    b = mv(M, a) + h
    lam_w = mtv(Jb_inv, b[:6])
    g = b - mtv(Jc[:6], lam_w)
    tau = np.zeros(nv)
    put(tau, 6, g[6:])
    tau[lock_v] = 0.0
    lam = np.empty(7)
    put(lam, 0, lam_w)
    lam[6] = g[lock_v]
    return a, tau, lam


@njit
def inverse_general(Jc, r, M, h, a_des, lock_v, w_tau, w_lam) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, tau, lam) of the double-support computed torque (``contact.inverse.solve_inverse``, general branch): the
    free-joint accelerations closest to the desired ones that satisfy the constraints (KKT), then the weighted
    minimum-norm [tau_act; lambda] of A x = M a + h, A = [S_act^T, J^T], weights ``w_tau`` (nv,, on the actuated
    coordinates: all but the base and the locked joint) and ``w_lam`` (m,)."""
    nv = a_des.size
    m = r.size
    K = np.zeros((nv + m, nv + m))
    rhs = np.zeros(nv + m)
    for i in range(6, nv):
        if i != lock_v:
            K[i, i] = 1.0
            rhs[i] = a_des[i]
    for k in range(m):
        for i in range(nv):
            K[i, nv + k] = Jc[k, i]
            K[nv + k, i] = Jc[k, i]
        rhs[nv + k] = -r[k]
    a = solve_dense(K, rhs)[:nv]
    b = mv(M, a) + h
    # A W^-1 A^T = sum over actuated i of e_i e_i^T / w_tau_i + J^T diag(1 / w_lam) J
    Z = np.zeros((nv, nv))
    for k in range(m):
        wk = 1.0 / w_lam[k]
        for i in range(nv):
            ci = Jc[k, i] * wk
            if ci != 0.0:
                for j in range(nv):
                    Z[i, j] += ci * Jc[k, j]
    for i in range(6, nv):
        if i != lock_v:
            Z[i, i] += 1.0 / w_tau[i]
    y = cholesky_solve(Z, b)
    tau = np.zeros(nv)
    for i in range(6, nv):
        if i != lock_v:
            tau[i] = y[i] / w_tau[i]
    lam = mv(Jc, y) / w_lam
    return a, tau, lam
