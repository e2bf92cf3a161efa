"""Compiled twin of the thesis controller's weld-model stage (numba): :mod:`humanoid_sim.controllers.thesis.command`
(``CommandAccelerations.compute``: cost rows, normal equations, thesis 5.1) followed by the computed torque of
:mod:`humanoid_sim.dynamics.contact` (5.2), the actuator torques (eq. 4.69) and the stage log, all four phases, in
one call per stage.  Each function names the reference function it mirrors, formula for formula; the Python side
is :class:`humanoid_sim.controllers.thesis.stage.StageKernel`.  ``tests/test_kernel.py`` compares every output
with the reference path at many states of real walks, and whole walks.

The compiled functions called from Python write into arrays the caller allocated and return nothing: returning
arrays would make numba call back into Python (to unpickle their dtype) in the middle of native code, where a
Ctrl-C then surfaces as a SystemError instead of a KeyboardInterrupt.

Arguments come grouped (:mod:`humanoid_sim.kernel.records`): the state and Pinocchio's terms at it
(:class:`~humanoid_sim.kernel.records.State`), the tree's constant tables (``Tree``), the thesis joint coordinates
(``Coords``), the phase's controller tables (:class:`SspTables` / :class:`DspTables`), the work buffers (``Work``),
the phase's contact rows and anchors (``Contact``, ``Anchor``), the actuator tables (``ActuatorTables``) and the
outputs (``StageBuffers``).  The entry points (:func:`ssp_stage`, :func:`dsp_stage`, and the two halves of the
first, :func:`ssp_controller` and :func:`ssp_dynamics`) receive them as plain tuples (``humanoid_sim.jit.entry``:
numba types those three times faster) and rebuild the records on their first lines.  SI units throughout.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from humanoid_sim.jit import entry, njit
from humanoid_sim.kernel.actuators import thesis_torques
from humanoid_sim.kernel.contact import contact_rows, inverse_general, inverse_square
from humanoid_sim.kernel.kinematics import F_O17, F_PC17, tree_state
from humanoid_sim.kernel.linalg import (
    cholesky_solve,
    cols_times,
    mm,
    mtm,
    mtv,
    mv,
    put,
    put_block,
    put_col,
    solve_dense,
    symmetric,
)
from humanoid_sim.kernel.log import LOG_ORI_ERR, LOG_POS_ERR, LOG_RESIDUAL, LOG_STATUS, log_frames
from humanoid_sim.kernel.records import ActuatorTables, Anchor, Contact, Coords, StageBuffers, State, Tree, Work
from humanoid_sim.references.chapter3.compiled import dsp_references, ssp_references


class SspTables(NamedTuple):
    """A single-support phase's constant controller tables (``CommandAccelerations._problems`` and the params):
    frame rows (int) of the root weld, the swing toe point, the swing weld; joint slots (theta order) of the stance
    and swing toes; ``k_toe`` the swing toe's slot in ``xo``; ``xs`` / ``xo`` the stance / swing chains' theta slots,
    ``qu`` the upper body's (10); the prediction times dt_a, dt_b (s) and step weights ha, hb; the swing toe's
    posture terms s_p, w_p, s_v, w_v and its offset theta0_toe (rad); the row weights (12 each), the
    regularisations dZ and joint weights W_q per chain; the upper-body numbers ``up`` (Wp, Wv, dt, den, dt^2, dt^3,
    10 each); ``need``: the frames whose [J | drift] the phase reads (bool, per frame row)."""

    root: int
    toe_pt: int
    other_weld: int
    stance_toe: int
    other_toe: int
    k_toe: int
    xs: np.ndarray
    xo: np.ndarray
    qu: np.ndarray
    dta: float
    dtb: float
    ha: float
    hb: float
    s_p: float
    w_p: float
    s_v: float
    w_v: float
    theta0_toe: float
    wa_rows: np.ndarray
    wb_rows: np.ndarray
    dZ_a: np.ndarray
    dZ_b: np.ndarray
    Wq_a: np.ndarray
    Wq_b: np.ndarray
    up: np.ndarray
    need: np.ndarray


class DspTables(NamedTuple):
    """A double-support phase's constant controller tables: frame rows of the root and the other weld, the stance
    toe's theta slot, the chain sizes n_s and n_o, ``x`` = [stance chain; trailing chain] theta slots, ``qu`` the
    upper body's; dt (s), ha, the 24 row weights, dZ and W_q (n each), ``up`` and ``need`` as :class:`SspTables`."""

    root: int
    other_weld: int
    stance_toe: int
    ns: int
    no: int
    x: np.ndarray
    qu: np.ndarray
    dt: float
    ha: float
    w_rows: np.ndarray
    dZ: np.ndarray
    W_q: np.ndarray
    up: np.ndarray
    need: np.ndarray


