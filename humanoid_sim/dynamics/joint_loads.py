"""Joint loads: the reaction wrench each joint transmits between bodies, and the bearing loads it amounts to.

The quantity is the thesis's "reaction forces and moments between bodies" (chapter 4, eq. 4.68 ff.) for any
engine's logged state.  For a joint j of the Pinocchio tree, its **transmitted wrench** W_j = [f; n] is the wrench
the parent side applies to the child body and, through it, to the child's whole subtree, resolved in joint j's
local frame with the moment taken about the joint's origin (N, N m).  It balances that subtree:

    W_j = sum over the subtree's bodies b of (rate of momentum_b - gravity wrench_b - external wrench_b).

Pinocchio's ``rnea(model, data, q, v, a, fext)`` leaves exactly this in ``data.f[j]`` (its backward pass
accumulates each body's I a + v x* I v - fext_b, gravity entering as the base acceleration -g), and
S_j^T W_j = tau_j, the joint's generalized torque.  Sign: for a tree rooted at the trunk, the child of a leg joint
is the foot side, so W of the knee is the thigh's wrench on shank and foot -- the opposite of the thesis's
F_{9,11} (shank on thigh).

External wrenches (``fext``) use Pinocchio's convention: per joint, the wrench applied to that joint's body,
local frame, about the joint origin.  :func:`fext_from_body_wrenches` builds them from the thesis convention that
the logs use (``body_force`` / ``body_moment``: F_0,k in body frame k, M_0,k about the CoM of body k, errata K-7).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from humanoid_sim.errors import InputError

THESIS_FOOT_FRAMES: tuple[str, ...] = ("O_1", "O_2", "O_3", "O_4")
"""The frames of the rows of the logged ground wrenches ``body_force`` / ``body_moment``: thesis bodies 1, 2, 3, 4
(the weld engine's ``BODY_FRAMES``)."""


class JointLoadsInputError(InputError):
    """An array of the wrong shape, or a frame or joint the model does not have (the message names it)."""


class JointLoads(NamedTuple):
    """Transmitted wrenches at n instants for m joints (see the module docstring).

    Attributes:
        names: the joints' names, in the order of the ``m`` axis.
        joint_ids: (m,) their Pinocchio joint indices.
        wrench: (n, m, 6) [fx fy fz mx my mz], N and N m: the wrench the parent side applies to the child
            subtree, joint-local frame, moment about the joint origin.
        axis: (m, 3) unit rotation axis of each joint in its local frame (NaN rows for non-revolute joints).
        root_wrench: (n, 6) the same quantity at the model's first joint (index 1), local frame.  For a free-flyer
            root it is the wrench the world would have to add for the inputs to be a motion of the free robot: a
            residual, ~0 when the state, accelerations and external wrenches are consistent.
    """

    names: tuple[str, ...]
    joint_ids: np.ndarray
    wrench: np.ndarray
    axis: np.ndarray
    root_wrench: np.ndarray

    @property
    def residual(self) -> np.ndarray:
        """(n,) max |root_wrench| per instant, N or N m (for a free-flyer root: the inputs' inconsistency)."""
        return np.abs(self.root_wrench).max(axis=1)

    def bearing(self) -> BearingLoads:
        """:func:`bearing_loads` of these wrenches about each joint's axis."""
        return bearing_loads(self.wrench, self.axis)


class BearingLoads(NamedTuple):
    """A joint wrench split along and across the joint's rotation axis u (the shaft axis), each (n, m).

    Attributes:
        axial: f . u, N (signed, along +u): the thrust load of the bearing.
        shear: |f - (f . u) u|, N: the radial load.
        torsion: n . u, N m (signed, about +u): the moment the actuator, its transmission and the joint friction
            carry; for a revolute joint it equals the joint's generalized torque (Pinocchio's sign).
        bending: |n - (n . u) u|, N m: the tilting moment the bearing pair carries, about the joint origin.
    """

    axial: np.ndarray
    shear: np.ndarray
    torsion: np.ndarray
    bending: np.ndarray


def bearing_loads(wrench: np.ndarray, axis: np.ndarray) -> BearingLoads:
    """Split joint wrenches into the loads a designer sizes a joint's bearing and actuator from.

    With u the joint's unit rotation axis and the wrench [f; n] in the same (joint-local) frame, the moment about
    the joint origin: axial = f . u (signed), shear = |f_perp| (radial force), torsion = n . u (signed: what the
    actuator and joint friction carry), bending = |n_perp| (tilting moment).  Shear and axial force do not depend
    on the moment's reference point; the bending moment does (here: the joint origin, on the axis), and a bearing
    pair of spacing s turns it into radial bearing forces of about bending / s.

    Args:
        wrench: (..., m, 6) [f (N); n (N m)], e.g. :attr:`JointLoads.wrench`.
        axis: (m, 3) or (3,) rotation axes in the wrench's frame (normalised here; must be non-zero).

    Returns:
        :class:`BearingLoads`, each of shape ``wrench.shape[:-1]``.
    """
    w = np.asarray(wrench, dtype=float)
    u = np.asarray(axis, dtype=float)
    if w.ndim < 1 or w.shape[-1] != 6:
        raise JointLoadsInputError(f"wrench: expected shape (..., 6), got {w.shape}")
    norm = np.linalg.norm(u, axis=-1, keepdims=True)
    if u.shape[-1:] != (3,) or not np.all(norm > 0):
        raise JointLoadsInputError(f"axis: expected non-zero 3-vectors, got shape {u.shape} with norms "
                                   f"{np.ravel(norm).tolist()}")
    u = u / norm
    f, n = w[..., :3], w[..., 3:]
    axial = np.einsum("...i,...i->...", f, u)
    torsion = np.einsum("...i,...i->...", n, u)
    shear = np.linalg.norm(f - axial[..., None] * u, axis=-1)
    bending = np.linalg.norm(n - torsion[..., None] * u, axis=-1)
    return BearingLoads(axial=axial, shear=shear, torsion=torsion, bending=bending)


def _frame_id(model: pin.Model, name: str) -> int:
    if not model.existFrame(name):
        raise JointLoadsInputError(f"frame {name!r}: the model has no such frame")
    return int(model.getFrameId(name))


def fext_from_body_wrenches(model: pin.Model, body_force: np.ndarray, body_moment: np.ndarray,
                            frames: Sequence[str] = THESIS_FOOT_FRAMES) -> np.ndarray:
    """External wrenches per joint (Pinocchio's ``fext``) from wrenches given in the thesis convention.

    Row k of ``body_force`` / ``body_moment`` is the wrench on the body that carries frame ``frames[k]``: the
    force F_0,k (N) resolved in that frame, and the moment M_0,k (N m) about the body's centre of mass (the CoM
    of its joint's inertia), resolved in that frame (errata K-7; the logs' ``body_force`` / ``body_moment``).
    Both the frame and the CoM are fixed in the joint frame, so the conversion needs no configuration:
    f_j = R f_k, n_j = R M_k + c x f_j, with R the frame's rotation in the joint frame and c the CoM (joint frame).

    Args:
        model: the Pinocchio model.
        body_force, body_moment: (n, len(frames), 3).
        frames: names of the frames the rows refer to (default: thesis bodies 1, 2, 3, 4).

    Returns:
        (n, model.njoints, 6): per joint the sum of the wrenches on its body, local frame, about the joint
        origin (zero rows for unloaded joints); ``fext[i]`` is what :func:`joint_loads` applies at instant i.
    """
    F = np.asarray(body_force, dtype=float)
    M = np.asarray(body_moment, dtype=float)
    k = len(frames)
    if F.ndim != 3 or F.shape[1:] != (k, 3) or M.shape != F.shape:
        raise JointLoadsInputError(f"body_force, body_moment: expected shapes (n, {k}, 3), got {F.shape} and "
                                   f"{M.shape}")
    fext = np.zeros((F.shape[0], model.njoints, 6))
    for row, name in enumerate(frames):
        frame = model.frames[_frame_id(model, name)]
        jid = frame.parentJoint
        R = frame.placement.rotation
        c = model.inertias[jid].lever
        f = F[:, row] @ R.T
        fext[:, jid, :3] += f
        fext[:, jid, 3:] += M[:, row] @ R.T + np.cross(c, f)
    return fext


def _joint_ids(model: pin.Model, joints: Sequence[str] | None) -> tuple[tuple[str, ...], np.ndarray]:
    """Names and indices of the requested joints; default: every joint but the universe and a free-flyer root."""
    if joints is None:
        ids = [j for j in range(1, model.njoints)
               if not (model.parents[j] == 0 and model.joints[j].shortname() == "JointModelFreeFlyer")]
        return tuple(model.names[j] for j in ids), np.array(ids, dtype=np.intp)
    missing = [n for n in joints if not model.existJointName(n)]
    if missing:
        raise JointLoadsInputError(f"joints {missing}: the model has no such joints")
    return tuple(joints), np.array([model.getJointId(n) for n in joints], dtype=np.intp)


def joint_axes(model: pin.Model, joint_ids: Sequence[int]) -> np.ndarray:
    """(m, 3) unit rotation axis of each joint in its local frame (the angular part of its motion subspace, from
    a LOCAL joint Jacobian at the neutral configuration); NaN rows for joints that are not 1-DOF revolute."""
    data = model.createData()
    q0 = pin.neutral(model)
    out = np.full((len(joint_ids), 3), np.nan)
    for k, jid in enumerate(joint_ids):
        if model.nvs[jid] != 1:
            continue
        col = pin.computeJointJacobian(model, data, q0, int(jid))[:, model.idx_vs[jid]]
        if np.linalg.norm(col[:3]) < 1e-12 and abs(np.linalg.norm(col[3:]) - 1.0) < 1e-12:
            out[k] = col[3:]
    return out


def _rows(model: pin.Model, Q: np.ndarray, V: np.ndarray, A: np.ndarray) -> tuple[np.ndarray, ...]:
    Q, V, A = (np.ascontiguousarray(X, dtype=float) for X in (Q, V, A))
    n = Q.shape[0] if Q.ndim == 2 else -1
    if Q.shape != (n, model.nq) or V.shape != (n, model.nv) or A.shape != (n, model.nv):
        raise JointLoadsInputError(f"Q, V, A: expected shapes (n, {model.nq}), (n, {model.nv}), (n, {model.nv}), "
                                   f"got {Q.shape}, {V.shape}, {A.shape}")
    return Q, V, A


def joint_loads(model: pin.Model, Q: np.ndarray, V: np.ndarray, A: np.ndarray, fext: np.ndarray | None = None,
                joints: Sequence[str] | None = None, data: pin.Data | None = None) -> JointLoads:
    """The wrench every joint transmits, at n instants (see the module docstring for the convention).

    Args:
        model: the Pinocchio model (gravity from ``model.gravity``).
        Q, V, A: (n, nq), (n, nv), (n, nv): configurations, velocities (m/s, rad/s) and accelerations
            (m/s^2, rad/s^2) in Pinocchio's conventions (a free-flyer base's twist and its rate in the base frame).
        fext: (n, njoints, 6) external wrenches per joint (Pinocchio's ``fext``: on the joint's body, local frame,
            about the joint origin; e.g. :func:`fext_from_body_wrenches` of the logged ground wrenches); None for
            none.
        joints: joint names in the order wanted (e.g. ``humanoid_sim.robot.model.THETA_NAMES`` for the thesis's
            eq. 4.1 order); None for every joint but the universe and a free-flyer root, in model order.
        data: a Pinocchio Data to work in (default: a fresh one).

    Returns:
        :class:`JointLoads` with ``wrench`` (n, m, 6) in N and N m.
    """
    Q, V, A = _rows(model, Q, V, A)
    n = Q.shape[0]
    names, ids = _joint_ids(model, joints)
    loaded: list[int] = []
    if fext is not None:
        fext = np.asarray(fext, dtype=float)
        if fext.shape != (n, model.njoints, 6):
            raise JointLoadsInputError(f"fext: expected shape ({n}, {model.njoints}, 6), got {fext.shape}")
        loaded = [j for j in range(model.njoints) if np.any(fext[:, j] != 0.0)]
    data = model.createData() if data is None else data
    fx = pin.StdVec_Force()
    for _ in range(model.njoints):
        fx.append(pin.Force.Zero())
    # Views into Pinocchio's own storage (fx's and data.f's elements), written and read in place: fetching Force
    # objects through the bindings at every instant would cost more than the rnea itself.
    ext = [(j, fx[j].vector) for j in loaded]
    out = [data.f[int(j)].vector for j in ids]
    root_out = data.f[1].vector
    wrench = np.empty((n, len(ids), 6))
    root = np.empty((n, 6))
    rnea = pin.rnea
    for i in range(n):
        if fext is not None:
            fi = fext[i]
            for j, view in ext:
                view[:] = fi[j]
            rnea(model, data, Q[i], V[i], A[i], fx)
        else:
            rnea(model, data, Q[i], V[i], A[i])
        wi = wrench[i]
        for k, view in enumerate(out):
            wi[k] = view
        root[i] = root_out
    return JointLoads(names=names, joint_ids=ids, wrench=wrench, axis=joint_axes(model, ids.tolist()), root_wrench=root)


__all__ = ["THESIS_FOOT_FRAMES", "BearingLoads", "JointLoads", "JointLoadsInputError", "bearing_loads",
           "fext_from_body_wrenches", "joint_axes", "joint_loads"]
