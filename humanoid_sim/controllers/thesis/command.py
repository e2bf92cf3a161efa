"""Optimum command accelerations of thesis section 5.1 (eqs. 5.1-5.90).

Each phase's command accelerations minimise quadratic costs of *predicted* tracking errors: a task quantity at
t + dt is predicted by the truncated Taylor expansion x(t) + x_dot dt + x_ddot dt^2/2 with x_ddot affine in the
unknown joint accelerations.  Every such cost is a weighted linear least-squares problem in the joint
accelerations; the thesis's closed forms (q_ddot^T Z = G, eqs. 5.8-5.11, 5.20-5.23; the Lagrange solution 5.62/5.63
in double support) are its normal equations, solved here in that form:

    cost = 1/2 sum_terms (r - A x)^T W (r - A x) + 1/2 x^T W_dd x      =>   (W_dd + sum A^T W A) x = sum A^T W r

Terms (dt = the prediction time of the step):
- position (eqs. 5.1, 5.12, 5.47): A = J dt^2/2, r = p_ref(t+dt) - (p + p_dot dt + drift dt^2/2)
- velocity (eqs. 5.2, 5.13, 5.49): A = J dt, r = v_ref(t+dt) - (v + drift dt)
- orientation C_diag (eqs. 5.3, 5.14, 5.51): A = L J_w dt^2/2, r = Cd_ref - (Cd + L w dt + (L alpha0 + b) dt^2/2)
  with d/dt C_diag = L w (taskspace.cdiag_rate_matrix) and b = diag([w]x[w]x C)
- joint deviation (eqs. 5.4, 5.15, 5.53): A = I dt^2/2, r = -(q + q_dot dt - q0), q0 = 0 (thesis)
- swing toe-joint penalties (eqs. 5.16/5.17): the same with dt3 and W_P,theta / W_V,theta.

Errata fixes applied: C-1 (the J_dot q_dot drift terms, whose dots the OCR lost, are the task accelerations at zero
joint acceleration, taken from Pinocchio's analytic derivatives); C-3 (W_qdd of eqs. 5.66/5.67/5.86/5.87
acts through the extraction matrix Phi, which the stacked formulation does implicitly); C-2 (Delta v derivative
is -J dt).  The upper body (eq. 5.90) is solved per joint in closed form.

Decisions where the thesis is silent:
- Current task values and rates are the *actual* ones (Pinocchio forward kinematics of the floating-base state),
  not recomputed through one chain; on the constraint manifold both are identical.
- The double-support loop closure (eq. 5.59: Body-17 acceleration equal through both legs) is imposed as the
  acceleration-level weld of the trailing toe body computed through the stance chain: the same constraint
  subspace, so the same optimum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dposv

from humanoid_sim.controllers.thesis.taskspace import TaskKinematics, cdiag_rate_matrix, cdiag_second_derivative_bias
from humanoid_sim.errors import ControllerError
from humanoid_sim.robot.model import THETA_NAMES, HumanoidModel
from humanoid_sim.scenario.thesis_controller import ControllerParams, StepWeights

IDX = {n: i for i, n in enumerate(THETA_NAMES)}
Q_R_H = [IDX[n] for n in ("theta3", "theta5", "theta7", "theta9", "theta11", "theta13", "theta15", "theta17r")]
Q_L_H = [IDX[n] for n in ("theta4", "theta6", "theta8", "theta10", "theta12", "theta14", "theta16", "theta17l")]
Q_R_HR, Q_L_HR = Q_R_H[1:], Q_L_H[1:]  # eqs. 4.6 / 4.16: the stance toe joint dropped
Q_UPPER = list(range(16, 26))  # eq. 4.5: theta18..theta27

from humanoid_sim.robot.frames import TASK_FRAMES  # noqa: E402  (re-exported: the task frames live in robot)


class CommandError(ControllerError):
    """The command-acceleration problem has no unique solution at this state (e.g. all weights zero)."""


@dataclass(frozen=True)
class PhaseLayout:
    """Which joints, frames and welds each phase's command-acceleration problem uses (thesis 5.1.1)."""

    name: str
    double: bool
    root_weld: str            # frame of the stance foot main body (O_3 / O_4), the chain root
    stance_vars: list[int]    # q_R_Hr / q_L_Hr
    stance_toe: int           # theta3 / theta4 index, command acceleration 0
    other_vars: list[int]     # q_L_H / q_R_H: swing leg (SSP) or trailing leg (DSP)
    other_toe: int            # toe joint of the other leg (penalised in SSP step 2)
    other_weld: str           # toe body frame of the other foot (O_2 / O_1)
    other_toe_point: str      # P_tpL / P_tpR


