"""Thesis section 4.5: velocity reset at touchdown (single support -> double support).

RFFSSP -> LFFDSP (4.5.1, L3040-3072): the left foot lands.  With q_dot_R_L = [q_dot_R_Hr; q_dot_L_H] (15 rates,
theta3 excluded because theta3_dot = 0 in RFFSSP, eq. 4.6) and J_v,tpL of eq. 4.8 (RFFSSP kinematics), drop
theta4 and its column (eq. 4.96) and take the weighted least change (eq. 4.97)

    q_ini_r = q_end_r + W^-1 J_r^T (J_r W^-1 J_r^T)^-1 ([V_tpL_ini; w_2_ini] - J_r q_end_r),  target = 0,

then set theta4_dot = 0 (L3072).  LFFSSP -> RFFDSP (4.5.2, eq. 4.100) mirrors it with J_v,tpR, theta3.
Only lower-body rates change (L3036).  W_adj is diag(14) in the order of the reduced vector (errata K-11):
[theta5,7,9,11,13,15,17r, theta6,8,10,12,14,16,17l] for RFFSSP -> LFFDSP and
[theta6,8,10,12,14,16,17l, theta5,7,9,11,13,15,17r] for LFFSSP -> RFFDSP.

Decision (thesis silent): the stance toe rate (theta3_dot in RFFSSP) is not in the reduced vector; the thesis
has it zero throughout the SSP (eq. 4.76 and the previous reset).  It is left unchanged here, so the landing foot
ends exactly at rest only when it is zero; :class:`ResetResult` reports the landing foot's residual velocity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humanoid_sim.thesis.frames import IDX
from humanoid_sim.thesis.jacobians import JACOBIAN_DEFS, point_jacobian
from humanoid_sim.thesis.kinematics import Fixed, Kinematics, velocities
from humanoid_sim.thesis.params import ThesisParams

# SSP -> (Jacobian name, landing toe point, landing toe body, toe joint dropped)
_RESET = {
    "RFFSSP": ("J_v,tpL", "tpL", 2, "theta4"),   # 4.5.1 -> LFFDSP
    "LFFSSP": ("J_v,tpR", "tpR", 1, "theta3"),   # 4.5.2 -> RFFDSP
}
NEXT_PHASE = {"RFFSSP": "LFFDSP", "LFFSSP": "RFFDSP"}


@dataclass
class ResetResult:
    """theta_dot after the reset (26,) rad/s, the reduced columns used, and the landing foot's toe-point velocity
    (m/s) and angular velocity (rad/s) after the reset, computed with the SSP kinematics."""

    theta_dot: np.ndarray
    columns: tuple[str, ...]
    V_landing: np.ndarray
    w_landing: np.ndarray


def touchdown_reset(kin: Kinematics, theta_dot: np.ndarray, fixed: Fixed, d: ThesisParams,
                    w_adj: np.ndarray) -> ResetResult:
    """Eq. 4.97 (RFFSSP -> LFFDSP) or eq. 4.100 (LFFSSP -> RFFDSP); ``kin`` holds the SSP positions."""
    if kin.phase not in _RESET:
        raise ValueError(f"touchdown happens at the end of a single support phase, got {kin.phase!r}")
    jname, point, body, dropped = _RESET[kin.phase]
    _, _, cols = JACOBIAN_DEFS[jname]
    cols_r = tuple(c for c in cols if c != dropped)                    # eq. 4.96 / 4.99
    w_adj = np.asarray(w_adj, float).reshape(-1)
    if w_adj.shape != (len(cols_r),) or np.any(w_adj <= 0):
        raise ValueError(f"W_adj must be {len(cols_r)} positive weights ordered as {cols_r}, got {w_adj}")
    J_r = point_jacobian(kin, point, body, cols_r, fixed, d)           # J_v,tp_r (6 x 14)
    qd = np.asarray(theta_dot, float).copy()
    idx = np.array([IDX[c] for c in cols_r])
    q_end = qd[idx]
    target = np.zeros(6)                                               # [V_tp_ini; w_ini] = 0 (L3058)
    Winv_JT = J_r.T / w_adj[:, None]
    q_ini = q_end + Winv_JT @ np.linalg.solve(J_r @ Winv_JT, target - J_r @ q_end)   # eq. 4.97 / 4.100
    qd[idx] = q_ini
    qd[IDX[dropped]] = 0.0                                             # L3072 / L3106
    w, V = velocities(kin, qd, fixed, d)
    return ResetResult(theta_dot=qd, columns=cols_r, V_landing=V[point], w_landing=w[body])
