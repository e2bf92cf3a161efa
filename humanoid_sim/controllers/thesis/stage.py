"""The Python side of the thesis controller's compiled stage (:mod:`.compiled`): its constant tables, built once
per simulator from the reference objects (so both paths use the same weights, layouts and actuator groups), and
the calls.

The compiled stage is the twin of ``ThesisController.evaluate`` on the weld model for all four phases when no
actuator saturates; saturated stages go to the reference path.  Pinocchio still does the dynamics passes
(``computeJointJacobiansTimeVariation``, ``crba``, ``nonLinearEffects``); the kernel does the rest (references,
placements, frame motions, cost rows and normal equations, computed torque, thesis torques, the log).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from humanoid_sim.controllers.thesis.command import LAYOUTS, CommandAccelerations
from humanoid_sim.controllers.thesis.compiled import (
    DspTables,
    SspTables,
    dsp_stage,
    ssp_controller,
    ssp_dynamics,
    ssp_stage,
)
from humanoid_sim.dynamics.contact.constraints import Anchors, Baumgarte
from humanoid_sim.kernel.log import LOG_SIZE
from humanoid_sim.kernel.records import Contact, Coords, StageBuffers, State
from humanoid_sim.kernel.support import FRAMES, StageOutput, SupportKernel, actuator_tables, check_contacts
from humanoid_sim.kernel.tree import TreeConstants
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import Phase

__all__ = ["StageKernel"]


class StageKernel:
    """The constant arguments of the compiled stage and projection.  ``w_tau`` (nv,) and ``w_lambda`` (per
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
        self.coords = Coords(np.asarray(hm.theta_v_idx, dtype=np.int64), np.asarray(hm.theta_sign, dtype=float),
                             np.asarray(hm.theta_q_idx, dtype=np.int64), cmd.theta0.copy())
        self.jcols, self.jsign = self.coords.jcols, self.coords.jsign
        self.w_tau = np.ascontiguousarray(np.ones(model.nv) if w_tau is None else w_tau, dtype=float)
        self.w_lambda = {ph: np.ascontiguousarray(np.ones(ph.contacts.n_rows) if w_lambda is None else w_lambda[ph],
                                                  dtype=float) for ph in (Phase.LFFDSP, Phase.RFFDSP)}
        self.tables: dict[Phase, SspTables | DspTables] = {}
        self.contact: dict[Phase, Contact] = {}
        fi = tr.frame_index
        up = cmd.params
        upper = np.concatenate([up.upper_Wp, up.upper_Wv, up.upper_dt, cmd._upper_den,
                                cmd._upper_dt2, cmd._upper_dt3]).astype(float)
        qu = np.asarray(cmd._q_upper, dtype=np.int64)
        for ph in Phase:
            lay = LAYOUTS[ph.value]
            P = cmd._problems[ph.value]
            wa, wb = cmd.params.steps[ph.value]
            need = self._motion_frames(ph)
            if ph.is_double_support:
                self.tables[ph] = DspTables(
                    fi[lay.root_weld], fi[lay.other_weld], int(lay.stance_toe), int(P.xs.size), int(P.xo.size),
                    np.asarray(P.x, dtype=np.int64), qu, float(wa.dt), float(P.ha),
                    np.ascontiguousarray(P.c.w[:, 0], dtype=float), np.asarray(P.dZ, dtype=float),
                    np.asarray(P.W_q, dtype=float), upper, need)
            else:
                self.tables[ph] = SspTables(
                    fi[lay.root_weld], fi[lay.other_toe_point], fi[lay.other_weld], int(lay.stance_toe),
                    int(lay.other_toe), int(P.k_toe), np.asarray(P.xs, dtype=np.int64),
                    np.asarray(P.xo, dtype=np.int64), qu, float(wa.dt), float(wb.dt), float(P.ha), float(P.hb),
                    float(P.toe_p[0]), float(P.toe_p[1]), float(P.toe_v[0]), float(P.toe_v[1]),
                    float(P.theta0_toe), _f(P.a.w[:, 0]), _f(P.b.w[:, 0]),
                    np.asarray(P.dZ_a, dtype=float), np.asarray(P.dZ_b, dtype=float),
                    np.asarray(wa.W_q, dtype=float), np.asarray(wb.W_q, dtype=float), upper, need)
            check_contacts(ph)
            contacts = ph.contacts
            jid = model.getJointId(contacts.locks[0])
            welds = np.array([fi[f] for f in contacts.welds], dtype=np.int64)
            self.contact[ph] = Contact(welds, int(model.idx_qs[jid]), int(model.idx_vs[jid]), self.kp, self.kd)
        self._model = model
        self._act = act
        self._limits = self._act_limits()
        self.act_tables = actuator_tables(model, act, self._limits)
        self.support = SupportKernel(hm, self.tree)
        self._anchor = self.support.anchor
        self.split = False
        """True: :meth:`stage` calls :meth:`controller` and :meth:`dynamics` separately (same results, one more call;
        for a profile that times the two apart, as ``scripts/bench.py`` does), else one fused compiled call."""
        self.work = tr.work()   # shared by the controller and dynamics calls

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
        """Re-point the actuator tables if ``Actuators.limits`` was replaced by another array."""
        if self._act.limits is not self._limits:
            self._limits = self._act_limits()
            self.act_tables = self.act_tables._replace(limits=self._limits)

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
        """theta_ddot_c (26,) at (q, v) and time t (s); ``data`` holds computeJointJacobiansTimeVariation at (q, v)
        (and crba, nonLinearEffects), ``table`` is the phase's ``ReferenceTrajectory.ssp_table``."""
        qdd = np.empty(26)
        ssp_controller(_state(q, v, data), table, t, self.tree.record, self.coords, self.tables[phase], self.work,
                       qdd)
        return qdd

    def dynamics(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, data: pin.Data,
                 qdd: np.ndarray) -> tuple:
        """(a, lam, T_cmd, tau, log) of the computed torque for ``qdd`` right after :meth:`controller` at (q, v);
        ``data`` also holds crba and nonLinearEffects."""
        out = _outputs(v.size, 7)._replace(qdd=qdd)
        ssp_dynamics(_state(q, v, data), self._anchor(phase, anchors), self.tree.record, self.coords, self.work,
                     self.contact[phase], self.act_tables, out)
        return out[1:]

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
        out = _outputs(v.size, 7)
        ssp_stage(_state(q, v, data), table, t, self._anchor(phase, anchors), self.tree.record, self.coords,
                  self.tables[phase], self.work, self.contact[phase], self.act_tables, out)
        return StageOutput(out.a, out.lam, out.qdd, out.T, out.tau, out.log)

    def double_support(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, data: pin.Data,
                       table: np.ndarray, t: float) -> StageOutput:
        """One double-support stage (controller with the closed chain and the weighted minimum-norm computed
        torque, one compiled call); arguments as :meth:`stage`."""
        out = _outputs(v.size, phase.contacts.n_rows)
        dsp_stage(_state(q, v, data), table, t, self._anchor(phase, anchors), self.tree.record, self.coords,
                  self.tables[phase], self.work, self.contact[phase], (self.w_tau, self.w_lambda[phase]),
                  self.act_tables, out)
        return StageOutput(out.a, out.lam, out.qdd, out.T, out.tau, out.log)

    def project(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`SupportKernel.project`."""
        return self.support.project(phase, anchors, q, v)

    def advance(self, phase: Phase, anchors: Anchors, q: np.ndarray, v: np.ndarray, coeffs: tuple[float, ...],
                vs: list[np.ndarray], accs: list[np.ndarray], h: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`SupportKernel.advance`."""
        return self.support.advance(phase, anchors, q, v, coeffs, vs, accs, h)


def _f(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


def _state(q: np.ndarray, v: np.ndarray, data: pin.Data) -> State:
    """The state and Pinocchio's terms at it as the compiled stages take them."""
    return State(q, v, data.J, data.dJ, data.M, data.nle)


def _outputs(nv: int, m: int) -> StageBuffers:
    """Fresh output arrays of one stage: theta_ddot_c (26,), a (nv,), lam (m,), T_cmd (26,), tau (nv,), log."""
    return StageBuffers(np.empty(26), np.empty(nv), np.empty(m), np.empty(26), np.empty(nv), np.empty(LOG_SIZE))
