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


def skew(w: np.ndarray) -> np.ndarray:
    """[w]x (3x3) with [w]x u = w x u."""
    return np.array(((0.0, -w[2], w[1]), (w[2], 0.0, -w[0]), (-w[1], w[0], 0.0)))


class TaskKinematics:
    """Evaluates frame states at (q, v) and reduces Jacobians/drifts to thesis joint space through a weld.

    Frames are read on first use after each :meth:`update` and cached, as are the reductions.
    """

    def __init__(self, hm: HumanoidModel, frames: list[str]) -> None:
        self.hm = hm
        self.model = hm.model
        self.data = hm.model.createData()
        self.names = list(frames)
        self.frame_ids = {name: hm.frame_id(name) for name in frames}
        self._a0 = np.zeros(hm.model.nv)
        # column selector/sign: pinocchio velocity columns -> thesis joint columns
        self.jcols = hm.theta_v_idx
        self.jsign = hm.theta_sign
        self._data: pin.Data = self.data
        self._states: dict[str, FrameState] = {}
        self._reduced: dict[tuple[str, str, str], tuple[np.ndarray, np.ndarray]] = {}
        self._weld_cols: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def update(self, q: np.ndarray, v: np.ndarray, data: pin.Data | None = None) -> None:
        """Set the state (q, v).  ``data`` may be a pinocchio Data that already holds
        ``forwardKinematics(q, v, 0)`` and ``computeJointJacobians`` at this state (shared with the contact
        solver); the passes are then not repeated."""
        if data is None:
            data = self.data
            pin.forwardKinematics(self.model, data, q, v, self._a0)
            pin.computeJointJacobians(self.model, data, q)
        self._data = data
        self._states = {}
        self._reduced = {}
        self._weld_cols = {}

    def state(self, name: str) -> FrameState:
        """World-frame state of a registered frame at the current state (cached)."""
        st = self._states.get(name)
        if st is None:
            model, data, fid = self.model, self._data, self.frame_ids[name]
            M = pin.updateFramePlacement(model, data, fid)
            st = FrameState(p=M.translation.copy(), R=M.rotation.copy(), v=pin.getFrameVelocity(model, data, fid, LWA).vector,
                            J=pin.getFrameJacobian(model, data, fid, LWA),
                            drift=pin.getFrameClassicalAcceleration(model, data, fid, LWA).vector)
            self._states[name] = st
        return st

    @property
    def states(self) -> dict[str, FrameState]:
        """Every registered frame's state (reads the frames not read yet)."""
        return {name: self.state(name) for name in self.names}

    def _weld(self, weld: str) -> tuple[np.ndarray, np.ndarray]:
        """The weld's joint-column Jacobian (6 x 26, pinocchio signs) and drift (cached)."""
        hit = self._weld_cols.get(weld)
        if hit is None:
            st = self.state(weld)
            hit = self._weld_cols[weld] = (st.J[:, self.jcols], st.drift)
        return hit

    def reduce_pair(self, point: str, body: str, weld: str) -> tuple[np.ndarray, np.ndarray]:
        """Joint-space Jacobian (6 x 26, thesis order/sign) and drift (6,) of [linear motion of the origin of
        ``point``; angular motion of ``body``], with the base eliminated through the 6-D weld of ``weld``
        (cached per update).  ``point`` and ``body`` may be the same frame."""
        key = (point, body, weld)
        hit = self._reduced.get(key)
        if hit is not None:
            return hit
        Jw, dw = self._weld(weld)
        sp, sb, sw = self.state(point), self.state(body), self.state(weld)
        S = skew(sw.p - sp.p)  # J_b J_Wb^-1 = [[I, S], [0, I]]
        cols = self.jcols
        J = np.empty((6, cols.size))
        J[:3] = sp.J[:3, cols] - Jw[:3] - S @ Jw[3:]
        J[3:] = sb.J[3:, cols] - Jw[3:]
        J *= self.jsign
        drift = np.empty(6)
        drift[:3] = sp.drift[:3] - dw[:3] - S @ dw[3:]
        drift[3:] = sb.drift[3:] - dw[3:]
        self._reduced[key] = (J, drift)
        return J, drift

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
    return w * (w @ R) - (w @ w) * np.diagonal(R)
