"""Inverse dynamics under the contact constraints (what the computed-torque controller needs).

Given (q, v) and desired accelerations of the free joints, find the accelerations actually compatible with
the constraints, the generalized torques ``tau`` and the multipliers ``lambda`` such that

    M a + h = S^T tau_act + J^T lambda,      J a = -(Jdot v + Kd J v + Kp e)

with the same Baumgarte law as the forward dynamics, so that feeding ``tau`` back to
:meth:`ContactDynamics.forward` returns ``a``.

Decisions (the thesis's computed-torque control, eqs. 5.91-5.98, uses the 96-component force vector F; this
is its floating-base counterpart):

- *Actuated coordinates* are all joint coordinates except the six base rows and the locked joints.  The
  torque of a locked joint is zero by the thesis's convention (errata K-10: T1 = M_{1,3y} is computed as
  0 when the toe is held; a torque there is indistinguishable from the lock multiplier).
- *Accelerations*: the base and locked-joint accelerations are unknowns fixed by the constraints.  When
  the constraints leave the free joints over-determined (double support: the closed chain needs 6 more
  rows), the free-joint accelerations used are the ones closest (Euclidean norm, rad/s^2) to the desired
  ones that satisfy the constraints; ``acceleration_correction`` reports the change (0 in single support,
  and 0 whenever the caller's accelerations already satisfy the closed-chain rows).
- *Torques*: unknowns x = [tau_act; lambda].  In single support x is unique (nv equations, nv unknowns).
  In double support it is determined up to the null space of A = [S_act^T, J^T] (6-dim: the internal
  wrench of the closed chain).  The result holds the weighted minimum-norm solution
  ``argmin x^T W x`` with W = diag(w_tau, w_lambda) given by the caller (default all ones), a basis of the
  null space, and :meth:`InverseResult.with_null` to pick another member of the family.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
import scipy.linalg as sla

from humanoid_sim.dynamics.contact.constraints import ConstraintRows, ContactSet
from humanoid_sim.dynamics.contact.errors import ContactInputError, SingularConstraintError


@dataclass
class InverseResult:
    """Torques, multipliers and accelerations from the constrained inverse dynamics (SI units).

    tau: generalized torques (nv,): zero on the base rows and on locked joints.
    lam: multipliers (m,), layout of :meth:`ContactSet.row_slices`.
    a:   accelerations actually realized (nv,), consistent with the constraints.
    """

    contacts: ContactSet
    tau: np.ndarray
    lam: np.ndarray
    a: np.ndarray
    a_desired: np.ndarray
    actuated: np.ndarray   # v indices of the actuated coordinates (n_act,)
    M: np.ndarray
    h: np.ndarray
    J: np.ndarray
    rhs_shift: np.ndarray
    free: np.ndarray       # v indices of the free (non-base, non-locked) joints
    _null: np.ndarray | None = field(default=None, repr=False)
    _A: np.ndarray | None = field(default=None, repr=False)

    @property
    def A(self) -> np.ndarray:
        """[S_act^T, J^T] (nv x (n_act + m)): A [tau_act; lambda] = M a + h."""
        if self._A is None:
            self._A = _torque_matrix(self.J, self.actuated)
        return self._A

    @property
    def dynamics_residual(self) -> float:
        """||M a + h - tau - J^T lambda||_inf (N, N m)."""
        return float(np.max(np.abs(self.M @ self.a + self.h - self.tau - self.J.T @ self.lam)))

    @property
    def constraint_residual(self) -> float:
        """||J a + Jdot v + Kd J v + Kp e||_inf."""
        return float(np.max(np.abs(self.J @ self.a + self.rhs_shift))) if self.J.size else 0.0

    @property
    def acceleration_correction(self) -> float:
        """||a_free - a_desired,free||_inf (rad/s^2): change needed to satisfy the constraints."""
        return float(np.max(np.abs(self.a[self.free] - self.a_desired[self.free]))) if self.free.size else 0.0

    @property
    def x(self) -> np.ndarray:
        """The unknown vector [tau_act; lambda] of this solution."""
        return np.concatenate([self.tau[self.actuated], self.lam])

    @property
    def null_space(self) -> np.ndarray:
        """Orthonormal basis (n_act + m, k) of the torque/multiplier family: A N = 0 (k = 0 single support,
        6 double support)."""
        if self._null is None:
            self._null = sla.null_space(self.A, rcond=1e-10)
        return self._null

    def with_null(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(tau, lambda) of x = x_this + N z, another exact solution for the same accelerations."""
        N = self.null_space
        z = np.asarray(z, dtype=float)
        if z.shape != (N.shape[1],):
            raise ContactInputError(f"z must have shape ({N.shape[1]},), got {z.shape}")
        x = self.x + N @ z
        tau = np.zeros_like(self.tau)
        n = self.actuated.size
        tau[self.actuated] = x[:n]
        return tau, x[n:]


