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
foot -- is the same in both formulations because the foot moves as one rigid body.

A controller may still drive the locked toe joint (the balance controller does; the thesis's sets T1 = 0).  The
lock then absorbs that torque, which on a real foot is the ground under the toe box pushing back.  Given the toe
joint's applied torque tau_toe (``toe_torque``), the toe body's share becomes its own wrench minus the couple
tau_toe about the toe axis, and the main body's share gains that couple: the total is unchanged, and inverse
dynamics from these body wrenches returns the applied tau_toe at the toe joint instead of zero.  When only the toe is
welded (trailing foot in double support), F_0,toe is that weld's wrench and the main body gets none.

Centre of pressure: the point on z = 0 about which the foot's ground wrench has no horizontal moment,
``p = (-n_y / f_z, n_x / f_z, 0)`` for the moment ``n`` about the world origin; NaN when f_z <= 0.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.dynamics.contact.constraints import ContactSet, _frame_id, _joint_idx
from humanoid_sim.dynamics.contact.errors import ContactInputError

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
                fid_toe: int | None, toe_local: np.ndarray | None, toe_held: bool,
                toe_torque: float = 0.0) -> tuple[pin.Force, pin.Force]:
    """World wrenches (about the origin) of the ground on a foot's main body and toe body from the weld
    multipliers (LOCAL, None where the body is not welded).  When the toe joint is locked with the main body
    welded, the toe body carries exactly its own Newton-Euler wrench and the main body the rest (errata K-10),
    less the couple of the toe joint's applied torque ``toe_torque`` (N m), which the ground under the toe box
    takes (module docstring)."""
    w_main = _spatial_world(model, data, fid_main, main_local) if main_local is not None else pin.Force.Zero()
    w_toe = pin.Force.Zero()
    if fid_toe is not None:
        if toe_local is not None:
            w_toe = w_toe + _spatial_world(model, data, fid_toe, toe_local)
        if toe_held:
            jid = model.frames[fid_toe].parentJoint
            own = _own_newton_euler(model, data, jid)
            couple = toe_torque * (data.oMi[jid].rotation @ _joint_axis(model, jid))
            own = pin.Force(own.linear, own.angular - couple)  # the ground pushes back on the driven toe
            w_toe = w_toe + own   # K-10: toe body carries its own weight and inertia ...
            w_main = w_main - own  # ... and the main body the rest of the foot load
    return w_main, w_toe


def _joint_axis(model: pin.Model, jid: int) -> np.ndarray:
    """Unit rotation axis of the revolute joint ``jid`` in its own frame (the angular part of its motion
    subspace, read once per model and joint from a LOCAL joint Jacobian at the neutral configuration)."""
    key = (id(model), jid)
    entry = _AXES.get(key)
    if entry is None or entry[0]() is not model:
        J = pin.computeJointJacobian(model, model.createData(), pin.neutral(model), jid)
        entry = _AXES[key] = (weakref.ref(model), J[3:, model.joints[jid].idx_v].copy())
    return entry[1]


_AXES: dict[tuple[int, int], tuple[weakref.ref, np.ndarray]] = {}


def centre_of_pressure(force: np.ndarray, moment_origin: np.ndarray) -> tuple[np.ndarray, float]:
    """(CoP on z = 0, vertical free moment about it) of a world wrench given about the origin."""
    fz = force[2]
    if not fz > MIN_NORMAL_FORCE:
        return np.full(3, np.nan), float("nan")
    p = np.array([-moment_origin[1] / fz, moment_origin[0] / fz, 0.0])
    free = moment_origin[2] - (p[0] * force[1] - p[1] * force[0])
    return p, float(free)


