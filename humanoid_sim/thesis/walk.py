"""``walk.py --engine thesis``: a whole walk on the NumPy oracle, as the thesis's Simulink model ran it.

State: the thesis joint angles theta and rates theta_dot (26 each, eq. 4.1 order, rad and rad/s) plus the
placement data of the toe bodies held on the ground (``fixed``: C^(0,1) / C^(0,2) and the toe points, world
frame), which is the chain root of section 4.1.1 (table of errata section 6.1):

| phase  | chain root (supplied)          | other supplied data            | toe joint locked |
|--------|--------------------------------|--------------------------------|------------------|
| LFFSSP | left toe body 2 (P_tpL, C^0,2)  | --                             | theta4           |
| RFFDSP | right toe body 1 (just landed) | left toe body 2 (trailing)     | theta3           |
| RFFSSP | right toe body 1               | --                             | theta3           |
| LFFDSP | left toe body 2 (just landed)  | right toe body 1 (trailing)    | theta4           |

The root switches to the landed foot at touchdown; its toe data are the actual landed placement computed through
the single-support chain at that instant (thesis L4024, "TPRF/TPLF").  Lift-off changes nothing but drops the
trailing foot's data.

Per ode3 stage (Bogacki-Shampine, ``integrator.TABLEAUS``, integrated directly in R^26 x R^26):

1. (q, v) for Pinocchio: ``hm.q_on_foot`` on the root toe body, v from theta_dot plus the base twist that keeps
   the root toe body at rest;
2. command accelerations of thesis 5.1 (:class:`humanoid_sim.command.CommandAccelerations`, shared with the fast
   path) at the references of the current phase;
3. the oracle's computed torque (5.2: SSP exact, DSP weighted minimum norm with the scenario's W_act);
4. saturation of T (``Actuators.saturate``, errata section 7 limits);
5. the oracle's 122 x 122 direct dynamic solution with the saturated T -> theta_ddot and F.

Phase selection (6.1.1) at step boundaries with the same rules as the fast path (``phases.ssp_should_end`` /
``dsp_should_end``); touchdown applies the oracle's velocity reset (eqs. 4.97 / 4.100, the scenario's W_adj) and
tells the trajectory the landing (``traj.set_landing``).

Logged signals (``results.SIGNALS``): task quantities (hip CoM, C^(0,17), toe points, C^(0,1), C^(0,2)) from the
oracle's own kinematics; ``q`` / ``v`` from the Pinocchio conversion of step 1 (so the viewer works); ground
reactions F_0,k / M_0,k (k = 1..4) straight from the solution F (thesis convention: body frame k, moment about
CoM k); per-foot world wrenches (about the world origin) and CoP from those; ``tau`` = the generalized forces of
the joint moments of F (``thesis.joint_space.Q_from_F``) in Pinocchio's v order; ``drift_*`` = the position-
level closure mismatch between the two estimates of frame 17 in double support (the thesis enforces the closed
chain at acceleration level only, eqs. 4.85/4.86; zero in single support, where the root is exact by
construction); ``dynamics_residual`` = ||M theta_ddot + B - K F||_inf of the Newton-Euler rows (eq. 4.73).

Decisions where the thesis is silent:
- Only the thesis's touchdown law exists on the oracle; a scenario asking for ``impact_law: inelastic`` is
  refused at construction with :class:`ThesisWalkError`.
- Touchdown keeps theta (errata K-9: whether theta3/theta4 are reset to 0 is ambiguous); the landing tilt is
  logged in the phase record like the fast path does.
- W_act: ``controller.Wact_RFFDSP`` / ``Wact_LFFDSP`` of the scenario when present, else
  ``thesis.forces.default_w_act()`` (errata A-3 reconstruction).

Speed: every stage builds M and B from 27 kinematic passes (section 4.4) and solves a 122 x 122 system.  These
are small dense problems on which a multi-threaded BLAS only adds synchronisation; on the shared 2-core machine
the walk ran 2.5-5 x slower with OpenBLAS's default threads.  ``run`` therefore limits the OpenBLAS libraries
bundled with NumPy and SciPy to one thread for its duration (:func:`single_threaded_blas`, restored afterwards;
a no-op where those libraries are not found).  Measured on sim1: 6-8 s of wall time per simulated second
(2 shared cores), against 15-50 s with the default BLAS threads.
"""

from __future__ import annotations

import ctypes
import importlib
import time
from contextlib import contextmanager
from typing import Callable, Iterator

import numpy as np
import pinocchio as pin

