"""The oracle engine (``walk.py --engine thesis``): a whole walk on the NumPy transcription of the thesis's
equations (:mod:`humanoid_sim.thesis`), as its Simulink model ran it.

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

1. (q, v) for Pinocchio (what a controller observes): ``hm.q_on_foot`` on the root toe body, v from theta_dot plus
   the base twist that keeps the root toe body at rest;
2. the oracle's dynamic terms M, B, K of the phase (section 4.4), offered to the controller as
   :class:`OracleModel` (the thesis controller's 5.2 computed torque: SSP exact, DSP weighted minimum norm with
   the scenario's W_act);
3. the controller (the stepping loop's, :mod:`humanoid_sim.sim.loop`), which returns the saturated T (or joint torques,
   converted to T by the actuator map);
4. the oracle's 122 x 122 direct dynamic solution with T -> theta_ddot and F.

Phase selection (6.1.1) is the stepping loop's; touchdown applies the oracle's velocity reset (eqs. 4.97 / 4.100,
the scenario's W_adj).

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
- A controller that returns joint torques only (no T) drives the oracle with T = B^-1 tau, B the actuator map of
  :meth:`humanoid_sim.robot.actuators.Actuators.torque_map` (T's components only, reactions held).

Speed: every stage builds M and B from 27 kinematic passes (section 4.4) and solves a 122 x 122 system.  These
are small dense problems on which a multi-threaded BLAS only adds synchronisation; with OpenBLAS's default
threads the walk runs several times slower (docs/notes/2026-11-26-code-measurements.md).  The engine therefore limits
the OpenBLAS libraries
bundled with NumPy and SciPy to one thread while it runs (:func:`single_threaded_blas`, restored afterwards;
a no-op where those libraries are not found).
"""

from __future__ import annotations

import ctypes
import importlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from humanoid_sim.dynamics.contact.wrenches import centre_of_pressure
from humanoid_sim.dynamics.integrator import TABLEAUS, Tableau
from humanoid_sim.engines.weld import BASIC, unwrap_to, yaw_of
from humanoid_sim.errors import InputError
from humanoid_sim.interfaces.controller import Command, Observation
from humanoid_sim.interfaces.engine import StepRow
from humanoid_sim.interfaces.log import SimLog
from humanoid_sim.interfaces.selector import PhaseSelector, SimulationError
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import Scenario
from humanoid_sim.thesis.dynamics import DynamicsError
from humanoid_sim.thesis.engine import ThesisEngine
from humanoid_sim.thesis.forces import N_F, default_w_act
from humanoid_sim.thesis.frames import PhaseError
from humanoid_sim.thesis.joint_space import Q_from_F
from humanoid_sim.thesis.kinematics import TOE_BODY, TOE_POINT, FootState, Kinematics, positions

ORACLE_ERRORS = (DynamicsError, PhaseError)
"""The oracle's own failures (a singular solve, a phase it does not know): the loop reports them as a failed run."""

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


class ThesisWalkError(InputError):
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



class OracleModel:
    """The oracle's constraint model at the stage the engine is evaluating, offered to controllers
    (``ControlContext.constraints``): the thesis's computed torque of 5.2 on the oracle's equations."""

    kind = "oracle"

    def __init__(self, engine: ThesisEngine, w_act: dict[str, np.ndarray]) -> None:
        self.engine = engine
        self.W_act = w_act
        self.current: tuple | None = None   # (phase name, theta, theta_dot, fixed, dynamic terms) of the stage

    def computed_torque(self, theta_ddot_cmd: np.ndarray) -> np.ndarray:
        """T (26,, N m) realising the command accelerations (rad/s^2) at the current stage (thesis 5.2)."""
        name, theta, theta_dot, fixed, terms = self.current
        return self.engine.computed_torque(name, theta, theta_dot, theta_ddot_cmd, fixed,
                                           W_act=self.W_act.get(name), terms=terms).T


class OracleRecord(NamedTuple):
    """The oracle engine's record of one step: the thesis state at its start (theta, theta_dot: 26 each, rad and
    rad/s), the held feet, and the first stage's outputs (a dict: forward dynamics, terms, command)."""

    theta: np.ndarray
    theta_dot: np.ndarray
    fixed: Any
    stage0: Any