@njit
def _body_task(motion: np.ndarray, vel: np.ndarray, fpos: np.ndarray, fparent: np.ndarray, point: int, body: int,
               weld: int, jcols: np.ndarray, jsign: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(J (6 x 26), drift (6,), velocity (6,)) of [linear motion of frame ``point``; angular motion of frame
    ``body``] in thesis joint space, the base eliminated through the weld of frame ``weld``."""
    nv = motion.shape[2] - 1
    W = motion[weld]
    T = motion[point].copy()
    v6 = vel[point].copy()
    if fparent[point] != fparent[body]:
        put_block(T, 3, 0, motion[body][3:])
        put(v6, 3, vel[body][3:])
    D = T - W
    d = fpos[weld] - fpos[point]  # S = [d]x: S x = d x x
    for c in range(nv + 1):
        wx, wy, wz = W[3, c], W[4, c], W[5, c]
        D[0, c] -= d[1] * wz - d[2] * wy
        D[1, c] -= d[2] * wx - d[0] * wz
        D[2, c] -= d[0] * wy - d[1] * wx
    J = np.empty((6, jcols.size))
    for i in range(jcols.size):
        put_col(J, 0, i, D[:, jcols[i]] * jsign[i])
    return J, D[:, nv].copy(), v6


@njit
def _tracking_rows(A: np.ndarray, r: np.ndarray, J6: np.ndarray, drift6: np.ndarray, p: np.ndarray,
                   v6: np.ndarray, R: np.ndarray, ref_p: np.ndarray, ref_v: np.ndarray, ref_R: np.ndarray,
                   dt: float) -> None:
    """The 12 rows (position 3, velocity 6, C_diag orientation 3) of one task body (eqs. 5.1-5.3, errata C-1)."""
    h2 = 0.5 * dt * dt
    put_block(A, 0, 0, J6[:3] * h2)
    put(r, 0, ref_p - (p + v6[:3] * dt + drift6[:3] * h2))
    put_block(A, 3, 0, J6 * dt)
    put(r, 3, ref_v - (v6 + drift6 * dt))
    w = v6[3:]
    L = np.zeros((3, 3))  # d/dt C_diag = L w (taskspace.cdiag_rate_matrix)
    L[0, 1], L[0, 2] = R[2, 0], -R[1, 0]
    L[1, 0], L[1, 2] = -R[2, 1], R[0, 1]
    L[2, 0], L[2, 1] = R[1, 2], -R[0, 2]
    diag = np.empty(3)
    for i in range(3):
        diag[i] = R[i, i]
    bias = w * mtv(R, w) - (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * diag  # diag([w]x [w]x C)
    put_block(A, 9, 0, mm(L, J6[3:]) * h2)
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
                ref_b_v, ref_b_R, tables) -> np.ndarray:
    """Command accelerations theta_ddot_c (26,) of a single-support phase (``CommandAccelerations.compute``, SSP
    branch); ``tables``: :class:`SspTables`."""
    root, toe_pt, other_weld, stance_toe, other_toe, k_toe = (tables.root, tables.toe_pt, tables.other_weld,
                                                              tables.stance_toe, tables.other_toe, tables.k_toe)
    xs, xo, qu = tables.xs, tables.xo, tables.qu
    ns, no = xs.size, xo.size
    dta, dtb, ha, hb = tables.dta, tables.dtb, tables.ha, tables.hb
    s_p, w_p, s_v, w_v, theta0_toe = tables.s_p, tables.w_p, tables.s_v, tables.w_v, tables.theta0_toe
    wa_rows, wb_rows = tables.wa_rows, tables.wb_rows
    dZ_a, dZ_b, Wq_a, Wq_b = tables.dZ_a, tables.dZ_b, tables.Wq_a, tables.Wq_b
    qdd = np.zeros(26)
    # step 1: stance-leg joints for Body 17 and its CoM (5.1.1.1.1)
    J, drift, v6 = _body_task(motion, vel, fpos, fparent, F_PC17, F_O17, root, jcols, jsign)
    Aa = np.zeros((12, ns))
    ra = np.zeros(12)
    Js = np.empty((6, ns))
    for i in range(ns):
        put_col(Js, 0, i, J[:, xs[i]])
    _tracking_rows(Aa, ra, Js, drift, fpos[F_PC17], v6, fR[F_O17], ref_a_p, ref_a_v, ref_a_R, dta)
    dg = np.empty(ns)
    for i in range(ns):
        dg[i] = Wq_a[i] * ha * -(th[xs[i]] + thd[xs[i]] * dta)
    Z, g = _normal(Aa, ra, wa_rows, dZ_a, dg)
    qdd_s = cholesky_solve(Z, g)
    for i in range(ns):
        qdd[xs[i]] = qdd_s[i]
    # step 2: swing-leg joints for the swing toe point and toe body, given step 1 (5.1.1.1.2)
    J, drift, v6 = _body_task(motion, vel, fpos, fparent, toe_pt, other_weld, root, jcols, jsign)
    drift = drift + cols_times(J, xs, qdd_s)
    Ab = np.zeros((12, no))
    rb = np.zeros(12)
    Jo = np.empty((6, no))
    for i in range(no):
        put_col(Jo, 0, i, J[:, xo[i]])
    _tracking_rows(Ab, rb, Jo, drift, fpos[toe_pt], v6, fR[other_weld], ref_b_p, ref_b_v, ref_b_R, dtb)
    dg = np.empty(no)
    for i in range(no):
        dg[i] = Wq_b[i] * hb * -(th[xo[i]] + thd[xo[i]] * dtb)
    th_toe = th[other_toe] + theta0_toe
    dg[k_toe] += (w_p * s_p * -(th_toe + thd[other_toe] * s_v)) + (w_v * s_v * -thd[other_toe])
    Z, g = _normal(Ab, rb, wb_rows, dZ_b, dg)
    qdd_o = cholesky_solve(Z, g)
    for i in range(no):
        qdd[xo[i]] = qdd_o[i]
    qdd[stance_toe] = 0.0
    _upper_body(qdd, th, thd, qu, tables.up)
    return qdd


@njit
def _upper_body(qdd: np.ndarray, th: np.ndarray, thd: np.ndarray, qu: np.ndarray, up: np.ndarray) -> None:
    """Eq. 5.90 per upper-body joint (``CommandAccelerations.upper``) into qdd[qu]; ``up`` = Wp, Wv, dt, den, dt^2,
    dt^3 (10 each)."""
    for i in range(10):
        k = qu[i]
        num = up[i] * th[k] * up[40 + i] / 2 + up[i] * thd[k] * up[50 + i] / 2 + up[10 + i] * thd[k] * up[20 + i]
        qdd[k] = -num / up[30 + i]


@njit
def _controller_dsp(motion, vel, fpos, fR, fparent, th, thd, jcols, jsign, ref_p, ref_v, ref_R, tables
                    ) -> np.ndarray:
    """Command accelerations theta_ddot_c (26,) of a double-support phase (``CommandAccelerations.compute``, DSP
    branch, thesis 5.1.1.3): both chains to Body 17 in one cost over x = [stance chain; trailing chain], the closed
    chain (eq. 5.59: the trailing toe body's acceleration through the stance chain is zero) by Lagrange multipliers
    (eqs. 5.62/5.63); ``tables``: :class:`DspTables`."""
    root, other_weld, stance_toe, ns, no = tables.root, tables.other_weld, tables.stance_toe, tables.ns, tables.no
    n = ns + no
    x, qu = tables.x, tables.qu
    dt, ha = tables.dt, tables.ha
    w_rows, dZ, W_q = tables.w_rows, tables.dZ, tables.W_q
    A = np.zeros((24, n))
    r = np.zeros(24)
    Ja, da, va = _body_task(motion, vel, fpos, fparent, F_PC17, F_O17, root, jcols, jsign)
    Js = np.empty((6, ns))
    for i in range(ns):
        put_col(Js, 0, i, Ja[:, x[i]])
    ra = np.zeros(12)
    Aa = np.zeros((12, ns))
    _tracking_rows(Aa, ra, Js, da, fpos[F_PC17], va, fR[F_O17], ref_p, ref_v, ref_R, dt)
    Jb, db, vb = _body_task(motion, vel, fpos, fparent, F_PC17, F_O17, other_weld, jcols, jsign)
    Jo = np.empty((6, no))
    for i in range(no):
        put_col(Jo, 0, i, Jb[:, x[ns + i]])
    rb = np.zeros(12)
    Ab = np.zeros((12, no))
    _tracking_rows(Ab, rb, Jo, db, fpos[F_PC17], vb, fR[F_O17], ref_p, ref_v, ref_R, dt)
    put_block(A, 0, 0, Aa)
    put_block(A, 12, ns, Ab)
    put(r, 0, ra)
    put(r, 12, rb)
    dg = np.empty(n)
    for i in range(n):
        dg[i] = W_q[i] * ha * -(th[x[i]] + thd[x[i]] * dt)
    Z, g = _normal(A, r, w_rows, dZ, dg)
    Jc, dc, _ = _body_task(motion, vel, fpos, fparent, other_weld, other_weld, root, jcols, jsign)
    K = np.zeros((n + 6, n + 6))
    rhs = np.zeros(n + 6)
    put_block(K, 0, 0, Z)
    for i in range(n):
        for c in range(6):
            K[i, n + c] = Jc[c, x[i]]
            K[n + c, i] = Jc[c, x[i]]
    put(rhs, 0, g)
    put(rhs, n, -dc)
    sol = solve_dense(K, rhs)
    qdd = np.zeros(26)
    for i in range(n):
        qdd[x[i]] = sol[i]
    qdd[stance_toe] = 0.0
    _upper_body(qdd, th, thd, qu, tables.up)
    return qdd


@njit
def _a_desired(qdd: np.ndarray, jcols: np.ndarray, jsign: np.ndarray, nv: int) -> np.ndarray:
    """Generalized accelerations (nv,) of the thesis command accelerations (``HumanoidModel.v_from_theta_dot``)."""
    a = np.zeros(nv)
    for i in range(jcols.size):
        a[jcols[i]] = jsign[i] * qdd[i]
    return a


@njit
def _finish(st, M, Jc, a, tau, lam, pos_err, ori_err, work, support, act, out) -> None:
    """The thesis torques T, the saturation flag, the dynamics residual and the logged quantities of a stage, with
    the outputs a, lam, T, tau copied into ``out`` (a ``records.StageBuffers``; ``out.qdd`` already written)."""
    J, dJ, v, h, qdd = st.J, st.dJ, st.v, st.h, out.qdd
    R, p, fR, fpos, vel = work.R, work.p, work.fR, work.fpos, work.vel
    limits, log = act.limits, out.log
    T = thesis_torques(J, dJ, v, a, tau, R, p, support, act)
    log[:] = 0.0
    for i in range(26):
        if T[i] > limits[i] or T[i] < -limits[i] or not np.isfinite(T[i]):
            log[LOG_STATUS] = 1.0
    if not (np.isfinite(qdd).all() and np.isfinite(a).all() and np.isfinite(tau).all()):
        log[LOG_STATUS] = -1.0  # a normal matrix or KKT system was singular: the reference path reports it
    res = mv(M, a) + h - tau - mtv(Jc, lam)
    log[LOG_POS_ERR], log[LOG_ORI_ERR], log[LOG_RESIDUAL] = pos_err, ori_err, np.max(np.abs(res))
    log_frames(log, fR, fpos, vel)
    put(out.a, 0, a)
    put(out.lam, 0, lam)
    put(out.T, 0, T)
    put(out.tau, 0, tau)


@entry
def ssp_controller(st, tab, t, tree, co, tables, work, qdd_out):
    """Command accelerations theta_ddot_c (26,) of a single-support stage, written into ``qdd_out``.

    Inputs: ``st`` (``records.State``) the state (q, v) at time t (s) with Pinocchio's WORLD joint Jacobians J, dJ
    at it; the phase's reference table ``tab`` (``ReferenceTrajectory.ssp_table``, queried at t + the two prediction
    times); ``tree`` (``Tree``), ``co`` (``Coords``), ``tables`` (:class:`SspTables`).  ``work`` (``Work``) is filled
    for :func:`ssp_dynamics`: joint placements R, p, frame placements fR, fpos, and for the frames flagged in
    ``tables.need`` (the ones this phase's tasks read) the frame [J | drift] ``motion`` and velocities ``vel``
    (LOCAL_WORLD_ALIGNED)."""
    st, tree, co, tables, work = State(*st), Tree(*tree), Coords(*co), SspTables(*tables), Work(*work)
    th, thd = tree_state(st, tree, co, tables.need, work)
    ref_a_p, ref_a_v, ref_a_R = np.empty(3), np.empty(6), np.empty((3, 3))
    ref_b_p, ref_b_v, ref_b_R = np.empty(3), np.empty(6), np.empty((3, 3))
    ssp_references(tab, t + tables.dta, t + tables.dtb, ref_a_p, ref_a_v, ref_a_R, ref_b_p, ref_b_v, ref_b_R)
    put(qdd_out, 0, _controller(work.motion, work.vel, work.fpos, work.fR, tree.fparent, th, thd, co.jcols, co.jsign,
                                ref_a_p, ref_a_v, ref_a_R, ref_b_p, ref_b_v, ref_b_R, tables))


@entry
def ssp_dynamics(st, anchor, tree, co, work, contact, act, out):
    """Computed torque of a single-support stage for the command accelerations ``out.qdd``, written into ``out``
    (a (nv,), lam (7,), T (26,, T_cmd), tau (nv,), log (LOG_SIZE,, zeroed here)).  ``st``: the state with crba's
    upper triangle and nonLinearEffects; ``contact.welds``: the support foot's weld frame row (one); ``work`` as
    :func:`ssp_controller` left it."""
    st, anchor, tree, co, work = State(*st), Anchor(*anchor), Tree(*tree), Coords(*co), Work(*work)
    contact, act, out = Contact(*contact), ActuatorTables(*act), StageBuffers(*out)
    qdd, v, M_upper, h = out.qdd, st.v, st.M_upper, st.h
    R, p, fR, fpos = work.R, work.p, work.fR, work.fpos
    M = symmetric(M_upper)
    a_des = _a_desired(qdd, co.jcols, co.jsign, v.size)
    Jc, r, pos_err, ori_err = contact_rows(st, tree, work, contact, anchor)
    w = contact.welds[0]
    a, tau, lam = inverse_square(Jc, r, M, h, a_des, R[1], p[1], fR[w], fpos[w], contact.lock_v)
    _finish(st, M, Jc, a, tau, lam, pos_err, ori_err, work, tree.support, act, out)


@entry
def ssp_stage(st, tab, t, anchor, tree, co, tables, work, contact, act, out) -> None:
    """:func:`ssp_controller` then :func:`ssp_dynamics` in one call (the simulator's hot path; the two halves stay
    separate functions so that a profile can time them apart).  The records go on as the plain tuples they came
    as, so that each half is the one compilation Python's calls of it use."""
    ssp_controller(st, tab, t, tree, co, tables, work, StageBuffers(*out).qdd)
    ssp_dynamics(st, anchor, tree, co, work, contact, act, out)


@entry
def dsp_stage(st, tab, t, anchor, tree, co, tables, work, contact, weights, act, out) -> None:
    """One double-support stage (the compiled twin of ``ThesisController.evaluate`` in RFFDSP / LFFDSP): command
    accelerations with the closed chain, the weighted minimum-norm computed torque under both welds and the lock,
    the thesis torques and the log; arguments as :func:`ssp_stage` (``tables``: :class:`DspTables`) plus the
    torque-split weights ``weights`` = (w_tau (nv,), w_lam (m,))."""
    st, anchor, tree, co, tables = State(*st), Anchor(*anchor), Tree(*tree), Coords(*co), DspTables(*tables)
    work, contact, act, out = Work(*work), Contact(*contact), ActuatorTables(*act), StageBuffers(*out)
    w_tau, w_lam = weights
    qdd_out, v, M_upper, h = out.qdd, st.v, st.M_upper, st.h
    th, thd = tree_state(st, tree, co, tables.need, work)
    ref_p, ref_v, ref_R = np.empty(3), np.empty(6), np.empty((3, 3))
    dsp_references(tab, t + tables.dt, ref_p, ref_v, ref_R)
    put(qdd_out, 0, _controller_dsp(work.motion, work.vel, work.fpos, work.fR, tree.fparent, th, thd, co.jcols,
                                    co.jsign, ref_p, ref_v, ref_R, tables))
    M = symmetric(M_upper)
    a_des = _a_desired(qdd_out, co.jcols, co.jsign, v.size)
    Jc, r, pos_err, ori_err = contact_rows(st, tree, work, contact, anchor)
    a, tau, lam = inverse_general(Jc, r, M, h, a_des, contact.lock_v, w_tau, w_lam)
    _finish(st, M, Jc, a, tau, lam, pos_err, ori_err, work, tree.support, act, out)
