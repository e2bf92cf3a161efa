"""The boundary-value polynomials of thesis section 3.2.3, solved exactly as printed.

Every polynomial of chapter 3 is found from a small linear system "A c = b" whose matrix the thesis
prints (L1352, L1366, L1457, L1487, L1537, L1574, L1603, L1708).  Coefficients are stored highest power
first, as in the thesis ([c3, c2, c1, c0] or [h4, ..., h0]).  Times are local phase times (s), L1339.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg


def cubic_bvp(T: float, p0: float, pT: float, v0: float, vT: float) -> tuple[float, float, float, float]:
    """Cubic with p(0)=p0, p(T)=pT, p'(0)=v0, p'(T)=vT; coefficients (c3, c2, c1, c0).

    The matrix and right-hand-side order are those of the thesis systems for theta_h (L1352),
    theta_hor (L1457), theta_rot (L1537), R_c (L1574, with T = t_z) and theta_For (L1708).
    """
    if not T > 0:
        raise ValueError(f"cubic_bvp: duration T must be > 0 (value: {T!r})")
    A = np.array([[0.0, 0.0, 0.0, 1.0],
                  [T**3, T**2, T, 1.0],
                  [0.0, 0.0, 1.0, 0.0],
                  [3 * T**2, 2 * T, 1.0, 0.0]])
    c = scipy.linalg.solve(A, np.array([p0, pT, v0, vT]))
    return float(c[0]), float(c[1]), float(c[2]), float(c[3])


def toe_height_quartic(t_ssp: float, k_sh: float, sh: float, z0: float) -> tuple[float, ...]:
    """Swing-toe height P_z(t) of thesis L1590-1603; coefficients (h4, h3, h2, h1, h0).

    P_z(0) = P_z(t_SSP) = z0 (0.015 m, flat toe), P_z(k_SH t_SSP) = SH, P_z'(0) = P_z'(t_SSP) = 0.
    """
    T, tm = t_ssp, k_sh * t_ssp
    A = np.array([[0.0, 0.0, 0.0, 0.0, 1.0],
                  [T**4, T**3, T**2, T, 1.0],
                  [tm**4, tm**3, tm**2, tm, 1.0],
                  [0.0, 0.0, 0.0, 1.0, 0.0],
                  [4 * T**3, 3 * T**2, 2 * T, 1.0, 0.0]])
    h = scipy.linalg.solve(A, np.array([z0, z0, sh, 0.0, 0.0]))
    return tuple(float(x) for x in h)


def eval_cubic(c: tuple[float, float, float, float], t: float) -> tuple[float, float, float]:
    """Value, first and second derivative of c3 t^3 + c2 t^2 + c1 t + c0 (Horner, scalar)."""
    c3, c2, c1, c0 = c
    return (((c3 * t + c2) * t + c1) * t + c0,
            (3.0 * c3 * t + 2.0 * c2) * t + c1,
            6.0 * c3 * t + 2.0 * c2)


def eval_quartic(h: tuple[float, ...], t: float) -> tuple[float, float, float]:
    """Value, first and second derivative of h4 t^4 + ... + h0 (Horner, scalar)."""
    h4, h3, h2, h1, h0 = h
    return ((((h4 * t + h3) * t + h2) * t + h1) * t + h0,
            ((4.0 * h4 * t + 3.0 * h3) * t + 2.0 * h2) * t + h1,
            (12.0 * h4 * t + 6.0 * h3) * t + 2.0 * h2)


def smoothstep(x):
    """x^2 (3 - 2 x): 0 -> 1 over x in [0, 1] with zero slope at both ends (the transfers and ramps of the zmp gait
    and its controller).  Not clamped: callers clamp x where it can leave [0, 1].  Scalar or array."""
    return x * x * (3.0 - 2.0 * x)
