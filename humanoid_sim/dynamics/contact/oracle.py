"""Plain NumPy KKT oracle for the constrained dynamics, built from routines the fast path does not use.

- ``J``: ``pin.computeFrameJacobian`` per frame (its own kinematics pass) and unit rows for locks;
- ``Jdot v``: ``pin.computeJointJacobiansTimeVariation`` + ``getFrameJacobianTimeVariation(...) @ v``
  (the fast path reads the LOCAL bias acceleration of a second-order forward-kinematics pass instead);
- ``M``: ``crba`` symmetrized; ``h``: ``rnea(q, v, 0)``;
- the full (nv + m) KKT matrix ``[[M, -J^T], [J, 0]]`` solved densely with ``numpy.linalg.solve``.

Slow (~10x the fast path); for tests and debugging only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.dynamics.contact.constraints import Anchors, Baumgarte, ContactSet, _frame_id, _joint_idx


@dataclass
class OracleTerms:
    """Dense terms at one state: M (nv x nv), h (nv,), J (m x nv), Jdot v (m,), J v (m,), error e (m,)."""

    M: np.ndarray
    h: np.ndarray
    J: np.ndarray
    drift: np.ndarray
    velocity: np.ndarray
    error: np.ndarray


def oracle_terms(model: pin.Model, contacts: ContactSet, anchors: Anchors | None, q: np.ndarray,
                 v: np.ndarray) -> OracleTerms:
    """Dense M, h and constraint rows; position errors are zero when ``anchors`` is None."""
    data = model.createData()
    nv = model.nv
    M = pin.crba(model, data, q).copy()
    M = np.triu(M) + np.triu(M, 1).T
    h = pin.rnea(model, data, q, v, np.zeros(nv)).copy()
    m = contacts.n_rows
    J = np.zeros((m, nv))
    drift = np.zeros(m)
    err = np.zeros(m)
    pin.computeJointJacobiansTimeVariation(model, data, q, v)
    pin.updateFramePlacements(model, data)
    for i, f in enumerate(contacts.welds):
        fid = _frame_id(model, f, contacts)
        r = slice(6 * i, 6 * i + 6)
        J[r] = pin.computeFrameJacobian(model, model.createData(), q, fid, pin.ReferenceFrame.LOCAL)
        drift[r] = pin.getFrameJacobianTimeVariation(model, data, fid, pin.ReferenceFrame.LOCAL) @ v
        if anchors is not None:
            err[r] = pin.log6(anchors.placements[f].actInv(data.oMf[fid])).vector
    n = 6 * len(contacts.welds)
    for i, j in enumerate(contacts.locks):
        iq, iv = _joint_idx(model, j, contacts)
        J[n + i, iv] = 1.0
        if anchors is not None:
            err[n + i] = q[iq] - anchors.joint_positions[j]
    return OracleTerms(M=M, h=h, J=J, drift=drift, velocity=J @ v, error=err)


def _kkt_matrix(t: OracleTerms) -> np.ndarray:
    """[[M, -J^T], [J, 0]]: the dense KKT matrix shared by the forward and the impulse solves."""
    nv, m = t.M.shape[0], t.J.shape[0]
    K = np.zeros((nv + m, nv + m))
    K[:nv, :nv] = t.M
    K[:nv, nv:] = -t.J.T
    K[nv:, :nv] = t.J
    return K


def kkt_forward(model: pin.Model, contacts: ContactSet, anchors: Anchors | None, q: np.ndarray,
                v: np.ndarray, tau: np.ndarray, gains: Baumgarte) -> tuple[np.ndarray, np.ndarray]:
    """(a, lambda) from the dense KKT system ``M a - J^T lam = tau - h``, ``J a = -(Jdot v + Kd J v + Kp e)``."""
    t = oracle_terms(model, contacts, anchors, q, v)
    nv = model.nv
    K = _kkt_matrix(t)
    rhs = np.concatenate([tau - t.h, -(t.drift + gains.kd * t.velocity + gains.kp * t.error)])
    sol = np.linalg.solve(K, rhs)
    return sol[:nv], sol[nv:]


def kkt_impulse(model: pin.Model, contacts: ContactSet, q: np.ndarray, v_minus: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Perfectly inelastic impact: ``M (v+ - v-) = J^T Lambda``, ``J v+ = 0``; returns (v+, Lambda (N s))."""
    t = oracle_terms(model, contacts, None, q, v_minus)
    nv, m = model.nv, contacts.n_rows
    K = _kkt_matrix(t)
    sol = np.linalg.solve(K, np.concatenate([t.M @ v_minus, np.zeros(m)]))
    return sol[:nv], sol[nv:]
