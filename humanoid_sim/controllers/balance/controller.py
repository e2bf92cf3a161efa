"""A whole-body controller that keeps every ground reaction feasible: task-space inverse dynamics as one QP.

The thesis's controller (5.1/5.2) cannot carry a balanced gait: its one-step prediction lags the planned CoM
acceleration around every double support, its orientation task (the diagonal of the rotation matrix) has no
first-order restoring term, and its double-support split of the ground reaction ignores the soles.  This
controller, in the family of TSID / PlaCo / mink, solves at each call

    min over x = [a (nv); lam (m)]   sum_tasks w_i |A_i a - b_i|^2  +  w_a |a|^2 + w_lam |lam|^2 + w_tau |tau|^2
    s.t.  M a + h = S^T tau + J^T lam  on the six base rows (no actuator there),
          J a = -gamma                  (the phase's welds and toe lock, as the engine enforces them),
          lam_lock = j_toe . W_t        (the toe lock carries only what the ground pushes under the toe box),
          every foot's ground wrench inside its sole and friction cone (linear inequalities in lam),

and returns tau = (M a + h - J^T lam) on the joints, with (a, lam) as the motion (the weld engine then does not
solve its forward dynamics again: the same (a, lam) by uniqueness).  The QP is solved by DAQP (a dual active-set
method for small dense QPs, exact to its 1e-6 feasibility tolerance; its optimum matches quadprog's:
``tests/controllers/test_balance_controller.py``).  The QP's matrices: :func:`.qp.qp_numpy` (reference) or
:mod:`.compiled` (numba; the records of its arguments: :mod:`.stage`).

The stance foot's toe joint: the thesis leaves its torque zero and lets the lock hold it (K-10); on real ground
nothing locks it, so here its motor holds it (the lock's multiplier is only the toe box's ground load, the torque
within the toe's 30 N m limit), which on the weld engine is the same motion.

Contact model: the phase's welds (humanoid_sim.robot.phases; the engine's ``WeldModel``, or on an engine without one --
MuJoCo -- the same rows built here).  A foot's ground wrench is its weld's multipliers (LOCAL [force; moment] at
the welded frame), the whole foot in single support (main body welded, toe locked: the whole sole), the toe body in
double support for the trailing foot (its toe part of the sole).  A flat foot carries two ground wrenches, one on
its heel box (main body, heel to toe joint) and one on its toe box (toe body): the toe box's wrench W_t reaches the
main-body weld as X W_t and the toe lock as j_toe . W_t, so the toe's motor is asked for exactly what the ground
pushes under the toe (a welded model that put the whole ground wrench on the main body let a real stance foot fold
at its toe joint when its CoP passed the joint line).  The sole geometry is the URDF's
(:class:`humanoid_sim.robot.sole.SoleGeometry`), so the contact audit measures what is constrained here.  Per loaded
foot: f_z >= 0; the centre of pressure inside the sole shrunk by ``cop_margin_ssp_m`` (single support) or
``cop_margin_dsp_m``; tangential force inside the friction pyramid inscribed in the cone of
``scenario.contact.friction_coefficient`` times ``friction_safety`` (the gait itself needs |f_t|/f_z of ~0.1; near
the full cone the QP leans on a just-landed, lightly loaded foot up to its friction limit and on real ground that
foot slides); a torsion bound.  Every actuator component the thesis's saturation limits (humanoid_sim.robot.actuators;
T linear in tau) stays within ``torque_margin`` of its limit (those rows join the QP only when its optimum without
them breaks one: ``lazy_torque_limits``, the same optimum).  When no motion satisfies them (the state is already
beyond recovery), the CoP margins are dropped, then every inequality; ``run_info`` counts such calls.  On real
ground the stance foot's boxes shrink to the part of its sole the ground supports (:mod:`.foothold`, rows by
:mod:`.boxes`), and the DCM plan leans against the external force the feet's sensors reveal (:mod:`.force`).

Tasks, world frame (LOCAL_WORLD_ALIGNED), each a PD on the error plus the reference's acceleration:
- Body-17 CoM (frame Pc_17): ``traj.hip_reference`` / ``traj.hip_acceleration``; gains ``hip_omega`` (rad/s,
  critically damped);
- Body-17 orientation (O_17): the rotation-vector error log3(R_ref R^T), the reference's yaw rate and yaw
  acceleration; ``trunk_omega``;
- single support: the swing toe point, and the swing toe body's and main body's orientations (``traj.toe_reference``;
  both bodies at the toe body's reference, so the foot stays flat and lands flat; the feed-forward acceleration is
  the reference velocity's central difference over ``ff_dt_s``, ramped in over ``swing_ramp_s`` because the
  thesis's toe path starts with a step of 4-5 m/s^2); ``swing_omega``; the main body's reference starts at the heel
  lift the foot left the ground with (measured at lift-off: on welds the toe-off's full ``heel_lift_rad``, on real
  ground less, the loaded heel box holds it back) and returns to flat over ``heel_return_time_s`` (a step back to
  flat kicks the stance foot); on real ground (an engine without a weld model) the last 20 % of the swing aims
  ``landing_depth_m`` below the path, so that the sole meets the ground on time (the swing foot lags its path by a
  few mm); on welds the geometric rule lands the foot on its path (aiming below pushes sole corners into the
  ground); a swing that outlasts its nominal duration keeps lowering the foot at ``landing_search_mps`` until
  touchdown is sensed;
- double support: the trailing foot (held by its toe) lifts its heel by ``heel_lift_rad`` (smoothstep over the
  phase or ``heel_lift_time_s``, whichever is shorter): the toe-off the toe weld assumes;
- every joint toward its initial angle (``posture_omega``; weights ``w_posture`` on the legs and the toe joints,
  ``w_upper`` on the upper body);
- double support: the trailing foot's normal force, weighted ``w_unload`` u^2 (u: the phase's progress), so the
  weight has left it when it lifts (without it the QP shares the load to the end, which lowers the joint torques,
  and the foot lifts still loaded; as a hard constraint, the load capped to zero at the phase end, walks fell).
The references run on the plan's clock (``time_shift``): when a phase starts later than planned (a touchdown
sensed late on real ground), every reference is read that much earlier, so the plan waits for the foot instead of
moving the hip on and starting the next swing part-way along its path.
One call: the references (Python, the trajectory's), Pinocchio's joint Jacobians with their time variation, M and h,
one compiled call that does the rest up to the QP (placements, frame motions, the weld and lock rows, the task rows,
the QP's matrices: :func:`.compiled.balance_stage`, the twin of :meth:`BalanceController._qp_reference`), DAQP, and
a compiled call for tau and the thesis torques (:func:`.compiled.balance_finish`).
``tests/controllers/test_balance_compiled.py`` runs both paths on every call of walks on welds and on MuJoCo.
Units: SI (m, rad, N, N m, s).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from humanoid_sim import kernel as _kernel
from humanoid_sim.controllers.balance.boxes import SoleBoxes
from humanoid_sim.controllers.balance.compiled import balance_finish, balance_stage
from humanoid_sim.controllers.balance.estimate import TwistFilter
from humanoid_sim.controllers.balance.foothold import FootholdTracker
from humanoid_sim.controllers.balance.force import ForceEstimate
from humanoid_sim.controllers.balance.qp import BalanceTables, BoxWrenches, pd, qp_numpy, rot_y
from humanoid_sim.controllers.balance.stage import FOOT_OF_MAIN, CompiledStage
from humanoid_sim.controllers.balance.steps import dcm_feedback
from humanoid_sim.controllers.balance.swing import swing_targets
from humanoid_sim.controllers.balance.targets import T_HEEL_ANGLE, TARGET_SIZE, Targets, pack_hip, pack_swing
from humanoid_sim.controllers.balance.trail import FlatContacts, FlatTrail
from humanoid_sim.interfaces.controller import Command, ControlContext, ControllerError, Observation
from humanoid_sim.kernel.records import Anchor, State
from humanoid_sim.references.chapter3.polynomials import smoothstep
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.phases import FOOT_SPECS, TOE_POINT_FRAME, other_foot
from humanoid_sim.robot.sole import SoleGeometry
from humanoid_sim.scenario.balance import BalanceSettings

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_DAQP_INF = 1e30          # DAQP reads a bound of 1e30 or more as no bound
_DAQP_EQUALITY = 5        # DAQP's constraint sense: an equality row
_DAQP_OPTIMAL = 1         # DAQP's exit flag of an optimal solution
_FOOT_OF_MAIN = FOOT_OF_MAIN                                                    # O_3 -> R, O_4 -> L
_TOE_FRAMES = {spec.toe_frame for spec in FOOT_SPECS.values()}                  # O_1, O_2
_NO_SATURATION = np.zeros(26, dtype=bool)                                       # shared: read-only
_NO_SATURATION.flags.writeable = False


def _own_trajectories() -> tuple[type, ...]:
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.references.zmp.zmp_walk import ZmpPreviewTrajectory

    return ReferenceTrajectory, ZmpPreviewTrajectory


_OWN_TRAJECTORIES = _own_trajectories()


class BalanceController:
    """See the module docstring.  ``settings``: :class:`BalanceSettings` (None = defaults)."""

    name = "balance"
    control_period_s: float | None = None
    """None: a feedthrough of the state, evaluated at every integration stage (the engine's own rate)."""

    def __init__(self, settings: BalanceSettings | None = None, compiled: bool = True) -> None:
        """``compiled``: when numba is installed, build the QP and read its solution in two compiled calls
        (``controllers.balance.compiled.balance_stage`` / ``balance_finish``); else, or False, the NumPy / Pinocchio
        reference
        (:meth:`_qp_reference`, :func:`qp_numpy`): the same command to round-off."""
        self.compiled = bool(compiled)
        if settings is not None and not isinstance(settings, BalanceSettings):
            raise ValueError(f"settings: expected a BalanceSettings or None, got {type(settings).__name__}")
        self.settings = settings or BalanceSettings()
        self.calls = 0
        self.relaxed_cop = 0
        self.relaxed_all = 0
        self.torque_rows = 0    # calls whose QP was solved with the actuator-limit rows (see lazy_torque_limits)

    # ------------------------------------------------------------------ set-up
    def setup(self, ctx: ControlContext) -> None:
        from humanoid_sim.dynamics.contact import ContactDynamics
        from humanoid_sim.dynamics.welds import WeldModel

        try:
            import daqp
        except ImportError as exc:   # pragma: no cover - a declared dependency
            raise ControllerError("the balance controller needs daqp (pip install daqp)") from exc
        self._daqp = daqp.solve
        hm = ctx.hm
        self.hm, self.model, self.traj = hm, hm.model, ctx.traj
        cons = ctx.constraints
        if getattr(cons, "kind", None) == "oracle":
            raise ControllerError("the balance controller runs on the weld model; the oracle engine offers the "
                                  "thesis's 122 x 122 equations only (use --engine pinocchio or mujoco)")
        self._real_ground = not isinstance(cons, WeldModel)
        self.weld = cons if isinstance(cons, WeldModel) else WeldModel(ContactDynamics(hm.model))
        self.dyn = self.weld.dyn
        self.act = Actuators(hm)
        self.sole = SoleGeometry.from_model(hm)
        fid = hm.frame_id
        self.fid = {n: fid(n) for n in ("Pc_17", "O_17", "P_tpR", "P_tpL", "O_1", "O_2", "O_3", "O_4")}
        self.theta0 = hm.theta_from_q(ctx.q0)
        nv = self.model.nv
        self.nv = nv
        self._Jpost = np.zeros((26, nv))                            # theta_dot = Jpost v (q = sign * theta)
        self._Jpost[np.arange(26), np.asarray(hm.theta_v_idx, dtype=int)] = hm.theta_sign
        self._upper = np.zeros(26, dtype=bool)
        self._upper[16:] = True                                     # theta18..theta27 (eq. 4.5)
        s = self.settings
        self._w_joint = np.where(self._upper, s.w_upper, s.w_posture)
        self._lift_k, self._lift0 = -1, 0.0     # the swing (its phase index) and its heel lift at lift-off, rad
        self._dsp_k, self._dsp_t0 = -1, 0.0     # the double support (its phase index) and its start, plan's clock, s
        self._task_buffers: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        # the components linear in tau (revolute and spherical joints; the shoulders' are not) and their bounds
        self._exact = self.act.component_map(ctx.q0)[1]
        self._exact_limits = self.act.limits[self._exact] * s.torque_margin
        self._box_kinds: dict[tuple, np.ndarray] = {}
        self._bounds: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}   # DAQP's row kinds, upper bounds
        self._stage = CompiledStage(self) if self.compiled and _kernel.AVAILABLE else None
        self._kin_data = self.model.createData()
        self._tgt = np.zeros(TARGET_SIZE)
        self._gains = np.array([*pd(s.hip_omega), s.w_hip, *pd(s.trunk_omega), s.w_trunk, *pd(s.swing_omega),
                                s.w_swing, *pd(s.posture_omega)], dtype=float)
        # the sole boxes' rows and the QP's constant inputs (boxes.py)
        self.boxes = SoleBoxes(self.sole, float(ctx.scenario.contact.friction_coefficient) * s.friction_safety, s,
                               self._gains, self._w_joint)
        self.dcm = dcm_feedback(s, self.model, self.fid["Pc_17"], self.traj)   # None: the hip PD
        if self.dcm is not None and self._real_ground and s.external_force:
            # real ground: lean against what the feet's sensors say the model does not know (force.py)
            mass = pin.computeTotalMass(self.model)
            self.dcm.force = ForceEstimate(mass, s.external_force_filter_hz, s.lean_max_m * mass * self.dcm.omega ** 2)
            self.dcm.lean_max = s.lean_max_m
        # real ground: the sensed base twist low-passed (its noise would reach every task and the welds' damping)
        self._twist = TwistFilter(s.base_velocity_filter_hz) \
            if self._real_ground and s.base_velocity == "filtered" else None
        # real ground: the supported part of the stance sole, from the foot's turn and its sensed CoP (foothold.py)
        self._footholds = FootholdTracker(self.model, self.sole, s) \
            if self._real_ground and s.footholds else None
        # real ground: a trailing foot that its toe cannot carry held flat on its heel box (trail.py)
        self._trail = FlatTrail(hm, self.traj, s, self._footholds, self.theta0)

    def _reference_time(self, obs: Observation) -> float:
        """The time at which the references are read, s: the plan's clock ``obs.t - obs.plan_delay`` (``time_shift``
        on), so that every reference (hip plan, swing path, toe-off) waits for a late touchdown.  On real ground a
        touchdown is sensed, not scheduled: a foot that lands 0.07 s late would otherwise start the next swing 0.07 s
        into its path (the swing foot lags its reference by ~1 cm and is kicked toward it, rocking the stance foot)
        and the hip plan would move on to a foot that is not down yet.  The phase selector keeps that delay (it also
        ends double supports on the same clock): only touchdowns count, and early ones do not move the plan forward."""
        return obs.t - obs.plan_delay if self.settings.time_shift else obs.t

    def run_info(self) -> dict:
        """For the run's summary: calls, calls whose contact constraints had to be relaxed, steps adjusted, the
        stances found partly supported (foot, toe box loaded, cuts as [time s, sole axis, bound m]), and the external
        force estimate (N, world x and y) and the lean (m) at the end."""
        out = {"balance_calls": self.calls, "balance_relaxed_cop": self.relaxed_cop,
               "balance_relaxed_all": self.relaxed_all}
        if self._steps is not None:
            out["balance_steps_adjusted"] = self._steps.adjusted
        if self._footholds is not None:   # the stances whose sole was found partly supported
            out["balance_partial_footholds"] = [
                {"foot": h.foot, "toe_loaded": h.toe_loaded, "cuts": [[t, axis, bound] for t, axis, bound in h.cuts]}
                for h in self._footholds.history]
        if self.dcm is not None and self.dcm.force is not None:   # the last estimate of the external force
            out["balance_external_force_N"] = [float(x) for x in self.dcm.force.force]
            out["balance_lean_m"] = [float(x) for x in self.dcm.lean]
        return out

    @property
    def _steps(self):
        """The DCM feedback's step adjustment (:class:`.steps.StepAdjuster`), or None (the hip PD, or none)."""
        return self.dcm.steps if self.dcm is not None else None

    def plan_jump(self, k: int) -> float:
        """How far (s) the plan's clock moves on at the touchdown ending single support k: the time step timing
        gained in that swing, up to ``step_max_jump_s`` (:meth:`.steps.StepAdjuster.plan_jump`); 0 without it."""
        return 0.0 if self._steps is None else self._steps.plan_jump(k)

    def swing_landing(self, k: int) -> np.ndarray | None:
        """Where single support k's swing lands (world toe point, m) when its foothold moved, else None."""
        return None if self._steps is None else self._steps.landing(k)

    # ------------------------------------------------------------------ one call
    def __call__(self, obs: Observation) -> Command:
        self.calls += 1
        if self._twist is not None:
            obs = obs.with_velocity(self._twist(obs.t, obs.v))
        k, phase, q, v = obs.k, obs.phase, obs.q, obs.v
        s = self.settings
        kin_data = None
        if self._stage is not None:
            # the compiled path's kinematics first: the QP's Jacobians, M and h, and the DCM's CoM read from them
            kin_data = self._kin_data
            pin.computeJointJacobiansTimeVariation(self.model, kin_data, q, v)
            pin.crba(self.model, kin_data, q)
            pin.nonLinearEffects(self.model, kin_data, q, v)
        flat = self._trail.contacts(obs, self._reference_time(obs), kin_data)
        tg = self._targets(obs, kin_data, flat is not None)
        # each flat foot (main body welded, toe locked) carries two ground wrenches, on its heel box and on its toe
        # box (see the module docstring); the box rows and weights of this phase
        contacts = phase.contacts if flat is None else flat[0]
        welds = contacts.welds
        key = (phase, flat is not None)
        kinds = self._box_kinds.get(key)
        if kinds is None:
            locks = contacts.locks
            kinds = self._box_kinds[key] = np.array(
                [0 if f in _FOOT_OF_MAIN and FOOT_SPECS[_FOOT_OF_MAIN[f]].toe_joint in locks else
                 1 if f in _TOE_FRAMES else 2 for f in welds], dtype=np.int64)
        unload = np.zeros(len(welds))   # double support: the trailing foot's normal force weighted w_unload u^2
        if phase.is_double_support and s.w_unload > 0.0:
            info = self.traj.phases[k]
            u = min(1.0, max(0.0, (tg.t - info.t_start) / info.duration))
            for i in range(1, len(welds)):     # the support foot's weld first (phases.py), the trailing foot's next
                unload[i] = s.w_unload * u * u
        hold = None
        if self._footholds is not None and obs.anchors is not None:   # real ground (foothold.py)
            hold = self._footholds.update(obs.t, phase.support_foot, obs.anchors, q, kin_data, obs.foot_wrenches)
        tables = self.boxes.tables(phase.is_double_support, hold, None if flat is None else flat.held)
        build = self._qp_compiled if self._stage is not None else self._qp_reference
        G, g, C, lo, ne, cop_rows, M, Tx, Jc, X, h, kin = build(obs, tg, kinds, tables, unload, flat)
        nv, m = self.nv, Jc.shape[0]

        # actuator limits |T| <= limit for the components linear in tau (T = P tau, tau = Tx x + h).  They rarely
        # bind (the toes' 30 N m), so by default the QP is first solved without them; its optimum is the full QP's
        # whenever it satisfies them (a relaxation's optimum that is feasible for the full problem is optimal for
        # it), else the QP is solved again with them.  44 fewer rows make DAQP's set-up (a factorisation over every
        # row) cheaper, and the component map is not needed
        x = None
        if s.lazy_torque_limits:
            x, level = self._solve(G, g, C, lo, ne, cop_rows)
            a, lam, tau, T_cmd, over = self._finish(x, M, h, Jc, q, v, kin)
            if over:
                x = None
        if x is None:
            self.torque_rows += 1
            P, _ = self.act.component_map(q, kin[0])
            P, lim = P[self._exact], self._exact_limits
            PT = P[:, 6:] @ Tx
            Ph = P[:, 6:] @ h[6:]
            x, level = self._solve(G, g, np.vstack([C, -PT, PT]), np.concatenate([lo, Ph - lim, -Ph - lim]), ne,
                                   np.concatenate([cop_rows, np.zeros(2 * len(lim), dtype=bool)]))
            a, lam, tau, T_cmd, _ = self._finish(x, M, h, Jc, q, v, kin)
        if self._twist is not None:
            self._twist.acc = a[:6]       # the base twist filter's prediction for the next call
        if self._inside:          # the compiled finish checked the limits: nothing to clip (the usual case)
            T_sat, sat = T_cmd.copy(), _NO_SATURATION
        else:
            T_sat, sat = self.act.saturate(T_cmd)
        extra = {"balance_level": level, "box_wrenches": BoxWrenches(x, X, kinds, welds, nv, m),
                 "flat_trail": flat is not None}
        if sat is not _NO_SATURATION and sat.any():
            B = self.act.torque_map(q, kin[0])
            tau = tau + B @ (T_sat - T_cmd)
            tau[:6] = 0.0
            return Command(tau=tau, T=T_sat, T_cmd=T_cmd, saturated=sat, extra=extra)
        if self._log is not None:
            # what the weld engine logs at a stage (``stage.StageOutput`` layout): the compiled path does not leave
            # the engine's shared Pinocchio data at this state, as the reference path's prepare does
            extra["kernel_log"] = self._log
        return Command(tau=tau, T=T_sat, T_cmd=T_cmd, saturated=sat, theta_ddot_cmd=self._thdd,
                       motion=(a, lam), motion_model=self.weld, extra=extra)

    def _targets(self, obs: Observation, kin_data: pin.Data | None = None, flat: bool = False) -> Targets:
        """The references of this call on the plan's clock: the hip's (through the DCM law, which measures the
        state: ``kin_data`` holds its forward kinematics when computed already), and the swing foot's (its
        feed-forward ramped in, the landing depth and search on real ground) or the trailing heel's lift in double
        support."""
        s = self.settings
        k, phase = obs.k, obs.phase
        t = self._reference_time(obs)   # the plan's clock: it waits for a late touchdown
        traj = self.traj
        # the package's own trajectories answer the hip's two queries in one evaluation and the toe's velocity
        # alone (the same numbers); any other (a user's, or a wrapper overriding a query) through the interface
        own = type(traj) in _OWN_TRAJECTORIES
        if own:
            tg = Targets(t=t, hip=traj.hip_targets(k, t))
        else:
            p_ref, v6_ref, R_ref = traj.hip_reference(k, t)
            tg = Targets(t=t, hip=(p_ref, v6_ref, R_ref, traj.hip_acceleration(k, t)))
        if self.dcm is not None:       # the hip task realises the DCM law (dcm.py) instead of its own PD
            tg.hip = self.dcm.hip_targets(tg.hip, traj.com_targets(k, t), k, t, obs.q, obs.v, kin_data,
                                          (obs.t, obs.foot_wrenches))
        info = traj.phases[k]
        if info.swing_foot is not None:
            steps = self._steps
            t_sw, rate = steps.swing_clock(k, t) if steps is not None else (t, 1.0)
            tg.swing = swing_targets(traj, s, k, t, info.swing_foot, self._real_ground, own, t_sw, rate)
            if steps is not None:    # a moved foothold (steps.py)
                tg.swing = steps.swing_target(k, tg.swing)
        elif phase.is_double_support and not flat:
            # the trailing foot, held by its toe: lift its heel (toe-off) so that only the toe part touches, as the
            # contact model (toe weld) assumes; on real ground a flat trailing foot would carry load on its heel
            # the ramp starts when this double support does: its planned start, or earlier after an early touchdown
            # (the plan's clock waits for a late one, not for an early one)
            if self._dsp_k != k:
                toe_off = self._trail.toe_off(k)     # a lead-in held flat: from its toe-off's start
                self._dsp_k, self._dsp_t0 = k, min(t, info.t_start) if toe_off is None else toe_off
            x = min(1.0, max(0.0, (t - self._dsp_t0) / min(info.duration, s.heel_lift_time_s)))
            trail = other_foot(phase.support_foot)
            # the lift is the main body's pitch about the toe body's y axis, -(toe joint angle): a toe that stood
            # bent on something (foothold.py) starts from its bend, not from a main body parallel to the toe box
            bend = self._footholds.toe_bend(trail) if self._footholds is not None else 0.0
            tg.heel = (trail, -bend + s.heel_lift_rad * x * x * (3.0 - 2.0 * x))
        return tg

    def _qp_reference(self, obs: Observation, tg: Targets, kinds: np.ndarray, tables: BalanceTables,
                      unload: np.ndarray, flat: FlatContacts | None = None) -> tuple:
        """The QP with Pinocchio's frame quantities and :func:`qp_numpy` (the reference of :meth:`_qp_compiled`),
        on the phase's contacts or ``flat``'s (:mod:`.trail`).  Returns :func:`qp_numpy`'s outputs, the
        constraint rows, X per flat foot, h and the Data holding the kinematics."""
        s = self.settings
        k, phase, q, v = obs.k, obs.phase, obs.q, obs.v
        model, d = self.model, self.dyn.data
        contacts, anchors = (phase.contacts, obs.anchors) if flat is None else (flat.contacts, flat.anchors)
        rows = self.dyn.prepare(contacts, anchors, q, v)   # kinematics, Jacobians, M (upper), nle
        pin.updateFramePlacements(model, d)
        A, b, w = self._task_rows(tg)                          # task Jacobians (rows x nv), targets, weights
        r = [0]                                                # the next free row of A, b, w

        def task(J: np.ndarray, acc_des: np.ndarray, drift: np.ndarray, wt: float) -> None:
            i = r[0]
            j = i + J.shape[0]
            A[i:j] = J
            b[i:j] = acc_des - drift
            w[i:j] = wt
            r[0] = j

        # Body-17 CoM and orientation
        p_ref, v6_ref, R_ref, a6_ref = tg.hip
        f = self.fid["Pc_17"]
        kp, kd = pd(s.hip_omega)
        task(pin.getFrameJacobian(model, d, f, LWA)[:3],
             a6_ref[:3] + kp * (p_ref - d.oMf[f].translation)
             + kd * (v6_ref[:3] - pin.getFrameVelocity(model, d, f, LWA).linear),
             pin.getFrameClassicalAcceleration(model, d, f, LWA).linear, s.w_hip)
        f = self.fid["O_17"]
        kp, kd = pd(s.trunk_omega)
        task(pin.getFrameJacobian(model, d, f, LWA)[3:],
             a6_ref[3:] + kp * pin.log3(R_ref @ d.oMf[f].rotation.T)
             + kd * (v6_ref[3:] - pin.getFrameVelocity(model, d, f, LWA).angular),
             pin.getFrameAcceleration(model, d, f, LWA).angular, s.w_trunk)
        kp, kd = pd(s.swing_omega)
        if tg.swing is not None:
            foot, pt, v6, Rr, a_ff, xr = tg.swing
            fpt = self.fid[TOE_POINT_FRAME[foot]]
            ftoe = self.fid[FOOT_SPECS[foot].toe_frame]
            task(pin.getFrameJacobian(model, d, fpt, LWA)[:3],
                 a_ff[:3] + kp * (pt - d.oMf[fpt].translation)
                 + kd * (v6[:3] - pin.getFrameVelocity(model, d, fpt, LWA).linear),
                 pin.getFrameClassicalAcceleration(model, d, fpt, LWA).linear, s.w_swing)
            task(pin.getFrameJacobian(model, d, ftoe, LWA)[3:],
                 a_ff[3:] + kp * pin.log3(Rr @ d.oMf[ftoe].rotation.T)
                 + kd * (v6[3:] - pin.getFrameVelocity(model, d, ftoe, LWA).angular),
                 pin.getFrameAcceleration(model, d, ftoe, LWA).angular, s.w_swing)
            # the swing foot's main body at the same orientation: a flat foot (toe joint straight) lands flat.  It
            # left the ground with its heel lifted (the double support's toe-off): the reference starts there and
            # returns to flat over heel_return_time_s (a step back to flat would kick the stance foot: on real
            # ground it rocked by 2-2.5 deg at every lift-off)
            fmain = self.fid[FOOT_SPECS[foot].main_frame]
            Rm, wm_ref, am_ff = Rr, v6[3:], a_ff[3:]
            if self._lift_k != k:
                # the heel lift the foot left the ground with (main body pitched about the toe body's y axis).  On
                # welds the toe-off reaches heel_lift_rad; on real ground the loaded heel box holds it back (sim 1:
                # 2.5 deg of 6.9), and a reference starting at the full lift kicked the stance foot at lift-off
                Rrel = d.oMf[ftoe].rotation.T @ d.oMf[fmain].rotation
                self._lift_k = k
                self._lift0 = min(max(math.atan2(Rrel[0, 2], Rrel[0, 0]), 0.0), s.heel_lift_rad)
            if xr < 1.0 and self._lift0 > 0.0:
                lift0 = self._lift0
                ang = lift0 * (1.0 - smoothstep(xr))
                dang = -lift0 * 6.0 * xr * (1.0 - xr) / s.heel_return_time_s
                ddang = -lift0 * 6.0 * (1.0 - 2.0 * xr) / s.heel_return_time_s ** 2
                Rm = Rr @ rot_y(ang)
                axis = Rr[:, 1]                       # the toe body's pitch axis, world
                wm_ref = v6[3:] + dang * axis
                am_ff = a_ff[3:] + ddang * axis
            task(pin.getFrameJacobian(model, d, fmain, LWA)[3:],
                 am_ff + kp * pin.log3(Rm @ d.oMf[fmain].rotation.T)
                 + kd * (wm_ref - pin.getFrameVelocity(model, d, fmain, LWA).angular),
                 pin.getFrameAcceleration(model, d, fmain, LWA).angular, s.w_swing)
        elif tg.heel is not None:
            foot, ang = tg.heel
            ftoe, fmain = self.fid[FOOT_SPECS[foot].toe_frame], self.fid[FOOT_SPECS[foot].main_frame]
            R_ref = d.oMf[ftoe].rotation @ rot_y(ang)
            task(pin.getFrameJacobian(model, d, fmain, LWA)[3:],
                 kp * pin.log3(R_ref @ d.oMf[fmain].rotation.T)
                 - kd * pin.getFrameVelocity(model, d, fmain, LWA).angular,
                 pin.getFrameAcceleration(model, d, fmain, LWA).angular, s.w_swing)
        # posture (thesis joint angles toward the initial ones)
        kp, kd = pd(s.posture_omega)
        i = r[0]
        A[i:] = self._Jpost
        theta0 = self.theta0 if flat is None else flat.theta0
        b[i:] = kp * (theta0 - self.hm.theta_from_q(q)) - kd * (self._Jpost @ v)
        w[i:] = self._w_joint
        splits = self._splits(rows, model, d)
        ns = len(splits)
        X = np.array([sp[2] for sp in splits]).reshape(ns, 6, 6)
        h = d.nle.copy()
        split = (np.array([sp[0] for sp in splits], dtype=np.int64), np.array([sp[1] for sp in splits], dtype=np.int64),
                 X, np.array([sp[3] for sp in splits]).reshape(ns, 6))
        out = qp_numpy(A, w, b, d.M, h, rows.J, rows.rhs_shift, rows.n_weld_rows, kinds, split, tables, unload)
        return out + (rows.J, X, h, (d, None, 0.0, 0.0, None))

    def _qp_compiled(self, obs: Observation, tg: Targets, kinds: np.ndarray, tables: BalanceTables,
                     unload: np.ndarray, flat: FlatContacts | None = None) -> tuple:
        """:meth:`_qp_reference` in one compiled call (:func:`.compiled.balance_stage`): Pinocchio has computed the
        joint Jacobians and their time variation, M and h (:meth:`__call__`); the kernel the placements, frame
        motions, constraint rows, task rows and the QP."""
        s = self.settings
        k, phase, q, v = obs.k, obs.phase, obs.q, obs.v
        d = self._kin_data
        h = d.nle.copy()
        st = self._stage
        tgt = self._tgt
        pack_hip(tgt, *tg.hip)
        if tg.swing is not None:
            foot, pt, v6, Rr, a_ff, xr = tg.swing
            mode = 1
            fi = st.swing_frames[foot]
            pack_swing(tgt, pt, v6, Rr, a_ff, xr, s.heel_return_time_s, self._lift0 if self._lift_k == k else -1.0)
        elif tg.heel is not None:
            foot, ang = tg.heel
            mode = 2
            fi = st.heel_frames[foot]
            tgt[T_HEEL_ANGLE] = ang
        else:
            mode, fi, foot = 0, st.no_frames, None
        state = State(q, v, d.J, d.dJ, d.M, h)
        need = st.need[(mode, foot)]
        if flat is None:
            contact, anchor, split = st.contacts[phase], st.support.anchor(phase, obs.anchors), st.split_toe[phase]
        else:
            contact, split = st.flat_contacts[phase], st.flat_split_toe[phase]
            # the trailing main body is welded: its placement and motion are read (the heel task's frames)
            need = st.need[(2, other_foot(phase.support_foot))]
            welds, lock = flat.contacts.welds, flat.contacts.locks[0]
            Ms = [flat.anchors.placements[f] for f in welds]
            anchor = Anchor(np.array([M.rotation for M in Ms]), np.array([M.translation for M in Ms]),
                            float(flat.anchors.joint_positions[lock]))
        coords = st.coords if flat is None else st.coords._replace(theta0=flat.theta0)
        G, g, C, lo, ne, cop, M, Tx, Jc, X, lift0, pos_err, ori_err = balance_stage(
            state, st.tree.record, coords, st.work, contact, anchor, (mode, fi, need, tgt), tables, (kinds, split),
            unload)
        if mode == 1:
            self._lift_k, self._lift0 = k, lift0
        return G, g, C, lo, ne, cop, M, Tx, Jc, X, h, (d, st, pos_err, ori_err, state)

    def _finish(self, x: np.ndarray, M: np.ndarray, h: np.ndarray, Jc: np.ndarray, q: np.ndarray, v: np.ndarray,
                kin: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(a, lam, tau, T_cmd) of a QP solution: tau = M a + h - Jc^T lam (base rows zero) and its thesis torques."""
        d, st, pos_err, ori_err, state = kin
        if st is not None:
            a, lam, tau, T, self._log, self._thdd, over, self._inside = balance_finish(
                x, M, Jc, state, st.work, st.tree.record, st.coords, st.actuators(self.act.limits), pos_err, ori_err,
                st.bounded, self._exact_limits)
            return a, lam, tau, T, over
        nv, m = self.nv, Jc.shape[0]
        a, lam = x[:nv], x[nv:nv + m]
        tau = M @ a + h - Jc.T @ lam
        tau[:6] = 0.0
        self._log = None
        self._inside = False      # (unknown: Actuators.saturate decides)
        self._thdd = self._Jpost @ a
        T = self.act.thesis_torques(q, v, a, tau, kin_data=d)
        return a, lam, tau, T, bool(np.any(np.abs(T[self._exact]) > self._exact_limits))

    def _task_rows(self, tg: Targets) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Work buffers (A (rows x nv), b (rows,), w (rows,)) for one call's tasks, every row written by the call:
        hip 3 + trunk 3, the swing foot's 9 (single support) or the trailing heel's 3 (double support with a
        toe-off), posture 26.  Kept per row count (reused across calls: no array is allocated per task)."""
        n = 6 + (9 if tg.swing is not None else 3 if tg.heel is not None else 0) + 26
        buf = self._task_buffers.get(n)
        if buf is None:
            buf = self._task_buffers[n] = (np.empty((n, self.nv)), np.empty(n), np.empty(n))
        return buf

    # ------------------------------------------------------------------ contact constraints
    def _splits(self, rows, model, d) -> list[tuple[int, int, np.ndarray, np.ndarray]]:
        """Per flat foot: (its weld's index, its toe lock's row in lam, X (6 x 6: a toe-frame wrench at the toe
        frame's origin as a main-frame wrench at the main frame's origin), j_toe (6,: the toe joint's column of the
        toe frame's LOCAL Jacobian))."""
        out = []
        welds, locks = rows.contacts.welds, list(rows.contacts.locks)
        for i, frame in enumerate(welds):
            foot = _FOOT_OF_MAIN.get(frame)
            if foot is None or FOOT_SPECS[foot].toe_joint not in locks:
                continue
            k = locks.index(FOOT_SPECS[foot].toe_joint)
            ftoe = self.fid[FOOT_SPECS[foot].toe_frame]
            rel = d.oMf[self.fid[frame]].actInv(d.oMf[ftoe])
            R, p = rel.rotation, rel.translation
            X = np.zeros((6, 6))
            X[:3, :3] = R
            X[3:, 3:] = R
            X[3:, :3] = pin.skew(p) @ R
            jt = pin.getFrameJacobian(model, d, ftoe, pin.ReferenceFrame.LOCAL)[:, int(rows.lock_v[k])]
            out.append((i, rows.n_weld_rows + k, X, jt))
        return out

    def _solve(self, G, g, C, lo, ne, cop_rows) -> tuple[np.ndarray, int]:
        """min 1/2 x^T G x - g^T x  s.t.  C[:ne] x = lo[:ne], C[ne:] x >= lo[ne:] (``cop_rows`` flags the CoP rows of
        the inequalities) by DAQP (a dual active-set method for small dense QPs, exact to its tolerances); relaxed
        (CoP rows dropped, then every inequality) when DAQP reports no optimum (an infeasible set of constraints: the
        state is beyond what the soles can carry)."""
        key = (ne, len(lo))
        bounds = self._bounds.get(key)
        if bounds is None:      # DAQP's row kinds and the upper bounds (none on the inequalities), per row counts
            sense = np.zeros(len(lo), dtype=np.int32)
            sense[:ne] = _DAQP_EQUALITY
            bounds = self._bounds[key] = (sense, np.full(len(lo), _DAQP_INF))
        sense_all, hi_all = bounds
        hi_all[:ne] = lo[:ne]
        f = -g
        x, _, flag, _ = self._daqp(G, f, C, hi_all, lo, sense_all)
        if flag == _DAQP_OPTIMAL:        # the usual case: every row kept
            return np.asarray(x, dtype=float), 0
        for level in (1, 2):
            keep = ~cop_rows if level == 1 else np.zeros(len(cop_rows), bool)
            rows = np.concatenate([np.ones(ne, dtype=bool), keep])
            x, _, flag, _ = self._daqp(G, f, C[rows], hi_all[rows], lo[rows], sense_all[rows])
            if flag != _DAQP_OPTIMAL:
                continue
            if level == 1:
                self.relaxed_cop += 1
            else:
                self.relaxed_all += 1
            return np.asarray(x, dtype=float), level
        raise ControllerError("balance controller: the QP has no solution even without contact inequalities "
                              "(dependent constraint rows?)")
