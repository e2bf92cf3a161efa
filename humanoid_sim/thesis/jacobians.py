"""Thesis section 4.2: Jacobian matrices built numerically from unit joint velocities, and their time derivatives.

Procedure of 4.2.2 (L2601-2625): for each column i, set the joint-rate sub-vector to the unit vector e_i (all
other rates and the supplied toe-body velocities zero), run the velocity relations of the phase (section 4.1.3 /
4.1.4) and stack [V; w] as column i.  Units: linear rows m/s per rad/s, angular rows rad/s per rad/s; vectors
in frame 0.  The C_diag Jacobians of eq. 4.9 (L2509) map the rates to diag(w~_k C^(0,k)) (1/s).

The time derivative is the forward difference of eq. 4.34 (L2631) with the configuration advanced by eq. 4.36,
theta(t0 + dt) = theta(t0) + theta_dot(t0) dt (the supplied toe-body data held constant, as in the phase).
The thesis gives no value of dt (errata A-14): it is an argument here.

Which Jacobians each phase needs (4.2.1.1-4.2.1.4, L2495-2599) is listed in :data:`PHASE_JACOBIANS`.
"""

from __future__ import annotations

import numpy as np

from humanoid_sim.thesis.frames import IDX, Q_L_H, Q_L_HR, Q_R_H, Q_R_HR, THETA_NAMES, Key, check_phase, skew
from humanoid_sim.thesis.kinematics import Fixed, Kinematics, at_rest, positions, velocities
from humanoid_sim.thesis.params import ThesisParams

Q_R_L = Q_R_HR + Q_L_H    # q_dot_R_L = [q_dot_R_Hr; q_dot_L_H], L2503 (RFFSSP, 15 columns)
Q_L_R = Q_L_HR + Q_R_H    # q_dot_L_R = [q_dot_L_Hr; q_dot_R_H], L2537 (LFFSSP, 15 columns)

# name -> (point, frame, columns); the point's velocity and the frame's angular velocity are the rows.
JACOBIAN_DEFS: dict[str, tuple[str, Key, tuple[str, ...]]] = {
    "J_v,17_fR": ("c17fR", "17fR", Q_R_HR),      # eq. 4.7 (RFFSSP) / 4.2.1.3 (RFFDSP)
    "J_v,tpL": ("tpL", 2, Q_R_L),                # eq. 4.8
    "J_v,17_fL": ("c17fL", "17fL", Q_L_HR),      # eq. 4.17 (LFFSSP) / 4.2.1.4 (LFFDSP)
    "J_v,tpR": ("tpR", 1, Q_L_R),                # eq. 4.18
    "J_v,17_fL_all": ("c17fL", "17fL", Q_L_H),   # eq. 4.25
    "J_v,17_fR_all": ("c17fR", "17fR", Q_R_H),   # eq. 4.29
}
CDIAG_OF = {  # C_diag Jacobian -> the Jacobian whose angular rows it uses (eqs. 4.12/4.13, 4.21/4.22, 4.27, 4.31)
    "J_v,Cdiag0_17_fR": "J_v,17_fR", "J_v,Cdiag0_2": "J_v,tpL", "J_v,Cdiag0_17_fL": "J_v,17_fL",
    "J_v,Cdiag0_1": "J_v,tpR", "J_v,Cdiag0_17_fL_all": "J_v,17_fL_all", "J_v,Cdiag0_17_fR_all": "J_v,17_fR_all",
}
PHASE_JACOBIANS: dict[str, tuple[str, ...]] = {
    "RFFSSP": ("J_v,17_fR", "J_v,tpL", "J_v,Cdiag0_17_fR", "J_v,Cdiag0_2"),                     # L2527
    "LFFSSP": ("J_v,17_fL", "J_v,tpR", "J_v,Cdiag0_17_fL", "J_v,Cdiag0_1"),                     # L2559 (K-5)
    "RFFDSP": ("J_v,17_fR", "J_v,Cdiag0_17_fR", "J_v,17_fL_all", "J_v,Cdiag0_17_fL_all"),       # L2579
    "LFFDSP": ("J_v,17_fL", "J_v,Cdiag0_17_fL", "J_v,17_fR_all", "J_v,Cdiag0_17_fR_all"),       # L2599
}


