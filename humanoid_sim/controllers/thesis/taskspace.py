"""Task-space kinematics for the controller: frame states and Jacobians with the floating base eliminated.

The thesis writes every task Jacobian in joint space, with the chain rooted at a body fixed to the ground
(section 4.2: e.g. J_v,17_fR relates the Body-17 twist to the right-leg joint rates in RFFSSP).  On the
floating-base Pinocchio model the same matrices follow by eliminating the base through a 6-D weld W:

    J_W v = 0   =>   v_base = -J_Wb^-1 J_Wj theta_dot_pin          (J_W = [J_Wb | J_Wj], 6x6 | 6x26)
    J_red = J_j - J_b J_Wb^-1 J_Wj                               (task Jacobian in joint space)
    drift = gamma_t - J_b J_Wb^-1 gamma_W                        (task acceleration when the joint
                                                                 accelerations are zero: the thesis's
                                                                 J_dot q_dot, errata C-1)

All quantities are in the world frame (LOCAL_WORLD_ALIGNED): linear rows = classical velocity/acceleration of
the frame origin (m/s, m/s^2), angular rows = angular velocity/acceleration (rad/s, rad/s^2).  Columns are the
thesis joint coordinates in eq. 4.1 order and sign (the pinocchio signs are folded in here).

With world-aligned Jacobians of a free-flyer base the base block has the closed form
``J_b J_Wb^-1 = [[I, [p_W - p_t]x], [0, I]]`` (the rigid transfer of the weld's twist to the task point), so
no 6 x 6 solve is needed: ``J_red = [J_t,lin - J_W,lin - [p_W - p_t]x J_W,ang ; J_t,ang - J_W,ang]`` on the
joint columns, and the drift likewise.

Frame states are read lazily (only the frames a phase's problem uses) and cached until the next
:meth:`TaskKinematics.update`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.robot.model import HumanoidModel

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass
class FrameState:
    """World-frame state of one frame (LOCAL_WORLD_ALIGNED).

    p: origin position (m); R: orientation (3x3); v: [linear; angular] velocity (6,);
    J: 6x32 frame Jacobian (pinocchio velocity coordinates); drift: [linear; angular] classical acceleration at
    zero generalized acceleration (6,).
    """

    p: np.ndarray
    R: np.ndarray
    v: np.ndarray
    J: np.ndarray
    drift: np.ndarray


def skew(w: np.ndarray) -> np.ndarray:
    """[w]x (3x3) with [w]x u = w x u."""
    return np.array(((0.0, -w[2], w[1]), (w[2], 0.0, -w[0]), (-w[1], w[0], 0.0)))


class TaskKinematics:
    """Evaluates frame states at (q, v) and reduces Jacobians/drifts to thesis joint space through a weld.

    Frames are read on first use after each :meth:`update` and cached per quantity (placement, velocity,
    Jacobian and drift), as are the reductions.  Arrays returned are valid until the next :meth:`update`.
    """

    def __init__(self, hm: HumanoidModel, frames: list[str]) -> None:
        self.hm = hm
        self.model = hm.model
        self.data = hm.model.createData()
        self.names = list(frames)
        self.frame_ids = {name: hm.frame_id(name) for name in frames}
        self.parent_joint = {name: self.model.frames[fid].parentJoint for name, fid in self.frame_ids.items()}
        self._a0 = np.zeros(hm.model.nv)
        # column selector/sign: pinocchio velocity columns -> thesis joint columns
        self.jcols = hm.theta_v_idx
        self.jsign = hm.theta_sign
        # the same on [J | drift] (6 x (nv + 1)): the drift rides along as one more column, sign +1
        self._motion_cols = np.append(self.jcols, hm.model.nv)
        self._motion_sign = np.append(self.jsign, 1.0)
        # per frame, a preallocated [J | drift] buffer, rewritten on the frame's first read after an update
        self._motion_buf = {name: np.zeros((6, hm.model.nv + 1)) for name in frames}
        self._data: pin.Data = self.data
        self._placements: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._velocities: dict[str, np.ndarray] = {}
        self._motions: dict[str, np.ndarray] = {}
        self._reduced: dict[tuple[str, str, str], tuple[np.ndarray, np.ndarray]] = {}

    def update(self, q: np.ndarray, v: np.ndarray, data: pin.Data | None = None) -> None:
        """Set the state (q, v).  ``data`` may be a pinocchio Data that already holds
        ``forwardKinematics(q, v, 0)`` and ``computeJointJacobians`` at this state (shared with the contact
        solver); the passes are then not repeated."""
        if data is None:
            data = self.data
            pin.forwardKinematics(self.model, data, q, v, self._a0)
            pin.computeJointJacobians(self.model, data, q)
        self._data = data
        self._placements = {}
        self._velocities = {}
        self._motions = {}
        self._reduced = {}

    def placement(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(origin position (3,), orientation (3x3)) of a registered frame, world frame (cached copies)."""
        hit = self._placements.get(name)
        if hit is None:
            M = pin.updateFramePlacement(self.model, self._data, self.frame_ids[name])
            hit = self._placements[name] = (M.translation.copy(), M.rotation.copy())
        return hit

    def velocity(self, name: str) -> np.ndarray:
        """[linear; angular] velocity (6,) of a registered frame, LOCAL_WORLD_ALIGNED (cached)."""
        hit = self._velocities.get(name)
        if hit is None:
            hit = self._velocities[name] = pin.getFrameVelocity(self.model, self._data, self.frame_ids[name],
                                                                LWA).vector
        return hit

    def motion(self, name: str) -> np.ndarray:
        """[J | drift] (6 x (nv + 1)) of a registered frame, LOCAL_WORLD_ALIGNED: the frame Jacobian and, as the
        last column, the classical acceleration at zero generalized acceleration (cached)."""
        hit = self._motions.get(name)
        if hit is None:
            model, data, fid = self.model, self._data, self.frame_ids[name]
            hit = self._motion_buf[name]
            hit[:, :-1] = pin.getFrameJacobian(model, data, fid, LWA)
            hit[:, -1] = pin.getFrameClassicalAcceleration(model, data, fid, LWA).vector
            self._motions[name] = hit
        return hit

    def state(self, name: str) -> FrameState:
        """World-frame state of a registered frame at the current state (built from the cached quantities)."""
        p, R = self.placement(name)
        JD = self.motion(name)
        return FrameState(p=p, R=R, v=self.velocity(name), J=JD[:, :-1], drift=JD[:, -1])

    def _task_motion(self, point: str, body: str) -> np.ndarray:
        """[J | drift] of [linear motion of ``point``; angular motion of ``body``].  Frames on one joint share
        the angular rows (the joint's angular velocity/acceleration), so then it is ``point``'s own."""
        TP = self.motion(point)
        if self.parent_joint[point] == self.parent_joint[body]:
            return TP
        T = TP.copy()
        T[3:] = self.motion(body)[3:]
        return T

    def reduce_pair(self, point: str, body: str, weld: str) -> tuple[np.ndarray, np.ndarray]:
        """Joint-space Jacobian (6 x 26, thesis order/sign) and drift (6,) of [linear motion of the origin of
        ``point``; angular motion of ``body``], with the base eliminated through the 6-D weld of ``weld``
        (cached per update).  ``point`` and ``body`` may be the same frame."""
        key = (point, body, weld)
        hit = self._reduced.get(key)
        if hit is not None:
            return hit
        W = self.motion(weld)
        # J_red = [J_t,lin - J_W,lin - [p_W - p_t]x J_W,ang ; J_t,ang - J_W,ang] (module docstring), applied to
        # the Jacobian columns and the drift column at once
        D = self._task_motion(point, body) - W
        S = skew(self.placement(weld)[0] - self.placement(point)[0])
        D[:3, :-1] -= S @ W[3:, :-1]
        D[:3, -1] -= S @ W[3:, -1]  # matrix-vector product apart: the rounding of the original drift formula
        red = D[:, self._motion_cols]
        red *= self._motion_sign
        hit = self._reduced[key] = (red[:, :-1], red[:, -1])
        return hit

    def reduce(self, task: str, weld: str, rows: slice = slice(0, 6)) -> tuple[np.ndarray, np.ndarray]:
        """Joint-space Jacobian (m x 26, thesis order/sign) and drift (m,) of ``task`` with the base eliminated
        through the 6-D weld of frame ``weld``."""
        J, drift = self.reduce_pair(task, task, weld)
        return J[rows], drift[rows]


def cdiag(R: np.ndarray) -> np.ndarray:
    """The thesis's orientation measure C_diag = the 3 diagonal elements of C^(0,k) (eq. 4.9, errata C-5)."""
    return np.array([R[0, 0], R[1, 1], R[2, 2]])


def cdiag_rate_matrix(R: np.ndarray) -> np.ndarray:
    """L (3x3) with d/dt C_diag = L w for angular velocity w (world): dC/dt = [w]x C, so
    d/dt C_ii = e_i . (w x c_i) = -e_i^T [c_i]x w, with c_i the i-th column of C."""
    return np.array([[0.0, R[2, 0], -R[1, 0]],
                     [-R[2, 1], 0.0, R[0, 1]],
                     [R[1, 2], -R[0, 2], 0.0]])


def cdiag_second_derivative_bias(R: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The part of d2/dt2 C_diag not linear in the angular acceleration: diag([w]x [w]x C), using
    [w]x [w]x = w w^T - |w|^2 I."""
    return w * (w @ R) - (w @ w) * R.diagonal()
