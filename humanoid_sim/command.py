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

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve

from humanoid_sim.model import THETA_NAMES, HumanoidModel
from humanoid_sim.taskspace import TaskKinematics, cdiag, cdiag_rate_matrix, cdiag_second_derivative_bias

IDX = {n: i for i, n in enumerate(THETA_NAMES)}
Q_R_H = [IDX[n] for n in ("theta3", "theta5", "theta7", "theta9", "theta11", "theta13", "theta15", "theta17r")]
Q_L_H = [IDX[n] for n in ("theta4", "theta6", "theta8", "theta10", "theta12", "theta14", "theta16", "theta17l")]
Q_R_HR, Q_L_HR = Q_R_H[1:], Q_L_H[1:]  # eqs. 4.6 / 4.16: the stance toe joint dropped
Q_UPPER = list(range(16, 26))  # eq. 4.5: theta18..theta27

TASK_FRAMES = ["Pc_17", "O_17", "P_tpR", "P_tpL", "O_1", "O_2", "O_3", "O_4"]


class ControllerParamError(ValueError):
    """A controller weight or prediction time is missing or malformed (message names the key and value)."""


class CommandError(RuntimeError):
    """The command-acceleration problem has no unique solution at this state (e.g. all weights zero)."""


def _solve_spd(qp: "QPTerms", what: str) -> np.ndarray:
    """Solve the normal equations Z x = g of one cost (eqs. 5.11 / 5.23); Z is symmetric positive definite."""
    Z, g = qp.normal()
    try:
        return cho_solve(cho_factor(Z, check_finite=False), g, check_finite=False)
    except (LinAlgError, ValueError) as exc:
        raise CommandError(f"{what}: the cost's normal matrix is singular or not finite (weights that leave some "
                           f"joint accelerations unpenalised, or a diverged state): {exc}") from None


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


@dataclass(frozen=True)
class StepWeights:
    """Weights of one cost (one step of an SSP, or one chain of a DSP), diagonal entries."""

    dt: float
    W_p: np.ndarray      # (3,) position
    W_v: np.ndarray      # (6,) [linear; angular] velocity
    W_or: np.ndarray     # (3,) C_diag orientation
    W_q: np.ndarray      # (n,) joint deviation
    W_qdd: np.ndarray    # (n,) joint acceleration
    dt3: float = 0.0     # toe-joint penalty horizon (SSP step 2 only)
    W_p_toe: float = 0.0
    W_v_toe: float = 0.0


