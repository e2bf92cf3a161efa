"""The compiled numerics of the simulator's fast path (numba), in ONE module on purpose.

numba caches compiled code on disk per source file and checks only that file's time stamp: a function compiled
into another module's cache would keep running the old code of a helper edited here.  Keeping every jitted
function of the package in this file makes any edit invalidate all of them.

Kinematics of a free-flyer + axis-aligned revolute tree (conventions are Pinocchio's, tested against it in
``tests/test_kernel.py``):

- joint placements ``oMi[j] = oMi[parent] * jointPlacement[j] * M_j(q)``, M_j a rotation about the joint's x, y or z
  axis (JointModelRX/RY/RZ) or, for the free flyer, the placement (position, quaternion x y z w) in q[:7];
- ``J`` / ``dJ`` (6 x nv) are Pinocchio's WORLD joint Jacobians and their time derivative
  (``computeJointJacobiansTimeVariation``): column c is the spatial motion [v_o; w] (linear part = velocity of the
  body point at the world origin) of a unit rate of coordinate c, so the spatial velocity of a body is J v and its
  spatial acceleration J a + dJ v over the columns that support it;
- LOCAL_WORLD_ALIGNED rows of a frame at world position p: linear = velocity / classical acceleration of the frame
  origin, angular = angular velocity / acceleration (world axes); LOCAL rows: the spatial motion resolved in the
  frame, linear part at its origin.

The stage (thesis 5.1 command accelerations, 5.2 computed torque, eq. 4.69 actuator torques; both phase kinds) mirrors
the reference functions named in each docstring, formula for formula; the Python side is
:mod:`humanoid_sim.kernel.stage`.

All arrays are float64 unless stated; rotations are (3, 3) with columns the body axes in world coordinates;
lengths in m, velocities in m/s and rad/s, accelerations in m/s^2 and rad/s^2, forces in N and N m.
"""

from __future__ import annotations

import math

import numpy as np

from humanoid_sim.trajectory.generator import DSP_TABLE, SSP_TABLE

try:
    from numba import njit as _numba_njit
except ImportError:  # pragma: no cover - the simulator then never calls this module
    _numba_njit = None


def njit(fn):
    """Compile ``fn`` with numba (nopython, cached on disk, no fastmath, NumPy's error model: a division by zero
    gives inf / nan as in the reference path instead of raising), or return it unchanged when numba is missing.
    Defined here, not in a shared module, so that changing these options invalidates the disk cache too."""
    if _numba_njit is None:
        return fn
    return _numba_njit(cache=True, nogil=True, error_model="numpy")(fn)


FREE_FLYER = -1
"""Axis code of the free-flyer root joint (revolute joints: 0, 1, 2 = x, y, z; -2: the universe).  Defined here:
numba freezes module constants into the compiled code, so they must live in this file too."""
F_PC17, F_O17, F_TPR, F_TPL, F_O1, F_O2, F_O3, F_O4 = range(8)
"""Rows of the frame arrays: the controller's task frames in ``command.TASK_FRAMES`` order."""
LOG_SIZE = 45
SSP_TABLE_LEN = len(SSP_TABLE)
"""Chapter 3's single-support table length; a longer table carries the zmp gait's hip grid after it."""
DSP_TABLE_LEN = len(DSP_TABLE)
"""Chapter 3's double-support table length (as :data:`SSP_TABLE_LEN`)."""
"""Floats of the per-stage log vector (layout in ``stage.StageOutput``)."""


# ----------------------------------------------------------------------------------------------- copies
# Loops instead of slice assignment (``dst[a:b] = src``): numba's slice assignment also compiles the code that formats
# its shape-mismatch message, which made up a good part of the kernel's compile time; a copy is exact either way.
@njit
def _put(dst: np.ndarray, o: int, src: np.ndarray) -> None:
    """dst[o:o + src.size] = src (1-D arrays)."""
    for i in range(src.size):
        dst[o + i] = src[i]


@njit
def _put_flat(dst: np.ndarray, o: int, src: np.ndarray) -> None:
    """dst[o:o + src.size] = src.ravel() (src 2-D, row-major order)."""
    n, m = src.shape
    for i in range(n):
        for j in range(m):
            dst[o + i * m + j] = src[i, j]


@njit
def _put_col(dst: np.ndarray, r: int, c: int, src: np.ndarray) -> None:
    """dst[r:r + src.size, c] = src."""
    for i in range(src.size):
        dst[r + i, c] = src[i]


@njit
def _put_block(dst: np.ndarray, r: int, c: int, src: np.ndarray) -> None:
    """dst[r:r + src.shape[0], c:c + src.shape[1]] = src."""
    n, m = src.shape
    for i in range(n):
        for j in range(m):
            dst[r + i, c + j] = src[i, j]


