"""Compiled twin of the balance controller's QP build (numba): :func:`balance_qp` mirrors
:func:`humanoid_sim.controllers.balance.qp.qp_numpy`, :func:`balance_stage` the controller's reference path
``BalanceController._qp_reference`` (task rows, the phase's weld and lock rows, the heel / toe box split),
:func:`balance_finish` its ``_finish`` (joint torques, thesis torques, the stage log).  Same formulas, sums in
loop order; ``tests/test_balance_compiled.py`` runs both paths on every call of walks on welds and on MuJoCo.

Arguments come grouped (:mod:`humanoid_sim.kernel.records` and :class:`.qp.BalanceTables`); the call's references are
one float vector with the named layout of :mod:`humanoid_sim.controllers.balance.targets`.  The entry points
(:func:`balance_stage`, :func:`balance_finish`) receive the records as plain tuples (``humanoid_sim.jit.entry``:
numba types those three times faster) and rebuild them on their first lines.  SI units.
"""

from __future__ import annotations

import math

import numpy as np

from humanoid_sim.controllers.balance.qp import BalanceTables
from humanoid_sim.controllers.balance.targets import (
    T_HEEL_ANGLE,
    T_HIP_A,
    T_HIP_P,
    T_HIP_R,
    T_HIP_V,
    T_LIFT0,
    T_RETURN_TIME,
    T_RETURN_X,
    T_SWING_A,
    T_SWING_P,
    T_SWING_R,
    T_SWING_V,
)
from humanoid_sim.jit import entry, njit
from humanoid_sim.kernel.actuators import thesis_torques
from humanoid_sim.kernel.contact import contact_rows
from humanoid_sim.kernel.kinematics import F_O17, F_PC17, log3, tree_state
from humanoid_sim.kernel.linalg import cross, mm, mtm, mtv, mv, symmetric
from humanoid_sim.kernel.log import LOG_ORI_ERR, LOG_POS_ERR, LOG_RESIDUAL, LOG_SIZE, log_frames
from humanoid_sim.kernel.records import ActuatorTables, Anchor, Contact, Coords, State, Tree, Work


