"""The thesis's controller: optimum command accelerations (5.1), computed torque under the phase's contact
constraints (5.2), saturation of the thesis's actuator components T (errata section 7).

Per call (the controller is a feedthrough function of the state, evaluated at every integration stage as in the
Simulink model): references at t + dt (nominal schedule, clamped to the current phase, errata T-3) -> command
accelerations theta_ddot_c (:class:`humanoid_sim.controllers.thesis.command.CommandAccelerations`) -> the generalized
torques that
realise them under the phase's constraints -> T (eq. 4.69) -> saturation.

The computed torque is solved by the constraint model of the engine it runs on (``ControlContext.constraints``):

- on the weld engine (``WeldModel``), Pinocchio's KKT inverse dynamics under the phase's welds and toe lock.  In
  single support it is unique (the stance toe torque is zero, K-10); in double support it is the weighted minimum
  norm of [tau; lambda] with weight 1000 on joint torques and 1 on contact wrenches (the floating-base counterpart
  of the thesis's W_act, 1000 on actuator torques and 1 on the rest).  The motion is the same for every choice;
  the split of the ground reaction between the feet is not.  When no actuator saturates, the torques realise the
  commanded motion exactly, so the command carries that motion (``Command.motion``) and the engine need not solve
  its forward dynamics again.  With numba installed, the whole stage runs in one compiled call
  (:class:`humanoid_sim.controllers.thesis.stage.StageKernel`, the twin :mod:`.compiled` on the shared compiled
  code of :mod:`humanoid_sim.kernel`), equal to this reference path to round-off (``tests/kernel/test_kernel.py``);
  saturated stages (~0.5 %) run on the reference path.
- on the oracle engine (``OracleModel``), the thesis's own computed torque of 5.2 (the 96-vector F minimised with
  the scenario's W_act) on the oracle's 122 x 122 equations.
- on an engine without a constraint model (real contact), the Pinocchio weld model of the phase (the contact the
  thesis's controller assumes), built here.
"""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin

from humanoid_sim import kernel as _kernel
from humanoid_sim.controllers.thesis.command import CommandAccelerations, CommandError, TaskReference
from humanoid_sim.dynamics.contact import ContactDynamics, ContactError, record_anchors
from humanoid_sim.interfaces.controller import Command, ControlContext, Observation
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.phases import Phase

W_TAU_DSP = 1000.0  # W_act weight of actuator torques (Appendix B, errata A-3)
W_LAMBDA_DSP = 1.0  # W_act weight of the other force components