def _resolve(kin: Kinematics, point: str, frame: Key) -> tuple[str, Key]:
    """In a single-support phase there is one frame 17: 17_fR / 17_fL name it (L2573, L2593)."""
    if point in ("c17fR", "c17fL") and point not in kin.P:
        return "c17", 17
    return point, frame


def point_jacobian(kin: Kinematics, point: str, frame: Key, columns: tuple[str, ...], fixed: Fixed,
                   d: ThesisParams) -> np.ndarray:
    """[V_point; w_frame] per unit rate of each named joint (6 x len(columns)), procedure of 4.2.2 (L2601-2625)."""
    point, frame = _resolve(kin, point, frame)
    rest = at_rest(fixed)
    J = np.zeros((6, len(columns)))
    for i, name in enumerate(columns):
        qd = np.zeros(26)
        qd[IDX[name]] = 1.0               # q_dot = e_i (L2605-2620)
        w, V = velocities(kin, qd, rest, d)
        J[:3, i] = V[point]
        J[3:, i] = w[frame]
    return J


def cdiag_jacobian(J: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Eq. 4.9 (L2509) column by column: diag([J_w e_i]~ C^(0,k)) (3 x n), procedure of L2625."""
    return np.column_stack([np.diag(skew(J[3:, i]) @ C) for i in range(J.shape[1])])


def thesis_jacobians(kin: Kinematics, fixed: Fixed, d: ThesisParams,
                     names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
    """The Jacobians the phase needs (default :data:`PHASE_JACOBIANS`), by their thesis names."""
    names = PHASE_JACOBIANS[check_phase(kin.phase)] if names is None else names
    out: dict[str, np.ndarray] = {}
    for name in names:
        base = CDIAG_OF.get(name, name)
        if base not in JACOBIAN_DEFS:
            raise KeyError(f"unknown thesis Jacobian {name!r}; known: {sorted(JACOBIAN_DEFS) + sorted(CDIAG_OF)}")
        if base not in out:
            point, frame, cols = JACOBIAN_DEFS[base]
            out[base] = point_jacobian(kin, point, frame, cols, fixed, d)
        if name in CDIAG_OF:
            frame = _resolve(kin, *JACOBIAN_DEFS[base][:2])[1]
            out[name] = cdiag_jacobian(out[base], kin.C[frame])
    return {n: out[n] for n in names}


def jacobian_derivatives(phase: str, theta: np.ndarray, theta_dot: np.ndarray, fixed: Fixed, d: ThesisParams,
                         dt: float, names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
    """J_dot(t0) ~ (J(t0 + dt) - J(t0)) / dt (eq. 4.34, L2631) with theta(t0 + dt) = theta + theta_dot dt
    (eq. 4.36, L2639).  ``dt`` (s) is not given by the thesis (errata A-14)."""
    if not dt > 0.0:
        raise ValueError(f"the finite-difference step dt must be positive, got {dt!r}")
    theta = np.asarray(theta, float)
    J0 = thesis_jacobians(positions(phase, theta, fixed, d), fixed, d, names)
    J1 = thesis_jacobians(positions(phase, theta + np.asarray(theta_dot, float) * dt, fixed, d), fixed, d, names)
    return {n: (J1[n] - J0[n]) / dt for n in J0}


def full_jacobian(kin: Kinematics, point: str, frame: Key, fixed: Fixed, d: ThesisParams) -> np.ndarray:
    """[V_point; w_frame] per unit rate of every joint of eq. 4.1 (6 x 26), same unit-rate procedure."""
    return point_jacobian(kin, point, frame, THETA_NAMES, fixed, d)
