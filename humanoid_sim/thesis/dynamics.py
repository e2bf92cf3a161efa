"""Thesis sections 4.3 and 4.4: Newton-Euler equations of the 13 real bodies and the direct dynamic solution.

Each body k gives six equations resolved in frame k (eqs. 4.39/4.40, L2651-2657):

    m_k C^(0,k)T a_c,k + m_k g C^(0,k)T u_3                       = K_k^trans F     (translational)
    J_c,k C^(0,k)T alpha_k + C^(0,k)T w~_k C^(0,k) J_c,k C^(0,k)T w_k = K_k^rot F      (rotational, about CoM k)

The left-hand sides are Z_k(q, q_dot, q_ddot) (gravity moved to the left, errata K-8); the right-hand sides
K_k(q) F are transcribed body by body from eqs. 4.42-4.67 in :func:`body_equations`.  Z and K stack the bodies
in the order of eqs. 4.70/4.71 (1, 3, 9, 11, 2, 4, 10, 12, 17, 20, 23, 24, 27), translation rows first.
Units: N and N m; q_ddot in rad/s^2.

Section 4.4 (L2774-2800): M(q) and B(q, q_dot) are found numerically, B = Z(q_ddot = 0) and column k of M is
Z(q_ddot = e_k) - B; the closed-chain rows A_17R - A_17L etc. of eqs. 4.85/4.86 (4.91/4.92) the same way
(L2936-2946).  The 122 x 122 systems of eqs. 4.78, 4.82, 4.88, 4.94 are then solved directly.

Decision (thesis silent): in the double-support phases body 17's own equations (4.58/4.59) use the same estimate
of frame 17 as the upper body, 17_fR in RFFDSP and 17_fL in LFFDSP (L1838); C^(11,17) and C^(12,17) in K are
built from each leg's own joint angles (section 4.1.1).  At a state that closes the chain the two coincide.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humanoid_sim.errors import SimulationError
from humanoid_sim.thesis.forces import (
    LOCKED_TOE,
    N_F,
    ZERO_GROUND,
    ZERO_REACTION,
    block,
    fslice,
    phi,
    selector,
)
from humanoid_sim.thesis.frames import IDX, U, check_phase, is_ssp, relative_rotation, skew
from humanoid_sim.thesis.kinematics import Fixed, Kinematics, accelerations, com_vectors
from humanoid_sim.thesis.params import REAL_BODIES, ThesisParams

N_Q = 26


class DynamicsError(SimulationError):
    """The direct dynamic system is singular or inconsistent; the message carries the numbers."""


def _l_vectors(d: ThesisParams) -> dict[tuple[int, int], np.ndarray]:
    """l_{k,z} in frame k (m), L946-992 (virtual-body lengths are zero, L996)."""
    u1, u2, u3 = U[:, 0], U[:, 1], U[:, 2]
    return {
        (3, 1): d["l3x"] * u1 - d["l3z"] * u3, (4, 2): d["l4x"] * u1 - d["l4z"] * u3,
        (9, 3): -d["l9"] * u3, (10, 4): -d["l10"] * u3, (11, 9): -d["l11"] * u3, (12, 10): -d["l12"] * u3,
        (17, 11): -d["l17z"] * u3 - d["l17y"] * u2, (17, 12): -d["l17z"] * u3 + d["l17y"] * u2,
        (20, 17): -d["l20z"] * u3, (20, 21): -d["l20y"] * u2, (20, 22): d["l20y"] * u2,
        (23, 21): d["l23z"] * u3 + d["l23y"] * u2, (24, 22): d["l24z"] * u3 - d["l24y"] * u2,
        (27, 20): -d["l27"] * u3,
    }


Terms = list[tuple[np.ndarray, str]]


def body_equations(k: int, theta: np.ndarray, d: ThesisParams) -> tuple[Terms, Terms]:
    """Right-hand sides of body k's equations as (3x3 coefficient, F block) lists: (translational, rotational)."""
    I3 = np.eye(3)
    c = {b: skew(v) for b, v in com_vectors(d).items()}
    lv = {key: skew(v) for key, v in _l_vectors(d).items()}

    def C(a: int, b: int) -> np.ndarray:
        return relative_rotation(theta, a, b)

    if k in (1, 2):       # eqs. 4.42/4.43 (body 1), 4.50/4.51 (body 2)
        n = 3 if k == 1 else 4
        Ckn = C(k, n)
        return ([(I3, f"F0_{k}"), (-Ckn, f"F{k}_{n}")],
                [(I3, f"M0_{k}"), (-Ckn, f"M{k}_{n}"), (c[k] @ Ckn, f"F{k}_{n}")])
    if k in (3, 4):       # eqs. 4.44/4.45 (body 3), 4.52/4.53 (body 4)
        toe, up = (1, 9) if k == 3 else (2, 10)
        Cku = C(k, up)
        return ([(I3, f"F0_{k}"), (I3, f"F{toe}_{k}"), (-Cku, f"F{k}_{up}")],
                [(I3, f"M0_{k}"), (I3, f"M{toe}_{k}"), (-Cku, f"M{k}_{up}"),
                 (lv[(k, toe)] - c[k], f"F{toe}_{k}"), (c[k] @ Cku, f"F{k}_{up}")])
    if k in (9, 10, 11, 12):  # eqs. 4.46/4.47 (9), 4.48/4.49 (11), 4.54/4.55 (10), 4.56/4.57 (12)
        low, up = {9: (3, 11), 10: (4, 12), 11: (9, 17), 12: (10, 17)}[k]
        Cku = C(k, up)
        return ([(I3, f"F{low}_{k}"), (-Cku, f"F{k}_{up}")],
                [(I3, f"M{low}_{k}"), (-Cku, f"M{k}_{up}"), (lv[(k, low)] - c[k], f"F{low}_{k}"),
                 (c[k] @ Cku, f"F{k}_{up}")])
    if k == 17:           # eqs. 4.58/4.59
        C1720 = C(17, 20)
        return ([(I3, "F11_17"), (I3, "F12_17"), (-C1720, "F17_20")],
                [(I3, "M11_17"), (I3, "M12_17"), (-C1720, "M17_20"), (lv[(17, 11)] - c[17], "F11_17"),
                 (lv[(17, 12)] - c[17], "F12_17"), (c[17] @ C1720, "F17_20")])
    if k == 20:           # eqs. 4.60/4.61
        C23, C24, C27 = C(20, 23), C(20, 24), C(20, 27)
        return ([(I3, "F17_20"), (-C23, "F20_23"), (-C24, "F20_24"), (-C27, "F20_27")],
                [(I3, "M17_20"), (-C23, "M20_23"), (-C24, "M20_24"), (-C27, "M20_27"),
                 (lv[(20, 17)] - c[20], "F17_20"), (-(lv[(20, 21)] - c[20]) @ C23, "F20_23"),
                 (-(lv[(20, 22)] - c[20]) @ C24, "F20_24"), (c[20] @ C27, "F20_27")])
    if k in (23, 24, 27):  # eqs. 4.62/4.63 (23), 4.64/4.65 (24), 4.66/4.67 (27)
        joint = {23: (23, 21), 24: (24, 22), 27: (27, 20)}[k]
        return ([(I3, f"F20_{k}")], [(I3, f"M20_{k}"), (lv[joint] - c[k], f"F20_{k}")])
    raise ValueError(f"body {k} is not a real body; real bodies are {REAL_BODIES}")