@njit
def balance_qp(A, w, b, M_upper, h, J, rhs_shift, nw, box_kind, split, tables, unload):
    """The QP of ``BalanceController`` from its task rows and the phase's constraint rows: the compiled twin of
    :func:`humanoid_sim.controllers.balance.qp.qp_numpy` (same formulas; sums in loop order).

    Inputs: task rows A (r, nv), weights w (r,), targets b (r,); M_upper (crba's upper triangle), h (nv,); the
    constraint rows J (m, nv) with ``rhs_shift`` (m,), of which the first ``nw`` are weld rows (6 per weld) and the rest
    toe locks; per weld ``box_kind`` (0: a flat foot, heel box on the weld and toe box on split variables; 1: a toe
    box alone; 2: the whole sole) and the extra weight ``unload`` on its normal force; per split foot j its weld
    ``split_weld[j]``, its lock row ``split_lock[j]`` in lam, X[j] (6, 6) and jt[j] (6,) (``split`` = (split_weld,
    split_lock, X, jt)); from ``tables`` (:class:`.qp.BalanceTables`) the box rows (11, 6) ``heel`` and ``toe``
    (kind 0), ``trail`` (kind 1), ``main`` (kind 2) and the regularisation weights.
    x = [a (nv); lam (m); W_t (6 per split)].

    Returns G, g (min 1/2 x'Gx - g'x), C, lo (the first ``ne`` rows of C the equalities C x = lo, the others the
    inequalities C x >= lo = 0: stacked as DAQP takes them), ne, cop (the inequality rows' CoP flags), M (nv, nv)
    symmetric and Tx (nv - 6, n) with tau[6:] = Tx x + h[6:]."""
    split_weld, split_lock, X, jt = split
    heel, toe, main, trail = tables.heel, tables.toe, tables.main, tables.trail
    w_acc, w_force, w_torque = tables.w_acc, tables.w_force, tables.w_torque
    nv = M_upper.shape[0]
    m = J.shape[0]
    ns = split_weld.size
    n = nv + m + 6 * ns
    r = A.shape[0]
    M = symmetric(M_upper)
    G = np.zeros((n, n))
    g = np.zeros(n)
    # G = A^T W A (first nv rows / columns) + w_torque Tx^T Tx, g = A^T W b - w_torque Tx^T h[6:] (BLAS products)
    WA = np.empty((r, nv))
    Wb = np.empty(r)
    for k in range(r):
        for j in range(nv):
            WA[k, j] = A[k, j] * w[k]
        Wb[k] = w[k] * b[k]
    G[:nv, :nv] = np.dot(A.T, WA)
    g[:nv] = np.dot(A.T, Wb)
    Tx = np.zeros((nv - 6, n))          # tau[6:] = Tx x + h[6:]: Tx = [M[6:] | -J[:, 6:]^T | 0]
    for k in range(nv - 6):
        for j in range(nv):
            Tx[k, j] = M[6 + k, j]
        for j in range(m):
            Tx[k, nv + j] = -J[j, 6 + k]
    kk = nv + m
    Tk = np.ascontiguousarray(Tx[:, :kk])
    G[:kk, :kk] += w_torque * np.dot(Tk.T, Tk)
    hj = np.ascontiguousarray(h[6:])
    g[:kk] -= w_torque * np.dot(Tk.T, hj)
    for i in range(nv):
        G[i, i] += w_acc
    for i in range(nv, n):
        G[i, i] += w_force
    for i in range(box_kind.size):
        G[nv + 6 * i + 2, nv + 6 * i + 2] += unload[i]
    # equalities: the base rows of M a + h - J^T lam = 0; lam_lock = j_toe . W_t; J a = -gamma
    n_lock = m - nw
    ne = 6 + n_lock + m
    nb = heel.shape[0]
    n_box = box_kind.size + ns
    C = np.zeros((ne + nb * n_box, n))     # equalities, then inequalities (11 rows a box)
    lo = np.zeros(ne + nb * n_box)
    Ceq = C[:ne]
    beq = lo[:ne]
    Cin = C[ne:]
    for i in range(6):
        for j in range(nv):
            Ceq[i, j] = M[i, j]
        for j in range(m):
            Ceq[i, nv + j] = -J[j, i]
        beq[i] = -h[i]
    for j in range(n_lock):
        Ceq[6 + j, nv + nw + j] = 1.0
    for s in range(ns):
        row = 6 + split_lock[s] - nw
        for c in range(6):
            Ceq[row, nv + m + 6 * s + c] = -jt[s, c]
    for i in range(m):
        for j in range(nv):
            Ceq[6 + n_lock + i, j] = J[i, j]
        beq[6 + n_lock + i] = -rhs_shift[i]
    # inequalities: 11 rows a box (7 force rows, 4 CoP rows)
    cop = np.zeros(nb * n_box, dtype=np.bool_)
    row = 0
    for i in range(box_kind.size):
        cw = nv + 6 * i
        if box_kind[i] == 0:
            s = 0
            while split_weld[s] != i:
                s += 1
            ct = nv + m + 6 * s
            for a in range(nb):
                for c in range(6):
                    Cin[row + a, cw + c] = heel[a, c]
                    acc = 0.0
                    for e in range(6):
                        acc += heel[a, e] * X[s, e, c]
                    Cin[row + a, ct + c] = -acc
                    Cin[row + nb + a, ct + c] = toe[a, c]
            for a in range(7, nb):
                cop[row + a] = True
                cop[row + nb + a] = True
            row += 2 * nb
        else:
            box = trail if box_kind[i] == 1 else main
            for a in range(nb):
                for c in range(6):
                    Cin[row + a, cw + c] = box[a, c]
            for a in range(7, nb):
                cop[row + a] = True
            row += nb
    return G, g, C, lo, ne, cop, M, Tx


@njit
def _rot_y_into(ang: float, out: np.ndarray) -> None:
    """Rotation by ``ang`` (rad) about the local y axis into out (3, 3) (``controllers.balance.qp.rot_y``)."""
    c, s = math.cos(ang), math.sin(ang)
    out[0, 0], out[0, 1], out[0, 2] = c, 0.0, s
    out[1, 0], out[1, 1], out[1, 2] = 0.0, 1.0, 0.0
    out[2, 0], out[2, 1], out[2, 2] = -s, 0.0, c


