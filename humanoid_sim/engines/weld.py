"""The weld engine: the thesis's contact model on Pinocchio (``walk.py --engine pinocchio``, the default).

A foot in contact is welded (thesis chapter 4): in the floating-base model a flat foot is a 6-D weld of its main
body plus a lock of its toe joint; in double support the trailing foot's toe body is welded too (7 / 13 constraint
rows, 25 / 19 free DOF, the thesis's counts).  The state (q, v) advances by fixed-step Runge-Kutta (ode3 =
Bogacki-Shampine, as Simulink's) with the controller evaluated at every stage (or, with a control period set,
once per period with its torques held: :attr:`WeldEngine.control_period_s`); the accelerations are the KKT
forward dynamics of the controller's torques under the phase's constraints (Baumgarte-stabilised,
:class:`humanoid_sim.dynamics.contact.ContactDynamics`), or the motion the controller solved for under this same model
(``Command.motion``; the thesis controller's computed torque realises it exactly when no actuator saturates).

Decisions where the thesis is silent:
- The support foot (welded main body plus locked toe joint, the thesis's chain root) is held exactly: every ode3
  stage state and every step's end is projected onto it -- the base placement re-derived from the foot's anchor,
  the base twist from the joint rates, the toe joint at its anchor angle with zero rate -- as the thesis's
  joint-space integration holds it by construction.  The other constraints (the trailing toe in double support)
  are held by the contact solver's Baumgarte stabilisation.
- Touchdown applies the velocity reset of 4.5 (or the inelastic impulse law) and welds the landing foot where it
  landed (errata K-9: a foot that lands tilted stays welded tilted).

Speed: with numba, each stage's integration and projection run compiled (:class:`humanoid_sim.kernel.support.
SupportKernel`), equal to :meth:`WeldEngine.project_on_support` to round-off.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from humanoid_sim import kernel as _kernel
from humanoid_sim.dynamics.contact import ContactDynamics, record_anchors
from humanoid_sim.dynamics.contact.inverse import symmetric_inertia
from humanoid_sim.dynamics.contact.wrenches import GroundReactionLog
from humanoid_sim.dynamics.integrator import RungeKutta
from humanoid_sim.dynamics.welds import WeldModel
from humanoid_sim.engines.impact import touchdown
from humanoid_sim.engines.landing import Landing, landing_record
from humanoid_sim.errors import SimulationError
from humanoid_sim.interfaces.controller import Command, Observation
from humanoid_sim.interfaces.engine import StepRow
from humanoid_sim.interfaces.log import SimLog
from humanoid_sim.interfaces.selector import PhaseSelector, all_finite
from humanoid_sim.interfaces.trace import Trace
from humanoid_sim.kernel.log import StageLog
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import FOOT_SPECS, Phase
from humanoid_sim.robot.sole import SoleGeometry
from humanoid_sim.scenario.schema import Scenario

BASIC = {Phase.LFFSSP: 0, Phase.RFFDSP: 1, Phase.RFFSSP: 2, Phase.LFFDSP: 3}
FEET = (FOOT_SPECS["R"], FOOT_SPECS["L"])
BODY_FRAMES = ("O_1", "O_2", "O_3", "O_4")  # rows of the logged thesis ground wrenches (bodies 1-4)
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def yaw_of(R: np.ndarray) -> float:
    """Heading of the body x-axis in the world ground plane (rad, from world x)."""
    return float(np.arctan2(R[1, 0], R[0, 0]))


def unwrap_to(angle: float, ref: float) -> float:
    """``angle`` shifted by a multiple of 2 pi into (ref - pi, ref + pi]."""
    return ref + (angle - ref + np.pi) % (2 * np.pi) - np.pi


class StageRecord(NamedTuple):
    """What the log needs from the first integration stage of a step (SI units; world frame unless said).

    Attributes:
        a: the acceleration (nv,). lam: the constraint forces of the phase's welds and locks.
        thdd_c: the thesis command accelerations (26,), NaN when the controller gives none.
        T_cmd, T: the thesis actuator torques before and after saturation (26,), N m. sat: where T saturated.
        tau: the generalized torques (nv,), N m. pos, ori: the largest weld drift, m and rad.
        residual: ||M a + h - tau - J^T lam||_inf, N m. hip_p, hip_v: the hip CoM, m and m/s.
        R17: Body 17's rotation. toe_R, toe_L: the toe points, m. R1, R2: the toe bodies' rotations.
    """

    a: np.ndarray
    lam: np.ndarray
    thdd_c: np.ndarray
    T_cmd: np.ndarray
    T: np.ndarray
    sat: np.ndarray
    tau: np.ndarray
    pos: float
    ori: float
    residual: float
    hip_p: np.ndarray
    hip_v: np.ndarray
    R17: np.ndarray
    toe_R: np.ndarray
    toe_L: np.ndarray
    R1: np.ndarray
    R2: np.ndarray


class WeldRecord(NamedTuple):
    """The weld engine's record of one step: the state at its start and its first stage's :class:`StageRecord`."""

    q: np.ndarray
    v: np.ndarray
    stage: StageRecord


class WeldEngine:
    """Pinocchio floating-base dynamics with the feet welded (see the module docstring).

    Engine interface (:class:`humanoid_sim.interfaces.engine.Engine`): ``start``, ``step``, ``hip_com``,
    ``toe_point``, ``toe_rotation``, ``state_vectors``, ``touchdown``, ``enter``, ``build_log``."""

    name = "pinocchio"

    def __init__(self, hm: HumanoidModel, scenario: Scenario, traj: ReferenceTrajectory,
                 compiled: bool | None = None, control_period_s: float | None = None) -> None:
        """``compiled``: run the integration and projection compiled (:class:`SupportKernel`); None = when numba
        is installed, False = never.  ``control_period_s``: see :attr:`control_period_s`."""
        self.hm = hm
        self.sc = scenario
        self.traj = traj
        self.model = hm.model
        self.dyn = ContactDynamics(hm.model)
        self.constraints = WeldModel(self.dyn)
        self.rk = RungeKutta(hm.model, scenario.simulation.method)
        self.act = Actuators(hm)
        self.fid = {n: hm.frame_id(n) for n in ("Pc_17", "O_17", "P_tpR", "P_tpL", "O_1", "O_2")}
        self.data = hm.model.createData()
        self.proj_data = hm.model.createData()
        self._weld_fid = {s.main_frame: hm.frame_id(s.main_frame) for s in FOOT_SPECS.values()}
        self._lock_idx = {}
        for s in FOOT_SPECS.values():
            jid = hm.model.getJointId(s.toe_joint)
            self._lock_idx[s.toe_joint] = (hm.model.idx_qs[jid], hm.model.idx_vs[jid])
        self._reactions = GroundReactionLog(hm.model, FEET, BODY_FRAMES)
        self._no_sat = np.zeros(26, dtype=bool)
        if compiled is None:
            compiled = _kernel.AVAILABLE
        self.support_kernel = None
        if compiled:
            from humanoid_sim.kernel.support import SupportKernel

            self.support_kernel = SupportKernel(hm)
        self.q = self.v = None
        self.anchors = None
        self.phase: Phase | None = None
        self.control_period_s: float | None = control_period_s
        """Control period, s: None calls the controller at every ode3 stage as a feedthrough function of the state
        (the thesis's controller and the balance controller); a period calls it once per period and holds its
        torques over the period (zero-order hold), ode3 integrating the robot over each period (the step ``h``
        must be a whole number of periods)."""
        self._sole = SoleGeometry.from_model(hm)
        self.landings: list[Landing] = []

    # ------------------------------------------------------------------ state
    def start(self, q0: np.ndarray, phase: Phase) -> None:
        """At rest at q0, the phase's contacts held where q0 puts them."""
        self.q = np.array(q0, dtype=float)
        self.v = np.zeros(self.model.nv)
        self.phase = phase
        self.landings = []
        self._substeps: list[tuple] = []   # held control: per integration step, what the trace needs
        self.anchors = record_anchors(self.model, self.q, phase.contacts)
        if self.support_kernel is not None:
            self.support_kernel.warm_up(self.q, len(self.rk.tab.c))

    def state_vectors(self) -> tuple[np.ndarray, np.ndarray]:
        return self.q, self.v

    # ------------------------------------------------------------------ one step
    def step(self, t: float, h: float, k: int, control: Callable[[Observation], Command],
             checks: PhaseSelector) -> WeldRecord:
        """Advance (q, v) from t to t + h under the current phase's welds; the controller is called at every
        stage, or once per :attr:`control_period_s` when one is set (:meth:`_step_held`).  Returns the step's log
        record (state at t and the stage-0 outputs)."""
        if self.control_period_s is not None:
            return self._step_held(t, h, k, control, checks)
        phase, anchors = self.phase, self.anchors
        stage0: list[StageRecord] = []

        def f(ts: float, qs: np.ndarray, vs: np.ndarray, stage: int) -> np.ndarray:
            checks.check_stage(ts, qs, vs, stage)
            cmd = control(Observation(ts, k, phase, qs, vs, anchors, stage, checks.plan_delay))
            a, lam = self._motion(phase, anchors, qs, vs, cmd)
            checks.check_acceleration(ts, a)
            if stage == 0:
                stage0.append(self._stage0_record(phase, qs, vs, cmd, a, lam))
            return a

        q, v = self.q, self.v
        if self.support_kernel is None:
            q_new, v_new = self.rk.step(f, t, q, v, h, lambda qs, vs: self.project_on_support(phase, anchors, qs, vs))
        else:
            adv = self.support_kernel.advance
            q_new, v_new = self.rk.step(f, t, q, v, h, advance=lambda *a: adv(phase, anchors, *a))
        self.q, self.v = q_new, v_new
        return WeldRecord(q, v, stage0[0])

    def _step_held(self, t: float, h: float, k: int, control: Callable[[Observation], Command],
                   checks: PhaseSelector) -> WeldRecord:
        """:meth:`step` at the control period p = :attr:`control_period_s`: h / p controller updates, each
        command's generalized torques held while one ode3 step of size p integrates the forward dynamics under the
        phase's welds (a command's own ``motion`` is not used: it holds only at the state it was solved at).

        Raises:
            SimulationError: when h is not a whole number of control periods, or the state diverges."""
        period = self.control_period_s
        n_ctrl = round(h / period)
        if not (n_ctrl >= 1 and abs(n_ctrl * period - h) <= 1e-9 * max(1.0, h)):
            raise SimulationError(f"loop step h = {h!r} s: expected a whole number of control periods "
                                  f"(WeldEngine.control_period_s = {period:g} s)")
        phase, anchors = self.phase, self.anchors
        stage0: list[StageRecord] = []
        held: list = [None, None]  # the update's command and its generalized torques, N m

        def f(ts: float, qs: np.ndarray, vs: np.ndarray, stage: int) -> np.ndarray:
            checks.check_stage(ts, qs, vs, stage)
            cmd, tau = held
            fwd = self.dyn.forward_prepared(self.dyn.prepare(phase.contacts, anchors, qs, vs), tau)
            checks.check_acceleration(ts, fwd.a)
            if not stage0:
                stage0.append(self._stage0_record(phase, qs, vs, cmd, fwd.a, fwd.lam))
            if stage == 0:  # the start of an integration step: a row of the full-rate trace
                self._substeps.append((ts, k, phase, qs, vs, fwd.a, fwd.lam, tau, cmd.T, cmd.saturated, cmd.T_cmd))
            return fwd.a

        if self.support_kernel is None:
            def project(qs: np.ndarray, vs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                return self.project_on_support(phase, anchors, qs, vs)
            opts = {"project": project}
        else:
            adv = self.support_kernel.advance
            opts = {"advance": lambda *a: adv(phase, anchors, *a)}
        q, v = self.q, self.v
        q_new, v_new = q, v
        for i in range(n_ctrl):
            ti = t + i * period
            if i:
                checks.check_stage(ti, q_new, v_new, i)
            cmd = control(Observation(ti, k, phase, q_new, v_new, anchors, i, checks.plan_delay))
            if cmd.tau is None:  # thesis actuator torques only: tau = B(q) T at the update's state
                cmd.tau = self.act.torque_map(q_new) @ cmd.T
                cmd.tau[:6] = 0.0
            held[:] = cmd, cmd.tau
            q_new, v_new = self.rk.step(f, ti, q_new, v_new, period, **opts)
        self.q, self.v = q_new, v_new
        return WeldRecord(q, v, stage0[0])

    def _motion(self, phase: Phase, anchors, q: np.ndarray, v: np.ndarray, cmd: Command
                ) -> tuple[np.ndarray, np.ndarray]:
        """(a, lam): the command's own motion when it was solved under this model, else the KKT forward dynamics."""
        if cmd.motion is not None and cmd.motion_model is self.constraints:
            return cmd.motion
        if cmd.tau is None:  # thesis actuator torques only: tau = B(q) T
            cmd.tau = self.act.torque_map(q) @ cmd.T
            cmd.tau[:6] = 0.0
        rows = self.dyn.prepare(phase.contacts, anchors, q, v)
        fwd = self.dyn.forward_prepared(rows, cmd.tau)
        return fwd.a, fwd.lam

    def _stage0_record(self, phase: Phase, q: np.ndarray, v: np.ndarray, cmd: Command, a: np.ndarray,
                       lam: np.ndarray) -> StageRecord:
        """What the log needs from the first stage of a step, read while the solver still holds that state: the
        command, the weld drifts, the dynamics residual and the task frames' positions, orientations and the hip
        velocity."""
        tau = cmd.tau
        extra = cmd.extra or {}
        lg = extra.get("kernel_log")
        if lg is not None:  # the compiled stage computed the same quantities (layout: kernel.log)
            r = StageLog(lg)
            return StageRecord(a, lam, cmd.theta_ddot_cmd, cmd.T_cmd, cmd.T, cmd.saturated, tau, r.weld_position_error,
                               r.weld_orientation_error, r.residual, r.hip_p, r.hip_v, r.R_17, r.toe_R_p, r.toe_L_p,
                               r.R_1, r.R_2)
        rows = self.dyn.rows(phase.contacts)
        d = self.dyn.data
        M = extra.get("M")
        if M is None:
            M = symmetric_inertia(d.M)
        residual = float(np.max(np.abs(M @ a + d.nle - tau - rows.J.T @ lam)))
        pos = float(np.max(rows.weld_position_error)) if rows.weld_position_error.size else 0.0
        ori = float(np.max(rows.weld_orientation_error)) if rows.weld_orientation_error.size else 0.0
        model, fid = self.model, self.fid
        place = {n: pin.updateFramePlacement(model, d, fid[n]) for n in ("Pc_17", "O_17", "P_tpR", "P_tpL", "O_1",
                                                                          "O_2")}
        hip_v = pin.getFrameVelocity(model, d, fid["Pc_17"], LWA).vector[:3].copy()
        T, T_cmd, sat, thdd_c = cmd.T, cmd.T_cmd, cmd.saturated, cmd.theta_ddot_cmd
        if T is None:  # a controller that gives joint torques only: the thesis components they amount to
            T = T_cmd = self.act.thesis_torques(q, v, a, tau, kin_data=d)
            sat = self._no_sat
        if thdd_c is None:
            thdd_c = np.full(26, np.nan)
        return StageRecord(a, lam, thdd_c, T_cmd, T, sat, tau, pos, ori, residual,
                           place["Pc_17"].translation.copy(), hip_v, place["O_17"].rotation.copy(),
                           place["P_tpR"].translation.copy(), place["P_tpL"].translation.copy(),
                           place["O_1"].rotation.copy(), place["O_2"].rotation.copy())

    def project_on_support(self, phase: Phase, anchors, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) with the support foot exactly at its anchor and at rest (see the module docstring).

        The foot's LOCAL Jacobian does not depend on the base placement, and its base block is the action matrix
        Ad(fMb) of the base seen from the foot frame, so the base twist is -Ad(bMf) J_joints v_joints."""
        spec = FOOT_SPECS[phase.support_foot]
        model, d = self.model, self.proj_data
        q = q.copy()
        v = v.copy()
        lock_q, lock_v = self._lock_idx[spec.toe_joint]
        q[lock_q] = anchors.joint_positions[spec.toe_joint]
        v[lock_v] = 0.0
        fid = self._weld_fid[spec.main_frame]
        pin.forwardKinematics(model, d, q)
        oMf = pin.updateFramePlacement(model, d, fid)
        base = pin.XYZQUATToSE3(q[:7])
        q[:7] = pin.SE3ToXYZQUAT(anchors.placements[spec.main_frame] * oMf.inverse() * base)
        J = pin.computeFrameJacobian(model, d, q, fid, pin.ReferenceFrame.LOCAL)
        v[:6] = -(base.actInv(oMf).toActionMatrix() @ (J[:, 6:] @ v[6:]))
        return q, v

    # ------------------------------------------------------------------ what the phase selector reads
    def hip_com(self) -> np.ndarray:
        """Body-17 CoM (world, m) at the current state (NaN when the state is not finite); updates the kinematics
        that :meth:`toe_point` and :meth:`toe_rotation` read."""
        if all_finite(self.q):
            pin.forwardKinematics(self.model, self.data, self.q)
            return pin.updateFramePlacement(self.model, self.data, self.fid["Pc_17"]).translation.copy()
        return np.full(3, np.nan)

    def toe_point(self, foot: str) -> np.ndarray:
        """Toe point P_tp of ``foot`` ("R"/"L"), world, m, at the state of the last :meth:`hip_com`."""
        return pin.updateFramePlacement(self.model, self.data, self.fid["P_tp" + foot]).translation.copy()

    def toe_rotation(self, foot: str) -> np.ndarray:
        """Orientation of the toe body of ``foot`` (O_1 / O_2) at the state of the last :meth:`hip_com`."""
        pin.updateFramePlacements(self.model, self.data)
        return self.data.oMf[self.fid["O_1" if foot == "R" else "O_2"]].rotation.copy()

    # ------------------------------------------------------------------ phase changes
    def touchdown(self, t: float, phase: Phase, foot: str, key: str) -> None:
        """The swing foot landed (end of SSP ``phase``): the velocity reset of 4.5 (weights ``reset.<key>``) or the
        inelastic impact, as the scenario's ``simulation.impact_law`` says."""
        res = touchdown(self.model, self.q, self.v, phase, self.sc.simulation.impact_law, w_adj=self.sc.W_adj.get(key))
        self.landings.append(landing_record(self.model, self.proj_data, self.q, res, t, foot, self._sole))
        self.v = res.v_plus

    def run_info(self) -> dict:
        """For the run's summary: the landing audit records (:mod:`humanoid_sim.engines.landing`), one per touchdown."""
        return {"landings": list(self.landings)}

    def enter(self, phase: Phase) -> None:
        """Start ``phase``: weld its contacts where they are now (held bodies keep their anchors)."""
        self.anchors = record_anchors(self.model, self.q, phase.contacts, previous=self.anchors)
        self.phase = phase

    # ------------------------------------------------------------------ logging
    def build_trace(self) -> Trace | None:
        """With a control period (:attr:`control_period_s`), the full-rate trace: one row per integration step of
        one period (:mod:`humanoid_sim.interfaces.trace`); None otherwise (every integration step is then a loop
        step, and the log is the trace)."""
        if self.control_period_s is None or not self._substeps:
            return None
        t, k, phase, q, v, a, lam, tau, T, sat, T_cmd = zip(*self._substeps)
        Q, V, A, TAU = np.array(q), np.array(v), np.array(a), np.array(tau)
        n = len(t)
        if all(x is not None for x in T):
            T_arr = np.array(T)
            T_cmd_arr = np.array([x if x is not None else y for x, y in zip(T_cmd, T)])
            sat_arr = np.array([x if x is not None else self._no_sat for x in sat])
        else:
            T_arr = T_cmd_arr = np.array([self.act.thesis_torques(Q[i], V[i], A[i], TAU[i]) for i in range(n)])
            sat_arr = np.zeros((n, 26), dtype=bool)
        bf, bm, fw, cop = self._reactions.batch(Q, V, A, [ph.contacts for ph in phase], lam, TAU)
        ftot, mtot = fw[:, :, :3].sum(axis=1), fw[:, :, 3:].sum(axis=1)
        zmp = np.full((n, 3), np.nan)
        ok = ftot[:, 2] > 1e-9
        zmp[ok] = np.stack([-mtot[ok, 1] / ftot[ok, 2], mtot[ok, 0] / ftot[ok, 2], np.zeros(ok.sum())], axis=1)
        stance = {ph: [f in ph.stance_feet for f in ("R", "L")] for ph in Phase}
        cols = {"t": np.array(t), "phase": np.array(k), "basic_phase": np.array([BASIC[ph] for ph in phase]),
                "q": Q, "v": V, "a": A, "tau": TAU, "T": T_arr, "T_cmd": T_cmd_arr, "saturated": sat_arr,
                "body_force": bf, "body_moment": bm, "foot_wrench": fw.reshape(n, 2, 6), "cop": cop, "zmp": zmp,
                "in_contact": np.array([stance[ph] for ph in phase])}
        return Trace(cols, float(self.control_period_s), "engine")

    def build_log(self, rows: list[StepRow]) -> SimLog:
        """The log from the loop's rows (their records are :class:`WeldRecord`): stacked, with the derived signals
        (thesis coordinates, unwrapped yaws, ground reactions, centres of pressure, ZMP) computed in one pass after
        the loop."""
        hm = self.hm
        n = len(rows)
        if n == 0:
            return SimLog()
        t, k, phase, ref, hip_ctrl, records = zip(*rows)
        q = [r.q for r in records]
        v = [r.v for r in records]
        (a, lam, thdd_c, T_cmd, T, sat, tau, pos, ori, res, hip_p, hip_v, R17, toe_R, toe_L, R1,
         R2) = zip(*(r.stage for r in records))
        Q, V, A, TAU = np.array(q), np.array(v), np.array(a), np.array(tau)
        thesis = lambda X: hm.theta_sign * X[:, hm.theta_v_idx]  # noqa: E731 -- v-ordered arrays -> thesis
        bf, bm, fw, cop = self._reactions.batch(Q, V, A, [ph.contacts for ph in phase], lam, TAU)
        stance = {ph: [f in ph.stance_feet for f in ("R", "L")] for ph in Phase}
        contact = np.array([stance[ph] for ph in phase])
        ftot = fw[:, :, :3].sum(axis=1)
        mtot = fw[:, :, 3:].sum(axis=1)
        zmp = np.full((n, 3), np.nan)
        ok = ftot[:, 2] > 1e-9
        zmp[ok] = np.stack([-mtot[ok, 1] / ftot[ok, 2], mtot[ok, 0] / ftot[ok, 2], np.zeros(ok.sum())], axis=1)
        yaw0 = yaw_of(hm.spec.C0)
        yaw, yaw_ref = np.empty(n), np.empty(n)
        prev, prev_ref = yaw0, yaw0
        for i in range(n):
            prev = yaw[i] = unwrap_to(yaw_of(R17[i]), prev)
            prev_ref = yaw_ref[i] = unwrap_to(yaw_of(ref[i].hip_R), prev_ref)
        cols = dict(
            t=np.array(t), phase=np.array(k), basic_phase=np.array([BASIC[ph] for ph in phase]), q=Q, v=V,
            theta=hm.theta_sign * Q[:, hm.theta_q_idx], theta_dot=thesis(V), theta_ddot=thesis(A), a=A,
            theta_ddot_cmd=np.array(thdd_c), T_cmd=np.array(T_cmd), T=np.array(T), saturated=np.array(sat),
            tau=TAU, hip_p=np.array(hip_p), hip_p_ref=np.array([r.hip_p for r in ref]),
            hip_p_ctrl_ref=np.array(hip_ctrl), hip_v=np.array(hip_v), hip_v_ref=np.array([r.hip_v for r in ref]),
            hip_R=np.array(R17), hip_R_ref=np.array([r.hip_R for r in ref]), hip_yaw=yaw, hip_yaw_ref=yaw_ref,
            toe_R_p=np.array(toe_R), toe_R_p_ref=np.array([r.toe_R_p for r in ref]), toe_L_p=np.array(toe_L),
            toe_L_p_ref=np.array([r.toe_L_p for r in ref]), foot_R_R=np.array(R1), foot_L_R=np.array(R2),
            body_force=bf, body_moment=bm, foot_wrench=fw.reshape(n, 2, 6), cop=cop, in_contact=contact, zmp=zmp,
            drift_position=np.array(pos), drift_orientation=np.array(ori), dynamics_residual=np.array(res))
        return SimLog.from_columns(cols)
