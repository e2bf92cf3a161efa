"""The simulation loop of thesis chapter 6: phase selector, controller at every stage, fixed-step ode3,
touchdown reset, logging.

Per integration stage (the controller is a feedthrough function of the state, as in the Simulink model):
references at t + dt (nominal schedule, clamped to the current phase, errata T-3) -> optimum command
accelerations (thesis 5.1) -> computed torque under the phase's constraints (5.2) -> saturation of the
thesis's actuator components (errata section 7) -> constrained forward dynamics -> accelerations.

At each step boundary the phase selector (6.1.1) decides: SSP -> DSP on touchdown of the swing toe (then the
velocity reset of 4.5 or an inelastic impact, the landing foot welded where it landed, the trajectory told
the actual landing); DSP -> SSP on the hip-distance or overtime rule (no state change).

Speed: when numba is installed, stages where no actuator saturates (~99.5 % of them) run through the compiled twin
of this module's reference path (:mod:`humanoid_sim.kernel`), together with each stage's integration and
projection; the results equal the reference path's to round-off (``tests/test_kernel.py``), which
``Simulator(compiled=False)`` (``walk.py --no-kernel``) runs throughout.

Failure handling (``selector.PhaseSelector``): a non-finite or diverging state, a singular constraint or command
system, the hip CoM below the fall height or a phase lasting far beyond its nominal duration stop the run with a
one-line reason; the log up to that point is kept.  KeyboardInterrupt stops the run the same way.

Decisions where the thesis is silent:
- The support foot (welded main body plus locked toe joint, the thesis's chain root) is held exactly: every ode3
  stage state and every step's end is projected onto it -- the base placement re-derived from the foot's anchor,
  the base twist from the joint rates, the toe joint at its anchor angle with zero rate -- as the thesis's
  joint-space integration holds it by construction.  The other constraints (the trailing toe in double support)
  are held by the contact solver's Baumgarte stabilisation.
- Logged references (``hip_p_ref``, ``toe_*_ref``, ``hip_yaw_ref``) are the planned motion at time t on the
  nominal schedule, the reference the user designed and the viewer draws; tracking errors are measured against
  it.  The controller tracks the current phase's reference clamped to the phase's nominal window (thesis 6.1.1,
  errata T-3), logged as ``hip_p_ctrl_ref``.  The two differ while a phase runs ahead of or behind its nominal
  window: with the thesis's 0.05 m double-support rule a DSP ends one or two steps after touchdown, so the next
  SSP's reference is held at its start for up to t_DSP.
- P_i of the SSP switching rule is the actual swing toe point at the phase start (thesis 6.1.1.1 wording).
- The double-support torque distribution (the thesis minimises the weighted 96-vector F with W_act, 1000 on
  actuator torques, 1 on the rest) is taken here as the weighted minimum norm of [tau; lambda] with weight
  1000 on joint torques and 1 on the contact wrenches: the contact-wrench part of F; the inter-body forces of F
  have no floating-base counterpart.  The motion does not depend on this choice (the closed chain realizes the
  commanded accelerations for every member of the family); the ground-reaction split between the feet does.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pinocchio as pin

from humanoid_sim import kernel as _kernel
from humanoid_sim.actuators import Actuators
from humanoid_sim.command import CommandAccelerations, CommandError, TaskReference
from humanoid_sim.contact import ContactDynamics, ContactError, record_anchors
from humanoid_sim.contact.wrenches import GroundReactionLog
from humanoid_sim.impact import touchdown
from humanoid_sim.initial import initial_configuration
from humanoid_sim.integrator import RungeKutta
from humanoid_sim.model import HumanoidModel
from humanoid_sim.phases import FOOT_SPECS, Phase, SwitchThresholds
from humanoid_sim.results import SimLog
# PhaseRecord and SimulationError are part of this module's interface (SimResult.phases, Simulator.run's failures)
from humanoid_sim.selector import PhaseRecord, PhaseSelector, SimulationError, all_finite
from humanoid_sim.scenario import Scenario
from humanoid_sim.trajectory import ReferenceTrajectory

BASIC = {Phase.LFFSSP: 0, Phase.RFFDSP: 1, Phase.RFFSSP: 2, Phase.LFFDSP: 3}
FEET = (FOOT_SPECS["R"], FOOT_SPECS["L"])
BODY_FRAMES = ("O_1", "O_2", "O_3", "O_4")  # rows of the logged thesis ground wrenches (bodies 1-4)
W_TAU_DSP = 1000.0  # W_act weight of actuator torques (Appendix B, errata A-3)
W_LAMBDA_DSP = 1.0  # W_act weight of the other force components
@dataclass
class SimResult:
    """Outcome of a run: the log, the phase history, and how it ended."""

    log: SimLog
    phases: list[PhaseRecord]
    phases_planned: int
    completed: bool
    reason: str
    sim_time: float
    wall_time: float
    steps: int
    stage_evaluations: int
    extra: dict = field(default_factory=dict)


def yaw_of(R: np.ndarray) -> float:
    """Heading of the body x-axis in the world ground plane (rad, from world x)."""
    return float(np.arctan2(R[1, 0], R[0, 0]))


def _unwrap_to(angle: float, ref: float) -> float:
    return ref + (angle - ref + np.pi) % (2 * np.pi) - np.pi


class Simulator:
    """Runs one scenario on the Pinocchio fast path."""

    def __init__(self, hm: HumanoidModel, scenario: Scenario, compiled: bool | None = None) -> None:
        """``compiled``: evaluate stages with the compiled kernel (:mod:`humanoid_sim.kernel`);
        None = whenever numba is installed and the kernel agrees with the reference path (:meth:`check_kernel`,
        else a RuntimeWarning), True = required (RuntimeError otherwise), False = always the reference path."""
        self.hm = hm
        self.sc = scenario
        self.model = hm.model
        self.traj = ReferenceTrajectory(scenario.path)
        self.q0 = initial_configuration(hm, scenario.path)
        self.cmd = CommandAccelerations(hm, scenario.controller, theta0=hm.theta_from_q(self.q0))
        self.dyn = ContactDynamics(hm.model)
        self.act = Actuators(hm)
        self.rk = RungeKutta(hm.model, scenario.simulation.method)
        sw = scenario.switch
        self.thresholds = SwitchThresholds(sw.toe_flat_height_m, sw.touchdown_tolerance_m,
                                           sw.min_horizontal_progress_fraction, sw.dsp_hip_distance_m,
                                           sw.dsp_overtime_fraction)
        self.fid = {n: hm.frame_id(n) for n in ("Pc_17", "O_17", "P_tpR", "P_tpL", "O_1", "O_2")}
        self.data = hm.model.createData()
        self.proj_data = hm.model.createData()
        self._weld_fid = {s.main_frame: hm.frame_id(s.main_frame) for s in FOOT_SPECS.values()}
        self._lock_idx = {}
        for s in FOOT_SPECS.values():
            jid = hm.model.getJointId(s.toe_joint)
            self._lock_idx[s.toe_joint] = (hm.model.idx_qs[jid], hm.model.idx_vs[jid])
        self.stage_evals = 0
        self.compiled_evals = 0
        self._w_tau = np.full(hm.model.nv, W_TAU_DSP)
        self._w_lam = {p: np.full(p.contacts.n_rows, W_LAMBDA_DSP) for p in Phase}
        self._reactions = GroundReactionLog(hm.model, FEET, BODY_FRAMES)
        explicit = compiled is not None
        if compiled is None:
            compiled = _kernel.AVAILABLE
        if compiled and not _kernel.AVAILABLE:
            raise RuntimeError("the compiled kernel needs numba, which is not installed (pip install numba)")
        self.kernel = None
        self._no_sat = np.zeros(26, dtype=bool)
        self._table: tuple = (None, None)
        if compiled:
            from humanoid_sim.kernel.stage import StageKernel
            self.kernel = StageKernel(hm, self.cmd, self.act, self.dyn.gains, self._w_tau, self._w_lam)
            self._kdata = hm.model.createData()
            problem = self.check_kernel()
            if problem is not None:
                self.kernel = None
                msg = (f"the compiled stage kernel disagrees with the reference path ({problem}): the reference code "
                       "(command.py, actuators.py, contact/) was probably changed without its compiled twin in "
                       "humanoid_sim/kernel/compiled.py")
                if explicit:
                    raise RuntimeError(msg)
                warnings.warn(msg + "; running on the reference path (about 4x slower)", RuntimeWarning, stacklevel=2)
            else:
                self.kernel.warm_up(self.q0, len(self.rk.tab.c))

    # ------------------------------------------------------------------ one stage
    def _references(self, k: int, t: float) -> tuple[TaskReference, TaskReference | None]:
        info = self.traj.phases[k]
        wa, wb = self.sc.controller.steps[info.name]
        ref_a = TaskReference(*self.traj.hip_reference(k, t + wa.dt))
        if info.swing_foot is None:
            return ref_a, None
        return ref_a, TaskReference(*self.traj.toe_reference(k, t + wb.dt, info.swing_foot))

    def evaluate(self, k: int, phase: Phase, anchors, t: float, q: np.ndarray, v: np.ndarray) -> dict:
        """Controller + computed torque + saturation + forward dynamics at one state.

        One pinocchio pass (placements, velocities, bias accelerations, joint Jacobians, CRBA, nonlinear effects)
        serves the controller, the constrained inverse dynamics and the actuator map.  When no actuator saturates,
        the computed torque realises the commanded motion exactly, so the forward dynamics of those torques is the
        inverse solution itself; otherwise the forward dynamics is solved for the saturated torques.
        """
        self.stage_evals += 1
        if self.kernel is not None:
            out = self.kernel.stage(phase, anchors, q, v, self._dynamics_pass(q, v), self._table_of(k), t)
            if out.log[0] == 0.0:  # else saturated or a singular cost: the reference path handles the stage
                self.compiled_evals += 1
                return {"a": out.a, "lam": out.lam, "thdd_c": out.thdd_c, "T_cmd": out.T_cmd, "T": out.T_cmd,
                        "sat": self._no_sat, "tau": out.tau, "kernel_log": out.log}
        return self._evaluate_reference(k, phase, anchors, t, q, v)

    def _table_of(self, k: int) -> np.ndarray:
        """The reference table of phase k for the kernel (``ssp_table`` / ``dsp_table``; cached, the cache is dropped
        whenever the trajectory learns a landing)."""
        if self._table[0] != k:
            tr = self.traj
            self._table = (k, tr.ssp_table(k) if tr.phases[k].is_ssp else tr.dsp_table(k))
        return self._table[1]

    def _evaluate_reference(self, k: int, phase: Phase, anchors, t: float, q: np.ndarray, v: np.ndarray) -> dict:
        """:meth:`evaluate` on the NumPy/Pinocchio reference path."""
        contacts = phase.contacts
        ref_a, ref_b = self._references(k, t)
        rows = self.dyn.prepare(contacts, anchors, q, v)
        thdd_c = self.cmd.compute(phase.value, q, v, ref_a, ref_b, data=self.dyn.data)
        a_des = self.hm.v_from_theta_dot(thdd_c)
        if phase.is_double_support:
            inv = self.dyn.inverse_prepared(rows, a_des, self._w_tau, self._w_lam[phase])
        else:
            inv = self.dyn.inverse_prepared(rows, a_des)
        T_cmd = self.act.thesis_torques(q, v, inv.a, inv.tau, kin_data=self.dyn.data)
        T_sat, sat = self.act.saturate(T_cmd)
        if sat.any():
            B = self.act.torque_map(q, self.dyn.data)
            tau = inv.tau + B @ (T_sat - T_cmd)
            tau[:6] = 0.0
            fwd = self.dyn.forward_prepared(rows, tau)
            a, lam = fwd.a, fwd.lam
        else:
            tau, a, lam = inv.tau, inv.a, inv.lam
        return {"a": a, "lam": lam, "thdd_c": thdd_c, "T_cmd": T_cmd, "T": T_sat, "sat": sat, "tau": tau,
                "M": inv.M}

    def _dynamics_pass(self, q: np.ndarray, v: np.ndarray) -> pin.Data:
        """The Pinocchio passes the compiled stage needs at (q, v): joint Jacobians and their time derivative
        (with placements and velocities), the joint-space inertia (upper triangle) and the nonlinear effects."""
        d, model = self._kdata, self.model
        pin.computeJointJacobiansTimeVariation(model, d, q, v)
        pin.crba(model, d, q)
        pin.nonLinearEffects(model, d, q, v)
        return d

    def check_kernel(self, tol: float = 1e-8) -> str | None:
        """Compare the compiled stage with the reference path at one deterministic state per phase
        (the initial posture with joint angles moved by ~0.02 rad and rates of ~0.1 rad/s, so that velocity terms
        count); None when every output agrees to ``tol`` relative (the two agree to ~1e-13 when unmodified), else
        what differs.  Guards against a reference formula edited without its compiled twin."""
        rng = np.random.default_rng(20101)
        q = self.q0.copy()
        q[7:] += rng.normal(0.0, 0.02, self.model.nq - 7)
        v = rng.normal(0.0, 0.1, self.model.nv)
        for phase in Phase:
            k = next((i for i, ph in enumerate(self.traj.phases) if ph.name == phase.value), None)
            if k is None:
                continue
            t = self.traj.phases[k].t_start + 0.4 * self.traj.phases[k].duration
            anchors = record_anchors(self.model, q, phase.contacts)
            self._table = (None, None)
            out = self.kernel.stage(phase, anchors, q, v, self._dynamics_pass(q, v), self._table_of(k), t)
            try:
                ref = self._evaluate_reference(k, phase, anchors, t, q, v)
            except (ContactError, CommandError, np.linalg.LinAlgError):
                continue  # no reference to compare with (e.g. all weights zero): the run reports that error itself
            if out.saturated != bool(ref["sat"].any()):
                return f"{phase.value}: saturation flags differ"
            checks = [("theta_ddot_c", out.thdd_c), ("T_cmd", out.T_cmd)]
            if not out.saturated:  # a saturated reference stage continues with the saturated torques
                checks += [("a", out.a), ("lam", out.lam), ("tau", out.tau)]
            for name, x in checks:
                y = ref[name if name != "theta_ddot_c" else "thdd_c"]
                err = float(np.max(np.abs(x - y))) / (1.0 + float(np.max(np.abs(y))))
                if not err <= tol:
                    return f"{phase.value}: {name} differs by {err:.2e} relative"
        return None

    def _stage0_record(self, phase: Phase, out: dict) -> tuple:
        """What the log needs from the first stage of a step, read while the solver still holds that state:
        the evaluation's outputs, the weld drifts, the dynamics residual and the task frames' positions,
        orientations and the hip velocity."""
        a, lam, tau = out["a"], out["lam"], out["tau"]
        lg = out.get("kernel_log")
        if lg is not None:  # the compiled stage computed the same quantities (layout: kernel.stage.StageOutput)
            return (a, lam, out["thdd_c"], out["T_cmd"], out["T"], out["sat"], tau, lg[1], lg[2], lg[3], lg[4:7],
                    lg[7:10], lg[10:19].reshape(3, 3), lg[19:22], lg[22:25], lg[25:34].reshape(3, 3),
                    lg[34:43].reshape(3, 3))
        rows = self.dyn.rows(phase.contacts)
        d = self.dyn.data
        M = out["M"]  # the symmetric joint-space inertia of this state (from the upper triangle crba fills)
        residual = float(np.max(np.abs(M @ a + d.nle - tau - rows.J.T @ lam)))
        pos = float(np.max(rows.weld_position_error)) if rows.weld_position_error.size else 0.0
        ori = float(np.max(rows.weld_orientation_error)) if rows.weld_orientation_error.size else 0.0
        kin = self.cmd.kin
        return (a, lam, out["thdd_c"], out["T_cmd"], out["T"], out["sat"], tau, pos, ori, residual,
                kin.placement("Pc_17")[0], kin.velocity("Pc_17")[:3].copy(), kin.placement("O_17")[1],
                kin.placement("P_tpR")[0], kin.placement("P_tpL")[0], kin.placement("O_1")[1],
                kin.placement("O_2")[1])

    # ------------------------------------------------------------------ the run
    def run(self, t_end: float | None = None, progress: Callable[[float, int], None] | None = None) -> SimResult:
        sc, traj = self.sc, self.traj
        h = sc.simulation.step_s
        n_phases = traj.n_phases
        nominal_end = traj.phases[-1].t_end
        t_stop = t_end if t_end is not None else (sc.simulation.t_end_s or np.inf)
        q = self.q0.copy()
        v = np.zeros(self.model.nv)
        t = 0.0
        sel = PhaseSelector(traj, self.thresholds, sc.simulation, self._toe(q, traj.phases[0].swing_foot))
        anchors = record_anchors(self.model, q, sel.phase.contacts)
        raw: list[tuple] = []   # per step: (t, k, phase, q, v, nominal references) + the stage-0 record
        stage0: list[tuple] = [()]
        fid_hip = self.fid["Pc_17"]
        project = self.project_on_support
        advance = None if self.kernel is None else self.kernel.advance  # integrate + project, compiled
        completed, reason = False, ""
        steps = 0
        wall0 = time.perf_counter()

        def f(ts: float, qs: np.ndarray, vs: np.ndarray, stage: int) -> np.ndarray:
            sel.check_stage(ts, qs, vs, stage)
            out = self.evaluate(sel.k, sel.phase, anchors, ts, qs, vs)
            sel.check_acceleration(ts, out["a"])
            if stage == 0:
                stage0[0] = self._stage0_record(sel.phase, out)
            return out["a"]

        try:
            while True:
                if t >= t_stop - 1e-12:
                    reason = f"stopped at t = {t:.3f} s (requested stop time)"
                    break
                k, phase = sel.k, sel.phase
                if advance is None:
                    q_new, v_new = self.rk.step(f, t, q, v, h, lambda qs, vs: project(phase, anchors, qs, vs))
                else:
                    q_new, v_new = self.rk.step(f, t, q, v, h, advance=lambda *a: advance(phase, anchors, *a))
                raw.append((t, k, phase, q, v, traj.sample_global(t), traj.hip_reference(k, t)[0]) + stage0[0])
                q, v, t = q_new, v_new, t + h
                steps += 1
                if progress is not None:
                    progress(t, k)
                if all_finite(q):
                    pin.forwardKinematics(self.model, self.data, q)
                    hip = pin.updateFramePlacement(self.model, self.data, fid_hip).translation.copy()
                else:
                    hip = np.full(3, np.nan)
                sel.check_state(t, q, v, hip)
                swing = sel.info.swing_foot
                toe = None
                if swing is not None:
                    toe = pin.updateFramePlacement(self.model, self.data, self.fid["P_tp" + swing]).translation.copy()
                if not sel.should_switch(t, hip, toe):
                    continue
                sel.end_phase(t)
                if sel.is_last:
                    completed, reason = True, f"all {n_phases} phases completed at t = {t:.3f} s"
                    break
                if swing is not None:  # touchdown: SSP -> DSP
                    pin.updateFramePlacements(self.model, self.data)
                    R_toe = self.data.oMf[self.fid["O_1" if swing == "R" else "O_2"]].rotation.copy()
                    key = sel.record_touchdown(toe, R_toe)
                    res = touchdown(self.model, q, v, phase, sc.simulation.impact_law, w_adj=sc.W_adj.get(key))
                    v = res.v_plus
                    traj.set_landing(swing, k, toe, R_toe)
                    self._table = (None, None)
                sel.advance(t, self._toe(q, traj.phases[k + 1].swing_foot))
                anchors = record_anchors(self.model, q, sel.phase.contacts, previous=anchors)
        except (SimulationError, ContactError, CommandError, np.linalg.LinAlgError) as exc:
            reason = str(exc) if isinstance(exc, SimulationError) else \
                f"{type(exc).__name__} at t = {t:.3f} s in {sel.where()}: {exc}"
        except KeyboardInterrupt:
            reason = f"interrupted by the user at t = {t:.3f} s"
        sel.close(t)
        records = sel.records
        try:
            log = self._build_log(raw)
        except KeyboardInterrupt:  # an interrupt during the post-loop pass: finish it, report the interruption
            log = self._build_log(raw)
            if completed or not reason.startswith("interrupted"):
                completed, reason = False, f"interrupted by the user at t = {t:.3f} s"
        return SimResult(log=log, phases=records, phases_planned=n_phases, completed=completed, reason=reason,
                         sim_time=t, wall_time=time.perf_counter() - wall0, steps=steps,
                         stage_evaluations=self.stage_evals,
                         extra={"nominal_end": nominal_end, "compiled_stages": self.compiled_evals})

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

    def _toe(self, q: np.ndarray, foot: str | None) -> np.ndarray | None:
        if foot is None:
            return None
        pin.forwardKinematics(self.model, self.data, q)
        oM = pin.updateFramePlacement(self.model, self.data, self.fid["P_tp" + foot])
        return oM.translation.copy()

    # ------------------------------------------------------------------ logging
    def _build_log(self, raw: list[tuple]) -> SimLog:
        """The log from the per-step records: stacked, with the derived signals (thesis coordinates, unwrapped
        yaws, ground reactions, centres of pressure, ZMP) computed in one pass after the loop."""
        hm = self.hm
        n = len(raw)
        if n == 0:
            return SimLog()
        (t, k, phase, q, v, ref, hip_ctrl, a, lam, thdd_c, T_cmd, T, sat, tau, pos, ori, res, hip_p, hip_v, R17,
         toe_R, toe_L, R1, R2) = zip(*raw)
        Q, V, A = np.array(q), np.array(v), np.array(a)
        thesis = lambda X: hm.theta_sign * X[:, hm.theta_v_idx]  # noqa: E731 -- v-ordered arrays -> thesis
        bf, bm, fw, cop = self._reactions.batch(Q, V, A, [ph.contacts for ph in phase], lam)
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
            prev = yaw[i] = _unwrap_to(yaw_of(R17[i]), prev)
            prev_ref = yaw_ref[i] = _unwrap_to(yaw_of(ref[i].hip_R), prev_ref)
        cols = dict(
            t=np.array(t), phase=np.array(k), basic_phase=np.array([BASIC[ph] for ph in phase]), q=Q, v=V,
            theta=hm.theta_sign * Q[:, hm.theta_q_idx], theta_dot=thesis(V), theta_ddot=thesis(A),
            theta_ddot_cmd=np.array(thdd_c), T_cmd=np.array(T_cmd), T=np.array(T), saturated=np.array(sat),
            tau=np.array(tau), hip_p=np.array(hip_p), hip_p_ref=np.array([r.hip_p for r in ref]),
            hip_p_ctrl_ref=np.array(hip_ctrl), hip_v=np.array(hip_v), hip_v_ref=np.array([r.hip_v for r in ref]),
            hip_R=np.array(R17), hip_R_ref=np.array([r.hip_R for r in ref]), hip_yaw=yaw, hip_yaw_ref=yaw_ref,
            toe_R_p=np.array(toe_R), toe_R_p_ref=np.array([r.toe_R_p for r in ref]), toe_L_p=np.array(toe_L),
            toe_L_p_ref=np.array([r.toe_L_p for r in ref]), foot_R_R=np.array(R1), foot_L_R=np.array(R2),
            body_force=bf, body_moment=bm, foot_wrench=fw.reshape(n, 2, 6), cop=cop, in_contact=contact, zmp=zmp,
            drift_position=np.array(pos), drift_orientation=np.array(ori), dynamics_residual=np.array(res))
        return SimLog.from_columns(cols)
