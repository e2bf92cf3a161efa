"""Kinematics of a free-flyer + axis-aligned revolute tree, compiled: placements, frame Jacobians, bias
accelerations, SE(3) logarithm, quaternions.

Conventions are Pinocchio's (tested against it in ``tests/test_kernel.py``):

- joint placements ``oMi[j] = oMi[parent] * jointPlacement[j] * M_j(q)``, M_j a rotation about the joint's x, y or z
  axis (JointModelRX/RY/RZ) or, for the free flyer, the placement (position, quaternion x y z w) in q[:7];
- ``J`` / ``dJ`` (6 x nv) are Pinocchio's WORLD joint Jacobians and their time derivative
  (``computeJointJacobiansTimeVariation``): column c is the spatial motion [v_o; w] (linear part = velocity of the
  body point at the world origin) of a unit rate of coordinate c, so the spatial velocity of a body is J v and its
  spatial acceleration J a + dJ v over the columns that support it;
- LOCAL_WORLD_ALIGNED rows of a frame at world position p: linear = velocity / classical acceleration of the frame
  origin, angular = angular velocity / acceleration (world axes); LOCAL rows: the spatial motion resolved in the
  frame, linear part at its origin.

All arrays are float64; rotations are (3, 3) with columns the body axes in world coordinates; lengths in m,
velocities in m/s and rad/s, accelerations in m/s^2 and rad/s^2.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from humanoid_sim.kernel import njit

FREE_FLYER = -1
"""Axis code of the free-flyer root joint (revolute joints: 0, 1, 2 = x, y, z)."""


class TreeConstants:
    """The constant arrays of a Pinocchio model that the compiled kinematics needs.

    parents (nj,), axis (nj,) (FREE_FLYER or 0/1/2; -2 for the universe), idx_q / idx_v (nj,), joint placements
    jR (nj, 3, 3) / jp (nj, 3), support (nj, nv) bool: the velocity columns of joint j and its ancestors.
    Frames are registered by name: fparent, fR, fp (placement of the frame in its parent joint's frame).
    """

    _AXES = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2, "JointModelFreeFlyer": FREE_FLYER}

    def __init__(self, model: pin.Model, frames: list[str]) -> None:
        nj, nv = model.njoints, model.nv
        self.parents = np.array(model.parents, dtype=np.int64)
        self.axis = np.full(nj, -2, dtype=np.int64)
        self.idx_q = np.zeros(nj, dtype=np.int64)
        self.idx_v = np.zeros(nj, dtype=np.int64)
        self.jR = np.zeros((nj, 3, 3))
        self.jp = np.zeros((nj, 3))
        self.support = np.zeros((nj, nv), dtype=np.bool_)
        self.jR[0] = np.eye(3)
        for j in range(1, nj):
            name = model.joints[j].shortname()
            if name not in self._AXES:
                raise ValueError(f"joint {model.names[j]!r}: the compiled kinematics handles the free flyer and "
                                 f"JointModelRX/RY/RZ, got {name}")
            if (name == "JointModelFreeFlyer") != (j == 1):
                raise ValueError(f"joint {model.names[j]!r}: the free flyer must be joint 1, the root")
            self.axis[j] = self._AXES[name]
            self.idx_q[j] = model.idx_qs[j]
            self.idx_v[j] = model.idx_vs[j]
            M = model.jointPlacements[j]
            self.jR[j] = M.rotation
            self.jp[j] = M.translation
            k = j
            while k > 0:
                s, n = model.idx_vs[k], model.nvs[k]
                self.support[j, s:s + n] = True
                k = model.parents[k]
        self.frames = list(frames)
        self.frame_index = {name: i for i, name in enumerate(frames)}
        fids = [model.getFrameId(name) for name in frames]
        for name, fid in zip(frames, fids):
            if fid >= model.nframes:
                raise ValueError(f"unknown frame {name!r}")
        self.fparent = np.array([model.frames[f].parentJoint for f in fids], dtype=np.int64)
        self.fR = np.array([model.frames[f].placement.rotation for f in fids])
        self.fp = np.array([model.frames[f].placement.translation for f in fids])
        self.nj, self.nv, self.nq = nj, nv, model.nq


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
    """A^T B for small matrices."""
    k, n = A.shape
    m = B.shape[1]
    out = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for l in range(k):
                s += A[l, i] * B[l, j]
            out[i, j] = s
    return out


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
    """A^T x for a small matrix."""
    k, n = A.shape
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for l in range(k):
            s += A[l, i] * x[l]
        out[i] = s
    return out


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
def _axis_rotation(axis: int, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    R = np.zeros((3, 3))
    if axis == 0:
        R[0, 0] = 1.0
        R[1, 1], R[1, 2], R[2, 1], R[2, 2] = c, -s, s, c
    elif axis == 1:
        R[1, 1] = 1.0
        R[0, 0], R[0, 2], R[2, 0], R[2, 2] = c, s, -s, c
    else:
        R[2, 2] = 1.0
        R[0, 0], R[0, 1], R[1, 0], R[1, 1] = c, -s, s, c
    return R


@njit
def forward_kinematics(q: np.ndarray, parents: np.ndarray, axis: np.ndarray, idx_q: np.ndarray, jR: np.ndarray,
                       jp: np.ndarray, R: np.ndarray, p: np.ndarray) -> None:
    """World placements of all joints into R (nj, 3, 3) and p (nj, 3) (Pinocchio's oMi)."""
    R[0] = np.eye(3)
    p[0] = 0.0
    for j in range(1, parents.size):
        if axis[j] == FREE_FLYER:
            i = idx_q[j]
            Rl = quat_to_rot(q[i + 3], q[i + 4], q[i + 5], q[i + 6])
            R[j] = mm(jR[j], Rl)
            p[j] = jp[j] + mv(jR[j], q[i:i + 3])
        else:
            Rp = R[parents[j]]
            R[j] = mm(Rp, mm(jR[j], _axis_rotation(axis[j], q[idx_q[j]])))
            p[j] = p[parents[j]] + mv(Rp, jp[j])


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
    vel[:3] = V[:3] + cross(w, pos)
    vel[3:] = w
    acc = A[:3] + cross(alpha, pos) + cross(w, vel[:3])
    out[:3, nv] = acc
    out[3:, nv] = alpha
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
            Jout[:3, c] = mv(RT, lin)
            Jout[3:, c] = mv(RT, ang)
        else:
            for r in range(6):
                Jout[r, c] = 0.0
    V, A = spatial_motion(J, dJ, v, support)
    vel = np.empty(6)
    acc = np.empty(6)
    vel[:3] = mv(RT, V[:3] + cross(V[3:], pos))
    vel[3:] = mv(RT, V[3:])
    acc[:3] = mv(RT, A[:3] + cross(A[3:], pos))
    acc[3:] = mv(RT, A[3:])
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
"""Angle (rad) below which log6 uses its Taylor coefficients (Pinocchio's threshold, eps^(1/3))."""


@njit
def log6(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """SE(3) logarithm [v; w] (6,) of the placement (R, p) (Pinocchio's log6)."""
    w = log3(R)
    t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    theta = math.sqrt(t2)
    if theta < _LOG6_TAYLOR:
        alpha = 1.0 - t2 / 12.0 - t2 * t2 / 720.0
        beta = 1.0 / 12.0 + t2 / 720.0
    else:
        st, ct = math.sin(theta), math.cos(theta)
        alpha = theta * st / (2.0 * (1.0 - ct))
        beta = 1.0 / t2 - st / (2.0 * theta * (1.0 - ct))
    out = np.empty(6)
    out[:3] = alpha * p - 0.5 * cross(w, p) + (beta * (w[0] * p[0] + w[1] * p[1] + w[2] * p[2])) * w
    out[3:] = w
    return out


@njit
def action_matrix(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Ad(M) (6 x 6) of M = (R, p) acting on [linear; angular] motions: [[R, [p]x R], [0, R]]."""
    A = np.zeros((6, 6))
    A[:3, :3] = R
    A[3:, 3:] = R
    for c in range(3):
        A[:3, 3 + c] = cross(p, R[:, c])
    return A