@dataclass(frozen=True)
class ControllerParams:
    """All weights and prediction times of Appendix B for the four phases and the upper body."""

    steps: dict[str, tuple[StepWeights, StepWeights]]   # phase -> (a: hip/stance chain, b: swing/other chain)
    upper_Wp: np.ndarray
    upper_Wv: np.ndarray
    upper_dt: np.ndarray
    raw: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_dict(cls, c: dict[str, Any], where: str = "controller") -> "ControllerParams":
        def vec(key: str, n: int) -> np.ndarray:
            if key not in c:
                raise ControllerParamError(f"{where}.{key}: missing (expected {n} non-negative weights)")
            v = np.atleast_1d(np.asarray(c[key], dtype=float))
            if v.shape != (n,):
                raise ControllerParamError(f"{where}.{key}: expected {n} entries, got {v.size}")
            bad = np.flatnonzero(~np.isfinite(v) | (v < 0))
            if bad.size:
                raise ControllerParamError(f"{where}.{key}[{bad[0]}]: expected a non-negative weight, got {v[bad[0]]}")
            return v

        def scal(key: str, positive: bool = False) -> float:
            v = vec(key, 1)[0]
            if positive and v <= 0:
                raise ControllerParamError(f"{where}.{key}: expected a positive time in s, got {v}")
            return float(v)

        steps = {}
        for ph, stance, other, toe in (("LFFSSP", "L", "R", "3"), ("RFFSSP", "R", "L", "4")):
            a = StepWeights(dt=scal(f"Delta_t1_{ph}", True), W_p=vec(f"Wp_fa_{ph}", 3), W_v=vec(f"Wv_fa_{ph}", 6),
                            W_or=vec(f"Wor_fa_{ph}", 3), W_q=vec(f"Wq{stance}_H_{ph}", 7),
                            W_qdd=vec(f"Wa_a_{ph}", 7))
            b = StepWeights(dt=scal(f"Delta_t2_{ph}", True), W_p=vec(f"Wp_fb_{ph}", 3), W_v=vec(f"Wv_fb_{ph}", 6),
                            W_or=vec(f"Wor_fb_{ph}", 3), W_q=vec(f"WqH_{other}_{ph}", 8),
                            W_qdd=vec(f"Wa_b_{ph}", 8), dt3=scal(f"Delta_t3_{ph}", True),
                            W_p_toe=scal(f"Wp_Tetha{toe}_{ph}"), W_v_toe=scal(f"Wv_Tetha{toe}_{ph}"))
            steps[ph] = (a, b)
        for ph, stance, other in (("LFFDSP", "L", "R"), ("RFFDSP", "R", "L")):
            # errata A-13: one prediction time per DSP (Delta_t1 = Delta_t2)
            dt = scal(f"Delta_t1_{ph}", True)
            a = StepWeights(dt=dt, W_p=vec(f"Wp_fa_{ph}", 3), W_v=vec(f"Wv_fa_{ph}", 6), W_or=vec(f"Wor_fa_{ph}", 3),
                            W_q=vec(f"Wq{stance}_H_{ph}", 7), W_qdd=vec(f"Wa_a_{ph}", 7))
            b = StepWeights(dt=dt, W_p=vec(f"Wp_fb_{ph}", 3), W_v=vec(f"Wv_fb_{ph}", 6), W_or=vec(f"Wor_fb_{ph}", 3),
                            W_q=vec(f"Wq{other}_H_{ph}", 8), W_qdd=vec(f"Wa_b_{ph}", 8))
            steps[ph] = (a, b)
        ks = range(18, 28)
        Wp = np.array([scal(f"WpTetha{k}") for k in ks])
        Wv = np.array([scal(f"WvTetha{k}") for k in ks])
        dts = np.array([scal(f"Delta_t{k}", True) for k in ks])
        return cls(steps=steps, upper_Wp=Wp, upper_Wv=Wv, upper_dt=dts, raw=dict(c))


@dataclass
class TaskReference:
    """Reference values at the prediction instant t + dt, world frame (from the trajectory generator)."""

    p: np.ndarray       # (3,) position of the task point
    v: np.ndarray       # (6,) [linear velocity; angular velocity]
    R: np.ndarray       # (3,3) orientation of the task body