@njit
def _task_row(A, b, w, row, motion, vel, f, lin, des, kp, kd, err, v_ref, wt) -> None:
    """Three task rows from frame f's LOCAL_WORLD_ALIGNED [J | drift] ``motion[f]`` and velocity ``vel[f]``: the
    linear (lin True) or angular rows, target des + kp err + kd (v_ref - velocity) minus the drift."""
    nv = motion.shape[2] - 1
    o = 0 if lin else 3
    for k in range(3):
        for c in range(nv):
            A[row + k, c] = motion[f, o + k, c]
        b[row + k] = des[k] + kp * err[k] + kd * (v_ref[k] - vel[f, o + k]) - motion[f, o + k, nv]
        w[row + k] = wt


@entry
def balance_stage(st, tree, co, work, contact, anchor, task, tables, feet, unload):
    """The balance controller's QP at (q, v): the compiled twin of ``BalanceController._qp_reference`` (task rows,
    the phase's weld and lock rows, the heel / toe box split, the QP of :func:`balance_qp`).  ``st``
    (``records.State``): the state with Pinocchio's computeJointJacobiansTimeVariation, crba and nonLinearEffects at
    it; ``tree``, ``co``, ``work`` as :func:`tree_state`; ``contact``, ``anchor`` as :func:`contact_rows`.

    ``task`` = (mode, fi, fneed, tgt): ``mode`` 0 no foot task, 1 swing (fi = [toe point, toe body, main body] frame
    rows), 2 double support's trailing heel (fi = [toe body, main body]); ``fneed`` the frames whose [J | drift] the
    call reads; ``tgt`` the target vector (layout :mod:`humanoid_sim.controllers.balance.targets`; lift0 < 0: measure
    it now from the foot's pose).  ``tables``: :class:`.qp.BalanceTables` (``gains``: kp, kd, weight of the hip, trunk,
    swing tasks, then kp, kd of the posture).  ``feet`` = (box_kind, split_toe): per weld its box kind (see
    :func:`balance_qp`) and the toe-body frame row of a flat foot (box_kind 0), else -1.  ``unload``: per weld.

    Returns (G, g, C, lo, ne, cop, M, Tx, Jc, X, lift0, pos_err, ori_err) (:func:`balance_qp`; Jc the constraint rows,
    X (n_split, 6, 6), lift0 the heel lift used, rad; the largest weld errors, m and rad)."""
    st, tree, co, work = State(*st), Tree(*tree), Coords(*co), Work(*work)
    contact, anchor, tables = Contact(*contact), Anchor(*anchor), BalanceTables(*tables)
    mode, fi, fneed, tgt = task
    box_kind, split_toe = feet
    v, J, M_upper, h = st.v, st.J, st.M_upper, st.h
    jcols, jsign = co.jcols, co.jsign
    fR, fpos, motion, vel = work.fR, work.fpos, work.motion, work.vel
    welds, lock_v = contact.welds, contact.lock_v
    gains, w_joint, heel_lift_rad = tables.gains, tables.w_joint, tables.heel_lift_rad
    nv = v.size
    th, thd = tree_state(st, tree, co, fneed, work)
    Jc, r, pos_err, ori_err = contact_rows(st, tree, work, contact, anchor)
    n_task = 6 + (9 if mode == 1 else 3 if mode == 2 else 0)
    nr = n_task + 26
    A = np.zeros((nr, nv))
    b = np.empty(nr)
    w = np.empty(nr)
    err = np.empty(3)
    # Body-17 CoM and orientation
    for k in range(3):
        err[k] = tgt[T_HIP_P + k] - fpos[F_PC17, k]
    _task_row(A, b, w, 0, motion, vel, F_PC17, True, tgt[T_HIP_A:T_HIP_A + 3], gains[0], gains[1], err,
              tgt[T_HIP_V:T_HIP_V + 3], gains[2])
    Rref = np.empty((3, 3))
    for i in range(3):
        for k in range(3):
            Rref[i, k] = tgt[T_HIP_R + 3 * i + k]
    err = log3(mm(Rref, fR[F_O17].T))
    _task_row(A, b, w, 3, motion, vel, F_O17, False, tgt[T_HIP_A + 3:T_HIP_A + 6], gains[3], gains[4], err,
              tgt[T_HIP_V + 3:T_HIP_V + 6], gains[5])
    lift0 = 0.0
    if mode == 1:
        fpt, ftoe, fmain = fi[0], fi[1], fi[2]
        kp, kd, ws = gains[6], gains[7], gains[8]
        for k in range(3):
            err[k] = tgt[T_SWING_P + k] - fpos[fpt, k]
        _task_row(A, b, w, 6, motion, vel, fpt, True, tgt[T_SWING_A:T_SWING_A + 3], kp, kd, err,
                  tgt[T_SWING_V:T_SWING_V + 3], ws)
        Rr = np.empty((3, 3))
        for i in range(3):
            for k in range(3):
                Rr[i, k] = tgt[T_SWING_R + 3 * i + k]
        _task_row(A, b, w, 9, motion, vel, ftoe, False, tgt[T_SWING_A + 3:T_SWING_A + 6], kp, kd,
                  log3(mm(Rr, fR[ftoe].T)), tgt[T_SWING_V + 3:T_SWING_V + 6], ws)
        xr, t_ret, lift0 = tgt[T_RETURN_X], tgt[T_RETURN_TIME], tgt[T_LIFT0]
        if lift0 < 0.0:   # the heel lift the foot left the ground with (main body pitched about the toe body's y)
            Rrel = mtm(fR[ftoe], fR[fmain])
            lift0 = min(max(math.atan2(Rrel[0, 2], Rrel[0, 0]), 0.0), heel_lift_rad)
        Rm = Rr.copy()
        wm = np.empty(3)
        am = np.empty(3)
        for k in range(3):
            wm[k] = tgt[T_SWING_V + 3 + k]
            am[k] = tgt[T_SWING_A + 3 + k]
        if xr < 1.0 and lift0 > 0.0:
            ang = lift0 * (1.0 - xr * xr * (3.0 - 2.0 * xr))
            dang = -lift0 * 6.0 * xr * (1.0 - xr) / t_ret
            ddang = -lift0 * 6.0 * (1.0 - 2.0 * xr) / t_ret ** 2
            Ry = np.empty((3, 3))
            _rot_y_into(ang, Ry)
            Rm = mm(Rr, Ry)
            for k in range(3):
                wm[k] = wm[k] + dang * Rr[k, 1]
                am[k] = am[k] + ddang * Rr[k, 1]
        _task_row(A, b, w, 12, motion, vel, fmain, False, am, kp, kd, log3(mm(Rm, fR[fmain].T)), wm, ws)
    elif mode == 2:
        ftoe, fmain = fi[0], fi[1]
        Ry = np.empty((3, 3))
        _rot_y_into(tgt[T_HEEL_ANGLE], Ry)
        zero = np.zeros(3)
        _task_row(A, b, w, 6, motion, vel, fmain, False, zero, gains[6], gains[7],
                  log3(mm(mm(fR[ftoe], Ry), fR[fmain].T)), zero, gains[8])
    # posture: the thesis joint angles toward the initial ones (theta_dot = Jpost v)
    kp, kd = gains[9], gains[10]
    for i in range(26):
        A[n_task + i, jcols[i]] = jsign[i]
        b[n_task + i] = -kp * th[i] - kd * thd[i]
        w[n_task + i] = w_joint[i]
    # each flat foot's toe box: X (a toe-frame wrench as a main-frame wrench) and the toe joint's LOCAL column
    ns = 0
    for i in range(box_kind.size):
        if box_kind[i] == 0:
            ns += 1
    split_weld = np.empty(ns, dtype=np.int64)
    split_lock = np.empty(ns, dtype=np.int64)
    X = np.zeros((ns, 6, 6))
    jt = np.empty((ns, 6))
    s = 0
    nw = 6 * welds.size
    for i in range(box_kind.size):
        if box_kind[i] != 0:
            continue
        fm, ft = welds[i], split_toe[i]
        Rrel = mtm(fR[fm], fR[ft])
        prel = mtv(fR[fm], fpos[ft] - fpos[fm])
        for a in range(3):
            for c in range(3):
                X[s, a, c] = Rrel[a, c]
                X[s, 3 + a, 3 + c] = Rrel[a, c]
        sk = np.zeros((3, 3))
        sk[0, 1], sk[0, 2], sk[1, 0], sk[1, 2], sk[2, 0], sk[2, 1] = -prel[2], prel[1], prel[2], -prel[0], -prel[1], \
            prel[0]
        X[s, 3:, :3] = mm(sk, Rrel)
        c = lock_v
        pos = fpos[ft]
        ang = np.empty(3)
        for k in range(3):
            ang[k] = J[3 + k, c]
        lin = J[:3, c] + cross(ang, pos)             # the toe joint's column at the toe frame's origin
        jl = mtv(fR[ft], lin)
        ja = mtv(fR[ft], ang)
        for k in range(3):
            jt[s, k] = jl[k]
            jt[s, 3 + k] = ja[k]
        split_weld[s] = i
        split_lock[s] = nw           # the phase's one lock row follows the weld rows
        s += 1
    G, g, C, lo, ne, cop, M, Tx = balance_qp(A, w, b, M_upper, h, Jc, r, nw, box_kind, (split_weld, split_lock, X, jt),
                                             tables, unload)
    return G, g, C, lo, ne, cop, M, Tx, Jc, X, lift0, pos_err, ori_err