def actuated_indices(model: pin.Model, rows: ConstraintRows) -> np.ndarray:
    """v indices of the actuated coordinates: every non-base coordinate except locked joints."""
    return rows.actuated


def solve_inverse(model: pin.Model, data: pin.Data, rows: ConstraintRows, a_desired: np.ndarray,
                  w_tau: np.ndarray | None = None, w_lambda: np.ndarray | None = None) -> InverseResult:
    """Constrained inverse dynamics on a prepared ``data`` (see :meth:`ContactDynamics.inverse`)."""
    nv, m = model.nv, rows.m
    a_desired = np.asarray(a_desired, dtype=float)
    if a_desired.shape != (nv,):
        raise ContactInputError(f"a_desired must have shape ({nv},) (base and locked entries are ignored), "
                                f"got {a_desired.shape}")
    act = actuated_indices(model, rows)
    n_act = act.size
    free = act  # free joints = actuated coordinates (same set: non-base, non-locked)
    M = symmetric_inertia(data.M)
    h = data.nle.copy()
    J = rows.J.copy()
    r = rows.rhs_shift.copy()
    if _square_support(rows):
        return _solve_square(rows, act, M, h, J, r, a_desired, data)

    # 1. accelerations: min 1/2 |a_free - a_des_free|^2  s.t.  J a = -r   (base, locked joints unweighted)
    a = a_desired.copy()
    a[:6] = 0.0
    a[rows.lock_v] = 0.0
    if m:
        H = np.zeros(nv)
        H[free] = 1.0
        K = np.zeros((nv + m, nv + m))
        K[np.arange(nv), np.arange(nv)] = H
        K[:nv, nv:] = J.T
        K[nv:, :nv] = J
        rhs = np.concatenate([H * a, -r])
        try:
            a = np.linalg.solve(K, rhs)[:nv]
        except np.linalg.LinAlgError:
            raise SingularConstraintError(f"contact set {rows.contacts.name!r}: acceleration KKT is singular "
                                          f"(rank J = {np.linalg.matrix_rank(J)} of {m})") from None

    # 2. torques and multipliers: A x = b, x = [tau_act; lambda], weighted minimum norm.
    b = M @ a + h
    A = _torque_matrix(J, act)
    wt = np.ones(n_act) if w_tau is None else _weights(w_tau, nv, "w_tau")[act]
    wl = np.ones(m) if w_lambda is None else _weights(w_lambda, m, "w_lambda")
    winv = 1.0 / np.concatenate([wt, wl])
    AW = A * winv  # A W^-1
    try:
        c, low = sla.cho_factor(AW @ A.T, check_finite=False)
    except np.linalg.LinAlgError:
        raise SingularConstraintError(f"contact set {rows.contacts.name!r}: torques cannot balance the "
                                      f"dynamics (A W^-1 A^T singular, rank A = {np.linalg.matrix_rank(A)} "
                                      f"< nv = {nv})") from None
    x = AW.T @ sla.cho_solve((c, low), b, check_finite=False)
    tau = np.zeros(nv)
    tau[act] = x[:n_act]
    return InverseResult(contacts=rows.contacts, tau=tau, lam=x[n_act:], a=a, a_desired=a_desired.copy(),
                         actuated=act, M=M, h=h, J=J, rhs_shift=r, free=free, _A=A)


