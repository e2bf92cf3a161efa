"""Compiled kinematics of a free-flyer + axis-aligned revolute tree (numba): the twin of Pinocchio's forward
kinematics, frame placements, frame velocities / accelerations and SE(3) logarithms, as the reference paths call
them (tested against Pinocchio in ``tests/test_kernel.py``).

Conventions are Pinocchio's:

- joint placements ``oMi[j] = oMi[parent] * jointPlacement[j] * M_j(q)``, M_j a rotation about the joint's x, y or z
  axis (JointModelRX/RY/RZ) or, for the free flyer, the placement (position, quaternion x y z w) in q[:7];
- ``J`` / ``dJ`` (6 x nv) are Pinocchio's WORLD joint Jacobians and their time derivative
  (``computeJointJacobiansTimeVariation``): column c is the spatial motion [v_o; w] (linear part = velocity of the
  body point at the world origin) of a unit rate of coordinate c, so the spatial velocity of a body is J v and its
  spatial acceleration J a + dJ v over the columns that support it;
- LOCAL_WORLD_ALIGNED rows of a frame at world position p: linear = velocity / classical acceleration of the frame
  origin, angular = angular velocity / acceleration (world axes); LOCAL rows: the spatial motion resolved in the
  frame, linear part at its origin.

Rotations are (3, 3) with columns the body axes in world coordinates; lengths in m, velocities in m/s and rad/s.
The constant tables come in a :class:`humanoid_sim.kernel.records.Tree`, the thesis joint coordinates in a
:class:`~humanoid_sim.kernel.records.Coords`, the per-call work buffers in a :class:`~humanoid_sim.kernel.records.Work`.
"""

from __future__ import annotations

import math

import numpy as np

from humanoid_sim.jit import njit
from humanoid_sim.kernel.linalg import cross, mm, mv, put, put_block, put_col
from humanoid_sim.robot.frames import TASK_FRAMES

FREE_FLYER = -1
"""Axis code of the free-flyer root joint (revolute joints: 0, 1, 2 = x, y, z; -2: the universe)."""
F_PC17, F_O17, F_TPR, F_TPL, F_O1, F_O2, F_O3, F_O4 = (TASK_FRAMES.index(n) for n in (
    "Pc_17", "O_17", "P_tpR", "P_tpL", "O_1", "O_2", "O_3", "O_4"))
"""Rows of the frame arrays: the task frames in :data:`humanoid_sim.robot.frames.TASK_FRAMES` order (numba freezes
these integers into the compiled code)."""
_LOG6_TAYLOR = float(np.finfo(float).eps) ** (1.0 / 3.0)
"""log6 uses its Taylor coefficients when tr R >= 3 - _LOG6_TAYLOR (angle below ~2.5e-3 rad), Pinocchio's switch
(spatial/log.hxx): above it the closed form's 1 - cos(theta) has lost no more than ~1e-11 relative."""


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
    put(vel, 0, V[:3] + cross(w, pos))
    put(vel, 3, w)
    acc = A[:3] + cross(alpha, pos) + cross(w, vel[:3])
    put_col(out, 0, nv, acc)
    put_col(out, 3, nv, alpha)
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
            put_col(Jout, 0, c, mv(RT, lin))
            put_col(Jout, 3, c, mv(RT, ang))
        else:
            for r in range(6):
                Jout[r, c] = 0.0
    V, A = spatial_motion(J, dJ, v, support)
    vel = np.empty(6)
    acc = np.empty(6)
    put(vel, 0, mv(RT, V[:3] + cross(V[3:], pos)))
    put(vel, 3, mv(RT, V[3:]))
    put(acc, 0, mv(RT, A[:3] + cross(A[3:], pos)))
    put(acc, 3, mv(RT, A[3:]))
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
    put(out, 0, alpha * p - 0.5 * cross(w, p) + (beta * (w[0] * p[0] + w[1] * p[1] + w[2] * p[2])) * w)
    put(out, 3, w)
    return out


@njit
def action_matrix(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Ad(M) (6 x 6) of M = (R, p) acting on [linear; angular] motions: [[R, [p]x R], [0, R]]."""
    A = np.zeros((6, 6))
    put_block(A, 0, 0, R)
    put_block(A, 3, 3, R)
    for c in range(3):
        put_col(A, 0, 3 + c, cross(p, R[:, c]))
    return A


@njit
def tree_state(st, tree, co, fneed, work) -> tuple[np.ndarray, np.ndarray]:
    """What every stage starts from (``st``: a ``records.State``, ``tree``: ``Tree``, ``co``: ``Coords``, ``work``:
    ``Work``): joint placements R, p, frame placements fR, fpos, and for the frames flagged in ``fneed`` the
    LOCAL_WORLD_ALIGNED [J | drift] ``motion`` and velocities ``vel`` (all written into the work buffers); returns
    the thesis joint deviations theta - theta0 and rates (26, each)."""
    q, v, J, dJ = st.q, st.v, st.J, st.dJ
    parents, axis, idx_q, jR, jp, support = tree.parents, tree.axis, tree.idx_q, tree.jR, tree.jp, tree.support
    fparent, fRp, fpp = tree.fparent, tree.fR, tree.fp
    jcols, jsign, theta_q, theta0 = co.jcols, co.jsign, co.theta_q, co.theta0
    R, p, fR, fpos, motion, vel = work.R, work.p, work.fR, work.fpos, work.motion, work.vel
    forward_kinematics(q, parents, axis, idx_q, jR, jp, R, p)
    for i in range(fparent.size):
        Rf, pf = frame_placement(R, p, fparent[i], fRp[i], fpp[i])
        put_block(fR[i], 0, 0, Rf)
        put(fpos[i], 0, pf)
        if fneed[i]:
            put(vel[i], 0, frame_motion_lwa(J, dJ, v, support[fparent[i]], fpos[i], motion[i]))
    th = np.empty(26)
    thd = np.empty(26)
    for i in range(26):
        th[i] = jsign[i] * q[theta_q[i]] - theta0[i]
        thd[i] = jsign[i] * v[jcols[i]]
    return th, thd
