"""Touchdown laws: the velocity reset applied when a single support phase ends.

Two laws, selectable:

``thesis`` -- weighted least change of the lower-body joint velocities (section 4.5, eqs. 4.95-4.100,
thesis L3035-3106).  After the reset the landing foot's toe-point velocity and angular velocity are zero
(eq. 4.95/4.98), its toe rate theta4' (theta3') is set to zero, the stance foot stays at rest, and every
other joint velocity (upper body) is unchanged.  Among the velocity changes that do this it picks the one
minimizing 1/2 dq^T W_adj dq over the 14 adjustable leg rates (errata K-11 order: stance leg from ankle to
hip, then landing leg without its toe; e.g. [theta5,7,9,11,13,15,17r, theta6,8,10,12,14,16,17l] for
RFFSSP -> LFFDSP).  In the floating-base model the base twist is a dependent unknown fixed by the stance
weld -- exactly as the thesis's kinematics derives body 17's motion from the stance foot -- so the
constrained least-change problem is the thesis's eq. 4.97 / 4.100 written as a KKT system.

``inelastic`` -- a physically based, perfectly inelastic impact (restitution 0) with the contact set that
holds after touchdown: M (v+ - v-) = J^T Lambda, J v+ = 0 (pinocchio's ``impulseDynamics`` with the full
constraint Jacobian, lock rows included).  It never increases the kinetic energy (v+ is the M-orthogonal
projection of v- onto the constraint-consistent velocities).

Decisions:
- The thesis law does not change q: the touchdown configuration (including a tilt of the landing foot and
  its toe angle, errata K-9) becomes the new anchor.
- For the inelastic law the default contact set is the next DSP's (the landing foot flat, the old stance
  foot by its toe); the caller may pass another.  The old stance foot's toe is unilateral in the impact: when
  its weld's impulse would pull (world-z force < 0), the impact is solved again without it, so the landing foot
  alone takes the impulse and the toe leaves with the small velocity the impact gives it (the next DSP's weld
  then takes it back with a pushing force, which the contact audit checks).  The toe patch counts as one
  contact (pushes or leaves), not as four corners: in the zmp walks, where the trailing toe is almost unloaded
  at touchdown, its corners move with |v_z| <= 1.2 mm/s after the impact (sim3_fast_zmp, measured: <= 12 um in
  a 10 ms step, some corners downward: a per-corner complementarity would differ by that much).  Without this
  rule a trailing toe can take a small pulling impulse, outside any friction cone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.dynamics.contact import ContactSet
from humanoid_sim.dynamics.contact.constraints import _frame_id, _joint_idx, check_state
from humanoid_sim.dynamics.contact.errors import ContactError, SingularConstraintError
from humanoid_sim.robot.phases import Phase, foot_held_flat, next_phase

LEG_JOINTS = {
    "R": ("theta5", "theta7", "theta9", "theta11", "theta13", "theta15", "theta17r"),
    "L": ("theta6", "theta8", "theta10", "theta12", "theta14", "theta16", "theta17l"),
}
"""Leg joints without the toe, ankle to hip (eqs. 4.3, 4.6: q_R_Hr / q_L_H minus theta4)."""


class ImpactError(ContactError):
    """Bad arguments to a touchdown law (unknown law, overlapping joint sets, bad weights)."""


def thesis_adjustable_joints(ssp: Phase) -> tuple[str, ...]:
    """The 14 joints whose rates the thesis law changes, in W_adj order (errata K-11): stance leg, then
    landing leg (both ankle to hip, toes excluded)."""
    if ssp.is_double_support:
        raise ImpactError(f"touchdown ends a single support phase, got {ssp.value}")
    return LEG_JOINTS[ssp.support_foot] + LEG_JOINTS[ssp.landing_foot]


@dataclass
class ImpactResult:
    """A touchdown velocity reset.  ``constraint_velocity`` = J v+ over ``contacts`` (m/s, rad/s)."""

    law: str
    contacts: ContactSet
    v_minus: np.ndarray
    v_plus: np.ndarray
    kinetic_energy_before: float   # J
    kinetic_energy_after: float    # J
    constraint_velocity: np.ndarray
    impulse: np.ndarray | None     # N s (inelastic law), layout of contacts.row_slices()

    @property
    def delta_v(self) -> np.ndarray:
        return self.v_plus - self.v_minus

    @property
    def constraint_residual(self) -> float:
        """||J v+||_inf."""
        return float(np.max(np.abs(self.constraint_velocity))) if self.constraint_velocity.size else 0.0

    @property
    def energy_change(self) -> float:
        """Kinetic energy after minus before (J); <= 0 for the inelastic law."""
        return self.kinetic_energy_after - self.kinetic_energy_before


def constraint_jacobian(model: pin.Model, data: pin.Data, q: np.ndarray, contacts: ContactSet) -> np.ndarray:
    """J (m x nv) of ``contacts`` at q: LOCAL rows of each weld, unit rows of each lock."""
    pin.computeJointJacobians(model, data, q)
    J = np.zeros((contacts.n_rows, model.nv))
    for i, f in enumerate(contacts.welds):
        J[6 * i:6 * i + 6] = pin.getFrameJacobian(model, data, _frame_id(model, f, contacts), pin.LOCAL)
    n = 6 * len(contacts.welds)
    for i, j in enumerate(contacts.locks):
        J[n + i, _joint_idx(model, j, contacts)[1]] = 1.0
    return J


def _kinetic(model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray) -> float:
    return float(pin.computeKineticEnergy(model, data, q, v))


def least_change_reset(model: pin.Model, q: np.ndarray, v_minus: np.ndarray, contacts: ContactSet,
                       adjustable: Sequence[str], weights: np.ndarray, data: pin.Data | None = None
                       ) -> ImpactResult:
    """Generic form of the thesis law (eqs. 4.97/4.100).

    After the reset every lock in ``contacts`` has zero rate, every weld has zero twist, the joints in
    ``adjustable`` (1-DOF joint names) have changed by the minimizer of 1/2 dq^T diag(weights) dq, the
    base twist is whatever the welds require, and every other joint rate is unchanged.
    """
    q, v_minus = check_state(model, q, v_minus)
    data = model.createData() if data is None else data
    weights = np.asarray(weights, dtype=float)
    if weights.shape != (len(adjustable),):
        raise ImpactError(f"weights must have shape ({len(adjustable)},) like the adjustable joints "
                          f"{tuple(adjustable)}, got {weights.shape}")
    if np.any(~(weights > 0.0)):
        raise ImpactError(f"weights must be > 0, got {weights}")
    adj = np.array([_joint_idx(model, j, contacts)[1] for j in adjustable], dtype=int)
    locked = np.array([_joint_idx(model, j, contacts)[1] for j in contacts.locks], dtype=int)
    clash = sorted(set(adjustable) & set(contacts.locks))
    if clash:
        raise ImpactError(f"joints {clash} are both adjustable and locked")
    J = constraint_jacobian(model, data, q, contacts)
    nw = 6 * len(contacts.welds)
    Jw = J[:nw]
    v_fixed = v_minus.copy()
    v_fixed[locked] = 0.0                      # theta3' / theta4' "taken as zero" (L3079, L3106)
    unknown = np.concatenate([np.arange(6), adj])
    n_u = unknown.size
    C = Jw[:, unknown]
    fixed_mask = np.ones(model.nv, dtype=bool)
    fixed_mask[unknown] = False
    r = -Jw[:, fixed_mask] @ v_fixed[fixed_mask]
    H = np.zeros(n_u)
    H[6:] = weights
    K = np.zeros((n_u + nw, n_u + nw))
    K[np.arange(n_u), np.arange(n_u)] = H
    K[:n_u, n_u:] = C.T
    K[n_u:, :n_u] = C
    rhs = np.concatenate([H * v_minus[unknown], r])
    try:
        sol = np.linalg.solve(K, rhs)
    except np.linalg.LinAlgError:
        raise SingularConstraintError(f"least-change reset over {contacts.name!r} is singular: the adjustable "
                                      f"joints {tuple(adjustable)} cannot bring the welds to rest") from None
    v_plus = v_fixed.copy()
    v_plus[unknown] = sol[:n_u]
    return ImpactResult(law="thesis", contacts=contacts, v_minus=v_minus.copy(), v_plus=v_plus,
                        kinetic_energy_before=_kinetic(model, data, q, v_minus),
                        kinetic_energy_after=_kinetic(model, data, q, v_plus),
                        constraint_velocity=J @ v_plus, impulse=None)


def inelastic_impact(model: pin.Model, q: np.ndarray, v_minus: np.ndarray, contacts: ContactSet,
                     data: pin.Data | None = None, unilateral: Sequence[str] = ()) -> ImpactResult:
    """Perfectly inelastic impact with ``contacts``: v+ = argmin 1/2 (v - v-)^T M (v - v-) s.t. J v = 0.

    ``unilateral``: welds of ``contacts`` that touch the ground and may leave it (e.g. the trailing foot's toe
    at a touchdown): a weld whose impulse would pull (world-z force component < 0) is dropped and the impact
    solved again without it (the complementarity of a unilateral contact: it either pushes or separates), until
    every remaining unilateral weld pushes.  ``result.contacts`` is the set that took the impulse; J v+ is zero
    on it, and a dropped weld leaves with the (small, upward) velocity the impact gives it."""
    q, v_minus = check_state(model, q, v_minus)
    data = model.createData() if data is None else data
    unknown = sorted(set(unilateral) - set(contacts.welds))
    if unknown:
        raise ImpactError(f"unilateral welds {unknown} are not welds of the contact set {contacts.name!r} "
                          f"{contacts.welds}")
    pin.framesForwardKinematics(model, data, q)           # the welds' orientations (q does not change)
    rotation = {f: data.oMf[_frame_id(model, f, contacts)].rotation.copy() for f in unilateral}
    while True:
        J = constraint_jacobian(model, data, q, contacts)
        if np.linalg.matrix_rank(J) < J.shape[0]:
            raise SingularConstraintError(f"impact contact set {contacts.name!r} has dependent rows "
                                          f"(rank {np.linalg.matrix_rank(J)} < {J.shape[0]})")
        v_plus = pin.impulseDynamics(model, data, q, v_minus, J, 0.0, 0.0).copy()
        impulse = data.impulse_c.copy()
        pulling = [f for i, f in enumerate(contacts.welds)
                   if f in rotation and (rotation[f] @ impulse[6 * i:6 * i + 3])[2] < 0.0]
        if not pulling:
            break
        contacts = ContactSet(tuple(f for f in contacts.welds if f not in pulling), contacts.locks,
                              name=f"{contacts.name} (without {', '.join(pulling)}: separating)")
    return ImpactResult(law="inelastic", contacts=contacts, v_minus=v_minus.copy(), v_plus=v_plus,
                        kinetic_energy_before=_kinetic(model, data, q, v_minus),
                        kinetic_energy_after=_kinetic(model, data, q, v_plus),
                        constraint_velocity=J @ v_plus, impulse=impulse)


def touchdown(model: pin.Model, q: np.ndarray, v_minus: np.ndarray, ssp: Phase, law: str = "thesis",
              w_adj: np.ndarray | None = None, contacts: ContactSet | None = None) -> ImpactResult:
    """The touchdown ending single support phase ``ssp`` of the thesis humanoid.

    law="thesis": ``w_adj`` (14,) in :func:`thesis_adjustable_joints` order (the scenario's Wadj vector,
    errata A-8/K-11); constraints = stance foot flat + landing foot flat.
    law="inelastic": ``contacts`` defaults to the next DSP's contact set, in which the old stance foot holds the
    ground by its toe: that toe contact is unilateral in the impact (it pushes or it separates).
    """
    if ssp.is_double_support:
        raise ImpactError(f"touchdown ends a single support phase, got {ssp.value}")
    if law == "thesis":
        if w_adj is None:
            raise ImpactError("law='thesis' needs the W_adj weights (14,) of the scenario")
        cs = foot_held_flat(ssp.support_foot).union(foot_held_flat(ssp.landing_foot),
                                                   name=f"{ssp.value}->{next_phase(ssp).value}")
        return least_change_reset(model, q, v_minus, cs, thesis_adjustable_joints(ssp), w_adj)
    if law == "inelastic":
        if contacts is not None:
            return inelastic_impact(model, q, v_minus, contacts)
        landing = set(foot_held_flat(ssp.landing_foot).welds)
        dsp = next_phase(ssp).contacts
        return inelastic_impact(model, q, v_minus, dsp, unilateral=[f for f in dsp.welds if f not in landing])
    raise ImpactError(f"unknown touchdown law {law!r}; expected 'thesis' or 'inelastic'")


__all__ = ["ImpactError", "ImpactResult", "LEG_JOINTS", "constraint_jacobian", "inelastic_impact",
           "least_change_reset", "thesis_adjustable_joints", "touchdown"]
