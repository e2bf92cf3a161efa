"""Contact-constrained forward dynamics: the hot path of the simulator.

Solves, for the generalized accelerations ``a`` (nv,) and the constraint multipliers ``lambda`` (m,),

    M(q) a + h(q, v) = tau + J(q)^T lambda          (equations of motion, floating base, v[:6] LOCAL)
    J(q) a = -(Jdot v + Kd J v + Kp e)               (constraint rows with Baumgarte stabilization)

This is the floating-base equivalent of the thesis's 122 x 122 direct dynamic solution (eqs. 4.82, 4.88,
4.94): the welds replace "supplying C^(0,1), P_tp, V = w = a = alpha = 0" for the fixed bodies, the lock
row is eq. 4.80/4.84 (theta3'' = 0 or theta4'' = 0), and in double support the second weld replaces the
closed-chain rows 4.85/4.86.  The thesis's internal joint forces are eliminated by the tree formulation.

Implementation: one ``forwardKinematics(q, v, 0)`` + ``computeJointJacobians`` + ``crba`` +
``nonLinearEffects`` pass, the constraint rows from the LOCAL frame Jacobians and LOCAL bias accelerations
(``getFrameAcceleration`` at a = 0 is ``Jdot v``), then pinocchio's C++ Schur-complement kernel
``forwardDynamics(model, data, tau, J, gamma)`` (tree-sparse Cholesky of M, LLT of ``J M^-1 J^T``).

``pin.constraintDynamics`` (``RigidConstraintModel(CONTACT_6D)``) is faster (docs/notes/2026-11-26-code-measurements.md;
it emulates the toe lock by a redundant second weld of the toe body: 12 rows of rank 7, several proximal
iterations), but it cannot express a 1-row joint lock: the redundant-weld emulation is
the thesis's constraint only for constraint-consistent velocities (the two rows sets differ at
acceleration level when J v != 0, and so do their Baumgarte terms), and its multipliers are not unique.
So the hot path is this exact KKT (it also yields J, drift and errors for the residual report), and
``constraintDynamics`` serves as an independent test oracle (it agrees to ~1e-11, Baumgarte included).
A forward call stays far under the 1 ms budget: 3 calls per 0.01 s step cost < 0.4 ms.

Decisions: torques on the six base rows must be zero (the base is unactuated) -- a non-zero entry raises
:class:`ContactInputError`; a torque on a locked joint is accepted and is absorbed by the lock multiplier.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.dynamics.contact.constraints import (
    Anchors,
    Baumgarte,
    ConstraintRows,
    ContactSet,
    check_state,
    kinematics_pass,
)
from humanoid_sim.dynamics.contact.errors import ContactInputError, SingularConstraintError
from humanoid_sim.dynamics.contact.inverse import InverseResult, solve_inverse

BASE_TORQUE_TOL = 1e-9
"""N / N m: largest |tau[:6]| accepted as 'zero' (round-off of a conversion from actuator torques)."""

SINGULAR_TOL = 1e-6
"""Relative constraint-acceleration residual above which the solve is declared singular.  A regular solve
leaves ~1e-12 (double round-off times cond(J M^-1 J^T) ~ 1e3 here); a failed LLT leaves O(1)."""


@dataclass
class ForwardResult:
    """Solution of one constrained forward-dynamics call, with everything needed to check it.

    a: generalized acceleration (nv,), base part = d/dt of the LOCAL base twist (m/s^2, rad/s^2).
    lam: constraint multipliers (m,), layout of :meth:`ContactSet.row_slices` (N, N m).
    """

    contacts: ContactSet
    a: np.ndarray
    lam: np.ndarray
    tau: np.ndarray
    M_upper: np.ndarray    # joint-space inertia, upper triangle as crba leaves it (nv x nv)
    h: np.ndarray          # nonlinear effects C v + g (nv,)
    J: np.ndarray          # constraint Jacobian (m x nv)
    rhs_shift: np.ndarray  # Jdot v + Kd J v + Kp e (m,)
    velocity: np.ndarray   # J v (m,)
    error: np.ndarray      # log6 / joint-angle position errors (m,)
    weld_position_error: np.ndarray     # m, per weld
    weld_orientation_error: np.ndarray  # rad, per weld

    @property
    def M(self) -> np.ndarray:
        """Symmetric joint-space inertia (kg, kg m, kg m^2)."""
        return np.triu(self.M_upper) + np.triu(self.M_upper, 1).T

    @property
    def dynamics_residual(self) -> float:
        """||M a + h - tau - J^T lambda||_inf (N, N m)."""
        return float(np.max(np.abs(self.M @ self.a + self.h - self.tau - self.J.T @ self.lam)))

    @property
    def constraint_residual(self) -> float:
        """||J a + Jdot v + Kd J v + Kp e||_inf: how well the stabilized acceleration law holds."""
        if self.J.shape[0] == 0:
            return 0.0
        return float(np.max(np.abs(self.J @ self.a + self.rhs_shift)))

    @property
    def velocity_drift(self) -> float:
        """||J v||_inf (m/s, rad/s): constraint violation at velocity level."""
        return float(np.max(np.abs(self.velocity))) if self.velocity.size else 0.0

    @property
    def position_drift(self) -> float:
        """Largest distance (m) of a welded frame from its anchor."""
        return float(np.max(self.weld_position_error)) if self.weld_position_error.size else 0.0

    @property
    def orientation_drift(self) -> float:
        """Largest rotation angle (rad) of a welded frame away from its anchor."""
        return float(np.max(self.weld_orientation_error)) if self.weld_orientation_error.size else 0.0

    @property
    def lock_drift(self) -> float:
        """Largest angle (rad) of a locked joint away from its anchor."""
        n = 6 * len(self.contacts.welds)
        return float(np.max(np.abs(self.error[n:]))) if self.error.size > n else 0.0

    def multipliers(self) -> dict[str, np.ndarray]:
        """``lam`` split per constraint (``"weld:<frame>"`` -> (6,) [f; n], ``"lock:<joint>"`` -> (1,))."""
        return {k: np.array(self.lam[s]) for k, s in self.contacts.row_slices().items()}

    def residuals(self) -> dict[str, float]:
        """All residuals by name (for logs)."""
        return {"dynamics": self.dynamics_residual, "constraint_acceleration": self.constraint_residual,
                "velocity_drift": self.velocity_drift, "position_drift": self.position_drift,
                "orientation_drift": self.orientation_drift, "lock_drift": self.lock_drift}


class ContactDynamics:
    """Constrained forward dynamics for any pinocchio model with a free-flyer root and any contact sets.

    One instance owns one ``pin.Data`` and a cache of preallocated constraint rows per contact set; it is
    not thread-safe.  ``gains`` is the Baumgarte stabilization (see :mod:`.constraints`).
    """

    def __init__(self, model: pin.Model, gains: Baumgarte | None = None) -> None:
        if model.nv < 6 or model.joints[1].shortname() != "JointModelFreeFlyer":
            raise ContactInputError(f"model {model.name!r} must have a free-flyer root joint, "
                                    f"got {model.joints[1].shortname() if model.njoints > 1 else 'none'}")
        self.model = model
        self.data = model.createData()
        self.gains = gains if gains is not None else Baumgarte()
        self._rows: dict[ContactSet, ConstraintRows] = {}
        self._zero = np.zeros(model.nv)

    def rows(self, contacts: ContactSet) -> ConstraintRows:
        """The (cached) constraint-row evaluator of ``contacts``."""
        r = self._rows.get(contacts)
        if r is None:
            r = self._rows[contacts] = ConstraintRows(self.model, contacts)
        return r

    def prepare(self, contacts: ContactSet, anchors: Anchors, q: np.ndarray, v: np.ndarray) -> ConstraintRows:
        """Run the kinematics pass at (q, v) and evaluate the constraint rows; ``self.data`` then holds
        M (upper triangle), nle, placements and Jacobians at this state."""
        rows = self.rows(contacts)
        self._q, self._v = q, v
        kinematics_pass(self.model, self.data, q, v, self._zero)
        rows.evaluate(self.model, self.data, q, v, anchors, self.gains)
        return rows

    def forward(self, contacts: ContactSet, anchors: Anchors, q: np.ndarray, v: np.ndarray,
                tau: np.ndarray) -> ForwardResult:
        """Accelerations and multipliers under ``contacts`` for generalized torques ``tau`` (nv,, zeros on
        the six base rows; N m on revolute joints)."""
        q, v = check_state(self.model, q, v)
        rows = self.prepare(contacts, anchors, q, v)
        return self.forward_prepared(rows, tau)

    def forward_prepared(self, rows: ConstraintRows, tau: np.ndarray) -> ForwardResult:
        """:meth:`forward` at the state of the last :meth:`prepare` (``self.data`` and ``rows`` still hold it)."""
        tau = np.asarray(tau, dtype=float)
        if tau.shape != (self.model.nv,):
            raise ContactInputError(f"tau must have shape ({self.model.nv},), got {tau.shape}")
        if np.max(np.abs(tau[:6])) > BASE_TORQUE_TOL:
            raise ContactInputError(f"tau on the unactuated free-flyer rows must be 0, got {tau[:6]}")
        contacts = rows.contacts
        d = self.data
        if rows.m:
            a = pin.forwardDynamics(self.model, d, tau, rows.J, rows.rhs_shift, 0.0).copy()
            lam = d.lambda_c.copy()
        else:
            a = pin.aba(self.model, d, self._q, self._v, tau).copy()
            lam = np.zeros(0)
        # A rank-deficient J makes the LLT of J M^-1 J^T fail silently: catch it through the residual.
        if not (np.isfinite(a).all() and np.isfinite(lam).all()) or (
                rows.m and np.max(np.abs(rows.J @ a + rows.rhs_shift)) > SINGULAR_TOL * (
                    1.0 + np.max(np.abs(rows.rhs_shift)))):
            raise SingularConstraintError(
                f"contact set {contacts.name!r}: constrained dynamics is singular at this state "
                f"(rank J = {np.linalg.matrix_rank(rows.J)} of {rows.m} rows)")
        return self._result(rows, a, lam, tau)

    def _result(self, rows: ConstraintRows, a: np.ndarray, lam: np.ndarray, tau: np.ndarray) -> ForwardResult:
        d = self.data
        return ForwardResult(contacts=rows.contacts, a=a, lam=lam, tau=tau.copy(), M_upper=d.M.copy(),
                             h=d.nle.copy(), J=rows.J.copy(), rhs_shift=rows.rhs_shift.copy(),
                             velocity=rows.velocity.copy(), error=rows.error.copy(),
                             weld_position_error=rows.weld_position_error.copy(),
                             weld_orientation_error=rows.weld_orientation_error.copy())

    def inverse_prepared(self, rows: ConstraintRows, a_desired: np.ndarray, w_tau: np.ndarray | None = None,
                         w_lambda: np.ndarray | None = None) -> InverseResult:
        """:meth:`inverse` at the state of the last :meth:`prepare`."""
        return solve_inverse(self.model, self.data, rows, a_desired, w_tau, w_lambda)

    def inverse(self, contacts: ContactSet, anchors: Anchors, q: np.ndarray, v: np.ndarray,
                a_desired: np.ndarray, w_tau: np.ndarray | None = None,
                w_lambda: np.ndarray | None = None) -> InverseResult:
        """Torques and multipliers realizing ``a_desired`` (nv,; base and locked entries ignored) under
        ``contacts``; weighted minimum-norm choice with weights ``w_tau`` (nv,, v order, only actuated
        entries used) and ``w_lambda`` (m,).  See :mod:`.inverse` for the conventions."""
        q, v = check_state(self.model, q, v)
        rows = self.prepare(contacts, anchors, q, v)
        return solve_inverse(self.model, self.data, rows, a_desired, w_tau, w_lambda)