from humanoid_sim.actuators import Actuators
from humanoid_sim.command import CommandAccelerations
from humanoid_sim.contact.wrenches import centre_of_pressure
from humanoid_sim.initial import initial_configuration
from humanoid_sim.integrator import TABLEAUS, Tableau
from humanoid_sim.model import HumanoidModel
from humanoid_sim.phases import Phase, SwitchThresholds
from humanoid_sim.results import SimLog
from humanoid_sim.scenario import Scenario
from humanoid_sim.selector import PhaseSelector, SimulationError
from humanoid_sim.simulate import BASIC, SimResult, Simulator, _unwrap_to, yaw_of
from humanoid_sim.thesis.dynamics import DynamicsError
from humanoid_sim.thesis.engine import ThesisEngine
from humanoid_sim.thesis.forces import N_F, default_w_act
from humanoid_sim.thesis.frames import PhaseError
from humanoid_sim.thesis.joint_space import Q_from_F
from humanoid_sim.thesis.kinematics import TOE_BODY, TOE_POINT, FootState, Kinematics, positions
from humanoid_sim.trajectory import ReferenceTrajectory

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
TOE_FRAME = {"R": "O_1", "L": "O_2"}
FOOT_BODIES = {"R": (1, 3), "L": (2, 4)}   # toe body, main body


def _openblas_thread_controls() -> list[tuple[Callable[[], int], Callable[[int], None]]]:
    """(get, set) thread-count functions of the OpenBLAS builds bundled with NumPy and SciPy that can be found
    (symbol names of the scipy-openblas wheels); empty if none."""
    found = []
    for module, names in (("numpy.linalg._umath_linalg", ("scipy_openblas_get_num_threads64_",
                                                          "scipy_openblas_set_num_threads64_")),
                          ("scipy.linalg._fblas", ("scipy_openblas_get_num_threads",
                                                   "scipy_openblas_set_num_threads"))):
        try:
            mod = importlib.import_module(module)
            lib = ctypes.CDLL(mod.__file__)
            get, set_ = getattr(lib, names[0]), getattr(lib, names[1])
        except (ImportError, OSError, AttributeError, TypeError):
            continue
        get.restype = ctypes.c_int
        set_.argtypes = [ctypes.c_int]
        found.append((get, set_))
    return found


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run the block with NumPy's / SciPy's OpenBLAS limited to one thread, then restore the thread counts."""
    controls = _openblas_thread_controls()
    saved = [get() for get, _ in controls]
    try:
        for _, set_ in controls:
            set_(1)
        yield
    finally:
        for (_, set_), n in zip(controls, saved):
            set_(max(int(n), 1))


class ThesisWalkError(ValueError):
    """The scenario asks for something the oracle engine does not implement (message names the setting)."""


def _w_act(controller_raw: dict, key: str) -> np.ndarray:
    """Diagonal of W_act (96,) for a DSP: the scenario's ``key`` if given, else the errata A-3 default."""
    if key not in controller_raw:
        return default_w_act()
    w = np.asarray(controller_raw[key], dtype=float).reshape(-1)
    if w.shape != (N_F,) or np.any(~(w > 0.0)):
        raise ThesisWalkError(f"controller.{key}: expected {N_F} positive weights (eq. 4.68 order), got "
                              f"shape {w.shape}, min {w.min() if w.size else 'n/a'}")
    return w