# ----------------------------------------------------------------------------------------------- kinematics
@njit
def mm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A B for small matrices (explicit loops: numba's ``@`` goes through BLAS, ~1 us per call at these sizes)."""
    n, k = A.shape
    m = B.shape[1]
    out = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for l in range(k):
                s += A[i, l] * B[l, j]
            out[i, j] = s
    return out


@njit
def mtm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A^T B for small matrices (:func:`mm` of the transposed view)."""
    return mm(A.T, B)


@njit
def mv(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A x for a small matrix."""
    n, k = A.shape
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for l in range(k):
            s += A[i, l] * x[l]
        out[i] = s
    return out


@njit
def mtv(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A^T x for a small matrix (:func:`mv` of the transposed view)."""
    return mv(A.T, x)


@njit
def quat_to_rot(x: float, y: float, z: float, w: float) -> np.ndarray:
    """Rotation matrix of the unit quaternion (x, y, z, w) (Eigen's toRotationMatrix)."""
    tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    R = np.empty((3, 3))
    R[0, 0] = 1.0 - (tyy + tzz)
    R[0, 1] = txy - twz
    R[0, 2] = txz + twy
    R[1, 0] = txy + twz
    R[1, 1] = 1.0 - (txx + tzz)
    R[1, 2] = tyz - twx
    R[2, 0] = txz - twy
    R[2, 1] = tyz + twx
    R[2, 2] = 1.0 - (txx + tyy)
    return R


@njit
def rot_to_quat(R: np.ndarray, out: np.ndarray) -> None:
    """Quaternion (x, y, z, w) of a rotation matrix into ``out`` (Eigen's Quaternion(Matrix3) algorithm, the one
    behind ``pin.SE3ToXYZQUAT``, so the sign convention is the same)."""
    t = R[0, 0] + R[1, 1] + R[2, 2]
    if t > 0.0:
        s = math.sqrt(t + 1.0)
        out[3] = 0.5 * s
        s = 0.5 / s
        out[0] = (R[2, 1] - R[1, 2]) * s
        out[1] = (R[0, 2] - R[2, 0]) * s
        out[2] = (R[1, 0] - R[0, 1]) * s
    else:
        i = 0
        if R[1, 1] > R[0, 0]:
            i = 1
        if R[2, 2] > R[i, i]:
            i = 2
        j = (i + 1) % 3
        k = (j + 1) % 3
        s = math.sqrt(R[i, i] - R[j, j] - R[k, k] + 1.0)
        out[i] = 0.5 * s
        s = 0.5 / s
        out[3] = (R[k, j] - R[j, k]) * s
        out[j] = (R[j, i] + R[i, j]) * s
        out[k] = (R[k, i] + R[i, k]) * s


@njit
def forward_kinematics(q: np.ndarray, parents: np.ndarray, axis: np.ndarray, idx_q: np.ndarray, jR: np.ndarray,
                       jp: np.ndarray, R: np.ndarray, p: np.ndarray) -> None:
    """World placements of all joints into R (nj, 3, 3) and p (nj, 3) (Pinocchio's oMi), without temporaries.

    A revolute joint about axis a rotates the placement's columns b = a+1, c = a+2 (mod 3):
    (jR Rot_a(t))[:, b] = cos t jR[:, b] + sin t jR[:, c], [:, c] = -sin t jR[:, b] + cos t jR[:, c]."""
    B = np.empty((3, 3))
    for r in range(3):
        for k in range(3):
            R[0, r, k] = 1.0 if r == k else 0.0
        p[0, r] = 0.0
    for j in range(1, parents.size):
        Rp = R[parents[j]]
        pp = p[parents[j]]
        if axis[j] == FREE_FLYER:
            i = idx_q[j]
            Rl = quat_to_rot(q[i + 3], q[i + 4], q[i + 5], q[i + 6])
            for r in range(3):  # jointPlacement * (quaternion, position): parent is the universe
                for k in range(3):
                    B[r, k] = jR[j, r, 0] * Rl[0, k] + jR[j, r, 1] * Rl[1, k] + jR[j, r, 2] * Rl[2, k]
                p[j, r] = jp[j, r] + (jR[j, r, 0] * q[i] + jR[j, r, 1] * q[i + 1] + jR[j, r, 2] * q[i + 2])
            for r in range(3):
                for k in range(3):
                    R[j, r, k] = B[r, k]
            continue
        a = axis[j]
        b = (a + 1) % 3
        c = (a + 2) % 3
        t = q[idx_q[j]]
        ct, st = math.cos(t), math.sin(t)
        for r in range(3):
            B[r, a] = jR[j, r, a]
            B[r, b] = ct * jR[j, r, b] + st * jR[j, r, c]
            B[r, c] = -st * jR[j, r, b] + ct * jR[j, r, c]
        for r in range(3):
            for k in range(3):
                R[j, r, k] = Rp[r, 0] * B[0, k] + Rp[r, 1] * B[1, k] + Rp[r, 2] * B[2, k]
            p[j, r] = pp[r] + (Rp[r, 0] * jp[j, 0] + Rp[r, 1] * jp[j, 1] + Rp[r, 2] * jp[j, 2])


@njit
def frame_placement(R: np.ndarray, p: np.ndarray, parent: int, fR: np.ndarray, fp: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, position) of a frame with placement (fR, fp) in joint ``parent`` (Pinocchio's oMf)."""
    Rj = R[parent]
    return mm(Rj, fR), p[parent] + mv(Rj, fp)


@njit
def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of 3-vectors."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit
def spatial_motion(J: np.ndarray, dJ: np.ndarray, v: np.ndarray, support: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """World spatial velocity J v and bias acceleration dJ v (6,, [linear at the origin; angular]) of the body
    whose supporting columns are ``support``."""
    V = np.zeros(6)
    A = np.zeros(6)
    for c in range(v.size):
        if support[c]:
            for r in range(6):
                V[r] += J[r, c] * v[c]
                A[r] += dJ[r, c] * v[c]
    return V, A


@njit
def frame_motion_lwa(J: np.ndarray, dJ: np.ndarray, v: np.ndarray, support: np.ndarray, pos: np.ndarray,
                     out: np.ndarray) -> np.ndarray:
    """[J | drift] (6 x (nv + 1)) of a frame at world position ``pos`` into ``out``, LOCAL_WORLD_ALIGNED:
    the frame Jacobian and, as the last column, the classical acceleration at zero generalized acceleration.
    Returns the frame's LOCAL_WORLD_ALIGNED velocity (6,)."""
    nv = v.size
    for c in range(nv):
        if support[c]:
            out[0, c] = J[0, c] + (J[4, c] * pos[2] - J[5, c] * pos[1])
            out[1, c] = J[1, c] + (J[5, c] * pos[0] - J[3, c] * pos[2])
            out[2, c] = J[2, c] + (J[3, c] * pos[1] - J[4, c] * pos[0])
            out[3, c] = J[3, c]
            out[4, c] = J[4, c]
            out[5, c] = J[5, c]
        else:
            for r in range(6):
                out[r, c] = 0.0
    V, A = spatial_motion(J, dJ, v, support)
    w = V[3:]
    alpha = A[3:]
    vel = np.empty(6)
    _put(vel, 0, V[:3] + cross(w, pos))
    _put(vel, 3, w)
    acc = A[:3] + cross(alpha, pos) + cross(w, vel[:3])
    _put_col(out, 0, nv, acc)
    _put_col(out, 3, nv, alpha)
    return vel


@njit
def frame_motion_local(J: np.ndarray, dJ: np.ndarray, v: np.ndarray, support: np.ndarray, Rf: np.ndarray,
                       pos: np.ndarray, Jout: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """LOCAL frame Jacobian (6 x nv) into ``Jout``; returns the LOCAL spatial velocity and the LOCAL spatial
    acceleration at zero generalized acceleration (Pinocchio's getFrameVelocity / getFrameAcceleration, LOCAL)."""
    RT = Rf.T.copy()
    lin = np.empty(3)
    ang = np.empty(3)
    for c in range(v.size):
        if support[c]:
            ang[0], ang[1], ang[2] = J[3, c], J[4, c], J[5, c]
            lin[0] = J[0, c] + (J[4, c] * pos[2] - J[5, c] * pos[1])
            lin[1] = J[1, c] + (J[5, c] * pos[0] - J[3, c] * pos[2])
            lin[2] = J[2, c] + (J[3, c] * pos[1] - J[4, c] * pos[0])
            _put_col(Jout, 0, c, mv(RT, lin))
            _put_col(Jout, 3, c, mv(RT, ang))
        else:
            for r in range(6):
                Jout[r, c] = 0.0
    V, A = spatial_motion(J, dJ, v, support)
    vel = np.empty(6)
    acc = np.empty(6)
    _put(vel, 0, mv(RT, V[:3] + cross(V[3:], pos)))
    _put(vel, 3, mv(RT, V[3:]))
    _put(acc, 0, mv(RT, A[:3] + cross(A[3:], pos)))
    _put(acc, 3, mv(RT, A[3:]))
    return vel, acc


@njit
def log3(R: np.ndarray) -> np.ndarray:
    """Rotation vector of R (rad), angle in [0, pi): w = theta / sin(theta) * vee(R - R^T) / 2 with theta from
    atan2(|vee|, (tr R - 1) / 2), accurate for small angles (the welds' errors are <= 1e-6 rad)."""
    s = np.empty(3)
    s[0] = 0.5 * (R[2, 1] - R[1, 2])
    s[1] = 0.5 * (R[0, 2] - R[2, 0])
    s[2] = 0.5 * (R[1, 0] - R[0, 1])
    sn = math.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2])
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    theta = math.atan2(sn, c)
    if sn < 1e-300:
        return np.zeros(3)
    return s * (theta / sn)


_LOG6_TAYLOR = float(np.finfo(float).eps) ** (1.0 / 3.0)
"""log6 uses its Taylor coefficients when tr R >= 3 - _LOG6_TAYLOR (angle below ~2.5e-3 rad), Pinocchio's switch
(spatial/log.hxx): above it the closed form's 1 - cos(theta) has lost no more than ~1e-11 relative."""


@njit
def log6(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """SE(3) logarithm [v; w] (6,) of the placement (R, p) (Pinocchio's log6)."""
    w = log3(R)
    t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    theta = math.sqrt(t2)
    if R[0, 0] + R[1, 1] + R[2, 2] >= 3.0 - _LOG6_TAYLOR:
        alpha = 1.0 - t2 / 12.0 - t2 * t2 / 720.0
        beta = 1.0 / 12.0 + t2 / 720.0
    else:
        st, ct = math.sin(theta), math.cos(theta)
        alpha = theta * st / (2.0 * (1.0 - ct))
        beta = 1.0 / t2 - st / (2.0 * theta * (1.0 - ct))
    out = np.empty(6)
    _put(out, 0, alpha * p - 0.5 * cross(w, p) + (beta * (w[0] * p[0] + w[1] * p[1] + w[2] * p[2])) * w)
    _put(out, 3, w)
    return out


@njit
def action_matrix(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Ad(M) (6 x 6) of M = (R, p) acting on [linear; angular] motions: [[R, [p]x R], [0, R]]."""
    A = np.zeros((6, 6))
    _put_block(A, 0, 0, R)
    _put_block(A, 3, 3, R)
    for c in range(3):
        _put_col(A, 0, 3 + c, cross(p, R[:, c]))
    return A


# ----------------------------------------------------------------------------------------------- small algebra
@njit
def _cholesky_solve(Z: np.ndarray, g: np.ndarray) -> np.ndarray:
    """x with Z x = g for symmetric positive definite Z (lower Cholesky factor, as LAPACK posv); NaNs when Z is
    not positive definite (the caller reports it)."""
    n = g.size
    L = np.zeros((n, n))
    for j in range(n):
        s = Z[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return np.full(n, np.nan)
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            s = Z[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    y = np.empty(n)
    for i in range(n):
        s = g[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x


@njit
def _solve3(B: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with B x = b for a 3 x 3 B (Gaussian elimination, partial pivoting)."""
    A = B.copy()
    x = b.copy()
    for c in range(3):
        piv = c
        for r in range(c + 1, 3):
            if abs(A[r, c]) > abs(A[piv, c]):
                piv = r
        if piv != c:
            for k in range(3):
                A[c, k], A[piv, k] = A[piv, k], A[c, k]
            x[c], x[piv] = x[piv], x[c]
        for r in range(c + 1, 3):
            f = A[r, c] / A[c, c]
            for k in range(c, 3):
                A[r, k] -= f * A[c, k]
            x[r] -= f * x[c]
    for c in range(2, -1, -1):
        s = x[c]
        for k in range(c + 1, 3):
            s -= A[c, k] * x[k]
        x[c] = s / A[c, c]
    return x


# ----------------------------------------------------------------------------------------------- references
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


# ----------------------------------------------------------------------------------------------- controller
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
        _put_block(T, 3, 0, motion[body][3:])
        _put(v6, 3, vel[body][3:])
    D = T - W
    d = fpos[weld] - fpos[point]  # S = [d]x: S x = d x x
    for c in range(nv + 1):
        wx, wy, wz = W[3, c], W[4, c], W[5, c]
        D[0, c] -= d[1] * wz - d[2] * wy
        D[1, c] -= d[2] * wx - d[0] * wz
        D[2, c] -= d[0] * wy - d[1] * wx
    J = np.empty((6, jcols.size))
    for i in range(jcols.size):
        _put_col(J, 0, i, D[:, jcols[i]] * jsign[i])
    return J, D[:, nv].copy(), v6


@njit
def _tracking_rows(A: np.ndarray, r: np.ndarray, J6: np.ndarray, drift6: np.ndarray, p: np.ndarray,
                   v6: np.ndarray, R: np.ndarray, ref_p: np.ndarray, ref_v: np.ndarray, ref_R: np.ndarray,
                   dt: float) -> None:
    """The 12 rows (position 3, velocity 6, C_diag orientation 3) of one task body (eqs. 5.1-5.3, errata C-1)."""
    h2 = 0.5 * dt * dt
    _put_block(A, 0, 0, J6[:3] * h2)
    _put(r, 0, ref_p - (p + v6[:3] * dt + drift6[:3] * h2))
    _put_block(A, 3, 0, J6 * dt)
    _put(r, 3, ref_v - (v6 + drift6 * dt))
    w = v6[3:]
    L = np.zeros((3, 3))  # d/dt C_diag = L w (taskspace.cdiag_rate_matrix)
    L[0, 1], L[0, 2] = R[2, 0], -R[1, 0]
    L[1, 0], L[1, 2] = -R[2, 1], R[0, 1]
    L[2, 0], L[2, 1] = R[1, 2], -R[0, 2]
    diag = np.empty(3)
    for i in range(3):
        diag[i] = R[i, i]
    bias = w * mtv(R, w) - (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * diag  # diag([w]x [w]x C)
    _put_block(A, 9, 0, mm(L, J6[3:]) * h2)
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
                ref_b_v, ref_b_R, ip, fp_) -> np.ndarray:
    """Command accelerations theta_ddot_c (26,) of a single-support phase (``CommandAccelerations.compute``, SSP
    branch).  ``ip`` (int64): root weld frame, other toe point frame, other weld frame, stance toe, other toe,
    k_toe, n_s, n_o, then xs (n_s), xo (n_o), upper joints (10).  ``fp_`` (float64): dt_a, dt_b, ha, hb, s_p, w_p,
    s_v, w_v, theta0_toe, then wa_rows (12), wb_rows (12), dZ_a (n_s), dZ_b (n_o), W_q_a (n_s), W_q_b (n_o),
    upper Wp, Wv, dt, den, dt2, dt3 (10 each)."""
    root, toe_pt, other_weld, stance_toe, other_toe, k_toe, ns, no = (ip[0], ip[1], ip[2], ip[3], ip[4], ip[5],
                                                                      ip[6], ip[7])
    xs = ip[8:8 + ns]
    xo = ip[8 + ns:8 + ns + no]
    qu = ip[8 + ns + no:18 + ns + no]
    dta, dtb, ha, hb, s_p, w_p, s_v, w_v, theta0_toe = (fp_[0], fp_[1], fp_[2], fp_[3], fp_[4], fp_[5], fp_[6],
                                                        fp_[7], fp_[8])
    o = 9
    wa_rows = fp_[o:o + 12]
    wb_rows = fp_[o + 12:o + 24]
    o += 24
    dZ_a = fp_[o:o + ns]
    dZ_b = fp_[o + ns:o + ns + no]
    Wq_a = fp_[o + ns + no:o + 2 * ns + no]
    Wq_b = fp_[o + 2 * ns + no:o + 2 * ns + 2 * no]
    o += 2 * (ns + no)
    qdd = np.zeros(26)
    # step 1: stance-leg joints for Body 17 and its CoM (5.1.1.1.1)
    J, drift, v6 = _body_task(motion, vel, fpos, fparent, F_PC17, F_O17, root, jcols, jsign)
    Aa = np.zeros((12, ns))
    ra = np.zeros(12)
    Js = np.empty((6, ns))
    for i in range(ns):
        _put_col(Js, 0, i, J[:, xs[i]])
    _tracking_rows(Aa, ra, Js, drift, fpos[F_PC17], v6, fR[F_O17], ref_a_p, ref_a_v, ref_a_R, dta)
    dg = np.empty(ns)
    for i in range(ns):
        dg[i] = Wq_a[i] * ha * -(th[xs[i]] + thd[xs[i]] * dta)
    Z, g = _normal(Aa, ra, wa_rows, dZ_a, dg)
    qdd_s = _cholesky_solve(Z, g)
    for i in range(ns):
        qdd[xs[i]] = qdd_s[i]
    # step 2: swing-leg joints for the swing toe point and toe body, given step 1 (5.1.1.1.2)
    J, drift, v6 = _body_task(motion, vel, fpos, fparent, toe_pt, other_weld, root, jcols, jsign)
    drift = drift + _cols_times(J, xs, qdd_s)
    Ab = np.zeros((12, no))
    rb = np.zeros(12)
    Jo = np.empty((6, no))
    for i in range(no):
        _put_col(Jo, 0, i, J[:, xo[i]])
    _tracking_rows(Ab, rb, Jo, drift, fpos[toe_pt], v6, fR[other_weld], ref_b_p, ref_b_v, ref_b_R, dtb)
    dg = np.empty(no)
    for i in range(no):
        dg[i] = Wq_b[i] * hb * -(th[xo[i]] + thd[xo[i]] * dtb)
    th_toe = th[other_toe] + theta0_toe
    dg[k_toe] += (w_p * s_p * -(th_toe + thd[other_toe] * s_v)) + (w_v * s_v * -thd[other_toe])
    Z, g = _normal(Ab, rb, wb_rows, dZ_b, dg)
    qdd_o = _cholesky_solve(Z, g)
    for i in range(no):
        qdd[xo[i]] = qdd_o[i]
    qdd[stance_toe] = 0.0
    _upper_body(qdd, th, thd, qu, fp_[o:o + 60])
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
def _controller_dsp(motion, vel, fpos, fR, fparent, th, thd, jcols, jsign, ref_p, ref_v, ref_R, ip, fp_
                    ) -> np.ndarray:
    """Command accelerations theta_ddot_c (26,) of a double-support phase (``CommandAccelerations.compute``, DSP
    branch, thesis 5.1.1.3): both chains to Body 17 in one cost over x = [stance chain; trailing chain], the closed
    chain (eq. 5.59: the trailing toe body's acceleration through the stance chain is zero) by Lagrange multipliers
    (eqs. 5.62/5.63).  ``ip``: root weld frame, other weld frame, stance toe, n_s, n_o, xs, xo, upper joints (10);
    ``fp_``: dt, ha, the 24 row weights, dZ (n), W_q (n), upper-body numbers (60)."""
    root, other_weld, stance_toe, ns, no = ip[0], ip[1], ip[2], ip[3], ip[4]
    n = ns + no
    x = ip[5:5 + n]
    qu = ip[5 + n:15 + n]
    dt, ha = fp_[0], fp_[1]
    w_rows = fp_[2:26]
    dZ = fp_[26:26 + n]
    W_q = fp_[26 + n:26 + 2 * n]
    A = np.zeros((24, n))
    r = np.zeros(24)
    Ja, da, va = _body_task(motion, vel, fpos, fparent, F_PC17, F_O17, root, jcols, jsign)
    Js = np.empty((6, ns))
    for i in range(ns):
        _put_col(Js, 0, i, Ja[:, x[i]])
    ra = np.zeros(12)
    Aa = np.zeros((12, ns))
    _tracking_rows(Aa, ra, Js, da, fpos[F_PC17], va, fR[F_O17], ref_p, ref_v, ref_R, dt)
    Jb, db, vb = _body_task(motion, vel, fpos, fparent, F_PC17, F_O17, other_weld, jcols, jsign)
    Jo = np.empty((6, no))
    for i in range(no):
        _put_col(Jo, 0, i, Jb[:, x[ns + i]])
    rb = np.zeros(12)
    Ab = np.zeros((12, no))
    _tracking_rows(Ab, rb, Jo, db, fpos[F_PC17], vb, fR[F_O17], ref_p, ref_v, ref_R, dt)
    _put_block(A, 0, 0, Aa)
    _put_block(A, 12, ns, Ab)
    _put(r, 0, ra)
    _put(r, 12, rb)
    dg = np.empty(n)
    for i in range(n):
        dg[i] = W_q[i] * ha * -(th[x[i]] + thd[x[i]] * dt)
    Z, g = _normal(A, r, w_rows, dZ, dg)
    Jc, dc, _ = _body_task(motion, vel, fpos, fparent, other_weld, other_weld, root, jcols, jsign)
    K = np.zeros((n + 6, n + 6))
    rhs = np.zeros(n + 6)
    _put_block(K, 0, 0, Z)
    for i in range(n):
        for c in range(6):
            K[i, n + c] = Jc[c, x[i]]
            K[n + c, i] = Jc[c, x[i]]
    _put(rhs, 0, g)
    _put(rhs, n, -dc)
    sol = _solve_dense(K, rhs)
    qdd = np.zeros(26)
    for i in range(n):
        qdd[x[i]] = sol[i]
    qdd[stance_toe] = 0.0
    _upper_body(qdd, th, thd, qu, fp_[26 + 2 * n:86 + 2 * n])
    return qdd


@njit
def _solve_dense(K: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with K x = b (Gaussian elimination with partial pivoting, as LAPACK gesv); NaNs when K is singular."""
    n = b.size
    A = K.copy()
    x = b.copy()
    for c in range(n):
        piv = c
        for rr in range(c + 1, n):
            if abs(A[rr, c]) > abs(A[piv, c]):
                piv = rr
        if A[piv, c] == 0.0:
            return np.full(n, np.nan)
        if piv != c:
            for k in range(n):
                A[c, k], A[piv, k] = A[piv, k], A[c, k]
            x[c], x[piv] = x[piv], x[c]
        for rr in range(c + 1, n):
            f = A[rr, c] / A[c, c]
            if f != 0.0:
                for k in range(c, n):
                    A[rr, k] -= f * A[c, k]
                x[rr] -= f * x[c]
    for c in range(n - 1, -1, -1):
        acc = x[c]
        for k in range(c + 1, n):
            acc -= A[c, k] * x[k]
        x[c] = acc / A[c, c]
    return x


@njit
def _cols_times(J: np.ndarray, cols: np.ndarray, x: np.ndarray) -> np.ndarray:
    """J[:, cols] @ x."""
    out = np.zeros(J.shape[0])
    for i in range(cols.size):
        out += J[:, cols[i]] * x[i]
    return out


# ----------------------------------------------------------------------------------------------- dynamics
@njit
def _contact_rows(J, dJ, v, q, support, fparent, fR, fpos, welds, anchor_R, anchor_p, lock_q, lock_v, lock_anchor, kp,
                  kd) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Constraint Jacobian Jc (6 n_w + 1 x nv: the LOCAL rows of each weld of frame rows ``welds`` with anchors
    ``anchor_R`` (n_w, 3, 3), ``anchor_p`` (n_w, 3), then the lock row), rhs shift r = Jdot v + Kd Jc v + Kp e, and
    the largest weld position and orientation errors (m, rad) (``ConstraintRows.evaluate``: welds + one lock)."""
    nv = v.size
    nw = welds.size
    m = 6 * nw + 1
    Jc = np.zeros((m, nv))
    r = np.empty(m)
    pos_err = 0.0
    ori_err = 0.0
    for w in range(nw):
        f = welds[w]
        Rf, pf = fR[f], fpos[f]
        vel, acc = frame_motion_local(J, dJ, v, support[fparent[f]], Rf, pf, Jc[6 * w:6 * w + 6])
        Ra, pa = anchor_R[w], anchor_p[w]
        e = log6(mtm(Ra, Rf), mtv(Ra, pf - pa))
        for i in range(6):
            r[6 * w + i] = kd * vel[i]
            r[6 * w + i] += acc[i]
            r[6 * w + i] += kp * e[i]
        dp = pf - pa
        pos_err = max(pos_err, np.sqrt(dp[0] * dp[0] + dp[1] * dp[1] + dp[2] * dp[2]))
        ori_err = max(ori_err, np.sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5]))
    Jc[m - 1, lock_v] = 1.0
    r[m - 1] = kd * v[lock_v]  # the lock row has no drift (its Jacobian is constant)
    r[m - 1] += kp * (q[lock_q] - lock_anchor)
    return Jc, r, pos_err, ori_err


@njit
def _inverse_square(Jc, r, M, h, a_des, Rb, pb, Rf, pf, lock_v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, tau, lam) of the single-support computed torque (``contact.inverse._solve_square``): free joints take
    the desired accelerations, the weld fixes the base (J_Wb^-1 = Ad(bMf)), the lock row the locked joint."""
    nv = a_des.size
    a = a_des.copy()
    a[lock_v] = -r[6]
    Jb_inv = action_matrix(mtm(Rb, Rf), mtv(Rb, pf - pb))
    _put(a, 0, mv(Jb_inv, -r[:6] - mv(Jc[:6, 6:], a[6:])))
    b = mv(M, a) + h
    lam_w = mtv(Jb_inv, b[:6])
    g = b - mtv(Jc[:6], lam_w)
    tau = np.zeros(nv)
    _put(tau, 6, g[6:])
    tau[lock_v] = 0.0
    lam = np.empty(7)
    _put(lam, 0, lam_w)
    lam[6] = g[lock_v]
    return a, tau, lam


@njit
def _inverse_general(Jc, r, M, h, a_des, lock_v, w_tau, w_lam) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, tau, lam) of the double-support computed torque (``contact.inverse.solve_inverse``, general branch): the
    free-joint accelerations closest to the desired ones that satisfy the constraints (KKT), then the weighted
    minimum-norm [tau_act; lambda] of A x = M a + h, A = [S_act^T, J^T], weights ``w_tau`` (nv,, on the actuated
    coordinates: all but the base and the locked joint) and ``w_lam`` (m,)."""
    nv = a_des.size
    m = r.size
    K = np.zeros((nv + m, nv + m))
    rhs = np.zeros(nv + m)
    for i in range(6, nv):
        if i != lock_v:
            K[i, i] = 1.0
            rhs[i] = a_des[i]
    for k in range(m):
        for i in range(nv):
            K[i, nv + k] = Jc[k, i]
            K[nv + k, i] = Jc[k, i]
        rhs[nv + k] = -r[k]
    a = _solve_dense(K, rhs)[:nv]
    b = mv(M, a) + h
    # A W^-1 A^T = sum over actuated i of e_i e_i^T / w_tau_i + J^T diag(1 / w_lam) J
    Z = np.zeros((nv, nv))
    for k in range(m):
        wk = 1.0 / w_lam[k]
        for i in range(nv):
            ci = Jc[k, i] * wk
            if ci != 0.0:
                for j in range(nv):
                    Z[i, j] += ci * Jc[k, j]
    for i in range(6, nv):
        if i != lock_v:
            Z[i, i] += 1.0 / w_tau[i]
    y = _cholesky_solve(Z, b)
    tau = np.zeros(nv)
    for i in range(6, nv):
        if i != lock_v:
            tau[i] = y[i] / w_tau[i]
    lam = mv(Jc, y) / w_lam
    return a, tau, lam


@njit
def _thesis_torques(J, dJ, v, a, tau, R, p, support, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity
                    ) -> np.ndarray:
    """T (26,, T-bar order) (``Actuators.thesis_torques``).  g1 (n1, 5) int: T row, v index, sign (+-1),
    higher-joint slot, component of the one-component groups; g3 (n3, 10) int: 3 T rows, 3 v indices, 3 signs,
    higher-joint slot; gs (2, 6) int: 2 T rows, 2 components, tree joint, higher-joint slot of the shoulders,
    with ``arm_mass`` (2,), ``arm_lever`` (2, 3), ``arm_I`` (2, 3, 3) (inertia about the CoM, joint frame);
    hj: joint ids of the higher bodies (slots)."""
    T = np.zeros(26)
    for i in range(g1.shape[0]):
        row, vi, sg, slot, comp = g1[i, 0], g1[i, 1], g1[i, 2], g1[i, 3], g1[i, 4]
        Rh = R[hj[slot]]
        b = sg * (J[3, vi] * Rh[0, comp] + J[4, vi] * Rh[1, comp] + J[5, vi] * Rh[2, comp])
        T[row] = tau[vi] / b
    B = np.empty((3, 3))
    rhs = np.empty(3)
    for i in range(g3.shape[0]):
        Rh = R[hj[g3[i, 9]]]
        for k in range(3):
            vi, sg = g3[i, 3 + k], g3[i, 6 + k]
            for c in range(3):
                B[k, c] = sg * (J[3, vi] * Rh[0, c] + J[4, vi] * Rh[1, c] + J[5, vi] * Rh[2, c])
            rhs[k] = tau[vi]
        x = _solve3(B, rhs)
        for k in range(3):
            T[g3[i, k]] = x[k]
    for i in range(gs.shape[0]):  # the arm (a leaf body): its Newton-Euler wrench about the shoulder point
        tj, slot = gs[i, 4], gs[i, 5]
        Rt, pt = R[tj], p[tj]
        V = np.zeros(6)
        A = np.zeros(6)
        for c in range(v.size):
            if support[tj, c]:
                for k in range(6):
                    V[k] += J[k, c] * v[c]
                    A[k] += J[k, c] * a[c] + dJ[k, c] * v[c]
        w, alpha = V[3:], A[3:]
        com = pt + mv(Rt, arm_lever[i])
        vc = V[:3] + cross(w, com)
        ac = A[:3] + cross(alpha, com) + cross(w, vc)
        f = arm_mass[i] * (ac - gravity)
        Iw = mm(mm(Rt, arm_I[i]), Rt.T)
        n = mv(Iw, alpha) + cross(w, mv(Iw, w)) + cross(com - pt, f)  # moment on the arm from the trunk, about pt
        m = mtv(R[hj[slot]], n)
        T[gs[i, 0]] = m[gs[i, 2]]
        T[gs[i, 1]] = m[gs[i, 3]]
    return T


# ----------------------------------------------------------------------------------------------- the stage
@njit
def _stage_state(q, v, J, dJ, parents, axis, idx_q, jR, jp, support, fparent, fRp, fpp, jcols, jsign, theta_q, theta0,
                 fneed, R, p, fR, fpos, motion, vel) -> tuple[np.ndarray, np.ndarray]:
    """What every stage starts from: joint placements R, p, frame placements fR, fpos, and for the frames flagged in
    ``fneed`` the LOCAL_WORLD_ALIGNED [J | drift] ``motion`` and velocities ``vel`` (all written into the work
    buffers); returns the thesis joint deviations theta - theta0 and rates (26, each)."""
    forward_kinematics(q, parents, axis, idx_q, jR, jp, R, p)
    for i in range(fparent.size):
        Rf, pf = frame_placement(R, p, fparent[i], fRp[i], fpp[i])
        _put_block(fR[i], 0, 0, Rf)
        _put(fpos[i], 0, pf)
        if fneed[i]:
            _put(vel[i], 0, frame_motion_lwa(J, dJ, v, support[fparent[i]], fpos[i], motion[i]))
    th = np.empty(26)
    thd = np.empty(26)
    for i in range(26):
        th[i] = jsign[i] * q[theta_q[i]] - theta0[i]
        thd[i] = jsign[i] * v[jcols[i]]
    return th, thd


@njit
def ssp_controller(q, v, J, dJ, tab, t, parents, axis, idx_q, jR, jp,
                   support, fparent, fRp, fpp, jcols, jsign, theta_q, theta0, ip, fp_, fneed, R, p, fR, fpos, motion,
                   vel, qdd_out):
    """Command accelerations theta_ddot_c (26,) of a single-support stage, written into ``qdd_out``.

    The compiled functions called from Python write into arrays the caller allocated and return nothing: returning
    arrays would make numba call back into Python (to unpickle their dtype) in the middle of native code, where a
    Ctrl-C then surfaces as a SystemError instead of a KeyboardInterrupt (and costs ~0.5 us per array).

    Inputs: the state (q, v) at time t (s); Pinocchio's WORLD joint Jacobians J, dJ at that state; the phase's
    reference table (``ReferenceTrajectory.ssp_table``, queried at t + the two prediction times); the constant arrays
    of :class:`StageKernel`.  Work buffers filled for :func:`ssp_dynamics`: joint placements R, p,
    frame placements fR, fpos, and for the frames flagged in ``fneed`` (the ones this phase's tasks read) the frame
    [J | drift] ``motion`` and velocities ``vel`` (LOCAL_WORLD_ALIGNED)."""
    th, thd = _stage_state(q, v, J, dJ, parents, axis, idx_q, jR, jp, support, fparent, fRp, fpp, jcols, jsign,
                           theta_q, theta0, fneed, R, p, fR, fpos, motion, vel)
    ref_a_p, ref_a_v, ref_a_R = np.empty(3), np.empty(6), np.empty((3, 3))
    ref_b_p, ref_b_v, ref_b_R = np.empty(3), np.empty(6), np.empty((3, 3))
    ssp_references(tab, t + fp_[0], t + fp_[1], ref_a_p, ref_a_v, ref_a_R, ref_b_p, ref_b_v, ref_b_R)
    _put(qdd_out, 0, _controller(motion, vel, fpos, fR, fparent, th, thd, jcols, jsign, ref_a_p, ref_a_v, ref_a_R,
                                 ref_b_p, ref_b_v, ref_b_R, ip, fp_))


@njit
def ssp_dynamics(q, v, J, dJ, M_upper, h, qdd, anchor_R, anchor_p, lock_anchor, support, fparent, jcols, jsign,
                 welds, lock_q, lock_v, kp, kd, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity, limits, R, p, fR,
                 fpos, vel, a_out, lam_out, T_out, tau_out, log):
    """Computed torque of a single-support stage for the command accelerations ``qdd``, written into a_out (nv,),
    lam_out (7,), T_out (26,, T_cmd), tau_out (nv,) and log (LOG_SIZE,, zeroed here).  M_upper: Pinocchio's crba
    (upper triangle), h: nonLinearEffects; ``welds``: the support foot's weld frame row (one); the work buffers
    R ... vel as :func:`ssp_controller` left them."""
    M = _symmetric(M_upper)
    a_des = _a_desired(qdd, jcols, jsign, v.size)
    Jc, r, pos_err, ori_err = _contact_rows(J, dJ, v, q, support, fparent, fR, fpos, welds, anchor_R, anchor_p,
                                            lock_q, lock_v, lock_anchor, kp, kd)
    w = welds[0]
    a, tau, lam = _inverse_square(Jc, r, M, h, a_des, R[1], p[1], fR[w], fpos[w], lock_v)
    _finish(J, dJ, v, qdd, M, h, Jc, a, tau, lam, pos_err, ori_err, R, p, fR, fpos, vel, support, g1, g3, gs, hj,
            arm_mass, arm_lever, arm_I, gravity, limits, a_out, lam_out, T_out, tau_out, log)


@njit
def _symmetric(M_upper: np.ndarray) -> np.ndarray:
    """The symmetric joint-space inertia from the upper triangle crba fills."""
    nv = M_upper.shape[0]
    M = M_upper.copy()
    for i in range(nv):
        for k in range(i):
            M[i, k] = M_upper[k, i]
    return M


@njit
def _a_desired(qdd: np.ndarray, jcols: np.ndarray, jsign: np.ndarray, nv: int) -> np.ndarray:
    """Generalized accelerations (nv,) of the thesis command accelerations (``HumanoidModel.v_from_theta_dot``)."""
    a = np.zeros(nv)
    for i in range(jcols.size):
        a[jcols[i]] = jsign[i] * qdd[i]
    return a


@njit
def _log_frames(log: np.ndarray, fR: np.ndarray, fpos: np.ndarray, vel: np.ndarray) -> None:
    """The task frames a stage log records (``stage.StageOutput`` layout, entries 4-42): the hip CoM and its
    velocity, Body 17's orientation, both toe points, both toe bodies' orientations."""
    _put(log, 4, fpos[F_PC17])
    _put(log, 7, vel[F_PC17][:3])
    _put_flat(log, 10, fR[F_O17])
    _put(log, 19, fpos[F_TPR])
    _put(log, 22, fpos[F_TPL])
    _put_flat(log, 25, fR[F_O1])
    _put_flat(log, 34, fR[F_O2])


@njit
def _finish(J, dJ, v, qdd, M, h, Jc, a, tau, lam, pos_err, ori_err, R, p, fR, fpos, vel, support, g1, g3, gs, hj,
            arm_mass, arm_lever, arm_I, gravity, limits, a_out, lam_out, T_out, tau_out, log) -> None:
    """The thesis torques T, the saturation flag, the dynamics residual and the logged quantities of a stage."""
    T = _thesis_torques(J, dJ, v, a, tau, R, p, support, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity)
    log[:] = 0.0
    for i in range(26):
        if T[i] > limits[i] or T[i] < -limits[i] or not np.isfinite(T[i]):
            log[0] = 1.0
    if not (np.isfinite(qdd).all() and np.isfinite(a).all() and np.isfinite(tau).all()):
        log[0] = -1.0  # a normal matrix or KKT system was singular: the reference path reports it
    res = mv(M, a) + h - tau - mtv(Jc, lam)
    log[1], log[2], log[3] = pos_err, ori_err, np.max(np.abs(res))
    _log_frames(log, fR, fpos, vel)
    _put(a_out, 0, a)
    _put(lam_out, 0, lam)
    _put(T_out, 0, T)
    _put(tau_out, 0, tau)


@njit
def ssp_stage(q, v, J, dJ, M_upper, h, tab, t, anchor_R, anchor_p, lock_anchor, parents, axis, idx_q, jR, jp,
              support, fparent, fRp, fpp, jcols, jsign, theta_q, theta0, ip, fp_, fneed, R, p, fR, fpos, motion, vel,
              welds, lock_q, lock_v, kp, kd, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity, limits, qdd_out,
              a_out, lam_out, T_out, tau_out, log) -> None:
    """:func:`ssp_controller` then :func:`ssp_dynamics` in one call (the simulator's hot path; the two halves stay
    separate functions so that a profile can time them apart)."""
    ssp_controller(q, v, J, dJ, tab, t, parents, axis, idx_q, jR, jp, support, fparent, fRp, fpp, jcols, jsign,
                   theta_q, theta0, ip, fp_, fneed, R, p, fR, fpos, motion, vel, qdd_out)
    ssp_dynamics(q, v, J, dJ, M_upper, h, qdd_out, anchor_R, anchor_p, lock_anchor, support, fparent, jcols, jsign,
                 welds, lock_q, lock_v, kp, kd, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity, limits, R, p, fR,
                 fpos, vel, a_out, lam_out, T_out, tau_out, log)


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


@njit
def dsp_stage(q, v, J, dJ, M_upper, h, tab, t, anchor_R, anchor_p, lock_anchor, parents, axis, idx_q, jR, jp,
              support, fparent, fRp, fpp, jcols, jsign, theta_q, theta0, ip, fp_, fneed, R, p, fR, fpos, motion, vel,
              welds, lock_q, lock_v, kp, kd, w_tau, w_lam, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity, limits,
              qdd_out, a_out, lam_out, T_out, tau_out, log) -> None:
    """One double-support stage (the compiled twin of ``ThesisController.evaluate`` in RFFDSP / LFFDSP): command
    accelerations with the closed chain, the weighted minimum-norm computed torque under both welds and the lock,
    the thesis torques and the log; arguments as :func:`ssp_stage` plus the torque-split weights."""
    th, thd = _stage_state(q, v, J, dJ, parents, axis, idx_q, jR, jp, support, fparent, fRp, fpp, jcols, jsign,
                           theta_q, theta0, fneed, R, p, fR, fpos, motion, vel)
    ref_p, ref_v, ref_R = np.empty(3), np.empty(6), np.empty((3, 3))
    dsp_references(tab, t + fp_[0], ref_p, ref_v, ref_R)
    _put(qdd_out, 0, _controller_dsp(motion, vel, fpos, fR, fparent, th, thd, jcols, jsign, ref_p, ref_v, ref_R, ip,
                                     fp_))
    M = _symmetric(M_upper)
    a_des = _a_desired(qdd_out, jcols, jsign, v.size)
    Jc, r, pos_err, ori_err = _contact_rows(J, dJ, v, q, support, fparent, fR, fpos, welds, anchor_R, anchor_p,
                                            lock_q, lock_v, lock_anchor, kp, kd)
    a, tau, lam = _inverse_general(Jc, r, M, h, a_des, lock_v, w_tau, w_lam)
    _finish(J, dJ, v, qdd_out, M, h, Jc, a, tau, lam, pos_err, ori_err, R, p, fR, fpos, vel, support, g1, g3, gs, hj,
            arm_mass, arm_lever, arm_I, gravity, limits, a_out, lam_out, T_out, tau_out, log)


@njit
def _project_inplace(q, v, anchor_R, anchor_p, lock_anchor, lock_q, lock_v, parents, axis, idx_q, idx_v, jR, jp,
                     support, f_parent, f_R, f_p) -> None:
    """Put (q, v) on the support foot in place (``WeldEngine.project_on_support``): toe lock at its anchor angle with
    zero rate, base placement re-derived from the foot's anchor (anchor * oMf^-1 * base: the base's own value
    cancels), base twist from the joint rates through the foot's LOCAL Jacobian."""
    q[lock_q] = lock_anchor
    v[lock_v] = 0.0
    nj = parents.size
    R = np.empty((nj, 3, 3))
    p = np.empty((nj, 3))
    forward_kinematics(q, parents, axis, idx_q, jR, jp, R, p)
    Rf, pf = frame_placement(R, p, f_parent, f_R, f_p)
    Rb = quat_to_rot(q[3], q[4], q[5], q[6])
    pb = q[:3].copy()
    X = mm(anchor_R, Rf.T)
    Rn = mm(X, Rb)
    _put(q, 0, anchor_p + mv(X, pb - pf))
    quat = np.empty(4)
    rot_to_quat(Rn, quat)
    # unit length, as Pinocchio's integrate leaves it (without this the round-off of a slightly non-unit quaternion
    # would compound from step to step, since the compiled advance does not pass through integrate)
    n = math.sqrt(quat[0] * quat[0] + quat[1] * quat[1] + quat[2] * quat[2] + quat[3] * quat[3])
    _put(q, 3, quat / n)
    # LOCAL Jacobian of the foot frame times the joint rates (the joint columns do not depend on the base)
    vj = np.zeros(3)
    wj = np.zeros(3)
    for j in range(2, nj):
        iv = idx_v[j]
        if support[f_parent, iv] and v[iv] != 0.0:
            u = R[j][:, axis[j]]
            wj += u * v[iv]
            vj += cross(u, pf - p[j]) * v[iv]
    lin = mtv(Rf, vj)
    ang = mtv(Rf, wj)
    Ad = action_matrix(mtm(Rb, Rf), mtv(Rb, pf - pb))
    tw = np.empty(6)
    _put(tw, 0, lin)
    _put(tw, 3, ang)
    _put(v, 0, -mv(Ad, tw))


@njit
def project_on_support(q, v, anchor_R, anchor_p, lock_anchor, lock_q, lock_v, parents, axis, idx_q, idx_v, jR, jp,
                       support, f_parent, f_R, f_p, q_out, v_out) -> None:
    """(q, v) projected on the support foot (:func:`_project_inplace`) into (q_out, v_out)."""
    _put(q_out, 0, q)
    _put(v_out, 0, v)
    _project_inplace(q_out, v_out, anchor_R, anchor_p, lock_anchor, lock_q, lock_v, parents, axis, idx_q, idx_v, jR,
                     jp, support, f_parent, f_R, f_p)


@njit
def advance_on_support(q, v, coeffs, vs, accs, h, anchor_R, anchor_p, lock_anchor, lock_q, lock_v, parents, axis,
                       idx_q, idx_v, jR, jp, support, f_parent, f_R, f_p, q_out, v_out) -> None:
    """The state at (q + h dq, v + h dv), dq = sum_j coeffs[j] vs[j] and dv = sum_j coeffs[j] accs[j] (a Runge-Kutta
    stage or step end), projected on the support foot, into (q_out, v_out): ``RungeKutta.step``'s combination,
    ``integrate`` and ``project`` in one call.  The sums run left to right over the non-zero coefficients (the
    rounding of ``integrator._combine``); revolute coordinates add (Pinocchio's integrate of a revolute joint); the
    base is not integrated, since the projection re-derives it from the foot (its input value cancels)."""
    nv = v.size
    dq = np.zeros(nv)
    dv = np.zeros(nv)
    first = True
    for j in range(len(vs)):
        c = coeffs[j]
        if c == 0.0:
            continue
        x, y = vs[j], accs[j]
        if first:
            for i in range(nv):
                dq[i] = c * x[i]
                dv[i] = c * y[i]
            first = False
        else:
            for i in range(nv):
                dq[i] = dq[i] + c * x[i]
                dv[i] = dv[i] + c * y[i]
    _put(q_out, 0, q)
    for j in range(2, parents.size):
        q_out[idx_q[j]] = q[idx_q[j]] + h * dq[idx_v[j]]
    for i in range(nv):
        v_out[i] = v[i] + h * dv[i]
    _project_inplace(q_out, v_out, anchor_R, anchor_p, lock_anchor, lock_q, lock_v, parents, axis, idx_q, idx_v, jR,
                     jp, support, f_parent, f_R, f_p)


# ----------------------------------------------------------------------------------------------- balance controller
@njit
def balance_qp(A, w, b, M_upper, h, J, rhs_shift, nw, box_kind, split_weld, split_lock, X, jt, heel, toe, full,
               w_acc, w_force, w_torque, unload):
    """The QP of ``controllers.balance.BalanceController`` from its task rows and the phase's constraint rows: the
    compiled twin of ``controllers.balance.qp_numpy`` (same formulas; sums in loop order).

    Inputs: task rows A (r, nv), weights w (r,), targets b (r,); M_upper (crba's upper triangle), h (nv,); the
    constraint rows J (m, nv) with ``rhs_shift`` (m,), of which the first ``nw`` are weld rows (6 per weld) and the rest
    toe locks; per weld ``box_kind`` (0: a flat foot, heel box on the weld and toe box on split variables; 1: a toe
    box alone; 2: the whole sole) and the extra weight ``unload`` on its normal force; per split foot j its weld
    ``split_weld[j]``, its lock row ``split_lock[j]`` in lam, X[j] (6, 6) and jt[j] (6,); the box rows (11, 6)
    ``heel``, ``toe``, ``full``; the regularisation weights.  x = [a (nv); lam (m); W_t (6 per split)].

    Returns G, g (min 1/2 x'Gx - g'x), C, lo (the first ``ne`` rows of C the equalities C x = lo, the others the
    inequalities C x >= lo = 0: stacked as DAQP takes them), ne, cop (the inequality rows' CoP flags), M (nv, nv)
    symmetric and Tx (nv - 6, n) with tau[6:] = Tx x + h[6:]."""
    nv = M_upper.shape[0]
    m = J.shape[0]
    ns = split_weld.size
    n = nv + m + 6 * ns
    r = A.shape[0]
    M = _symmetric(M_upper)
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
            box = toe if box_kind[i] == 1 else full
            for a in range(nb):
                for c in range(6):
                    Cin[row + a, cw + c] = box[a, c]
            for a in range(7, nb):
                cop[row + a] = True
            row += nb
    return G, g, C, lo, ne, cop, M, Tx


@njit
def _rot_y_into(ang: float, out: np.ndarray) -> None:
    """Rotation by ``ang`` (rad) about the local y axis into out (3, 3) (``controllers.balance._rot_y``)."""
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


@njit
def balance_stage(q, v, J, dJ, M_upper, h, parents, axis, idx_q, jR, jp, support, fparent, fRp, fpp, jcols, jsign,
                  theta_q, theta0, fneed, R, p, fR, fpos, motion, vel, welds, anchor_R, anchor_p, lock_q, lock_v,
                  lock_anchor, kp_c, kd_c, mode, fi, tgt, gains, w_joint, heel_lift_rad, box_kind, split_toe, heel,
                  toe, full, w_acc, w_force, w_torque, unload):
    """The balance controller's QP at (q, v): the compiled twin of ``BalanceController._qp_reference``
    (``controllers.balance``: task rows, the phase's weld and lock rows, the heel / toe box split, the QP of
    :func:`balance_qp`).  J, dJ: Pinocchio's computeJointJacobiansTimeVariation at (q, v); M_upper, h: crba and
    nonLinearEffects; tree constants and work buffers as :func:`_stage_state`; welds / anchors / lock / kp_c, kd_c as
    :func:`_contact_rows`.

    ``mode``: 0 no foot task, 1 swing (fi = [toe point, toe body, main body] frame rows), 2 double support's trailing
    heel (fi = [toe body, main body]).  ``tgt`` (floats): hip p (3), v (6), R (9, row-major), a (6); swing: toe point
    p (3), v (6), toe-body R (9), feed-forward acceleration (6), heel-return phase xr, heel return time, lift0 (rad;
    < 0: measure it now from the foot's pose); double support: the heel lift angle.  ``gains``: kp, kd, weight of
    the hip, trunk, swing tasks, then kp, kd of the posture.  ``split_toe``: per weld, the toe-body frame row of a
    flat foot (box_kind 0), else -1.

    Returns (G, g, C, lo, ne, cop, M, Tx, Jc, X, lift0, pos_err, ori_err) (:func:`balance_qp`; Jc the constraint rows,
    X (n_split, 6, 6), lift0 the heel lift used, rad; the largest weld errors, m and rad)."""
    nv = v.size
    th, thd = _stage_state(q, v, J, dJ, parents, axis, idx_q, jR, jp, support, fparent, fRp, fpp, jcols, jsign,
                           theta_q, theta0, fneed, R, p, fR, fpos, motion, vel)
    Jc, r, pos_err, ori_err = _contact_rows(J, dJ, v, q, support, fparent, fR, fpos, welds, anchor_R, anchor_p,
                                            lock_q, lock_v, lock_anchor, kp_c, kd_c)
    n_task = 6 + (9 if mode == 1 else 3 if mode == 2 else 0)
    nr = n_task + 26
    A = np.zeros((nr, nv))
    b = np.empty(nr)
    w = np.empty(nr)
    err = np.empty(3)
    # Body-17 CoM and orientation
    for k in range(3):
        err[k] = tgt[k] - fpos[F_PC17, k]
    _task_row(A, b, w, 0, motion, vel, F_PC17, True, tgt[18:21], gains[0], gains[1], err, tgt[3:6], gains[2])
    Rref = np.empty((3, 3))
    for i in range(3):
        for k in range(3):
            Rref[i, k] = tgt[9 + 3 * i + k]
    err = log3(mm(Rref, fR[F_O17].T))
    _task_row(A, b, w, 3, motion, vel, F_O17, False, tgt[21:24], gains[3], gains[4], err, tgt[6:9], gains[5])
    lift0 = 0.0
    if mode == 1:
        fpt, ftoe, fmain = fi[0], fi[1], fi[2]
        kp, kd, ws = gains[6], gains[7], gains[8]
        for k in range(3):
            err[k] = tgt[24 + k] - fpos[fpt, k]
        _task_row(A, b, w, 6, motion, vel, fpt, True, tgt[42:45], kp, kd, err, tgt[27:30], ws)
        Rr = np.empty((3, 3))
        for i in range(3):
            for k in range(3):
                Rr[i, k] = tgt[33 + 3 * i + k]
        _task_row(A, b, w, 9, motion, vel, ftoe, False, tgt[45:48], kp, kd, log3(mm(Rr, fR[ftoe].T)), tgt[30:33], ws)
        xr, t_ret, lift0 = tgt[48], tgt[49], tgt[50]
        if lift0 < 0.0:   # the heel lift the foot left the ground with (main body pitched about the toe body's y)
            Rrel = mtm(fR[ftoe], fR[fmain])
            lift0 = min(max(math.atan2(Rrel[0, 2], Rrel[0, 0]), 0.0), heel_lift_rad)
        Rm = Rr.copy()
        wm = np.empty(3)
        am = np.empty(3)
        for k in range(3):
            wm[k] = tgt[30 + k]
            am[k] = tgt[45 + k]
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
        _rot_y_into(tgt[24], Ry)
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
    G, g, C, lo, ne, cop, M, Tx = balance_qp(A, w, b, M_upper, h, Jc, r, nw, box_kind, split_weld, split_lock, X, jt,
                                             heel, toe, full, w_acc, w_force, w_torque, unload)
    return G, g, C, lo, ne, cop, M, Tx, Jc, X, lift0, pos_err, ori_err


@njit
def balance_finish(x, M, h, Jc, J, dJ, v, R, p, support, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity,
                   pos_err, ori_err, fR, fpos, vel, jcols, jsign, bounded, bounds, limits):
    """(a, lam, tau, T, log, theta_ddot, over, inside) of the balance controller's QP solution x = [a; lam; ...]: tau
    = M a + h - Jc^T lam with the base rows zeroed, T the thesis actuator torques (:func:`_thesis_torques`), the stage
    log the weld engine records (layout ``stage.StageOutput``: weld errors, dynamics residual, task frames), the
    thesis joint accelerations (jsign * a[jcols]), whether a bounded component T[bounded[i]] exceeds bounds[i] in
    magnitude, and whether every |T[i]| <= limits[i] (``Actuators.saturate``'s test: False for a NaN).
    R, p, fR, fpos, vel: what :func:`balance_stage` left in its buffers; pos_err, ori_err: what it returned."""
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
    T = _thesis_torques(J, dJ, v, a, tau, R, p, support, g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity)
    log = np.zeros(LOG_SIZE)
    res = mv(M, a) + h - tau - mtv(Jc, lam)
    log[1], log[2], log[3] = pos_err, ori_err, np.max(np.abs(res))
    _log_frames(log, fR, fpos, vel)
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