def symmetric_inertia(M_upper: np.ndarray) -> np.ndarray:
    """The symmetric joint-space inertia from the upper triangle that ``crba`` fills (a new array)."""
    n = M_upper.shape[0]
    il = _lower_indices(n)
    M = M_upper.copy()
    M[il] = M_upper.T[il]
    return M


_LOWER: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def _lower_indices(n: int) -> tuple[np.ndarray, np.ndarray]:
    il = _LOWER.get(n)
    if il is None:
        il = _LOWER[n] = np.tril_indices(n, -1)
    return il


def _torque_matrix(J: np.ndarray, act: np.ndarray) -> np.ndarray:
    """A = [S_act^T, J^T] (nv x (n_act + m))."""
    nv = J.shape[1]
    A = np.zeros((nv, act.size + J.shape[0]))
    A[act, np.arange(act.size)] = 1.0
    A[:, act.size:] = J.T
    return A


def _square_support(rows: ConstraintRows) -> bool:
    """One weld plus locks: the constraint rows determine exactly the base and locked-joint accelerations and
    multipliers (single support), so the solution is unique and has a closed form."""
    return len(rows.frame_ids) == 1


def _solve_square(rows: ConstraintRows, act: np.ndarray, M: np.ndarray, h: np.ndarray, J: np.ndarray,
                  r: np.ndarray, a_desired: np.ndarray, data: pin.Data) -> InverseResult:
    """The single-support case of :func:`solve_inverse` by elimination (same unique solution, fewer flops).

    Accelerations: the free joints take the desired values; the weld rows fix the base, the lock rows the locked
    joints (J a = -r).  Torques: the base rows of M a + h = S^T tau + J^T lambda involve only the weld multiplier
    (6 x 6 system); the joint rows then give tau, the locked rows the lock multipliers.

    The weld's base block is the action matrix of the base placement seen from the welded frame,
    ``J_Wb = Ad(fMb)`` (LOCAL rows, free-flyer velocity in the base frame), so its inverse is ``Ad(bMf)``:
    no 6 x 6 solve.
    """
    nv = J.shape[1]
    a = a_desired.copy()
    a[rows.lock_v] = -r[rows.n_weld_rows:]          # lock rows: a_k = -(Kd v_k + Kp e_k)
    Jw = J[:6]
    bMf = data.oMi[1].actInv(data.oMf[rows.frame_ids[0]])
    Jb_inv = bMf.toActionMatrix()                     # (Ad(fMb))^-1
    if not np.isfinite(Jb_inv).all():
        raise SingularConstraintError(f"contact set {rows.contacts.name!r}: the weld's base block is "
                                      "singular") from None
    a[:6] = Jb_inv @ (-r[:6] - Jw[:, 6:] @ a[6:])
    b = M @ a + h
    lam_w = Jb_inv.T @ b[:6]
    g = b - Jw.T @ lam_w
    tau = np.zeros(nv)
    tau[act] = g[act]
    lam = np.concatenate([lam_w, g[rows.lock_v]])
    return InverseResult(contacts=rows.contacts, tau=tau, lam=lam, a=a, a_desired=a_desired.copy(), actuated=act,
                         M=M, h=h, J=J, rhs_shift=r, free=act)


def _weights(w: np.ndarray, n: int, name: str) -> np.ndarray:
    w = np.asarray(w, dtype=float)
    if w.shape != (n,):
        raise ContactInputError(f"{name} must have shape ({n},), got {w.shape}")
    if np.any(~(w > 0.0)):
        raise ContactInputError(f"{name} must be > 0 everywhere, got {w}")
    return w
