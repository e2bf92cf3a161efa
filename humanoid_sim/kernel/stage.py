"""The Python side of the compiled stage: constant tables and the calls into :mod:`humanoid_sim.kernel.compiled`.

The compiled twin of ``ThesisController.evaluate`` for all four phases when no actuator saturates (see
:mod:`humanoid_sim.kernel`); each compiled function mirrors a reference function:

- ``_body_task`` = ``TaskKinematics.reduce_pair`` + ``CommandAccelerations._body_task`` (base eliminated through
  the stance-foot weld, thesis joint order and signs);
- ``_tracking_rows`` / ``_normal`` / ``_cholesky_solve`` = ``command._tracking_rows``, ``_CostRows.normal`` and
  ``_solve_spd`` (thesis eqs. 5.1-5.23);
- ``_controller_dsp`` = the double-support branch of ``CommandAccelerations.compute`` (closed chain by KKT);
- ``_contact_rows`` = ``ConstraintRows.evaluate`` for the phase's welds and its toe lock (Baumgarte rows);
- ``_inverse_square`` = ``contact.inverse._solve_square`` (the unique single-support computed torque);
- ``_inverse_general`` = ``contact.inverse.solve_inverse`` (double support: closest feasible accelerations, then
  the weighted minimum-norm torques and multipliers);
- ``_thesis_torques`` = ``Actuators.thesis_torques`` (T of eq. 4.69; shoulders from the arm's Newton-Euler
  equation, which is what RNEA's joint force of a leaf body is);
- ``project_on_support`` = ``WeldEngine.project_on_support``.

Saturated stages (about 0.5 %) go to the reference path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from humanoid_sim.actuators import Actuators
from humanoid_sim.command import LAYOUTS, TASK_FRAMES, CommandAccelerations
from humanoid_sim.contact.constraints import Anchors, Baumgarte, record_anchors
from humanoid_sim.kernel.compiled import (LOG_SIZE, advance_on_support, dsp_stage, project_on_support,
                                           ssp_controller, ssp_dynamics, ssp_stage)
from humanoid_sim.kernel.tree import TreeConstants
from humanoid_sim.model import HumanoidModel
from humanoid_sim.phases import FOOT_SPECS, Phase

FRAMES = list(TASK_FRAMES)
"""Frames the kernel evaluates: the controller's task frames (Pc_17, O_17, P_tpR, P_tpL, O_1, O_2, O_3, O_4), in
the row order of ``compiled.F_PC17 ... F_O4``."""
__all__ = ["FRAMES", "LOG_SIZE", "StageKernel", "StageOutput", "SupportKernel", "actuator_tables"]


# ----------------------------------------------------------------------------------------------- Python side
@dataclass
class StageOutput:
    """What one kernel stage returns (SI units; see ``ThesisController.evaluate``)."""

    a: np.ndarray
    lam: np.ndarray
    thdd_c: np.ndarray
    T_cmd: np.ndarray
    tau: np.ndarray
    log: np.ndarray  # [saturated flag, weld position error, weld orientation error, dynamics residual,
    #                  hip CoM p (3), hip CoM v (3), R_17 (9), toe R p (3), toe L p (3), R_1 (9), R_2 (9), pad]

    @property
    def saturated(self) -> bool:
        return self.log[0] > 0.0

    @property
    def failed(self) -> bool:
        """A normal matrix or KKT system was singular (the reference path then raises its error)."""
        return self.log[0] < 0.0


class SupportKernel:
    """The compiled projection onto the support foot and the compiled Runge-Kutta advance of the weld engine
    (``WeldEngine.project_on_support``), independent of any controller."""

    def __init__(self, hm: HumanoidModel, tree: TreeConstants | None = None) -> None:
        model = hm.model
        self.hm = hm
        self.tree = tree if tree is not None else TreeConstants(model, FRAMES)
        tr = self.tree
        fi = tr.frame_index
        self._frames: dict[Phase, tuple] = {}
        self._proj_args: dict[Phase, tuple] = {}
        for ph in Phase:
            contacts = ph.contacts
            if len(contacts.locks) != 1 or contacts.welds[0] != FOOT_SPECS[ph.support_foot].main_frame:
                raise ValueError(f"{ph.value}: the kernel expects the support foot's weld first and one toe lock")
            jid = model.getJointId(contacts.locks[0])
            w0 = fi[contacts.welds[0]]
            self._frames[ph] = (contacts.welds, contacts.locks[0])
            self._proj_args[ph] = (int(model.idx_qs[jid]), int(model.idx_vs[jid]), tr.parents, tr.axis, tr.idx_q,
                                   tr.idx_v, tr.jR, tr.jp, tr.support, tr.fparent[w0], tr.fR[w0], tr.fp[w0])
        self._anchor_cache: dict[Phase, tuple] = {}
        self._coeff_cache: dict = {}
        self._n_rates = 0
        """Stage rates :meth:`advance` passes to the compiled call (set by :meth:`warm_up`; fewer are padded)."""

    def anchor(self, phase: Phase, anchors: Anchors) -> tuple[np.ndarray, np.ndarray, float]:
        """(R (n_w, 3, 3), p (n_w, 3), toe angle) of the phase's weld anchors and lock anchor as arrays, re-read
        whenever the Anchors object, one of its placement entries or its toe angle is not the one last read for this
        phase (the simulator replaces anchors at phase changes; an SE3 modified in place would not be noticed)."""
        frames, toe = self._frames[phase]
        Ms = tuple(anchors.placements[f] for f in frames)
        angle = anchors.joint_positions[toe]
        hit = self._anchor_cache.get(phase)
        if hit is None or hit[0] is not anchors or any(a is not b for a, b in zip(hit[1], Ms)) or hit[2] != angle:
            val = (np.array([M.rotation for M in Ms]), np.array([M.translation for M in Ms]), float(angle))
            hit = self._anchor_cache[phase] = (anchors, Ms, angle, val)
        return hit[3]

    def project(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The compiled ``WeldEngine.project_on_support`` for the support foot of ``phase``."""
        aR, ap, alock = self.anchor(phase, anchors)
        q_out, v_out = np.empty_like(q), np.empty_like(v)
        project_on_support(q, v, aR[0], ap[0], alock, *self._proj_args[phase], q_out, v_out)
        return q_out, v_out

    def advance(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, coeffs: tuple[float, ...],
                vs: list[np.ndarray], accs: list[np.ndarray], h: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`project` of (q integrated by h sum c_j vs_j, v + h sum c_j accs_j): the integrator's stage and
        step-end states (``RungeKutta.step``'s ``advance``)."""
        aR, ap, alock = self.anchor(phase, anchors)
        q_out, v_out = np.empty_like(q), np.empty_like(v)
        n = len(vs)
        if n < self._n_rates:  # one compiled variant: pad with zero coefficients, which the sum skips (same bits)
            pad = self._n_rates - n
            vs, accs = list(vs) + [v] * pad, list(accs) + [v] * pad
        advance_on_support(q, v, self._coeffs(coeffs, n), tuple(vs), tuple(accs), h, aR[0], ap[0], alock,
                           *self._proj_args[phase], q_out, v_out)
        return q_out, v_out

    def warm_up(self, q: np.ndarray, n_stages: int) -> None:
        """Compile (or load from numba's cache) every entry point a run will call, before it starts: the projection
        and the advance, so that no compilation lands inside a timed run.  ``n_stages``: the integrator's stage
        count; :meth:`advance` passes that many rates whatever the stage (padding with zero coefficients), so that
        one compiled variant serves them all."""
        self._n_rates = max(self._n_rates, int(n_stages))
        phase = Phase.LFFSSP
        anchors = record_anchors(self.hm.model, q, phase.contacts)
        v = np.zeros(self.tree.nv)
        self.project(phase, anchors, q, v)
        n = self._n_rates
        self.advance(phase, anchors, q, v, (1.0,) * n, [v] * n, [v] * n, 0.0)

    def _coeffs(self, coeffs: tuple[float, ...], n: int) -> np.ndarray:
        """The first n Runge-Kutta coefficients as a float array, zero-padded to the :meth:`advance` rate count
        (cached per tableau row)."""
        key = (coeffs, n, self._n_rates)
        arr = self._coeff_cache.get(key)
        if arr is None:
            arr = np.zeros(max(n, self._n_rates))
            arr[:n] = coeffs[:n]
            self._coeff_cache[key] = arr
        return arr



def actuator_tables(model: pin.Model, act: Actuators) -> tuple[np.ndarray, ...]:
    """The actuator groups of ``act`` (``Actuators._groups``) as the flat tables ``compiled._thesis_torques`` reads:
    g1, g3, gs, hj, arm_mass, arm_lever, arm_I, gravity (see there)."""
    g1, g3, gs = [], [], []
    hj = np.array(act._hj_unique, dtype=np.int64)
    for gi, (rows, comps, hjid, sl, tj, higher_is_parent) in enumerate(act._groups):
        slot = act._hj_unique.index(hjid)
        vidx = act._vidx[sl]
        sg = act._signs[sl].astype(np.int64)
        if len(rows) == 1:
            g1.append([rows[0], vidx[0], sg[0], slot, comps[0]])
        elif len(rows) == 3:
            if list(comps) != [0, 1, 2]:
                raise ValueError(f"actuator group {gi}: three components must be x, y, z")
            g3.append(list(rows) + list(vidx) + list(sg) + [slot])
        else:
            if higher_is_parent:
                raise ValueError(f"actuator group {gi}: the two-component (universal) joint must carry a "
                                 "leaf body on its child side")
            gs.append(list(rows) + list(comps) + [tj, slot])
    for g in gs:
        if any(model.parents[j] == g[4] for j in range(model.njoints)):
            raise ValueError(f"joint {model.names[g[4]]!r} of a universal actuator is not a leaf")
    return (np.array(g1, dtype=np.int64), np.array(g3, dtype=np.int64), np.array(gs, dtype=np.int64), hj,
            np.array([model.inertias[g[4]].mass for g in gs], dtype=float),
            np.array([model.inertias[g[4]].lever for g in gs], dtype=float),
            np.array([model.inertias[g[4]].inertia for g in gs], dtype=float),
            np.array(model.gravity.linear, dtype=float))


class StageKernel:
    """The constant arrays of the compiled stage and projection, built once per simulator from the reference objects
    (so both paths use the same weights, layouts and actuator groups).  ``w_tau`` (nv,) and ``w_lambda`` (per
    double-support phase, (13,)) are the double-support torque-split weights of the reference path."""

    def __init__(self, hm: HumanoidModel, cmd: CommandAccelerations, act: Actuators,
                 gains: Baumgarte | None = None, w_tau: np.ndarray | None = None,
                 w_lambda: dict[Phase, np.ndarray] | None = None) -> None:
        model = hm.model
        self.hm = hm
        self.tree = TreeConstants(model, FRAMES)
        tr = self.tree
        gains = gains if gains is not None else Baumgarte()
        self.kp, self.kd = float(gains.kp), float(gains.kd)
        self.jcols = np.asarray(hm.theta_v_idx, dtype=np.int64)
        self.jsign = np.asarray(hm.theta_sign, dtype=float)
        self.theta_q = np.asarray(hm.theta_q_idx, dtype=np.int64)
        self.theta0 = cmd.theta0.copy()
        self.w_tau = np.ascontiguousarray(np.ones(model.nv) if w_tau is None else w_tau, dtype=float)
        self.w_lambda = {ph: np.ascontiguousarray(np.ones(ph.contacts.n_rows) if w_lambda is None else w_lambda[ph],
                                                  dtype=float) for ph in (Phase.LFFDSP, Phase.RFFDSP)}
        self.phase = {}
        fi = tr.frame_index
        up = cmd.params
        upper = [up.upper_Wp, up.upper_Wv, up.upper_dt, cmd._upper_den, cmd._upper_dt2, cmd._upper_dt3]
        for ph in Phase:
            lay = LAYOUTS[ph.value]
            P = cmd._problems[ph.value]
            wa, wb = cmd.params.steps[ph.value]
            ns, no = P.xs.size, P.xo.size
            if ph.is_double_support:
                ip = np.concatenate([[fi[lay.root_weld], fi[lay.other_weld], lay.stance_toe, ns, no], P.x,
                                     cmd._q_upper]).astype(np.int64)
                fp_ = np.concatenate([[wa.dt, P.ha], P.c.w[:, 0], P.dZ, P.W_q, *upper]).astype(float)
            else:
                ip = np.concatenate([[fi[lay.root_weld], fi[lay.other_toe_point], fi[lay.other_weld], lay.stance_toe,
                                      lay.other_toe, P.k_toe, ns, no], P.xs, P.xo, cmd._q_upper]).astype(np.int64)
                fp_ = np.concatenate([[wa.dt, wb.dt, P.ha, P.hb, P.toe_p[0], P.toe_p[1], P.toe_v[0], P.toe_v[1],
                                       P.theta0_toe], P.a.w[:, 0], P.b.w[:, 0], P.dZ_a, P.dZ_b, wa.W_q, wb.W_q,
                                      *upper]).astype(float)
            contacts = ph.contacts
            if len(contacts.locks) != 1 or contacts.welds[0] != FOOT_SPECS[ph.support_foot].main_frame:
                raise ValueError(f"{ph.value}: the kernel expects the support foot's weld first and one toe lock")
            jid = model.getJointId(contacts.locks[0])
            welds = np.array([fi[f] for f in contacts.welds], dtype=np.int64)
            self.phase[ph] = (ip, fp_, welds, int(model.idx_qs[jid]), int(model.idx_vs[jid]), contacts.welds,
                              contacts.locks[0])
        (self.g1, self.g3, self.gs, self.hj, self.arm_mass, self.arm_lever, self.arm_I,
         self.gravity) = actuator_tables(model, act)
        self._act = act
        self._limits = self._act_limits()
        self.support = SupportKernel(hm, self.tree)
        self._anchor = self.support.anchor
        self.split = False
        """True: :meth:`stage` calls :meth:`controller` and :meth:`dynamics` separately (same results, one more call;
        for a profile that times the two apart, as ``scripts/bench.py`` does), else one fused compiled call."""
        nf = len(FRAMES)
        # work buffers shared by the controller and dynamics calls: R, p (joints), fR, fpos, motion, vel (frames)
        self._work = (np.empty((tr.nj, 3, 3)), np.empty((tr.nj, 3)), np.empty((nf, 3, 3)), np.empty((nf, 3)),
                      np.empty((nf, 6, tr.nv + 1)), np.empty((nf, 6)))
        self._build_args()

    @property
    def limits(self) -> np.ndarray:
        """Saturation limits of the thesis torques T (26,, N m) the stage checks: ``Actuators.limits`` itself, so
        that changing them there (in place or by assignment) changes them here too."""
        return self._act.limits

    @limits.setter
    def limits(self, value: np.ndarray) -> None:
        self._act.limits = np.asarray(value, dtype=float)
        self._sync_limits()

    def _act_limits(self) -> np.ndarray:
        lim = self._act.limits
        if not (isinstance(lim, np.ndarray) and lim.dtype == np.float64 and lim.shape == (26,)
                and lim.flags.c_contiguous):
            lim = self._act.limits = np.ascontiguousarray(lim, dtype=float).reshape(26)
        return lim

    def _sync_limits(self) -> None:
        """Rebuild the call arguments if ``Actuators.limits`` was replaced by another array."""
        if self._act.limits is not self._limits:
            self._limits = self._act_limits()
            self._build_args()

    def _build_args(self) -> None:
        """The constant trailing arguments of the compiled calls, per phase."""
        tr, w = self.tree, self._work
        self._ctrl_args, self._dyn_args, self._stage_args = {}, {}, {}
        act = (self.g1, self.g3, self.gs, self.hj, self.arm_mass, self.arm_lever, self.arm_I, self.gravity,
               self._limits)
        for ph, (ip, fp_, welds, lock_q, lock_v, _, _) in self.phase.items():
            self._ctrl_args[ph] = (tr.parents, tr.axis, tr.idx_q, tr.jR, tr.jp, tr.support, tr.fparent, tr.fR, tr.fp,
                                   self.jcols, self.jsign, self.theta_q, self.theta0, ip, fp_,
                                   self._motion_frames(ph), *w)
            if ph.is_double_support:
                self._stage_args[ph] = self._ctrl_args[ph] + (welds, lock_q, lock_v, self.kp, self.kd, self.w_tau,
                                                              self.w_lambda[ph]) + act
            else:
                self._dyn_args[ph] = (tr.support, tr.fparent, self.jcols, self.jsign, welds, lock_q, lock_v,
                                      self.kp, self.kd) + act + (w[0], w[1], w[2], w[3], w[5])
                self._stage_args[ph] = self._ctrl_args[ph] + (welds, lock_q, lock_v, self.kp, self.kd) + act

    def _motion_frames(self, phase: Phase) -> np.ndarray:
        """Which frames' [J | drift] and velocity the phase's controller reads: the hip CoM (also logged), the stance
        weld, and the swing toe point with its body (single support) or the trailing toe body (double support)."""
        lay, fi, tr = LAYOUTS[phase.value], self.tree.frame_index, self.tree
        need = np.zeros(len(FRAMES), dtype=np.bool_)
        pairs = [("Pc_17", "O_17")]
        if phase.is_double_support:
            need[fi[lay.other_weld]] = True
        else:
            pairs.append((lay.other_toe_point, lay.other_weld))
        for point, body in pairs:
            need[fi[point]] = True
            if tr.fparent[fi[body]] != tr.fparent[fi[point]]:
                need[fi[body]] = True
        need[fi[lay.root_weld]] = True
        return need

    def controller(self, phase: Phase, q: np.ndarray, v: np.ndarray, data: pin.Data, table: np.ndarray, t: float
                   ) -> np.ndarray:
        """theta_ddot_c (26,) at (q, v) and time t (s); ``data`` holds computeJointJacobiansTimeVariation at (q, v),
        ``table`` is the phase's ``ReferenceTrajectory.ssp_table``."""
        qdd = np.empty(26)
        ssp_controller(q, v, data.J, data.dJ, table, t, *self._ctrl_args[phase], qdd)
        return qdd

    def dynamics(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, data: pin.Data,
                 qdd: np.ndarray) -> tuple:
        """(a, lam, T_cmd, tau, log) of the computed torque for ``qdd`` right after :meth:`controller` at (q, v);
        ``data`` also holds crba and nonLinearEffects."""
        out = _outputs(v.size, 7)[1:]
        ssp_dynamics(q, v, data.J, data.dJ, data.M, data.nle, qdd, *self._anchor(phase, anchors), *self._dyn_args[phase],
                     *out)
        return out

    def stage(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, data: pin.Data, table: np.ndarray,
              t: float) -> StageOutput:
        """Evaluate one stage at (q, v) and time t (s); ``data`` holds computeJointJacobiansTimeVariation, crba and
        nonLinearEffects at (q, v), ``table`` the phase's ``ReferenceTrajectory.ssp_table`` / ``dsp_table``."""
        self._sync_limits()
        if phase.is_double_support:
            return self.double_support(phase, anchors, q, v, data, table, t)
        if self.split:
            qdd = self.controller(phase, q, v, data, table, t)
            a, lam, T, tau, log = self.dynamics(phase, anchors, q, v, data, qdd)
            return StageOutput(a, lam, qdd, T, tau, log)
        qdd, a, lam, T, tau, log = _outputs(v.size, 7)
        ssp_stage(q, v, data.J, data.dJ, data.M, data.nle, table, t, *self._anchor(phase, anchors),
                  *self._stage_args[phase], qdd, a, lam, T, tau, log)
        return StageOutput(a, lam, qdd, T, tau, log)

    def double_support(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, data: pin.Data,
                       table: np.ndarray, t: float) -> StageOutput:
        """One double-support stage (controller with the closed chain and the weighted minimum-norm computed
        torque, one compiled call); arguments as :meth:`stage`."""
        qdd, a, lam, T, tau, log = _outputs(v.size, phase.contacts.n_rows)
        dsp_stage(q, v, data.J, data.dJ, data.M, data.nle, table, t, *self._anchor(phase, anchors),
                  *self._stage_args[phase], qdd, a, lam, T, tau, log)
        return StageOutput(a, lam, qdd, T, tau, log)

    def project(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`SupportKernel.project`."""
        return self.support.project(phase, anchors, q, v)

    def advance(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, coeffs: tuple[float, ...],
                vs: list[np.ndarray], accs: list[np.ndarray], h: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`SupportKernel.advance`."""
        return self.support.advance(phase, anchors, q, v, coeffs, vs, accs, h)


def _outputs(nv: int, m: int) -> tuple[np.ndarray, ...]:
    """Fresh output arrays of one stage: theta_ddot_c (26,), a (nv,), lam (m,), T_cmd (26,), tau (nv,), log."""
    return np.empty(26), np.empty(nv), np.empty(m), np.empty(26), np.empty(nv), np.empty(LOG_SIZE)