def K_matrix(theta: np.ndarray, d: ThesisParams) -> np.ndarray:
    """K(q) of eq. 4.72 (78 x 96), bodies in the order of eq. 4.71."""
    K = np.zeros((6 * len(REAL_BODIES), N_F))
    for r, k in enumerate(REAL_BODIES):
        trans, rot = body_equations(k, np.asarray(theta, float), d)
        for coef, name in trans:
            K[6 * r:6 * r + 3, fslice(name)] += coef
        for coef, name in rot:
            K[6 * r + 3:6 * r + 6, fslice(name)] += coef
    return K


def Z_vector(kin: Kinematics, alpha: dict, a: dict, d: ThesisParams) -> np.ndarray:
    """Z(q, q_dot, q_ddot) of eq. 4.72 (78,): left-hand sides of eqs. 4.42-4.67 with gravity (errata K-8)."""
    Z = np.zeros(6 * len(REAL_BODIES))
    for r, k in enumerate(REAL_BODIES):
        Ck, w, m, J = kin.C[k], kin.w[k], d.mass[k], d.inertia[k]
        Z[6 * r:6 * r + 3] = m * Ck.T @ a[f"c{k}"] + m * d.g * Ck.T @ U[:, 2]                 # eq. 4.39
        Z[6 * r + 3:6 * r + 6] = J @ Ck.T @ alpha[k] + Ck.T @ skew(w) @ Ck @ J @ Ck.T @ w      # eq. 4.40
    return Z


@dataclass
class DynamicTerms:
    """M (78 x 26), B (78,), K (78 x 96) and, in the DSPs, the closure rows A (6 x 26) q_ddot = b (6,)
    of eqs. 4.85/4.86 or 4.91/4.92."""

    M: np.ndarray
    B: np.ndarray
    K: np.ndarray
    A_closure: np.ndarray | None
    b_closure: np.ndarray | None