class ThesisSimulator:
    """Runs one scenario on the thesis oracle (:class:`humanoid_sim.thesis.ThesisEngine`).

    Same interface and output as :class:`humanoid_sim.simulate.Simulator`: attributes ``traj``, ``q0``, and
    ``run(t_end, progress) -> SimResult`` with a full :class:`humanoid_sim.results.SimLog`.  Slow on purpose
    (every matrix is built as the thesis builds it): 6-8 s of wall time per simulated second.
    """

    def __init__(self, hm: HumanoidModel, scenario: Scenario, engine: ThesisEngine | None = None) -> None:
        if scenario.simulation.impact_law != "thesis":
            raise ThesisWalkError(f"simulation.impact_law = {scenario.simulation.impact_law!r}: the thesis engine "
                                  "implements only the thesis's touchdown law (eqs. 4.97/4.100, 'thesis')")
        if scenario.simulation.method not in TABLEAUS:
            raise ThesisWalkError(f"simulation.method = {scenario.simulation.method!r}: expected one of "
                                  f"{sorted(TABLEAUS)}")
        self.hm = hm
        self.sc = scenario
        self.model = hm.model
        self.data = hm.model.createData()
        self.engine = engine if engine is not None else ThesisEngine(hm.spec)
        self.params = self.engine.params
        self.traj = ReferenceTrajectory(scenario.path)
        self.q0 = initial_configuration(hm, scenario.path)
        self.theta0 = hm.theta_from_q(self.q0)
        self.cmd = CommandAccelerations(hm, scenario.controller, theta0=self.theta0)
        self.act = Actuators(hm)
        self.tableau: Tableau = TABLEAUS[scenario.simulation.method]
        sw = scenario.switch
        self.thresholds = SwitchThresholds(sw.toe_flat_height_m, sw.touchdown_tolerance_m,
                                           sw.min_horizontal_progress_fraction, sw.dsp_hip_distance_m,
                                           sw.dsp_overtime_fraction)
        raw = scenario.controller.raw
        self.W_act = {"RFFDSP": _w_act(raw, "Wact_RFFDSP"), "LFFDSP": _w_act(raw, "Wact_LFFDSP")}
        self.fid = {n: hm.frame_id(n) for n in ("O_1", "O_2", "P_tpR", "P_tpL")}
        self.E = np.zeros((self.model.nv, 26))   # joint part of v from theta_dot (v = sign * theta_dot)
        self.E[hm.theta_v_idx, np.arange(26)] = hm.theta_sign
        self.stage_evals = 0

    # ------------------------------------------------------------------ thesis state <-> pinocchio
    def pin_state(self, phase: Phase, fixed: dict[str, FootState], theta: np.ndarray,
                  theta_dot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio (q, v) of the thesis state: the root toe body (the phase's support foot) at its supplied
        placement and at rest (base twist solved from its LOCAL_WORLD_ALIGNED Jacobian)."""
        root = phase.support_foot
        st = fixed[root]
        q = self.hm.q_on_foot(theta, root, st.P_tp, st.C)
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        J = pin.getFrameJacobian(self.model, self.data, self.fid[TOE_FRAME[root]], LWA)
        v = self.E @ np.asarray(theta_dot, dtype=float)
        v[:6] = -np.linalg.solve(J[:, :6], J @ v)
        return q, v

    # ------------------------------------------------------------------ one stage
    def evaluate(self, k: int, phase: Phase, fixed: dict[str, FootState], t: float, theta: np.ndarray,
                 theta_dot: np.ndarray) -> dict:
        """Command accelerations (5.1) -> computed torque (5.2) -> saturation -> 122 x 122 solution at a state.

        Returns theta_ddot (rad/s^2), the solution F (eq. 4.68), T_cmd / T (N m, eq. 4.69 order), the saturation
        mask, the command accelerations, the dynamic terms and the Pinocchio (q, v)."""
        self.stage_evals += 1
        name = phase.value
        q, v = self.pin_state(phase, fixed, theta, theta_dot)
        # Simulator._references reads only self.traj and self.sc.controller (see the report's refactor note)
        ref_a, ref_b = Simulator._references(self, k, t)  # type: ignore[arg-type]
        thdd_c = self.cmd.compute(name, q, v, ref_a, ref_b)
        terms = self.engine.dynamic_terms(name, theta, theta_dot, fixed)
        ct = self.engine.computed_torque(name, theta, theta_dot, thdd_c, fixed,
                                         W_act=self.W_act.get(name), terms=terms)
        T_sat, sat = self.act.saturate(ct.T)
        fd = self.engine.forward_dynamics(name, theta, theta_dot, T_sat, fixed, terms=terms)
        return {"thdd": fd.theta_ddot, "fd": fd, "terms": terms, "thdd_c": thdd_c, "T_cmd": ct.T, "T": T_sat,
                "sat": sat, "q": q, "v": v}

    def _step(self, f: Callable[[float, np.ndarray, np.ndarray, int], np.ndarray], t: float, theta: np.ndarray,
              theta_dot: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        """One explicit RK step in R^26 x R^26 with the scenario's tableau (ode3: Simulink's Bogacki-Shampine)."""
        tab = self.tableau
        rates: list[np.ndarray] = []
        accs: list[np.ndarray] = []
        for i, ci in enumerate(tab.c):
            th_i = theta + h * sum((aij * r for aij, r in zip(tab.a[i], rates)), np.zeros(26))
            thd_i = theta_dot + h * sum((aij * a for aij, a in zip(tab.a[i], accs)), np.zeros(26))
            rates.append(thd_i)
            accs.append(f(t + ci * h, th_i, thd_i, i))
        theta_new = theta + h * sum(bi * r for bi, r in zip(tab.b, rates))
        theta_dot_new = theta_dot + h * sum(bi * a for bi, a in zip(tab.b, accs))
        return theta_new, theta_dot_new

    # ------------------------------------------------------------------ the run
    def initial_fixed(self, phase: Phase) -> dict[str, FootState]:
        """Supplied toe-body data at the start: the support foot's toe body where the initial posture puts it."""
        pin.framesForwardKinematics(self.model, self.data, self.q0)
        foot = phase.support_foot
        M = self.data.oMf[self.fid[TOE_FRAME[foot]]]
        p = self.data.oMf[self.fid["P_tp" + foot]].translation
        return {foot: FootState(M.rotation.copy(), p.copy())}

    def run(self, t_end: float | None = None, progress: Callable[[float, int], None] | None = None) -> SimResult:
        """Simulate until every planned phase is done, ``t_end`` (s), the scenario's end time, or a failure.

        The log keeps everything up to a failure; ``SimResult.reason`` says how the run ended."""
        with single_threaded_blas():
            return self._run(t_end, progress)

    def _run(self, t_end: float | None, progress: Callable[[float, int], None] | None) -> SimResult:
        sc, traj = self.sc, self.traj
        h = sc.simulation.step_s
        n_phases = traj.n_phases
        nominal_end = traj.phases[-1].t_end
        t_stop = t_end if t_end is not None else (sc.simulation.t_end_s or np.inf)
        phase = Phase(traj.phases[0].name)
        fixed = self.initial_fixed(phase)
        theta = self.theta0.copy()
        theta_dot = np.zeros(26)
        t = 0.0
        log = SimLog()
        kin = positions(phase.value, theta, fixed, self.params)
        sel = PhaseSelector(traj, self.thresholds, sc.simulation, self._toe(kin, traj.phases[0].swing_foot))
        yaw_prev = {"hip": yaw_of(self.hm.spec.C0), "hip_ref": yaw_of(self.hm.spec.C0)}
        stage0: dict = {}
        completed, reason = False, ""
        steps = 0
        wall0 = time.perf_counter()

        def f(ts: float, th: np.ndarray, thd: np.ndarray, stage: int) -> np.ndarray:
            sel.check_stage(ts, th, thd, stage)
            out = self.evaluate(sel.k, sel.phase, fixed, ts, th, thd)
            sel.check_acceleration(ts, out["thdd"])
            if stage == 0:
                stage0.clear()
                stage0.update(out)
            return out["thdd"]

        try:
            while True:
                if t >= t_stop - 1e-12:
                    reason = f"stopped at t = {t:.3f} s (requested stop time)"
                    break
                k, phase = sel.k, sel.phase
                th_new, thd_new = self._step(f, t, theta, theta_dot, h)
                self._log(log, k, phase, t, theta, theta_dot, fixed, stage0, yaw_prev)
                theta, theta_dot, t = th_new, thd_new, t + h
                steps += 1
                if progress is not None:
                    progress(t, k)
                finite = np.all(np.isfinite(theta))
                kin = positions(phase.value, theta, fixed, self.params) if finite else None
                hip = kin.P["c17"] if finite else np.full(3, np.nan)
                sel.check_state(t, theta, theta_dot, hip)
                swing = sel.info.swing_foot
                toe = kin.P[TOE_POINT[swing]] if swing is not None else None
                if not sel.should_switch(t, hip, toe):
                    continue
                sel.end_phase(t)
                if sel.is_last:
                    completed, reason = True, f"all {n_phases} phases completed at t = {t:.3f} s"
                    break
                if swing is not None:     # touchdown: SSP -> DSP
                    toe = toe.copy()
                    R_toe = kin.C[TOE_BODY[swing]].copy()
                    key = sel.record_touchdown(toe, R_toe)
                    if key not in sc.W_adj:
                        raise SimulationError(f"touchdown at t = {t:.3f} s: the scenario has no reset.{key}")
                    res = self.engine.touchdown_reset(phase.value, theta, theta_dot, fixed, sc.W_adj[key])
                    theta_dot = res.theta_dot
                    traj.set_landing(swing, k, toe, R_toe)
                    fixed = {**fixed, swing: FootState(R_toe, toe)}   # the landed toe body: the new chain root
                nxt_phase = phase.next
                fixed = {ft: fixed[ft] for ft in nxt_phase.stance_feet}   # lift-off drops the trailing toe's data
                sel.advance(t, self._toe(positions(nxt_phase.value, theta, fixed, self.params),
                                         traj.phases[k + 1].swing_foot))
        except (SimulationError, DynamicsError, PhaseError, np.linalg.LinAlgError) as exc:
            reason = str(exc) if isinstance(exc, SimulationError) else \
                f"{type(exc).__name__} at t = {t:.3f} s in {sel.where()}: {exc}"
        except KeyboardInterrupt:
            reason = f"interrupted by the user at t = {t:.3f} s"
        sel.close(t)
        records = sel.records
        return SimResult(log=log, phases=records, phases_planned=n_phases, completed=completed, reason=reason,
                         sim_time=t, wall_time=time.perf_counter() - wall0, steps=steps,
                         stage_evaluations=self.stage_evals, extra={"nominal_end": nominal_end, "engine": "thesis"})

    @staticmethod
    def _toe(kin: Kinematics, foot: str | None) -> np.ndarray | None:
        return None if foot is None else kin.P[TOE_POINT[foot]].copy()

    # ------------------------------------------------------------------ logging
    def _log(self, log: SimLog, k: int, phase: Phase, t: float, theta: np.ndarray, theta_dot: np.ndarray,
             fixed: dict[str, FootState], out: dict, yaw_prev: dict) -> None:
        """One row of every signal of ``results.SIGNALS`` at the start of a step (stage-0 outputs)."""
        kin = self.engine.kinematics(phase.value, theta, theta_dot, fixed)
        fd, terms = out["fd"], out["terms"]
        ref = self.traj.sample_global(t)
        ref_ctrl = self.traj.sample_global(t, k)
        R17 = kin.C[17]
        yaw = _unwrap_to(yaw_of(R17), yaw_prev["hip"])
        yaw_ref = _unwrap_to(yaw_of(ref.hip_R), yaw_prev["hip_ref"])
        yaw_prev["hip"], yaw_prev["hip_ref"] = yaw, yaw_ref
        bf = np.zeros((4, 3))
        bm = np.zeros((4, 3))
        for i in range(4):   # bodies 1, 2, 3, 4: F_0,k / M_0,k in frame k, moment about CoM k
            bf[i], bm[i] = fd.ground[i + 1]
        fw = np.zeros((2, 6))
        cop = np.full((2, 3), np.nan)
        contact = np.zeros(2, dtype=bool)
        for i, foot in enumerate(("R", "L")):
            f_w = np.zeros(3)
            n_w = np.zeros(3)   # about the world origin
            for b in FOOT_BODIES[foot]:
                fk = kin.C[b] @ fd.ground[b][0]
                f_w += fk
                n_w += kin.C[b] @ fd.ground[b][1] + np.cross(kin.P[f"c{b}"], fk)
            fw[i] = np.concatenate([f_w, n_w])
            cop[i] = centre_of_pressure(f_w, n_w)[0]
            contact[i] = foot in phase.stance_feet
        ftot = fw[:, :3].sum(axis=0)
        mtot = fw[:, 3:].sum(axis=0)
        zmp = np.full(3, np.nan)
        if ftot[2] > 1e-9:
            zmp = np.array([-mtot[1] / ftot[2], mtot[0] / ftot[2], 0.0])
        drift_p = drift_o = 0.0
        if phase.is_double_support:   # closed chain held at acceleration level only: position-level mismatch
            drift_p = float(np.linalg.norm(kin.P["c17fR"] - kin.P["c17fL"]))
            drift_o = float(np.linalg.norm(pin.log3(kin.C["17fR"].T @ kin.C["17fL"])))
        residual = float(np.max(np.abs(terms.M @ fd.theta_ddot + terms.B - terms.K @ fd.F)))
        tau = self.hm.tau_from_joint_torques(Q_from_F(kin, fd.F))
        log.append(
            t=t, phase=k, basic_phase=BASIC[phase], q=out["q"], v=out["v"], theta=theta, theta_dot=theta_dot,
            theta_ddot=fd.theta_ddot, theta_ddot_cmd=out["thdd_c"], T_cmd=out["T_cmd"], T=out["T"],
            saturated=out["sat"], tau=tau, hip_p=kin.P["c17"], hip_p_ref=ref.hip_p, hip_p_ctrl_ref=ref_ctrl.hip_p,
            hip_v=kin.V["c17"], hip_v_ref=ref.hip_v, hip_R=R17, hip_R_ref=ref.hip_R, hip_yaw=yaw,
            hip_yaw_ref=yaw_ref, toe_R_p=kin.P["tpR"], toe_R_p_ref=ref.toe_R_p, toe_L_p=kin.P["tpL"],
            toe_L_p_ref=ref.toe_L_p, foot_R_R=kin.C[1], foot_L_R=kin.C[2], body_force=bf, body_moment=bm,
            foot_wrench=fw, cop=cop, in_contact=contact, zmp=zmp, drift_position=drift_p,
            drift_orientation=drift_o, dynamics_residual=residual)


__all__ = ["ThesisSimulator", "ThesisWalkError"]
