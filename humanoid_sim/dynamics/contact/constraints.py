"""Contact sets as data, their anchors, and the constraint rows they contribute (Jacobian, drift, errors).

A *contact set* is generic: a list of frames welded to the world (6 rows each) and a list of 1-DOF joints
locked (1 row each, acting on that joint's velocity coordinate).  The thesis's four phases are one instance
(:mod:`humanoid_sim.robot.phases`); a third-party humanoid standing on two soles is another (two welds, no lock).

Row layout of every constraint Jacobian ``J`` (m x nv): the welds in the order given, 6 rows each, expressed
in the welded frame (pinocchio ``LOCAL``: rows 0-2 linear velocity of the frame origin, rows 3-5 angular
velocity, both resolved in the frame), then one row per lock (``e_k^T``, k = the joint's index in v).
The matching multipliers ``lambda`` are, for a weld, the spatial force [f (N); n (N m)] that the world
applies to the body at the frame origin, resolved in the frame; for a lock, the generalized torque (N m)
that the lock applies on the joint coordinate.  Dynamics: ``M a + h = tau + J^T lambda``.

Decisions (the thesis is silent or uses another formulation):

- Drift stabilization is Baumgarte's: the rows are enforced as ``J a + Jdot v = -Kd (J v) - Kp e`` with
  ``e`` = ``log6(anchor^-1 * oMf)`` for a weld (LOCAL twist, m and rad) and ``q_k - q_k,anchor`` for a lock.
  Default gains: critically damped, omega = 20 rad/s -> Kp = 400 s^-2, Kd = 40 s^-1.  Time constant 50 ms,
  short against a step phase (~0.3-0.6 s), while omega*h = 0.2 at the walk's h = 0.01 s stays far inside
  the explicit ode3 stability region (|lambda h| < ~2.5 on the negative real axis).
- Anchors are the world placement of each welded frame and the angle of each locked joint *recorded at
  touchdown* (errata K-9: the toe angle is not reset to 0; a foot that lands tilted stays welded tilted).
  Anchors of frames that stay welded across a phase change are kept, not re-recorded, so drift cannot
  accumulate through phase switches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from humanoid_sim.dynamics.contact.errors import AnchorError, ContactInputError, ContactSetError


@dataclass(frozen=True)
class ContactSet:
    """Bilateral constraints of one support phase.

    welds: names of frames held fixed in the world (6-D: position and orientation).
    locks: names of 1-DOF joints whose coordinate is held fixed (1 row on the joint's velocity coordinate).
    name:  label used in messages and logs.
    """

    welds: tuple[str, ...] = ()
    locks: tuple[str, ...] = ()
    name: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "welds", tuple(self.welds))
        object.__setattr__(self, "locks", tuple(self.locks))
        for group, items in (("welds", self.welds), ("locks", self.locks)):
            if len(set(items)) != len(items):
                raise ContactSetError(f"contact set {self.name!r}: duplicate entries in {group}: {items}")

    @property
    def n_rows(self) -> int:
        """Number of constraint rows m = 6 * len(welds) + len(locks)."""
        return 6 * len(self.welds) + len(self.locks)

    def row_slices(self) -> dict[str, slice]:
        """Rows of each constraint in J / lambda: keys ``"weld:<frame>"`` and ``"lock:<joint>"``."""
        out: dict[str, slice] = {}
        for i, f in enumerate(self.welds):
            out[f"weld:{f}"] = slice(6 * i, 6 * i + 6)
        base = 6 * len(self.welds)
        for i, j in enumerate(self.locks):
            out[f"lock:{j}"] = slice(base + i, base + i + 1)
        return out

    def union(self, other: ContactSet, name: str | None = None) -> ContactSet:
        """Both sets' constraints (duplicates dropped, order kept: self first)."""
        welds = tuple(dict.fromkeys(self.welds + other.welds))
        locks = tuple(dict.fromkeys(self.locks + other.locks))
        return ContactSet(welds, locks, name if name is not None else f"{self.name}+{other.name}")


@dataclass(frozen=True)
class Baumgarte:
    """Baumgarte drift-stabilization gains: ``Kp = omega^2`` (s^-2), ``Kd = 2 zeta omega`` (s^-1)."""

    omega: float = 20.0
    zeta: float = 1.0

    def __post_init__(self) -> None:
        if not (self.omega >= 0.0 and self.zeta >= 0.0):
            raise ContactInputError(f"Baumgarte gains must be >= 0, got omega={self.omega}, zeta={self.zeta}")

    @property
    def kp(self) -> float:
        return self.omega * self.omega

    @property
    def kd(self) -> float:
        return 2.0 * self.zeta * self.omega


NO_STABILIZATION = Baumgarte(0.0, 0.0)


@dataclass
class Anchors:
    """Where the constraints hold: world placement of welded frames, angle (rad, pinocchio q) of locked joints."""

    placements: dict[str, pin.SE3] = field(default_factory=dict)
    joint_positions: dict[str, float] = field(default_factory=dict)

    def copy(self) -> Anchors:
        return Anchors({k: pin.SE3(v) for k, v in self.placements.items()}, dict(self.joint_positions))


def record_anchors(model: pin.Model, q: np.ndarray, contacts: ContactSet, previous: Anchors | None = None,
                   data: pin.Data | None = None) -> Anchors:
    """Anchors for ``contacts`` at configuration ``q``.

    Entries already in ``previous`` are kept (a foot that stays welded keeps its touchdown placement); the
    others are recorded from ``q``.  Entries of ``previous`` that ``contacts`` does not use are dropped.
    """
    data = model.createData() if data is None else data
    prev = previous if previous is not None else Anchors()
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    out = Anchors()
    for f in contacts.welds:
        if f in prev.placements:
            out.placements[f] = pin.SE3(prev.placements[f])
        else:
            out.placements[f] = pin.SE3(data.oMf[_frame_id(model, f, contacts)])
    for j in contacts.locks:
        if j in prev.joint_positions:
            out.joint_positions[j] = float(prev.joint_positions[j])
        else:
            out.joint_positions[j] = float(q[_joint_idx(model, j, contacts)[0]])
    return out


def _frame_id(model: pin.Model, name: str, contacts: ContactSet) -> int:
    if not model.existFrame(name):
        raise ContactSetError(f"contact set {contacts.name!r}: model {model.name!r} has no frame {name!r}")
    return model.getFrameId(name)


def _joint_idx(model: pin.Model, name: str, contacts: ContactSet) -> tuple[int, int]:
    if not model.existJointName(name):
        raise ContactSetError(f"contact set {contacts.name!r}: model {model.name!r} has no joint {name!r}")
    jid = model.getJointId(name)
    if model.nqs[jid] != 1 or model.nvs[jid] != 1:
        raise ContactSetError(f"contact set {contacts.name!r}: joint {name!r} is not 1-DOF "
                              f"(nq={model.nqs[jid]}, nv={model.nvs[jid]}); only 1-DOF joints can be locked")
    return model.idx_qs[jid], model.idx_vs[jid]


class ConstraintRows:
    """The constraint rows of one contact set on one model, with preallocated buffers.

    ``evaluate`` expects ``data`` to hold ``forwardKinematics(q, v, 0)`` (placements, velocities and the
    bias accelerations ``Jdot v``) and ``computeJointJacobians``.  It fills:

    - ``J`` (m x nv): constraint Jacobian (LOCAL rows for welds, unit rows for locks);
    - ``drift`` (m,): ``Jdot v`` (LOCAL spatial acceleration of the welded frame at a = 0; 0 for locks);
    - ``velocity`` (m,): ``J v``;
    - ``error`` (m,): position error ``log6(anchor^-1 oMf)`` / ``q_k - anchor``;
    - ``rhs_shift`` (m,): ``drift + Kd J v + Kp error``, so that the enforced law is ``J a = -rhs_shift``.
    """

    def __init__(self, model: pin.Model, contacts: ContactSet) -> None:
        self.contacts = contacts
        self.nv = model.nv
        self.m = contacts.n_rows
        self.frame_ids = [_frame_id(model, f, contacts) for f in contacts.welds]
        idx = [_joint_idx(model, j, contacts) for j in contacts.locks]
        self.lock_q = np.array([i[0] for i in idx], dtype=int)
        self.lock_v = np.array([i[1] for i in idx], dtype=int)
        self.n_weld_rows = 6 * len(self.frame_ids)
        mask = np.ones(self.nv, dtype=bool)
        mask[:6] = False
        mask[self.lock_v] = False
        self.actuated = np.flatnonzero(mask)  # v indices of every non-base, non-locked coordinate
        self.J = np.zeros((self.m, self.nv))
        for r, k in enumerate(self.lock_v):
            self.J[self.n_weld_rows + r, k] = 1.0
        self.drift = np.zeros(self.m)
        self.velocity = np.zeros(self.m)
        self.error = np.zeros(self.m)
        self.rhs_shift = np.zeros(self.m)
        self.weld_position_error = np.zeros(len(self.frame_ids))     # m, |p - p_anchor|
        self.weld_orientation_error = np.zeros(len(self.frame_ids))  # rad, |log3(R_anchor^T R)|

    def evaluate(self, model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray, anchors: Anchors,
                 gains: Baumgarte) -> None:
        """Fill the buffers at (q, v); see the class docstring for the preconditions on ``data``."""
        LOCAL = pin.ReferenceFrame.LOCAL
        J, drift, velocity, error = self.J, self.drift, self.velocity, self.error
        for i, (name, fid) in enumerate(zip(self.contacts.welds, self.frame_ids)):
            r = slice(6 * i, 6 * i + 6)
            J[r] = pin.getFrameJacobian(model, data, fid, LOCAL)
            drift[r] = pin.getFrameAcceleration(model, data, fid, LOCAL).vector
            velocity[r] = pin.getFrameVelocity(model, data, fid, LOCAL).vector
            try:
                anchor = anchors.placements[name]
            except KeyError:
                raise AnchorError(f"no anchor for welded frame {name!r} (contact set {self.contacts.name!r}); "
                                  f"anchored frames: {sorted(anchors.placements)}") from None
            oMf = pin.updateFramePlacement(model, data, fid)
            e = pin.log6(anchor.actInv(oMf)).vector
            error[r] = e
            dp = oMf.translation - anchor.translation
            self.weld_position_error[i] = math.sqrt(dp @ dp)
            # the angular part of log6 is log3 of the relative rotation: its norm is the rotation angle
            self.weld_orientation_error[i] = math.sqrt(e[3:] @ e[3:])
        n = self.n_weld_rows
        if len(self.lock_v):
            self.velocity[n:] = v[self.lock_v]
            try:
                ref = np.array([anchors.joint_positions[j] for j in self.contacts.locks])
            except KeyError as exc:
                raise AnchorError(f"no anchor angle for locked joint {exc.args[0]!r} (contact set "
                                  f"{self.contacts.name!r}); anchored joints: {sorted(anchors.joint_positions)}"
                                  ) from None
            self.error[n:] = q[self.lock_q] - ref
        np.multiply(gains.kd, self.velocity, out=self.rhs_shift)
        self.rhs_shift += self.drift
        self.rhs_shift += gains.kp * self.error

    def split(self, lam: np.ndarray) -> dict[str, np.ndarray]:
        """Multipliers per constraint: ``{"weld:O_3": (6,), "lock:theta3": (1,), ...}``."""
        return {k: np.array(lam[s]) for k, s in self.contacts.row_slices().items()}


def kinematics_pass(model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray, zero_a: np.ndarray) -> None:
    """The pinocchio passes every constrained solve needs: placements, velocities and bias accelerations
    (forwardKinematics with a = 0), joint Jacobians, the joint-space inertia (crba: upper triangle of
    ``data.M``) and the nonlinear effects ``data.nle`` = C(q, v) v + g(q)."""
    pin.forwardKinematics(model, data, q, v, zero_a)
    pin.computeJointJacobians(model, data)
    pin.crba(model, data, q)
    pin.nonLinearEffects(model, data, q, v)


def check_state(model: pin.Model, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validate and convert (q, v)."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    if q.shape != (model.nq,):
        raise ContactInputError(f"q must have shape ({model.nq},), got {q.shape}")
    if v.shape != (model.nv,):
        raise ContactInputError(f"v must have shape ({model.nv},), got {v.shape}")
    return q, v