class ThesisController:
    """Thesis sections 5.1 and 5.2 (see the module docstring).

    ``compiled``: evaluate weld-model stages with the compiled kernel; None = whenever numba is installed and the
    kernel agrees with the reference path (:meth:`check_kernel`, else a RuntimeWarning), True = required
    (RuntimeError otherwise), False = always the reference path.  Only the weld model has a compiled twin.
    """

    name = "thesis"
    control_period_s: float | None = None
    """None: a feedthrough of the state, evaluated at every integration stage (the engine's own rate)."""

    def __init__(self, compiled: bool | None = None) -> None:
        self.compiled = compiled
        self.kernel = None
        self.stage_evals = 0
        self.compiled_evals = 0

    # ------------------------------------------------------------------ set-up
    def setup(self, ctx: ControlContext) -> None:
        hm = ctx.hm
        self.hm = hm
        self.model = hm.model
        self.sc = ctx.scenario
        self.traj = ctx.traj
        self.q0 = ctx.q0
        self.cmd = CommandAccelerations(hm, ctx.scenario.controller, theta0=hm.theta_from_q(ctx.q0))
        self.act = Actuators(hm)
        cons = ctx.constraints
        self.oracle = cons if getattr(cons, "kind", None) == "oracle" else None
        if self.oracle is not None:
            self.weld = None
            self.dyn = None
        else:
            from humanoid_sim.dynamics.welds import WeldModel

            self.weld = cons if isinstance(cons, WeldModel) else WeldModel(ContactDynamics(hm.model))
            self.dyn = self.weld.dyn
        self._w_tau = np.full(hm.model.nv, W_TAU_DSP)
        self._w_lam = {p: np.full(p.contacts.n_rows, W_LAMBDA_DSP) for p in Phase}
        self._no_sat = np.zeros(26, dtype=bool)
        self._table: tuple = (None, None)
        self.kernel = None
        compiled, explicit = self.compiled, self.compiled is not None
        if self.weld is None:
            if compiled:
                raise RuntimeError("the compiled kernel covers the weld constraint model only, not the "
                                   f"{ctx.engine!r} engine's")
            return
        if compiled is None:
            compiled = _kernel.AVAILABLE
        if compiled and not _kernel.AVAILABLE:
            raise RuntimeError("the compiled kernel needs numba, which is not installed (pip install numba)")
        if compiled:
            from humanoid_sim.controllers.thesis.stage import StageKernel

            self.kernel = StageKernel(hm, self.cmd, self.act, self.dyn.gains, self._w_tau, self._w_lam)
            self._kdata = hm.model.createData()
            problem = self.check_kernel()
            if problem is not None:
                self.kernel = None
                msg = (f"the compiled stage kernel disagrees with the reference path ({problem}): the reference code "
                       "(command.py, actuators.py, contact/) was probably changed without its compiled twin in "
                       "humanoid_sim/controllers/thesis/compiled.py and humanoid_sim/kernel/)")
                if explicit:
                    raise RuntimeError(msg)
                warnings.warn(msg + "; running on the reference path (about 4x slower)", RuntimeWarning, stacklevel=2)

    # ------------------------------------------------------------------ one call
    def __call__(self, obs: Observation) -> Command:
        return self.evaluate(obs.k, obs.phase, obs.anchors, obs.t, obs.q, obs.v)

    def run_info(self) -> dict:
        """For the run's summary: how many weld-model stages ran compiled (none on the oracle engine)."""
        return {} if self.oracle is not None else {"compiled_stages": self.compiled_evals}

    def references(self, k: int, t: float) -> tuple[TaskReference, TaskReference | None]:
        """The hip reference at t + dt_a and (single support) the swing toe's at t + dt_b, clamped to phase k."""
        info = self.traj.phases[k]
        wa, wb = self.sc.controller.steps[info.name]
        ref_a = TaskReference(*self.traj.hip_reference(k, t + wa.dt))
        if info.swing_foot is None:
            return ref_a, None
        return ref_a, TaskReference(*self.traj.toe_reference(k, t + wb.dt, info.swing_foot))

    def evaluate(self, k: int, phase: Phase, anchors, t: float, q: np.ndarray, v: np.ndarray) -> Command:
        """Controller (5.1) + computed torque (5.2) + saturation at one state.

        On the weld model, one Pinocchio pass (placements, velocities, bias accelerations, joint Jacobians, CRBA,
        nonlinear effects) serves the controller, the constrained inverse dynamics and the actuator map."""
        self.stage_evals += 1
        if self.oracle is not None:
            return self._evaluate_oracle(k, phase, t, q, v)
        if self.kernel is not None:
            out = self.kernel.stage(phase, anchors, q, v, self._dynamics_pass(q, v), self._table_of(k), t)
            if out.status == 0.0:  # else saturated or a singular cost: the reference path handles the stage
                self.compiled_evals += 1
                return Command(tau=out.tau, T=out.T_cmd, T_cmd=out.T_cmd, saturated=self._no_sat,
                               theta_ddot_cmd=out.thdd_c, motion=(out.a, out.lam), motion_model=self.weld,
                               extra={"kernel_log": out.log})
        return self._evaluate_reference(k, phase, anchors, t, q, v)

    def _table_of(self, k: int) -> np.ndarray:
        """The reference table of phase k for the kernel (``ssp_table`` / ``dsp_table``; cached, the cache is dropped
        whenever the trajectory learns a landing: :meth:`landing`)."""
        if self._table[0] != k:
            tr = self.traj
            self._table = (k, tr.ssp_table(k) if tr.phases[k].is_ssp else tr.dsp_table(k))
        return self._table[1]

    def landing(self) -> None:
        """The trajectory learned a landing (``traj.set_landing``): drop the cached reference table."""
        self._table = (None, None)

    def _evaluate_reference(self, k: int, phase: Phase, anchors, t: float, q: np.ndarray, v: np.ndarray) -> Command:
        """:meth:`evaluate` on the NumPy/Pinocchio reference path (weld model)."""
        contacts = phase.contacts
        ref_a, ref_b = self.references(k, t)
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
            return Command(tau=tau, T=T_sat, T_cmd=T_cmd, saturated=sat, theta_ddot_cmd=thdd_c,
                           extra={"M": inv.M})
        return Command(tau=inv.tau, T=T_sat, T_cmd=T_cmd, saturated=sat, theta_ddot_cmd=thdd_c,
                       motion=(inv.a, inv.lam), motion_model=self.weld, extra={"M": inv.M})

    def _evaluate_oracle(self, k: int, phase: Phase, t: float, q: np.ndarray, v: np.ndarray) -> Command:
        """5.1 on Pinocchio's task kinematics, 5.2 on the oracle's equations at the stage the oracle engine holds."""
        ref_a, ref_b = self.references(k, t)
        thdd_c = self.cmd.compute(phase.value, q, v, ref_a, ref_b)
        T_cmd = self.oracle.computed_torque(thdd_c)
        T_sat, sat = self.act.saturate(T_cmd)
        return Command(tau=None, T=T_sat, T_cmd=T_cmd, saturated=sat,
                       theta_ddot_cmd=thdd_c)

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
            if out.saturated != bool(ref.saturated.any()):
                return f"{phase.value}: saturation flags differ"
            checks = [("theta_ddot_c", out.thdd_c, ref.theta_ddot_cmd), ("T_cmd", out.T_cmd, ref.T_cmd)]
            if not out.saturated:  # a saturated reference stage continues with the saturated torques
                checks += [("a", out.a, ref.motion[0]), ("lam", out.lam, ref.motion[1]), ("tau", out.tau, ref.tau)]
            for name, x, y in checks:
                err = float(np.max(np.abs(x - y))) / (1.0 + float(np.max(np.abs(y))))
                if not err <= tol:
                    return f"{phase.value}: {name} differs by {err:.2e} relative"
        self._table = (None, None)
        return None
