"""Thesis section 5.2: computed-torque control, T from commanded joint accelerations.

With Z(q, q_dot, q_ddot_c) = M q_ddot_c + B (section 4.4) and K(q) of eq. 4.72, eq. 5.91 (L3806) appends the
phase's zero-force rows K_c F = Z_c = 0 (section 5.2.1-5.2.4, L3812-3880; see ``forces.CTC_ZERO``):

- single support: [K; K_c] is 96 x 96 and is inverted directly, T = phi [K; K_c]^-1 [Z; 0]   (eqs. 5.92, 5.93);
- double support: [K; K_c] is 90 x 96; the weighted minimum-norm solution of min 1/2 F^T W_act F subject to
  K_T F = Z_T is F = W^-1 K_T^T (K_T W^-1 K_T^T)^-1 Z_T, T = phi F                          (eqs. 5.96, 5.98).

K_c zeroes the whole M_{1,3} (M_{2,4}) so T1 (T2) is zero in the phases where the right (left) foot is welded
(L3810).  Units: N, N m.  Default W_act: ``forces.default_w_act`` (errata A-3 reconstruction).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humanoid_sim.thesis.dynamics import DynamicsError, DynamicTerms
from humanoid_sim.thesis.forces import CTC_ZERO, N_F, default_w_act, phi, selector
from humanoid_sim.thesis.frames import check_phase, is_ssp


@dataclass
class ComputedTorqueResult:
    """T (26,) in eq. 4.69 order (N m), F (96,) in eq. 4.68 order, residual ||K_T F - Z_T||."""

    phase: str
    T: np.ndarray
    F: np.ndarray
    residual: float


def computed_torque(phase: str, terms: DynamicTerms, theta_ddot_c: np.ndarray,
                    w_act: np.ndarray | None = None) -> ComputedTorqueResult:
    """Eqs. 5.91-5.98 for the phase, given the dynamic terms at the current state."""
    check_phase(phase)
    qdd = np.asarray(theta_ddot_c, float)
    if qdd.shape != (26,):
        raise ValueError(f"theta_ddot_c must have shape (26,), got {qdd.shape}")
    Z = terms.M @ qdd + terms.B                      # Z(q, q_dot, q_ddot_c)
    Kc = selector(CTC_ZERO[phase])                   # K_c, Z_c = 0
    KT = np.vstack([terms.K, Kc])                    # eq. 5.91
    ZT = np.concatenate([Z, np.zeros(Kc.shape[0])])
    if is_ssp(phase):                                # eqs. 5.92/5.93: square 96 x 96
        if KT.shape != (N_F, N_F):
            raise DynamicsError(f"{phase}: [K; K_c] is {KT.shape}, expected 96 x 96")
        try:
            F = np.linalg.solve(KT, ZT)
        except np.linalg.LinAlgError as exc:
            raise DynamicsError(f"{phase}: [K; K_c] is singular (cond {np.linalg.cond(KT):.3g})") from exc
    else:                                            # eqs. 5.96/5.98: weighted minimum norm
        w = default_w_act() if w_act is None else np.asarray(w_act, float)
        if w.shape == (N_F, N_F):
            w = np.diag(w)
        if w.shape != (N_F,) or np.any(w <= 0):
            raise ValueError(f"W_act must be 96 positive weights (diagonal), got shape {w.shape}")
        Winv_KT = KT.T / w[:, None]                  # W^-1 K_T^T
        F = Winv_KT @ np.linalg.solve(KT @ Winv_KT, ZT)
    res = float(np.linalg.norm(KT @ F - ZT))
    return ComputedTorqueResult(phase=phase, T=phi() @ F, F=F, residual=res)