def ground_reactions(model: pin.Model, q: np.ndarray, v: np.ndarray, a: np.ndarray, contacts: ContactSet,
                     lam: np.ndarray, feet: Sequence[FootSpec], data: pin.Data | None = None,
                     tau: np.ndarray | None = None) -> GroundReactions:
    """Per-body (thesis) and per-foot (world) ground wrenches from a constrained-dynamics solution; ``tau``
    (nv,), N m: the applied generalized torques, whose toe components the ground under a held toe box takes
    (module docstring; None = zero)."""
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
        toe_tau = 0.0
        if toe_held and tau is not None:
            toe_tau = float(tau[model.joints[model.getJointId(foot.toe_joint)].idx_v])
        w_main, w_toe = _foot_split(model, data, fid_main, welds.get(foot.main_frame), fid_toe,
                                    welds.get(foot.toe_frame) if fid_toe is not None else None, toe_held, toe_tau)
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
    frame transform), written into preallocated rows instead of result objects: per body of ``body_frames`` the thesis
    wrench (F_0,k, M_0,k in
    body frame k, zero for a body without ground contact), per foot the world wrench about the origin and the
    centre of pressure.  Frame and joint lookups are done once per contact set.

    ``__call__`` fills one instant (~60-90 us: pinocchio object arithmetic); :meth:`batch` computes many instants
    at once (~10 us each: one forwardKinematics per instant and a few joint reads, the rest vectorised over the
    instants).
    """

    def __init__(self, model: pin.Model, feet: Sequence[FootSpec], body_frames: Sequence[str]) -> None:
        self.model = model
        self.data = model.createData()
        self.feet = list(feet)
        self.body_row = {f: i for i, f in enumerate(body_frames)}
        self._plans: dict[ContactSet, list[tuple]] = {}
        self._batch_plans: dict[ContactSet, _BatchPlan] = {}

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
                 bf: np.ndarray, bm: np.ndarray, fw: np.ndarray, cop: np.ndarray,
                 tau: np.ndarray | None = None) -> None:
        """Fill bf, bm (n_bodies x 3, thesis convention; untouched rows stay as given), fw (n_feet x 6: world
        force and moment about the origin) and cop (n_feet x 3, NaN when unloaded) at one instant; ``tau``: the
        applied generalized torques (nv,), N m, whose toe components a held toe box passes to the ground
        (module docstring; None = zero)."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, a)
        pin.updateFramePlacements(model, data)
        for i, (fid_main, main_sl, jid_main, row_main, toe) in enumerate(self._plan(contacts)):
            fid_toe, toe_sl, toe_held, jid_toe, row_toe = toe if toe is not None else (None, None, False, 0, None)
            toe_tau = float(tau[model.joints[jid_toe].idx_v]) if toe_held and tau is not None else 0.0
            w_main, w_toe = _foot_split(model, data, fid_main, lam[main_sl] if main_sl is not None else None,
                                        fid_toe, lam[toe_sl] if toe_sl is not None else None, toe_held, toe_tau)
            if toe is not None:
                self._body(jid_toe, fid_toe, w_toe, row_toe, bf, bm)
            self._body(jid_main, fid_main, w_main, row_main, bf, bm)
            total = w_main + w_toe
            fw[i, :3] = total.linear
            fw[i, 3:] = total.angular
            cop[i] = centre_of_pressure(fw[i, :3], fw[i, 3:])[0]

    # ------------------------------------------------------------------ many instants at once
    def _batch_plan(self, contacts: ContactSet) -> _BatchPlan:
        """The per-contact-set constants of :meth:`batch` (built on :meth:`_plan`, so names are validated the
        same way): per foot body its joint, its frame placement in the joint frame, its inertia and which
        rows of lambda load it; the joints whose placements / motions the kinematics pass must read."""
        bplan = self._batch_plans.get(contacts)
        if bplan is not None:
            return bplan
        model = self.model
        pose_joints: list[int] = []
        motion_joints: list[int] = []

        def body(fid: int, jid: int, row: int | None, weld: slice | None, loaded: bool) -> _BatchBody:
            if loaded and jid not in pose_joints:
                pose_joints.append(jid)
            jMf = model.frames[fid].placement
            return _BatchBody(jid=jid, row=row, weld=weld, pose=pose_joints.index(jid) if loaded else -1,
                              R_jf=jMf.rotation.copy(), p_jf=jMf.translation.copy(),
                              lever=model.inertias[jid].lever.copy())

        feet: list[_BatchFoot | None] = []
        for fid_main, main_sl, jid_main, row_main, toe in self._plan(contacts):
            fid_toe, toe_sl, toe_held, jid_toe, row_toe = toe if toe is not None else (None, None, False, 0, None)
            if main_sl is None and toe_sl is None and not toe_held:
                feet.append(None)  # no ground contact: zero wrenches, NaN CoP (the initial values)
                continue
            main = body(fid_main, jid_main, row_main, main_sl, main_sl is not None or toe_held)
            toe_body = None
            motion = -1
            if fid_toe is not None:
                toe_body = body(fid_toe, jid_toe, row_toe, toe_sl, toe_sl is not None or toe_held)
                if toe_held:
                    if jid_toe not in motion_joints:
                        motion_joints.append(jid_toe)
                    motion = motion_joints.index(jid_toe)
            inertia = model.inertias[jid_toe] if toe_held else None
            feet.append(_BatchFoot(main=main, toe=toe_body, toe_held=toe_held, motion=motion,
                                   toe_v=model.joints[jid_toe].idx_v if toe_held else -1,
                                   toe_axis=_joint_axis(model, jid_toe) if toe_held else np.zeros(3),
                                   mass=float(inertia.mass) if inertia is not None else 0.0,
                                   rot_inertia=inertia.inertia.copy() if inertia is not None else np.zeros((3, 3))))
        bplan = _BatchPlan(feet=tuple(feet), pose_joints=tuple(pose_joints), motion_joints=tuple(motion_joints))
        self._batch_plans[contacts] = bplan
        return bplan

    def _kinematics(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray, plan: _BatchPlan
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Per instant one forwardKinematics, then only the joints the plan needs: placements ``H``
        (g x n_pose x 4 x 4, world <- joint, homogeneous, m) and spatial velocities / accelerations ``VA``
        (g x n_motion x 2 x 6: [v; w] in m/s, rad/s and [a; alpha] in m/s^2, rad/s^2, joint frame, pinocchio
        spatial convention)."""
        model, data = self.model, self.data
        pose, motion = plan.pose_joints, plan.motion_joints
        g = Q.shape[0]
        H = np.empty((g, len(pose), 4, 4))
        VA = np.empty((g, len(motion), 2, 6))
        fk = pin.forwardKinematics
        oMi, vel, acc = data.oMi, data.v, data.a
        if motion:
            for i in range(g):
                fk(model, data, Q[i], V[i], A[i])
                Hi, VAi = H[i], VA[i]
                for k, j in enumerate(pose):
                    Hi[k] = oMi[j].homogeneous
                for k, j in enumerate(motion):
                    VAi[k, 0] = vel[j].vector
                    VAi[k, 1] = acc[j].vector
        elif pose:
            for i in range(g):
                fk(model, data, Q[i])
                Hi = H[i]
                for k, j in enumerate(pose):
                    Hi[k] = oMi[j].homogeneous
        return H, VA

    def batch(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray, contacts: Sequence[ContactSet],
              lams: Sequence[np.ndarray], taus: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Ground reactions at n instants: exactly what n calls of ``__call__`` fill, computed in one pass.

        Q (n x nq), V (n x nv), A (n x nv): stacked configurations, velocities (m/s, rad/s) and accelerations
        (m/s^2, rad/s^2), pinocchio conventions; ``contacts[i]`` the contact set of instant i (instants are
        grouped by contact set, so repeat the same object); ``lams[i]`` its multipliers (contacts[i].n_rows,
        layout of :mod:`humanoid_sim.dynamics.contact.constraints`); ``taus`` (n x nv, N m): the applied generalized
        torques, whose toe components a held toe box passes to the ground (module docstring; None = zero).

        Returns (bf, bm, fw, cop):
        bf, bm  n x n_bodies x 3: F_0,k (N) and M_0,k (N m, about the CoM of body k), both in body frame k
                (thesis convention, K-7); zero for a body without ground contact;
        fw      n x n_feet x 6: total ground force (N) and moment about the world origin (N m), world frame;
        cop     n x n_feet x 3: centre of pressure on z = 0 (m, world), NaN where f_z <= MIN_NORMAL_FORCE.
        """
        model = self.model
        Q = np.ascontiguousarray(Q, dtype=float)
        V = np.ascontiguousarray(V, dtype=float)
        A = np.ascontiguousarray(A, dtype=float)
        n = Q.shape[0] if Q.ndim == 2 else -1
        if Q.shape != (n, model.nq) or V.shape != (n, model.nv) or A.shape != (n, model.nv):
            raise ContactInputError(f"Q, V, A must have shapes (n, {model.nq}), (n, {model.nv}), (n, {model.nv}), "
                                    f"got {Q.shape}, {V.shape}, {A.shape}")
        if len(contacts) != n or len(lams) != n:
            raise ContactInputError(f"contacts and lams must have one entry per row of Q ({n}), "
                                    f"got {len(contacts)} and {len(lams)}")
        bf = np.zeros((n, len(self.body_row), 3))
        bm = np.zeros((n, len(self.body_row), 3))
        fw = np.zeros((n, len(self.feet), 6))
        cop = np.full((n, len(self.feet), 3), np.nan)
        groups: dict[int, tuple[ContactSet, list[int]]] = {}  # by identity: hashing a ContactSet costs more
        for i, cs in enumerate(contacts):
            grp = groups.get(id(cs))
            if grp is None:
                grp = groups[id(cs)] = (cs, [])
            grp[1].append(i)
        g_lin, g_ang = model.gravity.linear.copy(), model.gravity.angular.copy()
        for cs, rows in groups.values():
            plan = self._batch_plan(cs)
            m = cs.n_rows
            try:
                L = np.array([lams[i] for i in rows], dtype=float)
            except ValueError:  # ragged: the loop below names the culprit
                L = np.empty(0)
            if L.shape != (len(rows), m):
                for i in rows:
                    shape = np.shape(lams[i])
                    if shape != (m,):
                        raise ContactInputError(f"lams[{i}] must have shape ({m},) for contact set {cs.name!r}, "
                                                f"got {shape}")
            if not plan.pose_joints:
                continue  # no foot touches the ground
            idx = np.asarray(rows, dtype=np.intp)
            H, VA = self._kinematics(Q[idx], V[idx], A[idx], plan)
            Rj, pj = H[:, :, :3, :3], H[:, :, :3, 3]  # g x n_pose x (3 x 3 | 3): world <- joint
            for k, foot in enumerate(plan.feet):
                if foot is None:
                    continue
                w_main = _weld_world(foot.main, Rj, pj, L)
                w_toe = _weld_world(foot.toe, Rj, pj, L) if foot.toe is not None else None
                if foot.toe_held:  # K-10: the toe body carries its own weight and inertia, the main body the rest
                    own = _own_newton_euler_batch(foot, Rj[:, foot.toe.pose], pj[:, foot.toe.pose],
                                                  VA[:, foot.motion], g_lin, g_ang)
                    if taus is not None:  # the ground under the toe box pushes back on the driven toe
                        couple = np.asarray(taus, dtype=float)[idx, foot.toe_v][:, None] * _mv(
                            Rj[:, foot.toe.pose], np.broadcast_to(foot.toe_axis, (len(rows), 3)))
                        own = (own[0], own[1] - couple)
                    w_toe = own if w_toe is None else (w_toe[0] + own[0], w_toe[1] + own[1])
                    w_main = (-own[0], -own[1]) if w_main is None else (w_main[0] - own[0], w_main[1] - own[1])
                f_tot, n_tot = np.zeros((len(rows), 3)), np.zeros((len(rows), 3))
                for b, w in ((foot.toe, w_toe), (foot.main, w_main)):
                    if w is None:
                        continue
                    f_tot += w[0]
                    n_tot += w[1]
                    if b.row is not None:
                        bf[idx, b.row], bm[idx, b.row] = _in_body_frame_batch(b, Rj[:, b.pose], pj[:, b.pose], w)
                fw[idx, k, :3] = f_tot
                fw[idx, k, 3:] = n_tot
                cop[idx, k] = _centre_of_pressure_rows(f_tot, n_tot)
        return bf, bm, fw, cop


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for 3-vectors (np.cross costs ~10 us on 3-vectors)."""
    return np.array((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))


# ---------------------------------------------------------------------------------------------- batch helpers
@dataclass(frozen=True)
class _BatchBody:
    """A foot body in a batch plan: its joint ``jid``, its row in bf/bm (None: not logged), the rows ``weld`` of
    its weld in lambda (None: not welded), its index ``pose`` in the read joint placements (-1: carries no
    ground load), its frame's placement in the joint frame (``R_jf``, ``p_jf`` in m) and its CoM ``lever``
    (m, joint frame)."""

    jid: int
    row: int | None
    weld: slice | None
    pose: int
    R_jf: np.ndarray
    p_jf: np.ndarray
    lever: np.ndarray


@dataclass(frozen=True)
class _BatchFoot:
    """A foot with ground contact in a batch plan; ``motion`` (index in the read joint motions), ``toe_v`` (the toe
    joint's index in v), ``toe_axis`` (its unit axis, joint frame), ``mass`` (kg) and ``rot_inertia`` (kg m^2,
    about the CoM, joint frame) of the toe body are used when ``toe_held``."""

    main: _BatchBody
    toe: _BatchBody | None
    toe_held: bool
    motion: int
    toe_v: int
    toe_axis: np.ndarray
    mass: float
    rot_inertia: np.ndarray


@dataclass(frozen=True)
class _BatchPlan:
    """Per contact set: one entry per foot (None: no ground contact) and the joints to read per instant."""

    feet: tuple[_BatchFoot | None, ...]
    pose_joints: tuple[int, ...]
    motion_joints: tuple[int, ...]


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a x b of g x 3 arrays (either may be one 3-vector); np.cross costs ~60 us a call here."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


def _mv(R: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Stacked R x: (g x 3 x 3, g x 3) -> g x 3."""
    return (R @ x[:, :, None])[:, :, 0]


def _mtv(R: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Stacked R^T x: (g x 3 x 3, g x 3) -> g x 3."""
    return (x[:, None, :] @ R)[:, 0, :]


def _frame_pose(body: _BatchBody, Rj: np.ndarray, pj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World placement of the body's frame (g x 3 x 3 rotation, g x 3 position in m) from its joint's."""
    R_i, p_i = Rj[:, body.pose], pj[:, body.pose]
    return R_i @ body.R_jf, R_i @ body.p_jf + p_i


def _weld_world(body: _BatchBody, Rj: np.ndarray, pj: np.ndarray, L: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """The body's weld multipliers (LOCAL [f; n] at the frame origin) as a world force (N) and moment about
    the world origin (N m), g x 3 each; None when the body is not welded (batched ``_spatial_world``)."""
    if body.weld is None:
        return None
    R, p = _frame_pose(body, Rj, pj)
    lam = L[:, body.weld]
    f = _mv(R, lam[:, :3])
    return f, _mv(R, lam[:, 3:]) + _cross_rows(p, f)


def _own_newton_euler_batch(foot: _BatchFoot, R_i: np.ndarray, p_i: np.ndarray, va: np.ndarray,
                            g_lin: np.ndarray, g_ang: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched ``_own_newton_euler`` of the toe body: I (a - g) + v x* (I v) in the joint frame, returned as a
    world force (N) and moment about the world origin (N m), g x 3 each.  ``R_i``, ``p_i``: world <- joint;
    ``va``: g x 2 x 6 spatial velocity and acceleration in the joint frame; gravity (m/s^2) in the world."""
    m, c, Ic = foot.mass, foot.toe.lever, foot.rot_inertia
    v, w = va[:, 0, :3], va[:, 0, 3:]
    a, alpha = va[:, 1, :3], va[:, 1, 3:]
    # a - g with g moved into the joint frame (SE3.actInv of a motion: R^T (v - p x w), R^T w)
    a_lin = a - _mtv(R_i, g_lin - _cross_rows(p_i, g_ang))
    a_ang = alpha - _mtv(R_i, np.broadcast_to(g_ang, p_i.shape))
    # Inertia * motion: f = m (v - c x w), n = Ic w + c x f
    f1 = m * (a_lin - _cross_rows(c, a_ang))
    n1 = a_ang @ Ic.T + _cross_rows(c, f1)
    f2 = m * (v - _cross_rows(c, w))
    n2 = w @ Ic.T + _cross_rows(c, f2)
    # motion x* force: (w x f, w x n + v x f)
    f = f1 + _cross_rows(w, f2)
    n = n1 + (_cross_rows(w, n2) + _cross_rows(v, f2))
    f_w = _mv(R_i, f)
    return f_w, _mv(R_i, n) + _cross_rows(p_i, f_w)


def _in_body_frame_batch(body: _BatchBody, R_i: np.ndarray, p_i: np.ndarray,
                         w: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Batched ``_in_body_frame``: world wrenches about the origin (g x 3 force in N, moment in N m) -> force
    and moment about the body's CoM, both in the body frame (thesis convention, K-7)."""
    com = R_i @ body.lever + p_i
    R = R_i @ body.R_jf
    f, n = w
    return _mtv(R, f), _mtv(R, n - _cross_rows(com, f))


def _centre_of_pressure_rows(force: np.ndarray, moment_origin: np.ndarray) -> np.ndarray:
    """Stacked :func:`centre_of_pressure` (the point only): g x 3 world forces (N) and moments about the
    origin (N m) -> g x 3 CoPs on z = 0 (m), NaN rows where f_z <= MIN_NORMAL_FORCE (or is NaN)."""
    out = np.full(force.shape, np.nan)
    fz = force[:, 2]
    ok = fz > MIN_NORMAL_FORCE
    out[ok, 0] = -moment_origin[ok, 1] / fz[ok]
    out[ok, 1] = moment_origin[ok, 0] / fz[ok]
    out[ok, 2] = 0.0
    return out
