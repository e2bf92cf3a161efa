"""Compiled twin of :mod:`humanoid_sim.references.chapter3.generator`'s reference queries (numba): the hip and
swing-toe references of a phase from its ``ReferenceTrajectory.ssp_table`` / ``dsp_table`` (thesis 3.2.3;
``hip_reference``, ``toe_reference``), and the zmp gait's hip grid appended to those tables.  Compared with the
reference in ``tests/test_kernel.py`` and ``tests/test_gait_walk.py``.  Lengths in m, angles in rad, times in s.
"""

from __future__ import annotations

import math

import numpy as np

from humanoid_sim.jit import njit
from humanoid_sim.references.chapter3.generator import DSP_TABLE, SSP_TABLE

SSP_TABLE_LEN = len(SSP_TABLE)
"""Chapter 3's single-support table length; a longer table carries the zmp gait's hip grid after it."""
DSP_TABLE_LEN = len(DSP_TABLE)
"""Chapter 3's double-support table length (as :data:`SSP_TABLE_LEN`)."""


@njit
def _cubic(c: np.ndarray, o: int, t: float) -> tuple[float, float]:
    """Value and rate of c[o] t^3 + c[o+1] t^2 + c[o+2] t + c[o+3] (``polynomials.eval_cubic``, Horner)."""
    c3, c2, c1, c0 = c[o], c[o + 1], c[o + 2], c[o + 3]
    return ((c3 * t + c2) * t + c1) * t + c0, (3.0 * c3 * t + 2.0 * c2) * t + c1


@njit
def _rz_into(R: np.ndarray, yaw: float) -> None:
    """R = Rz(yaw) (``generator._rz``)."""
    c, s = math.cos(yaw), math.sin(yaw)
    R[0, 0], R[0, 1], R[0, 2] = c, -s, 0.0
    R[1, 0], R[1, 1], R[1, 2] = s, c, 0.0
    R[2, 0], R[2, 1], R[2, 2] = 0.0, 0.0, 1.0


@njit
def _grid_hip(tab: np.ndarray, o: int, t: float, hip_z: float, p: np.ndarray, v: np.ndarray) -> None:
    """Body-17 CoM position and linear velocity at global time t from the hip grid appended at ``tab[o:]`` (the zmp
    gait: ``gait.zmp_walk.GRID_HEADER``): cubic Hermite of (position, velocity) (``gait.zmp_walk.hermite``)."""
    t0, T, n = tab[o], tab[o + 1], int(tab[o + 2])
    u = (t - t0) / T
    i = min(max(int(math.floor(u)), 0), n - 2)
    s = min(max(u - i, 0.0), 1.0)
    s2 = s * s
    s3 = s2 * s
    h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
    d00, d10, d01, d11 = 6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s
    a = o + 3 + 4 * i
    b = a + 4
    for j in range(2):
        p0, p1, m0, m1 = tab[a + j], tab[b + j], T * tab[a + 2 + j], T * tab[b + 2 + j]
        p[j] = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
        v[j] = (d00 * p0 + d10 * m0 + d01 * p1 + d11 * m1) / T
    p[2] = hip_z
    v[2] = 0.0


@njit
def ssp_references(tab: np.ndarray, t_a: float, t_b: float, p_a: np.ndarray, v_a: np.ndarray, R_a: np.ndarray,
                   p_b: np.ndarray, v_b: np.ndarray, R_b: np.ndarray) -> None:
    """The controller's references in a single-support phase from its ``ReferenceTrajectory.ssp_table``: the hip
    (Body-17 CoM position, [linear; angular] velocity, orientation) at global time t_a and the swing toe (point,
    [point velocity; foot angular velocity], toe-body orientation) at t_b, both clamped to the phase's nominal
    window (``ReferenceTrajectory.hip_reference`` / ``toe_reference``, thesis 3.2.3)."""
    t0, dur, hip_z, Ox, Oy, s, Rad, theta_cs = tab[0], tab[1], tab[2], tab[3], tab[4], tab[5], tab[6], tab[7]
    tc = min(max(t_a - t0, 0.0), dur)
    th, thd = _cubic(tab, 8, tc)
    phi = theta_cs + s * th
    sp, cp = math.sin(phi), math.cos(phi)
    if tab.size > SSP_TABLE_LEN:  # the zmp gait: the hip position from its planned grid, the yaw chapter 3's
        _grid_hip(tab, SSP_TABLE_LEN, t0 + tc, hip_z, p_a, v_a)
    else:
        p_a[0], p_a[1], p_a[2] = Ox + s * Rad * sp, Oy - s * Rad * cp, hip_z
        v_a[0], v_a[1], v_a[2] = Rad * thd * cp, Rad * thd * sp, 0.0
    v_a[3], v_a[4], v_a[5] = 0.0, 0.0, s * thd
    _rz_into(R_a, phi)
    tc = min(max(t_b - t0, 0.0), dur)
    t_z, R_f, theta_i = tab[12], tab[13], tab[14]
    if tc <= t_z:
        r, rd = _cubic(tab, 15, tc)
    else:
        r, rd = R_f, 0.0
    rot, rotd = _cubic(tab, 19, tc)
    h4, h3, h2, h1, h0 = tab[23], tab[24], tab[25], tab[26], tab[27]
    z = (((h4 * tc + h3) * tc + h2) * tc + h1) * tc + h0
    zd = ((4.0 * h4 * tc + 3.0 * h3) * tc + 2.0 * h2) * tc + h1
    phi = theta_cs + s * (theta_i + rot)
    sp, cp = math.sin(phi), math.cos(phi)
    p_b[0], p_b[1], p_b[2] = Ox + s * r * sp, Oy - s * r * cp, z
    v_b[0], v_b[1], v_b[2] = s * rd * sp + r * rotd * cp, -s * rd * cp + r * rotd * sp, zd
    yaw, yawd = _cubic(tab, 28, tc)
    v_b[3], v_b[4], v_b[5] = 0.0, 0.0, yawd
    _rz_into(R_b, yaw)


@njit
def dsp_references(tab: np.ndarray, t_a: float, p_a: np.ndarray, v_a: np.ndarray, R_a: np.ndarray) -> None:
    """The hip reference of a double-support phase from its ``ReferenceTrajectory.dsp_table`` at global time t_a,
    clamped to the phase's nominal window (``ReferenceTrajectory.hip_reference``, DSP branch: arc angle cubic d, yaw
    cubic e)."""
    t0, dur, hip_z, Ox, Oy, s, Rad, theta_cs = tab[0], tab[1], tab[2], tab[3], tab[4], tab[5], tab[6], tab[7]
    tc = min(max(t_a - t0, 0.0), dur)
    th, thd = _cubic(tab, 8, tc)
    phi = theta_cs + s * th
    yaw, yawd = _cubic(tab, 12, tc)
    sp, cp = math.sin(phi), math.cos(phi)
    if tab.size > DSP_TABLE_LEN:  # the zmp gait: the hip position from its planned grid, the yaw chapter 3's
        _grid_hip(tab, DSP_TABLE_LEN, t0 + tc, hip_z, p_a, v_a)
    else:
        p_a[0], p_a[1], p_a[2] = Ox + s * Rad * sp, Oy - s * Rad * cp, hip_z
        v_a[0], v_a[1], v_a[2] = Rad * thd * cp, Rad * thd * sp, 0.0
    v_a[3], v_a[4], v_a[5] = 0.0, 0.0, yawd
    _rz_into(R_a, yaw)