def dynamic_terms(kin: Kinematics, theta_dot: np.ndarray, fixed: Fixed, d: ThesisParams) -> DynamicTerms:
    """M and B by unit accelerations (L2790-2800), and the closure rows by the same procedure (L2936-2946)."""
    dual = not is_ssp(kin.phase)
    zero = np.zeros(N_Q)
    al0, a0 = accelerations(kin, theta_dot, zero, fixed, d)
    B = Z_vector(kin, al0, a0, d)                                  # Z_0 = B (L2790)
    M = np.zeros((B.size, N_Q))
    A = np.zeros((6, N_Q)) if dual else None
    for k in range(N_Q):
        e = np.zeros(N_Q)
        e[k] = 1.0
        alk, ak = accelerations(kin, theta_dot, e, fixed, d)
        M[:, k] = Z_vector(kin, alk, ak, d) - B                    # M_k = Z_k - Z_0 (L2798)
        if dual:                                                   # A_17R,k = a_c,17fR,k - a_c,17fR,0 (L2944)
            A[:3, k] = (ak["c17fR"] - a0["c17fR"]) - (ak["c17fL"] - a0["c17fL"])
            A[3:, k] = (alk["17fR"] - al0["17fR"]) - (alk["17fL"] - al0["17fL"])
    b = None
    if dual:
        b = np.concatenate([a0["c17fL"] - a0["c17fR"], al0["17fL"] - al0["17fR"]])   # eqs. 4.85/4.86 rhs
    return DynamicTerms(M=M, B=B, K=K_matrix(kin.theta, d), A_closure=A, b_closure=b)


def system_122(phase: str, terms: DynamicTerms, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 122 x 122 matrix and right-hand side of eq. 4.78 (RFFSSP), 4.82 (LFFSSP), 4.88 (RFFDSP) or 4.94
    (LFFDSP), rows in the thesis's order.  Unknowns: [q_ddot (26); F (96)]."""
    check_phase(phase)
    T = np.asarray(T, float)
    if T.shape != (26,):
        raise ValueError(f"T must have shape (26,) in eq. 4.69 order, got {T.shape}")
    nF = N_F
    rows, rhs = [], []
    rows.append(np.hstack([terms.M, -terms.K]))                    # eq. 4.73 (78)
    rhs.append(-terms.B)
    rows.append(np.hstack([np.zeros((26, N_Q)), phi()]))           # eq. 4.74 (26)
    rhs.append(T)
    Zg = selector(ZERO_GROUND[phase])                              # eqs. 4.75/4.79/4.83/4.89 (12 or 6)
    rows.append(np.hstack([np.zeros((Zg.shape[0], N_Q)), Zg]))
    rhs.append(np.zeros(Zg.shape[0]))
    Zr = selector(ZERO_REACTION[phase])                            # eqs. 4.77/4.81/4.87/4.93 (5)
    rows.append(np.hstack([np.zeros((5, N_Q)), Zr]))
    rhs.append(np.zeros(5))
    lock = np.zeros((1, N_Q + nF))                                 # eqs. 4.76/4.80/4.84/4.90 (1)
    lock[0, IDX[LOCKED_TOE[phase]]] = 1.0
    rows.append(lock)
    rhs.append(np.zeros(1))
    if not is_ssp(phase):                                          # eqs. 4.85/4.86 or 4.91/4.92 (6)
        rows.append(np.hstack([terms.A_closure, np.zeros((6, nF))]))
        rhs.append(terms.b_closure)
    A = np.vstack(rows)
    b = np.concatenate(rhs)
    if A.shape != (122, 122):
        raise DynamicsError(f"{phase}: direct dynamic system is {A.shape}, expected (122, 122)")
    return A, b


@dataclass
class DirectDynamicsResult:
    """Solution of the 122 x 122 system: theta_ddot (26,) rad/s^2, F (96,) in eq. 4.68 order, the ground
    wrenches F_0,k (N) / M_0,k (N m, about CoM k) in frame k for k = 1..4, and the system's residual norm."""

    phase: str
    theta_ddot: np.ndarray
    F: np.ndarray
    ground: dict[int, tuple[np.ndarray, np.ndarray]]
    residual: float


def ground_wrenches(F: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """{k: (F_0,k^(k), M_0,k^(k))} for the four foot bodies."""
    return {k: (block(F, f"F0_{k}").copy(), block(F, f"M0_{k}").copy()) for k in (1, 2, 3, 4)}


def solve_direct(phase: str, terms: DynamicTerms, T: np.ndarray) -> DirectDynamicsResult:
    """Solve eq. 4.78 / 4.82 / 4.88 / 4.94 for [q_ddot; F]."""
    A, b = system_122(phase, terms, T)
    try:
        x = np.linalg.solve(A, b)
    except np.linalg.LinAlgError as exc:
        raise DynamicsError(f"{phase}: the 122 x 122 system is singular (cond = {np.linalg.cond(A):.3g})") from exc
    res = float(np.linalg.norm(A @ x - b))
    F = x[N_Q:]
    return DirectDynamicsResult(phase=phase, theta_ddot=x[:N_Q], F=F, ground=ground_wrenches(F), residual=res)