class QPTerms:
    """Accumulates 1/2 sum (r - A x)^T diag(w) (r - A x) over x in R^n; blocks with A = s I (joint terms and the
    acceleration penalty) are kept as diagonals.  :meth:`normal` stacks everything once: Z x = g."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.diag_Z = np.zeros(n)
        self.diag_g = np.zeros(n)
        self.diag_terms: list[tuple[float, np.ndarray, np.ndarray]] = []

    def add(self, A: np.ndarray, r: np.ndarray, w: np.ndarray) -> None:
        self.blocks.append((A, r, w))

    def add_scaled_identity(self, s: float, r: np.ndarray, w: np.ndarray) -> None:
        """A block with A = s I (n x n)."""
        self.diag_Z += w * s * s
        self.diag_g += w * s * r
        self.diag_terms.append((s, r, w))

    def add_reg(self, w_dd: np.ndarray) -> None:
        """The acceleration penalty 1/2 x^T diag(w_dd) x."""
        self.add_scaled_identity(1.0, np.zeros(self.n), w_dd)

    def normal(self) -> tuple[np.ndarray, np.ndarray]:
        """(Z, g) of the normal equations Z x = g."""
        A = np.vstack([b[0] for b in self.blocks])
        r = np.concatenate([b[1] for b in self.blocks])
        w = np.concatenate([b[2] for b in self.blocks])
        WA = A * w[:, None]
        Z = A.T @ WA
        Z[np.diag_indices(self.n)] += self.diag_Z
        return Z, WA.T @ r + self.diag_g

    def cost(self, x: np.ndarray) -> float:
        """The cost function itself (for checks against direct minimisation)."""
        c = sum(0.5 * np.sum(w * (r - A @ x) ** 2) for A, r, w in self.blocks)
        return float(c + sum(0.5 * np.sum(w * (r - s * x) ** 2) for s, r, w in self.diag_terms))


def _tracking_terms(qp: QPTerms, J6: np.ndarray, drift6: np.ndarray, p: np.ndarray, v6: np.ndarray, R: np.ndarray,
                    ref: TaskReference, w: StepWeights, dt: float) -> None:
    """Add the position, velocity and C_diag orientation terms of one task body (J6: 6 x n over x)."""
    h2 = 0.5 * dt * dt
    # position, eq. 5.1 (with the C-1 fix: drift = J_dot q_dot)
    qp.add(J6[:3] * h2, ref.p - (p + v6[:3] * dt + drift6[:3] * h2), w.W_p)
    # velocity, eq. 5.2
    qp.add(J6 * dt, ref.v - (v6 + drift6 * dt), w.W_v)
    # orientation, eq. 5.3: C_diag(t+dt) ~ Cd + L w dt + (L alpha + b) dt^2/2
    L = cdiag_rate_matrix(R)
    bias = cdiag_second_derivative_bias(R, v6[3:])
    Jor = L @ J6[3:]
    pred = cdiag(R) + L @ v6[3:] * dt + (L @ drift6[3:] + bias) * h2
    qp.add(Jor * h2, cdiag(ref.R) - pred, w.W_or)


def _joint_terms(qp: QPTerms, th: np.ndarray, thd: np.ndarray, W_q: np.ndarray, dt: float) -> None:
    """Joint deviation from the basic position q0 (eqs. 5.4/5.15/5.53); ``th`` is already theta - q0."""
    qp.add_scaled_identity(0.5 * dt * dt, -(th + thd * dt), W_q)


class CommandAccelerations:
    """Optimum command accelerations theta_ddot_c (26,, thesis order) for the current phase and state."""

    def __init__(self, hm: HumanoidModel, params: ControllerParams, theta0: np.ndarray | None = None) -> None:
        """``theta0``: the basic joint positions q0 of eqs. 5.4/5.15/5.53/5.90, "the initial values" (thesis
        L3213); zero for the thesis's zero-posture start."""
        self.hm = hm
        self.params = params
        self.theta0 = np.zeros(26) if theta0 is None else np.asarray(theta0, dtype=float).copy()
        self.kin = TaskKinematics(hm, TASK_FRAMES)
        self.last_qp: dict[str, QPTerms] = {}

    def _body_task(self, point: str, body: str, weld: str, cols: list[int]):
        """Joint-space Jacobian (6 x len(cols)) and drift (6,) of [point linear; body angular] through ``weld``,
        plus the full 26-column Jacobian (for the contribution of already-commanded joints)."""
        Jp, dp = self.kin.reduce(point, weld, slice(0, 3))
        Jw, dw = self.kin.reduce(body, weld, slice(3, 6))
        J = np.vstack([Jp, Jw])
        drift = np.concatenate([dp, dw])
        st_p, st_b = self.kin.states[point], self.kin.states[body]
        v6 = np.concatenate([st_p.v[:3], st_b.v[3:]])
        return J[:, cols], drift, J, st_p.p, v6, st_b.R

    def compute(self, phase: str, q: np.ndarray, v: np.ndarray, ref_a: TaskReference,
                ref_b: TaskReference | None, data=None) -> np.ndarray:
        """Command accelerations (rad/s^2, 26,) for ``phase``.

        ref_a: Body-17 reference (CoM position, [V_c17; w17], C^(0,17)) at t + dt of the first step (SSP) or of
        the phase (DSP).  ref_b: swing toe point / toe body reference at t + dt2 (SSP only; ignored in DSP).
        """
        lay = LAYOUTS[phase]
        wa, wb = self.params.steps[phase]
        self.kin.update(q, v, data)
        th = self.hm.theta_from_q(q) - self.theta0  # deviation from the basic positions q0
        thd = self.hm.theta_dot_from_v(v)
        qdd = np.zeros(26)
        if not lay.double:
            # Step 1 (5.1.1.1.1): stance-leg joints for Body 17 and its CoM, chain rooted at the stance foot.
            xs = lay.stance_vars
            J, drift, _, p, v6, R = self._body_task("Pc_17", "O_17", lay.root_weld, xs)
            qp1 = QPTerms(len(xs))
            _tracking_terms(qp1, J, drift, p, v6, R, ref_a, wa, wa.dt)
            _joint_terms(qp1, th[xs], thd[xs], wa.W_q, wa.dt)
            qp1.add_reg(wa.W_qdd)
            qdd[xs] = _solve_spd(qp1, f"{phase} step 1 (Body 17)")  # eq. 5.11
            # Step 2 (5.1.1.1.2): swing-leg joints for the swing toe point and toe body, given step 1.
            xo = lay.other_vars
            J, drift, Jfull, p, v6, R = self._body_task(lay.other_toe_point, lay.other_weld, lay.root_weld, xo)
            drift = drift + Jfull[:, xs] @ qdd[xs]  # eq. 5.12: q_ddot_R_Hr_c enters as a known term
            qp2 = QPTerms(len(xo))
            _tracking_terms(qp2, J, drift, p, v6, R, ref_b, wb, wb.dt)
            _joint_terms(qp2, th[xo], thd[xo], wb.W_q, wb.dt)
            # swing toe joint penalties, eqs. 5.16/5.17 (theta_4 in RFFSSP, theta_3 in LFFSSP)
            k = xo.index(lay.other_toe)
            e = np.zeros((1, len(xo)))
            e[0, k] = 1.0
            h3 = wb.dt3
            # the toe penalty is on theta itself (eq. 5.16: Delta theta_4 = theta_4), not on theta - q0
            th_toe = th[lay.other_toe] + self.theta0[lay.other_toe]
            qp2.add(e * 0.5 * h3 * h3, np.array([-(th_toe + thd[lay.other_toe] * h3)]),
                    np.array([wb.W_p_toe]))
            qp2.add(e * h3, np.array([-thd[lay.other_toe]]), np.array([wb.W_v_toe]))
            qp2.add_reg(wb.W_qdd)
            qdd[xo] = _solve_spd(qp2, f"{phase} step 2 (swing foot)")  # eq. 5.23
            self.last_qp = {"a": qp1, "b": qp2}
        else:
            # 5.1.1.3: both chains to Body 17 in one problem over x = [stance chain; trailing chain], subject to
            # the closed-chain constraint (eq. 5.59), solved by Lagrange multipliers (eqs. 5.62/5.63).
            xs, xo = lay.stance_vars, lay.other_vars
            x = xs + xo
            n, ns = len(x), len(xs)
            qp = QPTerms(n)
            Ja, da, _, p, v6, R = self._body_task("Pc_17", "O_17", lay.root_weld, xs)
            Aa = np.zeros((6, n))
            Aa[:, :ns] = Ja
            _tracking_terms(qp, Aa, da, p, v6, R, ref_a, wa, wa.dt)
            Jb, db, _, p, v6, R = self._body_task("Pc_17", "O_17", lay.other_weld, xo)
            Ab = np.zeros((6, n))
            Ab[:, ns:] = Jb
            _tracking_terms(qp, Ab, db, p, v6, R, ref_a, wb, wb.dt)
            Wq = np.concatenate([wa.W_q, wb.W_q])
            _joint_terms(qp, th[x], thd[x], Wq, wa.dt)
            qp.add_reg(np.concatenate([wa.W_qdd, wb.W_qdd]))
            # closure: the trailing toe body's acceleration through the stance chain is zero
            Jc, dc = self.kin.reduce(lay.other_weld, lay.root_weld)
            A = Jc[:, x]
            b = -dc
            Z, g = qp.normal()
            K = np.block([[Z, A.T], [A, np.zeros((6, 6))]])
            try:
                sol = np.linalg.solve(K, np.concatenate([g, b]))
            except np.linalg.LinAlgError as exc:
                raise CommandError(f"{phase}: the double-support KKT system is singular (weights that leave some "
                                   f"joint accelerations unpenalised, or a diverged state): {exc}") from None
            qdd[x] = sol[:n]
            self.last_qp = {"dsp": qp, "A": A, "b": b}
        qdd[lay.stance_toe] = 0.0  # theta_3c / theta_4c = 0 (5.1.1.1, 5.1.1.3)
        qdd[Q_UPPER] = self.upper(th[Q_UPPER], thd[Q_UPPER])
        return qdd

    def upper(self, th: np.ndarray, thd: np.ndarray) -> np.ndarray:
        """Eq. 5.90, per joint; ``th`` = theta - theta_k0, theta_dot_k0 = 0 (errata C-6)."""
        Wp, Wv, dt = self.params.upper_Wp, self.params.upper_Wv, self.params.upper_dt
        num = Wp * th * dt**2 / 2 + Wp * thd * dt**3 / 2 + Wv * thd * dt
        den = Wp * dt**4 / 4 + Wv * dt**2
        return -num / den
