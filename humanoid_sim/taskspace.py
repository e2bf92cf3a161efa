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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.model import HumanoidModel

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


class TaskKinematics:
    """Evaluates frame states at (q, v) and reduces Jacobians/drifts to thesis joint space through a weld.

    All registered frames are stacked (6 rows each) so that one reduction per weld serves every task; reductions
    are cached until the next :meth:`update`.
    """

    def __init__(self, hm: HumanoidModel, frames: list[str]) -> None:
        self.hm = hm
        self.model = hm.model
        self.data = hm.model.createData()
        self.names = list(frames)
        self.frame_ids = {name: hm.frame_id(name) for name in frames}
        self.row = {name: 6 * i for i, name in enumerate(frames)}
        self._a0 = np.zeros(hm.model.nv)
        # column selector/sign: pinocchio velocity columns -> thesis joint columns
        self.jcols = hm.theta_v_idx
        self.jsign = hm.theta_sign
        n = len(frames)
        self.J = np.zeros((6 * n, hm.model.nv))
        self.drift = np.zeros(6 * n)
        self.vel = np.zeros(6 * n)
        self.states: dict[str, FrameState] = {}
        self._reduced: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def update(self, q: np.ndarray, v: np.ndarray, data: pin.Data | None = None) -> dict[str, FrameState]:
        """Compute every registered frame's state at (q, v).  ``data`` may be a pinocchio Data that already holds
        ``forwardKinematics(q, v, 0)`` and ``computeJointJacobians`` at this state (shared with the contact
        solver); the passes are then not repeated."""
        model = self.model
        if data is None:
            data = self.data
            pin.forwardKinematics(model, data, q, v, self._a0)
            pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        out = {}
        for name, fid in self.frame_ids.items():
            i = self.row[name]
            M = data.oMf[fid]
            J = self.J[i:i + 6]
            J[:] = pin.getFrameJacobian(model, data, fid, LWA)
            self.vel[i:i + 6] = pin.getFrameVelocity(model, data, fid, LWA).vector
            self.drift[i:i + 6] = pin.getFrameClassicalAcceleration(model, data, fid, LWA).vector
            out[name] = FrameState(p=M.translation.copy(), R=M.rotation.copy(), v=self.vel[i:i + 6], J=J,
                                   drift=self.drift[i:i + 6])
        self.states = out
        self._reduced = {}
        return out

    def reduced_all(self, weld: str) -> tuple[np.ndarray, np.ndarray]:
        """Joint-space Jacobians (6 n_frames x 26, thesis order/sign) and drifts of every registered frame, with
        the base eliminated through the 6-D weld of frame ``weld`` (cached per update)."""
        hit = self._reduced.get(weld)
        if hit is not None:
            return hit
        i = self.row[weld]
        Jw = self.J[i:i + 6]
        K = np.linalg.solve(Jw[:, :6].T, self.J[:, :6].T).T  # J_b J_Wb^-1
        J_red = (self.J[:, self.jcols] - K @ Jw[:, self.jcols]) * self.jsign
        drift = self.drift - K @ self.drift[i:i + 6]
        self._reduced[weld] = (J_red, drift)
        return J_red, drift

    def reduce(self, task: str, weld: str, rows: slice = slice(0, 6)) -> tuple[np.ndarray, np.ndarray]:
        """Joint-space Jacobian (m x 26, thesis order/sign) and drift (m,) of ``task`` with the base eliminated
        through the 6-D weld of frame ``weld``."""
        J_red, drift = self.reduced_all(weld)
        i = self.row[task]
        sl = slice(i + (rows.start or 0), i + (rows.stop if rows.stop is not None else 6))
        return J_red[sl], drift[sl]


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
    return w * (w @ R) - (w @ w) * np.diagonal(R)
