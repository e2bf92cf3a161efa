"""Ground reaction wrenches: per body in the thesis's convention, per foot in the world, centre of pressure.

Thesis convention (eqs. 4.42-4.53, errata K-7): F_0,k is the force the ground applies to body k and M_0,k
the moment about the CoM of body k, both resolved in body frame k.

Per-foot split between toe body and main body (eqs. 4.75-4.81, errata K-10): when the foot is held flat
(main body welded and toe joint locked), the thesis sets the toe-joint interaction to zero
(F_{1,3} = 0, M_{1,3x} = M_{1,3z} = 0, T1 = 0), so the toe body receives from the ground exactly its own
Newton-Euler wrench (its weight plus inertia: F_0,1 = m_1 (a_c1 - g), M_0,1 = J alpha + w x J w) and the
main body the rest.  In the floating-base model the whole foot load arrives through the weld of the main
body (the toe is held through its joint and the lock), so the split is computed as: toe share = the toe's
own Newton-Euler wrench, main share = weld wrench - toe share.  The sum -- the total ground wrench on the
foot -- is the same in both formulations because the foot moves as one rigid body.  When only the toe is
welded (trailing foot in double support), F_0,toe is that weld's wrench and the main body gets none.

Centre of pressure: the point on z = 0 about which the foot's ground wrench has no horizontal moment,
``p = (-n_y / f_z, n_x / f_z, 0)`` for the moment ``n`` about the world origin; NaN when f_z <= 0.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pinocchio as pin

from humanoid_sim.contact.constraints import ContactSet, _frame_id, _joint_idx
from humanoid_sim.contact.errors import ContactInputError

MIN_NORMAL_FORCE = 1e-9
"""N: below this vertical force the centre of pressure is undefined (reported as NaN)."""


_SCRATCH: dict[int, tuple[weakref.ref, pin.Data]] = {}


def _scratch_data(model: pin.Model) -> pin.Data:
    """A reusable Data for ``model`` (createData costs ~90 us, more than the rest of this module's work)."""
    entry = _SCRATCH.get(id(model))
    if entry is None or entry[0]() is not model:
        entry = (weakref.ref(model), model.createData())
        _SCRATCH[id(model)] = entry
    return entry[1]


@dataclass(frozen=True)
class FootSpec:
    """A foot: its main body frame (welded in stance), optionally a toe body frame and the toe joint."""

    name: str
    main_frame: str
    toe_frame: str | None = None
    toe_joint: str | None = None


@dataclass
class BodyWrench:
    """Ground wrench on one body, thesis convention: ``force`` F_0,k (N) and ``moment`` M_0,k (N m, about the
    body's CoM), both in body frame k; ``com`` (m, world) and ``rotation`` (world <- k) to move it."""

    frame: str
    force: np.ndarray
    moment: np.ndarray
    com: np.ndarray
    rotation: np.ndarray

    def world(self, point: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(force, moment about ``point``), world frame."""
        f = self.rotation @ self.force
        n = self.rotation @ self.moment + np.cross(self.com - np.asarray(point, dtype=float), f)
        return f, n


@dataclass
class FootWrench:
    """Total ground wrench on one foot, world frame: ``force`` (N), ``moment`` about the world origin (N m),
    centre of pressure ``cop`` on z = 0 (m; NaN when unloaded) and the vertical free moment about it."""

    foot: str
    force: np.ndarray
    moment: np.ndarray
    cop: np.ndarray
    free_moment: float

    def moment_about(self, point: np.ndarray) -> np.ndarray:
        return self.moment - np.cross(np.asarray(point, dtype=float), self.force)


@dataclass
class GroundReactions:
    """Every ground reaction at one instant."""

    bodies: dict[str, BodyWrench]   # keyed by body frame name (e.g. "O_3")
    feet: dict[str, FootWrench]     # keyed by FootSpec.name
    welds: dict[str, np.ndarray]    # raw weld multipliers [f; n] (LOCAL, at the frame origin)


def _spatial_world(model: pin.Model, data: pin.Data, fid: int, w_local: np.ndarray) -> pin.Force:
    """A LOCAL spatial force at frame ``fid`` -> world frame, about the world origin."""
    return data.oMf[fid].act(pin.Force(np.asarray(w_local, dtype=float)))


def _own_newton_euler(model: pin.Model, data: pin.Data, jid: int) -> pin.Force:
    """World-frame wrench (about the origin) that body ``jid`` alone needs for its current motion under
    gravity: I (a - g) + v x* (I v).  Needs data from forwardKinematics(q, v, a)."""
    inertia = model.inertias[jid]
    a_gf = data.a[jid] - data.oMi[jid].actInv(model.gravity)
    vel = data.v[jid]
    f = inertia * a_gf + vel.cross(inertia * vel)
    return data.oMi[jid].act(f)


def _in_body_frame(model: pin.Model, data: pin.Data, jid: int, fid: int, w_world: pin.Force
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A world wrench about the origin on the body of joint ``jid`` in the thesis convention (K-7): force and
    moment about the body's CoM, both in body frame ``fid``; also the CoM (world) and the frame's rotation."""
    com = data.oMi[jid].act(model.inertias[jid].lever)
    oMf = data.oMf[fid]  # held while its rotation is read (the array is a view into this object)
    R = oMf.rotation.copy()
    f = w_world.linear
    n_com = w_world.angular - _cross(com, f)
    return R.T @ f, R.T @ n_com, com, R


def _body_wrench(model: pin.Model, data: pin.Data, frame: str, fid: int, w_world: pin.Force) -> BodyWrench:
    force, moment, com, R = _in_body_frame(model, data, model.frames[fid].parentJoint, fid, w_world)
    return BodyWrench(frame=frame, force=force, moment=moment, com=np.array(com), rotation=R)


def _foot_split(model: pin.Model, data: pin.Data, fid_main: int, main_local: np.ndarray | None,
                fid_toe: int | None, toe_local: np.ndarray | None, toe_held: bool) -> tuple[pin.Force, pin.Force]:
    """World wrenches (about the origin) of the ground on a foot's main body and toe body from the weld
    multipliers (LOCAL, None where the body is not welded).  When the toe joint is locked with the main body
    welded, the toe body carries exactly its own Newton-Euler wrench and the main body the rest (errata K-10)."""
    w_main = _spatial_world(model, data, fid_main, main_local) if main_local is not None else pin.Force.Zero()
    w_toe = pin.Force.Zero()
    if fid_toe is not None:
        if toe_local is not None:
            w_toe = w_toe + _spatial_world(model, data, fid_toe, toe_local)
        if toe_held:
            own = _own_newton_euler(model, data, model.frames[fid_toe].parentJoint)
            w_toe = w_toe + own   # K-10: toe body carries its own weight and inertia ...
            w_main = w_main - own  # ... and the main body the rest of the foot load
    return w_main, w_toe


def centre_of_pressure(force: np.ndarray, moment_origin: np.ndarray) -> tuple[np.ndarray, float]:
    """(CoP on z = 0, vertical free moment about it) of a world wrench given about the origin."""
    fz = force[2]
    if not fz > MIN_NORMAL_FORCE:
        return np.full(3, np.nan), float("nan")
    p = np.array([-moment_origin[1] / fz, moment_origin[0] / fz, 0.0])
    free = moment_origin[2] - (p[0] * force[1] - p[1] * force[0])
    return p, float(free)


def ground_reactions(model: pin.Model, q: np.ndarray, v: np.ndarray, a: np.ndarray, contacts: ContactSet,
                     lam: np.ndarray, feet: Sequence[FootSpec], data: pin.Data | None = None) -> GroundReactions:
    """Per-body (thesis) and per-foot (world) ground wrenches from a constrained-dynamics solution."""
    lam = np.asarray(lam, dtype=float)
    if lam.shape != (contacts.n_rows,):
        raise ContactInputError(f"lam must have shape ({contacts.n_rows},) for contact set {contacts.name!r}, "
                                f"got {lam.shape}")
    data = _scratch_data(model) if data is None else data
    pin.forwardKinematics(model, data, q, v, a)
    pin.updateFramePlacements(model, data)
    slices = contacts.row_slices()
    welds = {f: lam[slices[f"weld:{f}"]].copy() for f in contacts.welds}
    bodies: dict[str, BodyWrench] = {}
    out_feet: dict[str, FootWrench] = {}
    for foot in feet:
        fid_main = _frame_id(model, foot.main_frame, contacts)
        fid_toe = _frame_id(model, foot.toe_frame, contacts) if foot.toe_frame is not None else None
        toe_held = (fid_toe is not None and foot.toe_joint is not None and foot.toe_joint in contacts.locks
                    and foot.main_frame in welds)
        if toe_held:
            _joint_idx(model, foot.toe_joint, contacts)  # validates the name
        w_main, w_toe = _foot_split(model, data, fid_main, welds.get(foot.main_frame), fid_toe,
                                    welds.get(foot.toe_frame) if fid_toe is not None else None, toe_held)
        if fid_toe is not None:
            bodies[foot.toe_frame] = _body_wrench(model, data, foot.toe_frame, fid_toe, w_toe)
        bodies[foot.main_frame] = _body_wrench(model, data, foot.main_frame, fid_main, w_main)
        total = w_main + w_toe
        cop, free = centre_of_pressure(total.linear, total.angular)
        out_feet[foot.name] = FootWrench(foot=foot.name, force=total.linear.copy(), moment=total.angular.copy(),
                                         cop=cop, free_moment=free)
    return GroundReactions(bodies=bodies, feet=out_feet, welds=welds)


class GroundReactionLog:
    """Ground reactions as plain arrays, for logging many instants cheaply.

    The same quantities as :func:`ground_reactions` (the same helpers: the K-10 foot split and the thesis body
    frame transform), written into preallocated rows instead of result objects: per body of ``body_frames`` the thesis wrench (F_0,k, M_0,k in
    body frame k, zero for a body without ground contact), per foot the world wrench about the origin and the
    centre of pressure.  Frame and joint lookups are done once per contact set.
    """

    def __init__(self, model: pin.Model, feet: Sequence[FootSpec], body_frames: Sequence[str]) -> None:
        self.model = model
        self.data = model.createData()
        self.feet = list(feet)
        self.body_row = {f: i for i, f in enumerate(body_frames)}
        self._plans: dict[ContactSet, list[tuple]] = {}

    def _plan(self, contacts: ContactSet) -> list[tuple]:
        plan = self._plans.get(contacts)
        if plan is None:
            model, slices = self.model, contacts.row_slices()
            plan = []
            for foot in self.feet:
                fid_main = _frame_id(model, foot.main_frame, contacts)
                main_sl = slices.get(f"weld:{foot.main_frame}")
                toe = None
                if foot.toe_frame is not None:
                    fid_toe = _frame_id(model, foot.toe_frame, contacts)
                    toe_held = foot.toe_joint is not None and foot.toe_joint in contacts.locks
                    if toe_held and main_sl is not None:
                        _joint_idx(model, foot.toe_joint, contacts)  # validates the name
                    toe = (fid_toe, slices.get(f"weld:{foot.toe_frame}"), toe_held and main_sl is not None,
                           model.frames[fid_toe].parentJoint, self.body_row.get(foot.toe_frame))
                plan.append((fid_main, main_sl, model.frames[fid_main].parentJoint,
                             self.body_row.get(foot.main_frame), toe))
            self._plans[contacts] = plan
        return plan

    def _body(self, jid: int, fid: int, w: pin.Force, row: int | None, bf: np.ndarray, bm: np.ndarray) -> None:
        if row is not None:
            bf[row], bm[row] = _in_body_frame(self.model, self.data, jid, fid, w)[:2]

    def __call__(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, contacts: ContactSet, lam: np.ndarray,
                 bf: np.ndarray, bm: np.ndarray, fw: np.ndarray, cop: np.ndarray) -> None:
        """Fill bf, bm (n_bodies x 3, thesis convention; untouched rows stay as given), fw (n_feet x 6: world
        force and moment about the origin) and cop (n_feet x 3, NaN when unloaded) at one instant."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, a)
        pin.updateFramePlacements(model, data)
        for i, (fid_main, main_sl, jid_main, row_main, toe) in enumerate(self._plan(contacts)):
            fid_toe, toe_sl, toe_held, jid_toe, row_toe = toe if toe is not None else (None, None, False, 0, None)
            w_main, w_toe = _foot_split(model, data, fid_main, lam[main_sl] if main_sl is not None else None,
                                        fid_toe, lam[toe_sl] if toe_sl is not None else None, toe_held)
            if toe is not None:
                self._body(jid_toe, fid_toe, w_toe, row_toe, bf, bm)
            self._body(jid_main, fid_main, w_main, row_main, bf, bm)
            total = w_main + w_toe
            fw[i, :3] = total.linear
            fw[i, 3:] = total.angular
            cop[i] = centre_of_pressure(fw[i, :3], fw[i, 3:])[0]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for 3-vectors (np.cross costs ~10 us on 3-vectors)."""
    return np.array((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))