@entry
def balance_finish(x, M, Jc, st, work, tree, co, act, pos_err, ori_err, bounded, bounds):
    """(a, lam, tau, T, log, theta_ddot, over, inside) of the balance controller's QP solution x = [a; lam; ...]: tau
    = M a + h - Jc^T lam with the base rows zeroed, T the thesis actuator torques (:func:`thesis_torques`), the stage
    log the weld engine records (layout :mod:`humanoid_sim.kernel.log`: weld errors, dynamics residual, task
    frames), the thesis joint accelerations (jsign * a[jcols]), whether a bounded component T[bounded[i]] exceeds
    bounds[i] in magnitude, and whether every |T[i]| <= act.limits[i] (``Actuators.saturate``'s test: False for a
    NaN).  ``st``: the state :func:`balance_stage` ran at; ``work``: what it left in its buffers; pos_err, ori_err:
    what it returned."""
    st, work, tree, co, act = State(*st), Work(*work), Tree(*tree), Coords(*co), ActuatorTables(*act)
    J, dJ, v, h = st.J, st.dJ, st.v, st.h
    R, p, fR, fpos, vel = work.R, work.p, work.fR, work.fpos, work.vel
    jcols, jsign, limits = co.jcols, co.jsign, act.limits
    nv = v.size
    m = Jc.shape[0]
    a = np.empty(nv)
    lam = np.empty(m)
    for i in range(nv):
        a[i] = x[i]
    for i in range(m):
        lam[i] = x[nv + i]
    tau = mv(M, a) + h - mtv(Jc, lam)
    for i in range(6):
        tau[i] = 0.0
    T = thesis_torques(J, dJ, v, a, tau, R, p, tree.support, act)
    log = np.zeros(LOG_SIZE)
    res = mv(M, a) + h - tau - mtv(Jc, lam)
    log[LOG_POS_ERR], log[LOG_ORI_ERR], log[LOG_RESIDUAL] = pos_err, ori_err, np.max(np.abs(res))
    log_frames(log, fR, fpos, vel)
    thdd = np.empty(jcols.size)
    for i in range(jcols.size):
        thdd[i] = jsign[i] * a[jcols[i]]
    over = False
    for i in range(bounded.size):
        if abs(T[bounded[i]]) > bounds[i]:
            over = True
    inside = True
    for i in range(limits.size):
        if not abs(T[i]) <= limits[i]:
            inside = False
    return a, lam, tau, T, log, thdd, over, inside