class OracleEngine:
    """The whole walk on the thesis oracle (:class:`humanoid_sim.thesis.ThesisEngine`): see the module docstring.
    Slow on purpose: every matrix is built as the thesis builds it.

    Engine interface (:class:`humanoid_sim.interfaces.engine.Engine`) as :class:`humanoid_sim.engines.weld.WeldEngine`.
    """

    name = "thesis"
    errors = ORACLE_ERRORS

    def __init__(self, hm: HumanoidModel, scenario: Scenario, traj: ReferenceTrajectory,
                 engine: ThesisEngine | None = None) -> None:
        if scenario.gait.is_zmp:
            raise ThesisWalkError("gait.hip_reference = 'zmp_preview': the thesis engine runs only chapter 3's gait "
                                  "('thesis'); run the zmp_preview gait on the pinocchio engine")
        if scenario.simulation.impact_law != "thesis":
            raise ThesisWalkError(f"simulation.impact_law = {scenario.simulation.impact_law!r}: the thesis engine "
                                  "implements only the thesis's touchdown law (eqs. 4.97/4.100, 'thesis')")
        if scenario.simulation.method not in TABLEAUS:
            raise ThesisWalkError(f"simulation.method = {scenario.simulation.method!r}: expected one of "
                                  f"{sorted(TABLEAUS)}")
        self.hm = hm
        self.sc = scenario
        self.traj = traj
        self.model = hm.model
        self.data = hm.model.createData()
        self.engine = engine if engine is not None else ThesisEngine(hm.spec)
        self.params = self.engine.params
        self.act = Actuators(hm)
        self.tableau: Tableau = TABLEAUS[scenario.simulation.method]
        raw = scenario.controller.raw
        self.constraints = OracleModel(self.engine, {"RFFDSP": _w_act(raw, "Wact_RFFDSP"),
                                                     "LFFDSP": _w_act(raw, "Wact_LFFDSP")})
        self.fid = {n: hm.frame_id(n) for n in ("O_1", "O_2", "P_tpR", "P_tpL")}
        self.E = np.zeros((self.model.nv, 26))   # joint part of v from theta_dot (v = sign * theta_dot)
        self.E[hm.theta_v_idx, np.arange(26)] = hm.theta_sign
        self.theta = self.theta_dot = None
        self.fixed: dict[str, FootState] = {}
        self.phase: Phase | None = None
        self._kin: Kinematics | None = None
        self._blas = None

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

    def pin_acceleration(self, phase: Phase, q: np.ndarray, v: np.ndarray, theta_ddot: np.ndarray) -> np.ndarray:
        """Pinocchio's acceleration a (nv,) of the thesis accelerations at the state (q, v) of :meth:`pin_state`:
        the joint rows from ``theta_ddot`` (rad/s^2), the base rows from the root toe body staying at rest (its
        LOCAL spatial acceleration J a + dJ v = 0)."""
        model, data = self.model, self.data
        a = self.E @ np.asarray(theta_ddot, dtype=float)
        a[:6] = 0.0
        fid = self.fid[TOE_FRAME[phase.support_foot]]
        pin.forwardKinematics(model, data, q, v, a)
        drift = pin.getFrameAcceleration(model, data, fid, pin.ReferenceFrame.LOCAL).vector
        J = pin.computeFrameJacobian(model, data, q, fid, pin.ReferenceFrame.LOCAL)
        a[:6] = -np.linalg.solve(J[:, :6], drift)
        return a

    # ------------------------------------------------------------------ state
    def start(self, q0: np.ndarray, phase: Phase) -> None:
        """At rest at q0; the support foot's toe body is the chain root.  Limits NumPy's and SciPy's OpenBLAS to one
        thread until :meth:`close` (see the module docstring)."""
        self.theta = self.hm.theta_from_q(q0)
        self.theta_dot = np.zeros(26)
        self.phase = phase
        pin.framesForwardKinematics(self.model, self.data, q0)
        self.fixed = {}
        for foot in phase.stance_feet:   # the support foot's toe body (and a trailing toe's in double support)
            M = self.data.oMf[self.fid[TOE_FRAME[foot]]]
            p = self.data.oMf[self.fid["P_tp" + foot]].translation
            self.fixed[foot] = FootState(M.rotation.copy(), p.copy())
        if self._blas is None:
            self._blas = single_threaded_blas()
            self._blas.__enter__()

    def close(self) -> None:
        """Restore the BLAS thread counts changed by :meth:`start`."""
        if self._blas is not None:
            self._blas.__exit__(None, None, None)
            self._blas = None

    def state_vectors(self) -> tuple[np.ndarray, np.ndarray]:
        return self.theta, self.theta_dot

    # ------------------------------------------------------------------ one step
    def _T_of(self, q: np.ndarray, cmd: Command) -> np.ndarray:
        if cmd.T is not None:
            return cmd.T
        return np.linalg.solve(self.act.torque_map(q)[6:], cmd.tau[6:])   # tau = B T on the 26 joint rows

    def stage(self, control: Callable[[Observation], Command], k: int, phase: Phase, fixed: dict[str, FootState],
              t: float, theta: np.ndarray, theta_dot: np.ndarray, stage: int = 0) -> dict:
        """One stage at a thesis state: the Pinocchio state the controller observes, the oracle's dynamic terms,
        the controller's command, and the oracle's direct dynamic solution (``fd``) of its T."""
        name = phase.value
        q, v = self.pin_state(phase, fixed, theta, theta_dot)
        terms = self.engine.dynamic_terms(name, theta, theta_dot, fixed)
        self.constraints.current = (name, theta, theta_dot, fixed, terms)
        cmd = control(Observation(t, k, phase, q, v, None, stage))
        T = self._T_of(q, cmd)
        fd = self.engine.forward_dynamics(name, theta, theta_dot, T, fixed, terms=terms)
        return {"fd": fd, "terms": terms, "cmd": cmd, "T": T, "q": q, "v": v}

    def step(self, t: float, h: float, k: int, control: Callable[[Observation], Command],
             checks: PhaseSelector) -> OracleRecord:
        """One explicit RK step in R^26 x R^26 with the scenario's tableau (ode3: Simulink's Bogacki-Shampine);
        returns the step's log record (state at t and the stage-0 outputs)."""
        phase, fixed = self.phase, self.fixed
        stage0: dict = {}

        def f(ts: float, th: np.ndarray, thd: np.ndarray, stage: int) -> np.ndarray:
            checks.check_stage(ts, th, thd, stage)
            out = self.stage(control, k, phase, fixed, ts, th, thd, stage)
            checks.check_acceleration(ts, out["fd"].theta_ddot)
            if stage == 0:
                stage0.update(out)
            return out["fd"].theta_ddot

        tab = self.tableau
        theta, theta_dot = self.theta, self.theta_dot
        rates: list[np.ndarray] = []
        accs: list[np.ndarray] = []
        for i, ci in enumerate(tab.c):
            th_i = theta + h * sum((aij * r for aij, r in zip(tab.a[i], rates)), np.zeros(26))
            thd_i = theta_dot + h * sum((aij * a for aij, a in zip(tab.a[i], accs)), np.zeros(26))
            rates.append(thd_i)
            accs.append(f(t + ci * h, th_i, thd_i, i))
        self.theta = theta + h * sum(bi * r for bi, r in zip(tab.b, rates))
        self.theta_dot = theta_dot + h * sum(bi * a for bi, a in zip(tab.b, accs))
        self._kin = None
        return OracleRecord(theta, theta_dot, fixed, stage0)

    # ------------------------------------------------------------------ what the phase selector reads
    def _positions(self) -> Kinematics:
        if self._kin is None:
            self._kin = positions(self.phase.value, self.theta, self.fixed, self.params)
        return self._kin

    def hip_com(self) -> np.ndarray:
        if not np.all(np.isfinite(self.theta)):
            return np.full(3, np.nan)
        return self._positions().P["c17"]

    def toe_point(self, foot: str) -> np.ndarray:
        return self._positions().P[TOE_POINT[foot]].copy()

    def toe_rotation(self, foot: str) -> np.ndarray:
        return self._positions().C[TOE_BODY[foot]].copy()

    # ------------------------------------------------------------------ phase changes
    def touchdown(self, t: float, phase: Phase, foot: str, key: str) -> None:
        """The oracle's velocity reset (eqs. 4.97 / 4.100, weights ``reset.<key>``); the landed toe body becomes the
        new chain root where it landed (thesis L4024)."""
        if key not in self.sc.W_adj:
            raise SimulationError(f"touchdown at t = {t:.3f} s: the scenario has no reset.{key}")
        kin = self._positions()
        toe, R_toe = kin.P[TOE_POINT[foot]].copy(), kin.C[TOE_BODY[foot]].copy()
        res = self.engine.touchdown_reset(phase.value, self.theta, self.theta_dot, self.fixed, self.sc.W_adj[key])
        self.theta_dot = res.theta_dot
        self.fixed = {**self.fixed, foot: FootState(R_toe, toe)}

    def enter(self, phase: Phase) -> None:
        """Start ``phase``: lift-off drops the trailing toe's data."""
        self.fixed = {ft: self.fixed[ft] for ft in phase.stance_feet}
        self.phase = phase
        self._kin = None

    # ------------------------------------------------------------------ logging
    def build_log(self, rows: list[StepRow]) -> SimLog:
        """Every signal of ``results.SIGNALS`` per step, from the loop's records (see the module docstring)."""
        log = SimLog()
        yaw_prev = {"hip": yaw_of(self.hm.spec.C0), "hip_ref": yaw_of(self.hm.spec.C0)}
        for row in rows:
            r = row.record
            self._log(log, row.k, row.phase, row.t, r.theta, r.theta_dot, r.fixed, r.stage0, row.reference,
                      row.hip_ctrl_ref, yaw_prev)
        return log

    def _log(self, log: SimLog, k: int, phase: Phase, t: float, theta: np.ndarray, theta_dot: np.ndarray,
             fixed: dict[str, FootState], out: dict, ref, hip_ctrl: np.ndarray, yaw_prev: dict) -> None:
        """One row of every signal at the start of a step (stage-0 outputs)."""
        kin = self.engine.kinematics(phase.value, theta, theta_dot, fixed)
        fd, terms, cmd = out["fd"], out["terms"], out["cmd"]
        R17 = kin.C[17]
        yaw = unwrap_to(yaw_of(R17), yaw_prev["hip"])
        yaw_ref = unwrap_to(yaw_of(ref.hip_R), yaw_prev["hip_ref"])
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
        T = out["T"]
        T_cmd = cmd.T_cmd if cmd.T_cmd is not None else T
        sat = cmd.saturated if cmd.saturated is not None else np.zeros(26, dtype=bool)
        thdd_c = cmd.theta_ddot_cmd if cmd.theta_ddot_cmd is not None else np.full(26, np.nan)
        log.append(
            t=t, phase=k, basic_phase=BASIC[phase], q=out["q"], v=out["v"], theta=theta, theta_dot=theta_dot,
            theta_ddot=fd.theta_ddot, a=self.pin_acceleration(phase, out["q"], out["v"], fd.theta_ddot),
            theta_ddot_cmd=thdd_c, T_cmd=T_cmd, T=T,
            saturated=sat, tau=tau, hip_p=kin.P["c17"], hip_p_ref=ref.hip_p, hip_p_ctrl_ref=hip_ctrl,
            hip_v=kin.V["c17"], hip_v_ref=ref.hip_v, hip_R=R17, hip_R_ref=ref.hip_R, hip_yaw=yaw,
            hip_yaw_ref=yaw_ref, toe_R_p=kin.P["tpR"], toe_R_p_ref=ref.toe_R_p, toe_L_p=kin.P["tpL"],
            toe_L_p_ref=ref.toe_L_p, foot_R_R=kin.C[1], foot_L_R=kin.C[2], body_force=bf, body_moment=bm,
            foot_wrench=fw, cop=cop, in_contact=contact, zmp=zmp, drift_position=drift_p,
            drift_orientation=drift_o, dynamics_residual=residual)


__all__ = ["ORACLE_ERRORS", "OracleEngine", "OracleModel", "ThesisWalkError", "single_threaded_blas"]