LAYOUTS = {
    "RFFSSP": PhaseLayout("RFFSSP", False, "O_3", Q_R_HR, IDX["theta3"], Q_L_H, IDX["theta4"], "O_2", "P_tpL"),
    "LFFSSP": PhaseLayout("LFFSSP", False, "O_4", Q_L_HR, IDX["theta4"], Q_R_H, IDX["theta3"], "O_1", "P_tpR"),
    "RFFDSP": PhaseLayout("RFFDSP", True, "O_3", Q_R_HR, IDX["theta3"], Q_L_H, IDX["theta4"], "O_2", "P_tpL"),
    "LFFDSP": PhaseLayout("LFFDSP", True, "O_4", Q_L_HR, IDX["theta4"], Q_R_H, IDX["theta3"], "O_1", "P_tpR"),
}


@dataclass
class TaskReference:
    """Reference values at the prediction instant t + dt, world frame (from the trajectory generator)."""

    p: np.ndarray       # (3,) position of the task point
    v: np.ndarray       # (6,) [linear velocity; angular velocity]
    R: np.ndarray       # (3,3) orientation of the task body


class _CostRows:
    """Preallocated stacked rows of one cost's tracking terms, 1/2 (r - A x)^T diag(w) (r - A x) over x in R^n,
    plus its diagonal terms (joint deviation, acceleration penalty, toe-joint penalties: blocks with A = s I, or
    s e_k, kept as diagonals ``dZ``, ``dg``).  :meth:`normal` forms the normal equations Z x = g."""

    def __init__(self, n_rows: int, n: int, w: np.ndarray) -> None:
        self.A = np.zeros((n_rows, n))
        self.r = np.zeros(n_rows)
        self.w = np.asarray(w, dtype=float)[:, None]
        self.n = n

    def normal(self, dZ: np.ndarray, dg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Z, g) of the normal equations Z x = g, with diagonal contributions dZ (n,) and dg (n,)."""
        WA = self.A * self.w
        Z = self.A.T @ WA
        Z.flat[::self.n + 1] += dZ
        return Z, WA.T @ self.r + dg


def _tracking_rows(A: np.ndarray, r: np.ndarray, J6: np.ndarray, drift6: np.ndarray, p: np.ndarray,
                   v6: np.ndarray, R: np.ndarray, ref: TaskReference, dt: float) -> None:
    """Write the 12 rows (position 3, velocity 6, C_diag orientation 3) of one task body into A / r
    (J6: 6 x n over x, [point linear; body angular])."""
    h2 = 0.5 * dt * dt
    # position, eq. 5.1 (with the C-1 fix: drift = J_dot q_dot)
    np.multiply(J6[:3], h2, out=A[0:3])
    r[0:3] = ref.p - (p + v6[:3] * dt + drift6[:3] * h2)
    # velocity, eq. 5.2
    np.multiply(J6, dt, out=A[3:9])
    r[3:9] = ref.v - (v6 + drift6 * dt)
    # orientation, eq. 5.3: C_diag(t+dt) ~ Cd + L w dt + (L alpha + b) dt^2/2
    w = v6[3:]
    L = cdiag_rate_matrix(R)
    bias = cdiag_second_derivative_bias(R, w)
    np.multiply(L @ J6[3:], h2, out=A[9:12])
    pred = R.diagonal() + L @ w * dt + (L @ drift6[3:] + bias) * h2  # R.diagonal() = cdiag(R), as a view
    r[9:12] = ref.R.diagonal() - pred


def _solve_spd(Z: np.ndarray, g: np.ndarray, what: str) -> np.ndarray:
    """Solve the normal equations Z x = g of one cost (eqs. 5.11 / 5.23); Z is symmetric positive definite
    (LAPACK posv: the Cholesky factorisation and solve of scipy's cho_factor / cho_solve in one call)."""
    _, x, info = dposv(Z, g)
    if info != 0 or not np.isfinite(x).all():
        raise CommandError(f"{what}: the cost's normal matrix is singular or not finite (weights that leave some "
                           f"joint accelerations unpenalised, or a diverged state): LAPACK posv info = {info}")
    return x


class _PhaseProblem:
    """Everything about one phase's problems that does not change during the walk: index arrays, stacked
    weights, the constant diagonal parts of the normal equations, preallocated buffers."""

    def __init__(self, lay: PhaseLayout, wa: StepWeights, wb: StepWeights, theta0: np.ndarray) -> None:
        self.xs = np.array(lay.stance_vars)
        self.xo = np.array(lay.other_vars)
        self.x = np.concatenate([self.xs, self.xo])
        ns, no = self.xs.size, self.xo.size
        wa_rows = np.concatenate([wa.W_p, wa.W_v, wa.W_or])
        wb_rows = np.concatenate([wb.W_p, wb.W_v, wb.W_or])
        ha, hb = 0.5 * wa.dt * wa.dt, 0.5 * wb.dt * wb.dt
        if not lay.double:
            self.a = _CostRows(12, ns, wa_rows)
            self.b = _CostRows(12, no, wb_rows)
            # joint deviation (A = h2 I) then acceleration penalty (A = I), as accumulated term by term
            self.dZ_a = wa.W_q * ha * ha + wa.W_qdd * 1.0 * 1.0
            self.dZ_b = wb.W_q * hb * hb + wb.W_qdd * 1.0 * 1.0
            # swing toe joint penalties, eqs. 5.16/5.17: rows s e_k on the toe's variable
            self.k_toe = lay.other_vars.index(lay.other_toe)
            h3 = wb.dt3
            self.toe_p = (0.5 * h3 * h3, wb.W_p_toe)
            self.toe_v = (h3, wb.W_v_toe)
            self.dZ_b[self.k_toe] += (wb.W_p_toe * self.toe_p[0] ** 2) + (wb.W_v_toe * h3 ** 2)
        else:
            n = ns + no
            self.c = _CostRows(24, n, np.concatenate([wa_rows, wb_rows]))
            W_q = np.concatenate([wa.W_q, wb.W_q])
            self.dZ = W_q * ha * ha + np.concatenate([wa.W_qdd, wb.W_qdd]) * 1.0 * 1.0
            self.W_q = W_q
            self.K = np.zeros((n + 6, n + 6))
            self.rhs = np.zeros(n + 6)
        self.ha, self.hb = ha, hb
        self.theta0_toe = float(theta0[lay.other_toe])


class CommandAccelerations:
    """Optimum command accelerations theta_ddot_c (26,, thesis order) for the current phase and state."""

    def __init__(self, hm: HumanoidModel, params: ControllerParams, theta0: np.ndarray | None = None) -> None:
        """``theta0``: the basic joint positions q0 of eqs. 5.4/5.15/5.53/5.90, "the initial values" (thesis
        L3213); zero for the thesis's zero-posture start."""
        self.hm = hm
        self.params = params
        self.theta0 = np.zeros(26) if theta0 is None else np.asarray(theta0, dtype=float).copy()
        self.kin = TaskKinematics(hm, TASK_FRAMES)
        self._problems = {name: _PhaseProblem(lay, *params.steps[name], self.theta0) for name, lay in LAYOUTS.items()}
        Wp, Wv, dt = params.upper_Wp, params.upper_Wv, params.upper_dt
        self._upper_den = Wp * dt**4 / 4 + Wv * dt**2
        self._upper_dt2, self._upper_dt3 = dt**2, dt**3  # constant powers of eq. 5.90, computed once
        self._q_upper = np.array(Q_UPPER)

    def _body_task(self, point: str, body: str, weld: str) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                     np.ndarray, np.ndarray]:
        """Joint-space Jacobian (6 x 26) and drift (6,) of [point linear; body angular] through ``weld``, and the
        current point position, [point linear; body angular] velocity and body orientation."""
        kin = self.kin
        J, drift = kin.reduce_pair(point, body, weld)
        v6 = kin.velocity(point)
        if kin.parent_joint[point] != kin.parent_joint[body]:  # else the angular rows are already the body's
            v6 = np.concatenate([v6[:3], kin.velocity(body)[3:]])
        return J, drift, kin.placement(point)[0], v6, kin.placement(body)[1]

    def compute(self, phase: str, q: np.ndarray, v: np.ndarray, ref_a: TaskReference,
                ref_b: TaskReference | None, data=None) -> np.ndarray:
        """Command accelerations (rad/s^2, 26,) for ``phase``.

        ref_a: Body-17 reference (CoM position, [V_c17; w17], C^(0,17)) at t + dt of the first step (SSP) or of
        the phase (DSP).  ref_b: swing toe point / toe body reference at t + dt2 (SSP only; ignored in DSP).
        ``data``: optional pinocchio Data holding ``forwardKinematics(q, v, 0)`` and ``computeJointJacobians``.
        """
        lay = LAYOUTS[phase]
        wa, wb = self.params.steps[phase]
        P = self._problems[phase]
        self.kin.update(q, v, data)
        th = self.hm.theta_from_q(q) - self.theta0  # deviation from the basic positions q0
        thd = self.hm.theta_dot_from_v(v)
        qdd = np.zeros(26)
        if not lay.double:
            # Step 1 (5.1.1.1.1): stance-leg joints for Body 17 and its CoM, chain rooted at the stance foot.
            xs = P.xs
            J, drift, p, v6, R = self._body_task("Pc_17", "O_17", lay.root_weld)
            _tracking_rows(P.a.A, P.a.r, J[:, xs], drift, p, v6, R, ref_a, wa.dt)
            # joint deviation, eqs. 5.4/5.15 (A = h2 I, r = -(theta + theta_dot dt)); acceleration penalty
            Z, g = P.a.normal(P.dZ_a, wa.W_q * P.ha * -(th[xs] + thd[xs] * wa.dt))
            qdd_s = _solve_spd(Z, g, f"{phase} step 1 (Body 17)")  # eq. 5.11
            qdd[xs] = qdd_s
            # Step 2 (5.1.1.1.2): swing-leg joints for the swing toe point and toe body, given step 1.
            xo = P.xo
            J, drift, p, v6, R = self._body_task(lay.other_toe_point, lay.other_weld, lay.root_weld)
            drift = drift + J[:, xs] @ qdd_s  # eq. 5.12: q_ddot_R_Hr_c enters as a known term
            _tracking_rows(P.b.A, P.b.r, J[:, xo], drift, p, v6, R, ref_b, wb.dt)
            dg = wb.W_q * P.hb * -(th[xo] + thd[xo] * wb.dt)
            # swing toe joint penalties, eqs. 5.16/5.17 (theta_4 in RFFSSP, theta_3 in LFFSSP); the toe penalty is
            # on theta itself (eq. 5.16: Delta theta_4 = theta_4), not on theta - q0
            t = lay.other_toe
            th_toe = th[t] + P.theta0_toe
            (s_p, w_p), (s_v, w_v) = P.toe_p, P.toe_v
            dg[P.k_toe] += (w_p * s_p * -(th_toe + thd[t] * s_v)) + (w_v * s_v * -thd[t])
            Z, g = P.b.normal(P.dZ_b, dg)
            qdd[xo] = _solve_spd(Z, g, f"{phase} step 2 (swing foot)")  # eq. 5.23
        else:
            # 5.1.1.3: both chains to Body 17 in one problem over x = [stance chain; trailing chain], subject to
            # the closed-chain constraint (eq. 5.59), solved by Lagrange multipliers (eqs. 5.62/5.63).
            xs, xo, x = P.xs, P.xo, P.x
            ns, n = xs.size, x.size
            A, r = P.c.A, P.c.r
            Ja, da, p, v6, R = self._body_task("Pc_17", "O_17", lay.root_weld)
            _tracking_rows(A[:12, :ns], r[:12], Ja[:, xs], da, p, v6, R, ref_a, wa.dt)
            Jb, db, p, v6, R = self._body_task("Pc_17", "O_17", lay.other_weld)
            _tracking_rows(A[12:, ns:], r[12:], Jb[:, xo], db, p, v6, R, ref_a, wb.dt)
            Z, g = P.c.normal(P.dZ, P.W_q * P.ha * -(th[x] + thd[x] * wa.dt))
            # closure: the trailing toe body's acceleration through the stance chain is zero
            Jc, dc = self.kin.reduce(lay.other_weld, lay.root_weld)
            K, rhs = P.K, P.rhs
            K[:n, :n] = Z
            Ac = Jc[:, x]
            K[:n, n:] = Ac.T
            K[n:, :n] = Ac
            rhs[:n] = g
            rhs[n:] = -dc
            try:
                sol = np.linalg.solve(K, rhs)
            except np.linalg.LinAlgError as exc:
                raise CommandError(f"{phase}: the double-support KKT system is singular (weights that leave some "
                                   f"joint accelerations unpenalised, or a diverged state): {exc}") from None
            qdd[x] = sol[:n]
        qdd[lay.stance_toe] = 0.0  # theta_3c / theta_4c = 0 (5.1.1.1, 5.1.1.3)
        qu = self._q_upper
        qdd[qu] = self.upper(th[qu], thd[qu])
        return qdd

    def upper(self, th: np.ndarray, thd: np.ndarray) -> np.ndarray:
        """Eq. 5.90, per joint; ``th`` = theta - theta_k0, theta_dot_k0 = 0 (errata C-6)."""
        Wp, Wv, dt = self.params.upper_Wp, self.params.upper_Wv, self.params.upper_dt
        num = Wp * th * self._upper_dt2 / 2 + Wp * thd * self._upper_dt3 / 2 + Wv * thd * dt
        return -num / self._upper_den
