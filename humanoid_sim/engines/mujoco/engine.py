"""The MuJoCo engine (``walk.py --engine mujoco``): the controller on real ground -- unilateral, frictional foot
contact resolved by an independent physics engine (:mod:`humanoid_sim.engines.mujoco`).

Nothing holds the feet: the model (:func:`humanoid_sim.engines.mujoco.model.build_model`) is the generated URDF with a
free
joint at the lower trunk, a ground plane, the two sole boxes of each foot as the only collision geometry, and 26
motors; :class:`humanoid_sim.engines.mujoco.model.MujocoSettings` documents its timestep, friction cone, impratio and
solref / solimp.  The engine offers no constraint model (``constraints = None``): the thesis controller then
computes its 5.1 / 5.2 torque under the Pinocchio weld model of the phase (the contact it assumes), with the
held bodies anchored where they were when the phase started (``Observation.anchors``); any controller of the
interface works the same way.  The controller reads MuJoCo's state only through
:class:`humanoid_sim.engines.mujoco.state.
StateMap` (Pinocchio's q / v).

Control rate: the controller runs every :attr:`MujocoEngineSettings.control_period_s` (default 2 ms, 500 Hz), its
torques held on the motors in between (zero-order hold) while MuJoCo steps at its own timestep (1 ms).  The loop's
step ``h`` (``scenario.simulation.step_s``, 10 ms for the thesis's sims) is the log and phase-decision rate: each
loop step runs h / control_period controller updates (h must be a whole number of control periods, which must be a
whole number of MuJoCo timesteps).  ``Observation.stage`` is the update's index within the step (0 = the step's
start).  Why 2 ms: ``tests/test_mujoco_engine.py::test_control_rate_converges`` drops the robot 5 mm onto both
feet under a 10 rad/s PD (a walking controller's bandwidth: the thesis controller's retuned hip gain is ~9 rad/s)
and compares the hip path over 0.6 s at control periods 10, 5 and 2 ms with 1 ms (control at every MuJoCo step):
10 ms diverges, 5 ms is 0.18 mm off, 2 ms 0.044 mm (first order).  The thesis gait itself falls within 6 ms on
real ground, so it cannot show the convergence; ``test_control_rate_converges_on_the_zmp_walk`` checks it on the
zmp walk with the balance controller.  A user's controller runs at 1 ms with an armature of 0.02 kg m^2 on every
joint (:func:`humanoid_sim.sim.simulate.user_engine_options`): a PD held over a period T is stable only while kd T /
I < 2, and a free foot's toe body (1.3e-4 kg m^2 about its joint) leaves kd = 20 N m s/rad unstable down to 13 us.

Phase switching (the loop's hooks :meth:`touchdown_signal` and :meth:`check`):

- touchdown ends a single support when the swing foot's soles carry a normal force of at least
  :attr:`MujocoEngineSettings.contact_force_N` (20 N, ~4 % of the robot's weight: well above the force of a sole
  brushing the ground, well below a landing's) AND the swing toe has covered the share of its planned horizontal
  travel of the geometric rule of 6.1.1 (the guard against a foot scuffing the ground early in the swing).  The
  geometric rule's height clause is what the force measures directly, so it is not required: a foot that lands
  tilted still ends the swing.  Nothing is done to the state at touchdown: MuJoCo resolved the impact;
  the trajectory learns the actual landing from the loop (``traj.set_landing``);
- double support ends by the loop's rule (hip distance or overtime), as on the weld engine.

Falls (:meth:`check`, at every loop step; each ends the run with a :class:`MujocoFall` naming what happened): the
Body-17 CoM below ``scenario.simulation.fall_height_m``; the lower trunk's z axis more than
:attr:`MujocoEngineSettings.trunk_tilt_fall_rad` (45 deg) from the vertical; or the only supporting foot (the other
carries less than ``contact_force_N``) tipping onto an edge: its centre of pressure within ``edge_tolerance_m``
(2 mm) of a sole edge (toe, heel, outer, inner) while the sole box bearing its load is tilted more than
``edge_tilt_rad`` (3 deg, ten times the tilt penetration alone gives a flat sole) from the ground under it (the
vertical on the floor; with terrain boxes, the top faces the foot presses on: a foot flat on a slope has not tipped;
:func:`humanoid_sim.engines.mujoco.contact.bearing_tilt`).  A flat-footed controller cannot recover from that: the
ground can no longer push back on that side.

Logged signals (same schema as the other engines, ``results.SIGNALS``), per loop step, at the state at the step's
start and with the torques of its first control update: ``foot_wrench``, ``cop``, ``zmp``, ``body_force`` /
``body_moment`` from MuJoCo's contact forces (``mj_contactForce``, :mod:`humanoid_sim.engines.mujoco.contact`) of that
first MuJoCo step; ``theta_ddot`` from MuJoCo's acceleration (``qacc``); ``in_contact`` = the feet the phase's
contact set holds (what the controller assumes; the contact audit reads it); ``drift_position`` /
``drift_orientation`` = how far the phase's held bodies are from their anchors (m / rad; the weld engine's drift
is the same measure: there it is the welds' numerical drift, here the real feet's slip and tilt against the weld
the controller assumes); ``dynamics_residual`` = ||RNEA(q, v, a) - tau - tau_contact||_inf with Pinocchio's RNEA,
MuJoCo's acceleration and MuJoCo's constraint forces (a check that both engines describe the same robot).  A step
keeps what these need from MuJoCo (acceleration, constraint forces, the contact wrenches: :meth:`MujocoEngine._record`)
and :meth:`MujocoEngine.build_log` derives the Pinocchio quantities after the run.

Full-rate trace (:meth:`build_trace`): every MuJoCo step is recorded by :class:`humanoid_sim.engines.mujoco.trace.
TraceRecorder` (the state at its start, its acceleration, the ground's wrenches, the control update it held); a
step's log record takes its ground wrenches from the trace row of its first MuJoCo step.

Cost: the ground reads at every control update (:mod:`humanoid_sim.engines.mujoco.ground`) and the trace rows are
compiled (:mod:`humanoid_sim.engines.mujoco.compiled`, numba) unless ``compiled=False`` (``walk.py --no-kernel``) or
numba is missing; both paths give the same numbers (to the bit on the development machine's builds; the tests
allow a few units in the last place where pinocchio's or NumPy's own rounding enters:
``tests/engines/test_mujoco_compiled.py``).

summary.json gains (``run_info``): ``fell``, ``fall_time_s``, ``fall_reason``, ``foot_slip_max_m`` (largest
horizontal travel of a sole box's corners while that box stays loaded, over both feet and the walk after the
start-up settling window, :mod:`humanoid_sim.engines.mujoco.ground`),
``foot_tilt_max_rad`` (largest tilt of a foot's main body while it carries load: a trailing foot rolling onto its
toe counts), ``stance_tilt_max_rad`` (the same for the foot the phase holds flat, the stance foot only),
``penetration_max_m`` (all after the settling window), and the ground's ``settling`` and ``sliding`` reports
(:meth:`humanoid_sim.engines.mujoco.ground.GroundMeter.report`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from typing import Any, NamedTuple

import mujoco
import numpy as np
import pinocchio as pin

from humanoid_sim.dynamics.contact import record_anchors
from humanoid_sim.engines.mujoco import compiled as mjc
from humanoid_sim.engines.mujoco.contact import bearing_tilt, foot_contacts, ground_slope, sole_cop
from humanoid_sim.engines.mujoco.disturb import disturbance_info, scenario_pusher, scenario_terrain
from humanoid_sim.engines.mujoco.ground import GroundMeter, ReferenceGroundMeter, end_loads, trunk_tilt
from humanoid_sim.engines.mujoco.model import MujocoModelError, MujocoSettings
from humanoid_sim.engines.mujoco.sim import MujocoSim, MujocoSimError
from humanoid_sim.engines.mujoco.trace import TraceRecorder
from humanoid_sim.engines.weld import BASIC, unwrap_to, yaw_of
from humanoid_sim.errors import FallError
from humanoid_sim.interfaces.controller import Command, Observation
from humanoid_sim.interfaces.engine import StepRow
from humanoid_sim.interfaces.log import SimLog
from humanoid_sim.interfaces.selector import PhaseSelector, all_finite
from humanoid_sim.interfaces.trace import Trace
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import Scenario

FEET = ("R", "L")
FOOT_NAME = {"R": "right", "L": "left"}
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_STANCE = {None: -1, "R": 0, "L": 1}
_NEAR = 1e-9
"""rad: a libm tilt (:class:`GroundMeter`) this close to a fall threshold is recomputed by NumPy, whose value the
tests compare (libm's and NumPy's arctan2 agree to a few units in the last place, ~1e-16 rad)."""


class MujocoFall(FallError):
    """The robot fell on MuJoCo's ground; the message says when and how (which foot, which edge)."""


@dataclass(frozen=True)
class MujocoEngineSettings:
    """Settings of the MuJoCo engine (SI units); the module docstring gives the reasons for the defaults.

    ``armature_kg_m2``: rotor inertia reflected on each of the 26 joints (MuJoCo's ``dof_armature``, kg m^2), 0 for
    the thesis's rigid bodies; a user's controller runs with some (module docstring, "Control rate").  The model's
    own armature (``hm.model.armature``: the scenario's motors, :mod:`humanoid_sim.scenario.actuators`) is added.

    ``contact``: MuJoCo's numerical settings, None = :meth:`MujocoSettings.from_scenario` (defaults with the
    scenario's friction coefficient)."""

    control_period_s: float = 0.002
    armature_kg_m2: float = 0.0
    contact_force_N: float = 20.0
    trunk_tilt_fall_rad: float = math.pi / 4
    edge_tilt_rad: float = math.radians(3.0)
    edge_tolerance_m: float = 0.002
    contact: MujocoSettings | None = None

    def __post_init__(self) -> None:
        def bad(name: str, expected: str) -> MujocoModelError:
            return MujocoModelError(f"MujocoEngineSettings.{name} = {getattr(self, name)!r}: expected {expected}")

        def pos(x: Any) -> bool:
            return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0

        if not pos(self.control_period_s) or self.control_period_s > 0.1:
            raise bad("control_period_s", "a period in (0, 0.1] s")
        a = self.armature_kg_m2
        if not (isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a) and 0 <= a <= 10):
            raise bad("armature_kg_m2", "an inertia in [0, 10] kg m^2")
        for name in ("contact_force_N", "edge_tilt_rad", "edge_tolerance_m"):
            if not pos(getattr(self, name)):
                raise bad(name, "a positive number")
        if not (pos(self.trunk_tilt_fall_rad) and self.trunk_tilt_fall_rad <= math.pi):
            raise bad("trunk_tilt_fall_rad", "an angle in (0, pi] rad")
        if self.contact is not None and not isinstance(self.contact, MujocoSettings):
            raise bad("contact", "a MujocoSettings or None")


class MujocoRecord(NamedTuple):
    """The MuJoCo engine's record of one step, read right after its first MuJoCo step (SI units).

    Attributes:
        q, v: the state at the step's start (Pinocchio's conventions).
        qacc: MuJoCo's acceleration. qfrc_constraint: MuJoCo's constraint forces (its dof order).
        T, T_cmd, sat: the thesis actuator torques after and before saturation (N m; None when the controller gave
            joint torques only) and where they saturated.
        thdd_c: the thesis command accelerations, or None. tau: the generalized torques applied (nv,), N m.
        anchors: the phase's anchors. body_force, body_moment: the ground's wrenches on bodies 1-4 (4, 3) in their
            frames. foot_wrench: per foot (R, L) the world ground wrench (2, 6). cop: per foot the centre of
            pressure (2, 3), NaN off the ground.
    """

    q: np.ndarray
    v: np.ndarray
    qacc: np.ndarray
    qfrc_constraint: np.ndarray
    T: Any
    T_cmd: Any
    sat: Any
    thdd_c: Any
    tau: np.ndarray
    anchors: Any
    body_force: np.ndarray
    body_moment: np.ndarray
    foot_wrench: np.ndarray
    cop: np.ndarray


class MujocoEngine:
    """The thesis humanoid on MuJoCo's ground (see the module docstring).

    Engine interface (:class:`humanoid_sim.interfaces.engine.Engine`) plus the optional hooks :meth:`touchdown_signal`,
    :meth:`check` and :meth:`run_info`.  ``settings``: a :class:`MujocoEngineSettings`, or None for the
    defaults; ``overrides`` replace named fields of it (``MujocoEngine(hm, sc, control_period_s=0.001)``).
    ``compiled``: the engine's bookkeeping by the compiled functions of :mod:`humanoid_sim.engines.mujoco.compiled`
    (None =
    when numba is installed, True = required, False = never: the NumPy reference path, the same numbers): the state
    and torque maps, and with an elliptic friction cone (the default) the ground reads too (a pyramidal cone's
    forces are decoded by ``mj_contactForce``: the reference path)."""

    name = "mujoco"
    constraints = None
    errors = (MujocoSimError, MujocoModelError)

    def __init__(self, hm: HumanoidModel, scenario: Scenario, traj: Any = None,
                 settings: MujocoEngineSettings | None = None, compiled: bool | None = None,
                 **overrides: Any) -> None:
        settings = MujocoEngineSettings() if settings is None else settings
        if not isinstance(settings, MujocoEngineSettings):
            raise MujocoModelError(f"settings: expected a MujocoEngineSettings, got {type(settings).__name__}")
        names = {f.name for f in fields(MujocoEngineSettings)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise MujocoModelError(f"MujocoEngine: unknown setting(s) {unknown}; expected some of {sorted(names)}")
        self.settings = replace(settings, **overrides)
        self.hm = hm
        self.sc = scenario
        self.traj = traj
        self.model = hm.model
        contact = self.settings.contact or MujocoSettings.from_scenario(scenario)
        if compiled and not mjc.AVAILABLE:
            raise MujocoModelError("MujocoEngine(compiled=True): numba is not installed")
        self.terrain = scenario_terrain(hm, scenario, traj)   # a scenario's terrain boxes (disturb.py), or []
        self.sim = MujocoSim(hm, contact, compiled=compiled, terrain=self.terrain)
        self.mm = self.sim.mm
        self.map = self.sim.map
        self._armature = float(self.settings.armature_kg_m2)
        if self._armature:
            self.mm.model.dof_armature[6:] = self._armature  # the 26 hinge dofs (the free joint's 6 come first)
        if np.any(hm.model.armature[6:]):   # motors' rotor inertias in the model (scenario actuators): MuJoCo's too
            for jid in range(2, hm.model.njoints):
                dof = self.mm.model.joint(hm.model.names[jid]).dofadr[0]
                self.mm.model.dof_armature[dof] += hm.model.armature[hm.model.idx_vs[jid]]
        self.sim.model_changed()
        self.act = Actuators(hm)
        self.data = hm.model.createData()
        self.rec_data = hm.model.createData()
        self.fid = {n: hm.frame_id(n) for n in ("Pc_17", "O_17", "P_tpR", "P_tpL", "O_1", "O_2")}
        self._frame_ids: dict[str, int] = {}
        self._n_sub = self.sim.substeps(self.settings.control_period_s)  # checks the period is whole timesteps
        self._no_sat = np.zeros(26, dtype=bool)
        elliptic = self.mm.model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
        self.compiled = compiled is not False and mjc.AVAILABLE and elliptic
        self.pusher = scenario_pusher(hm, scenario, traj, self.mm, self.sim.data)   # None without pushes
        # the full-rate trace; the kernel's contact wrenches know the floor alone: with terrain the NumPy path
        # reads them
        self.recorder = TraceRecorder(self.sim, self.act, self.compiled, not self.mm.terrain_geoms)
        self.q = self.v = None
        self.phase: Phase | None = None
        self.anchors = None
        self.sensed: np.ndarray | None = None
        """The feet's wrenches (2, 6) over the last control period (its mean), as ``Observation.foot_wrenches``."""
        self._end = np.zeros(6)       # the loads at the state after the last step (ground.end_loads)
        self._reset_measures()

    def _reset_measures(self) -> None:
        """A new run's ground measures (:attr:`ground`, reading the settings' and the scenario's thresholds now)."""
        s = self.settings
        # a foot flat on a slope is tilted from the vertical by the slope: the edge test then reads the tilt from
        # the ground under the foot (contact.bearing_tilt), which is at most the slope larger
        self._slope = ground_slope(self.mm)
        if self.compiled:
            limits = (s.edge_tilt_rad - _NEAR - self._slope, self.sc.simulation.fall_height_m,
                      s.trunk_tilt_fall_rad - _NEAR)
            self.ground = GroundMeter(self.mm, s.contact_force_N, limits)
        else:
            self.ground = ReferenceGroundMeter(self.mm, s.contact_force_N)
        self.fall: tuple[float, str] | None = None

    # ------------------------------------------------------------------ state
    def start(self, q0: np.ndarray, phase: Phase) -> None:
        """At rest at q0 (the feet where q0 puts them, on the ground), time 0."""
        self.sim.set_state(q0, np.zeros(self.model.nv))
        self.sim.time = 0.0
        self.q, self.v = self.sim.state()
        self.phase = phase
        self.anchors = record_anchors(self.model, self.q, phase.contacts)
        self.sensed = None
        self._reset_measures()
        self.recorder.start()
        if self.pusher is not None:
            self.pusher.reset()
        self.sim.forward()
        end_loads(self.mm, self.sim.data, self._end, self.compiled)

    def state_vectors(self) -> tuple[np.ndarray, np.ndarray]:
        return self.q, self.v

    # ------------------------------------------------------------------ one step
    def step(self, t: float, h: float, k: int, control: Callable[[Observation], Command],
             checks: PhaseSelector) -> MujocoRecord:
        """Advance from t to t + h: h / control_period controller updates, each held for its period.  Returns the
        log record of the state at t with the first update's torques and the contact forces they produce (raw:
        :meth:`build_log` derives the logged kinematics from it after the run)."""
        period = self.settings.control_period_s
        n_ctrl = round(h / period)
        if not (n_ctrl >= 1 and abs(n_ctrl * period - h) <= 1e-9 * max(1.0, h)):
            raise MujocoSimError(f"loop step h = {h!r} s: expected a whole number of control periods "
                                 f"(MujocoEngineSettings.control_period_s = {period:g} s)")
        phase, anchors, sim, pusher, rec = self.phase, self.anchors, self.sim, self.pusher, self.recorder
        qacc, dt, basic = sim.data.qacc, sim.timestep, BASIC[phase]
        record: MujocoRecord | None = None
        q, v = self.q, self.v
        n_sub = self._n_sub
        for i in range(n_ctrl):
            ti = t + i * period
            if i:
                q, v = sim.state()
                checks.check_stage(ti, q, v, i)
            cmd = control(Observation(ti, k, phase, q, v, anchors, i, checks.plan_delay, self.sensed))
            tau = self._tau(q, cmd)
            rec.control(tau, cmd.T, cmd.saturated, cmd.T_cmd)
            if pusher is not None:
                pusher.apply(ti, period)
            # one MuJoCo step first: its acceleration and contact forces are those of the state at ti
            sim.hold(tau)
            sim.advance(1)
            checks.check_acceleration(ti, qacc)  # finite iff Pinocchio's a is
            rec.row(ti, k, basic)
            wrench = rec.foot_wrenches().copy()
            if i == 0:
                record = self._record(q, v, cmd, tau)
            if self._measure(ti):
                break  # a fall: the run ends at this state (check() reports it)
            for j in range(1, n_sub):   # the rest of the control period, tau still held
                sim.advance(1)
                rec.row(ti + j * dt, k, basic)
                wrench += rec.foot_wrenches()
            if n_sub > 1:
                wrench *= 1.0 / n_sub
            self.sensed = wrench     # the period's mean: its impulse over the period, as the next call sees it
        self.q, self.v = sim.state()
        sim.forward()
        end_loads(self.mm, sim.data, self._end, self.compiled)
        assert record is not None, "a step runs at least one control update"
        return record

    def _tau(self, q: np.ndarray, cmd: Command) -> np.ndarray:
        """Generalized torques of a command (thesis T mapped by the actuator map when tau is not given)."""
        if cmd.tau is None:
            cmd.tau = self.act.torque_map(q) @ cmd.T
            cmd.tau[:6] = 0.0
        return cmd.tau

    def _record(self, q: np.ndarray, v: np.ndarray, cmd: Command, tau: np.ndarray) -> MujocoRecord:
        """What the log keeps of the state (q, v) at a step's start, read right after its first MuJoCo step (whose
        acceleration and contact forces are those of that state): MuJoCo's acceleration and constraint forces,
        the command, the phase's anchors, and the ground's wrenches on the feet (foot wrench, centre of pressure,
        body wrenches, as the trace row of the same step read them: :class:`.trace.TraceRecorder`).  :meth:`_derive`
        computes the rest after the run."""
        data = self.sim.data
        fw, cop, bf, bm = self.recorder.last_wrenches()
        qacc = data.qacc.copy()
        T, T_cmd, sat = cmd.T, cmd.T_cmd, cmd.saturated
        if T is None:   # the controller gave tau only: the thesis torques now (a failure ends the run with a reason)
            T = T_cmd = self.act.thesis_torques(q, v, self._acceleration(q, v, qacc), tau)
            sat = self._no_sat
        return MujocoRecord(q, v, qacc, data.qfrc_constraint.copy(), T, T_cmd, sat, cmd.theta_ddot_cmd, tau.copy(),
                            self.anchors, bf, bm, fw, cop)

    def _acceleration(self, q: np.ndarray, v: np.ndarray, qacc: np.ndarray) -> np.ndarray:
        """Pinocchio's acceleration at (q, v) from MuJoCo's qacc (:meth:`humanoid_sim.engines.mujoco.state.StateMap.
        a_from_qacc`)."""
        return mjc.pin_acceleration(q, v, qacc, self.map.v_gather) if self.compiled else \
            self.map.a_from_qacc(q, v, qacc)

    def _derive(self, q: np.ndarray, v: np.ndarray, qacc: np.ndarray, qfrc_c: np.ndarray, T: Any, T_cmd: Any,
                sat: Any, thdd_c: Any, tau: np.ndarray, anchors: Any) -> tuple:
        """The logged quantities of a record (:meth:`_record`) that Pinocchio gives at (q, v, a): the acceleration
        a, the anchors' drift, the dynamics residual and the task frames (and the command's defaults)."""
        model, d, fid, smap = self.model, self.rec_data, self.fid, self.map
        a = self._acceleration(q, v, qacc)
        if T_cmd is None:
            T_cmd = T
        if sat is None:
            sat = self._no_sat
        if thdd_c is None:
            thdd_c = np.full(26, np.nan)
        rnea = pin.rnea(model, d, q, v, a)
        if self._armature:  # the rotor inertia MuJoCo adds to the rigid bodies' joint rows
            rnea = rnea.copy()
            rnea[6:] += self._armature * a[6:]
        if self.compiled:
            residual = mjc.dynamics_residual(rnea, tau, q, qfrc_c, smap.v_gather)
        else:
            residual = float(np.max(np.abs(rnea - tau - smap.tau_from_qfrc(q, qfrc_c))))
        pin.forwardKinematics(model, d, q, v)
        pin.updateFramePlacements(model, d)
        pos = ori = 0.0
        for frame, M in anchors.placements.items():
            err = M.actInv(d.oMf[self._frame_id(frame)])
            x, w = err.translation, pin.log3(err.rotation)
            pos = max(pos, math.sqrt(x.dot(x)))              # np.linalg.norm's arithmetic, less overhead
            ori = max(ori, math.sqrt(w.dot(w)))
        hip_v = pin.getFrameVelocity(model, d, fid["Pc_17"], LWA).linear.copy()
        o = d.oMf
        return (a, thdd_c, T_cmd, T, sat, pos, ori, residual, o[fid["Pc_17"]].translation.copy(), hip_v,
                o[fid["O_17"]].rotation.copy(), o[fid["P_tpR"]].translation.copy(),
                o[fid["P_tpL"]].translation.copy(), o[fid["O_1"]].rotation.copy(), o[fid["O_2"]].rotation.copy())

    def _frame_id(self, name: str) -> int:
        """Pinocchio frame id of a named frame, cached."""
        fid = self._frame_ids.get(name)
        if fid is None:
            fid = self._frame_ids[name] = self.hm.frame_id(name)
        return fid

    def build_trace(self) -> Trace | None:
        """The run's full-rate trace: one row per MuJoCo step (:meth:`.trace.TraceRecorder.build`; None before any
        step)."""
        return self.recorder.build()

    # ------------------------------------------------------------------ ground measures and falls
    def _measure(self, t: float) -> bool:
        """Slip, tilt and penetration (:attr:`ground`) at the state at t of a control update, whose kinematics and
        contact forces MuJoCo's data hold (right after the update's first MuJoCo step); True when it is a fall (the
        first is kept for :meth:`check`)."""
        data = self.sim.data
        code = self.ground.update(data, _STANCE[None if self.phase is None else self.phase.support_foot])
        if self.fall is not None:
            return True
        if not code & 4:              # no fall test can fire (GroundMeter's limits)
            return False
        s, mm, out = self.settings, self.mm, self.ground.out
        loaded = code & 3
        edge = ""
        if loaded == 1 or loaded == 2:       # one foot alone carries the robot
            i = loaded - 1
            f = FEET[i]
            # its CoP's edges only when its sole tilts (sole_cop costs ~0.1 ms, and this runs at every update)
            if out[7 + i] > s.edge_tilt_rad - _NEAR - self._slope:
                tilt = bearing_tilt(mm, data, f, out[2 * i + 1], s.contact_force_N)
                cop = sole_cop(mm, data, foot_contacts(mm, data)[f], s.edge_tolerance_m) \
                    if tilt > s.edge_tilt_rad else None
                if cop is not None and cop.edges:
                    names = " and ".join(cop.edges)
                    edge = (f"the {FOOT_NAME[f]} foot, the only one on the ground, tipped onto its {names} edge"
                            f"{'s (a corner)' if len(cop.edges) > 1 else ''} (sole tilt {math.degrees(tilt):.1f} "
                            f"deg, centre of pressure {1000 * abs(cop.margin):.1f} mm from the edge)")
        fall_h = self.sc.simulation.fall_height_m
        hip_z = float(out[10])                           # Body-17 CoM
        if edge:
            self.fall = (t, f"fall at t = {t:.3f} s: {edge}")
        elif hip_z < fall_h:
            self.fall = (t, f"fall at t = {t:.3f} s: hip CoM height {hip_z:.3f} m below {fall_h} m")
        elif out[9] > s.trunk_tilt_fall_rad - _NEAR:
            tilt = trunk_tilt(mm, data)
            if tilt > s.trunk_tilt_fall_rad:
                self.fall = (t, f"fall at t = {t:.3f} s: lower trunk tilted {math.degrees(tilt):.1f} deg from "
                                f"the vertical (limit {math.degrees(s.trunk_tilt_fall_rad):.0f} deg)")
        return self.fall is not None

    def check(self, t: float) -> None:
        """Raise :class:`MujocoFall` if the state after the last step is a fall (module docstring)."""
        if self.fall is not None:
            raise MujocoFall(self.fall[1])

    def touchdown_signal(self, foot: str) -> bool:
        """True when ``foot``'s soles carry at least ``contact_force_N`` of normal force at the current state."""
        i = 0 if foot == "R" else 2
        return self._end[i] + self._end[i + 1] >= self.settings.contact_force_N

    def run_info(self) -> dict:
        """For summary.json (SI units): fall, slip, tilt and penetration measures of the run."""
        g = self.ground
        return {"ground": {"fell": self.fall is not None,
                           "fall_time_s": None if self.fall is None else float(self.fall[0]),
                           "fall_reason": None if self.fall is None else self.fall[1],
                           "foot_slip_max_m": float(g.slip_max), "foot_tilt_max_rad": float(g.tilt_max),
                           "stance_tilt_max_rad": float(g.stance_tilt_max),
                           "penetration_max_m": float(g.penetration_max),
                           "control_period_s": self.settings.control_period_s,
                           "timestep_s": self.sim.timestep, **g.report()},
                **disturbance_info(self.terrain, self.pusher)}

    # ------------------------------------------------------------------ what the phase selector reads
    def hip_com(self) -> np.ndarray:
        """Body-17 CoM (world, m) at the current state (NaN when the state is not finite)."""
        if all_finite(self.q):
            pin.forwardKinematics(self.model, self.data, self.q)
            return pin.updateFramePlacement(self.model, self.data, self.fid["Pc_17"]).translation.copy()
        return np.full(3, np.nan)

    def toe_point(self, foot: str) -> np.ndarray:
        """Toe point P_tp of ``foot`` at the state of the last :meth:`hip_com`."""
        return pin.updateFramePlacement(self.model, self.data, self.fid["P_tp" + foot]).translation.copy()

    def toe_rotation(self, foot: str) -> np.ndarray:
        """Orientation of the toe body of ``foot`` (O_1 / O_2) at the state of the last :meth:`hip_com`."""
        return pin.updateFramePlacement(self.model, self.data, self.fid["O_1" if foot == "R" else "O_2"]
                                        ).rotation.copy()

    # ------------------------------------------------------------------ phase changes
    def touchdown(self, t: float, phase: Phase, foot: str, key: str) -> None:
        """Nothing: MuJoCo resolved the impact (no velocity reset)."""

    def enter(self, phase: Phase) -> None:
        """Start ``phase``: its held bodies are anchored where they are now (those held before keep their
        anchors), for the controller's weld model."""
        self.anchors = record_anchors(self.model, self.q, phase.contacts, previous=self.anchors)
        self.phase = phase

    # ------------------------------------------------------------------ logging
    def build_log(self, rows: list[StepRow]) -> SimLog:
        """The log from the loop's rows (their records are :class:`MujocoRecord`), the records' kinematics derived
        here (:meth:`_derive`)."""
        hm = self.hm
        n = len(rows)
        if n == 0:
            return SimLog()
        t, k, phase, ref, hip_ctrl, records = zip(*rows)
        q, v, qacc, qfrc_c, T, T_cmd, sat, thdd_c, tau, anchors, bf, bm, fw, cop = zip(*records)
        derived = [self._derive(*r) for r in zip(q, v, qacc, qfrc_c, T, T_cmd, sat, thdd_c, tau, anchors)]
        a, thdd_c, T_cmd, T, sat, pos, ori, res, hip_p, hip_v, R17, toe_R, toe_L, R1, R2 = zip(*derived)
        Q, V, A = np.array(q), np.array(v), np.array(a)
        fw = np.array(fw)
        thesis = lambda X: hm.theta_sign * X[:, hm.theta_v_idx]  # noqa: E731 -- v-ordered arrays -> thesis
        stance = {ph: [f in ph.stance_feet for f in FEET] for ph in Phase}
        ftot = fw[:, :, :3].sum(axis=1)
        mtot = fw[:, :, 3:].sum(axis=1)
        zmp = np.full((n, 3), np.nan)
        ok = ftot[:, 2] > 1e-9
        zmp[ok] = np.stack([-mtot[ok, 1] / ftot[ok, 2], mtot[ok, 0] / ftot[ok, 2], np.zeros(ok.sum())], axis=1)
        yaw0 = yaw_of(hm.spec.C0)
        hip_R, hip_R_ref = np.array(R17), np.array([r.hip_R for r in ref])
        # yaw_of of every row in one np.arctan2 each (the same function on the same numbers: the same angles)
        heading = np.arctan2(hip_R[:, 1, 0].copy(), hip_R[:, 0, 0].copy()).tolist()
        heading_ref = np.arctan2(hip_R_ref[:, 1, 0].copy(), hip_R_ref[:, 0, 0].copy()).tolist()
        yaw, yaw_ref = np.empty(n), np.empty(n)
        prev, prev_ref = yaw0, yaw0
        for i in range(n):
            prev = yaw[i] = unwrap_to(heading[i], prev)
            prev_ref = yaw_ref[i] = unwrap_to(heading_ref[i], prev_ref)
        cols = dict(
            t=np.array(t), phase=np.array(k), basic_phase=np.array([BASIC[ph] for ph in phase]), q=Q, v=V,
            theta=hm.theta_sign * Q[:, hm.theta_q_idx], theta_dot=thesis(V), theta_ddot=thesis(A), a=A,
            theta_ddot_cmd=np.array(thdd_c), T_cmd=np.array(T_cmd), T=np.array(T), saturated=np.array(sat),
            tau=np.array(tau), hip_p=np.array(hip_p), hip_p_ref=np.array([r.hip_p for r in ref]),
            hip_p_ctrl_ref=np.array(hip_ctrl), hip_v=np.array(hip_v), hip_v_ref=np.array([r.hip_v for r in ref]),
            hip_R=hip_R, hip_R_ref=hip_R_ref, hip_yaw=yaw, hip_yaw_ref=yaw_ref,
            toe_R_p=np.array(toe_R), toe_R_p_ref=np.array([r.toe_R_p for r in ref]), toe_L_p=np.array(toe_L),
            toe_L_p_ref=np.array([r.toe_L_p for r in ref]), foot_R_R=np.array(R1), foot_L_R=np.array(R2),
            body_force=np.array(bf), body_moment=np.array(bm), foot_wrench=fw, cop=np.array(cop),
            in_contact=np.array([stance[ph] for ph in phase]), zmp=zmp, drift_position=np.array(pos),
            drift_orientation=np.array(ori), dynamics_residual=np.array(res))
        return SimLog.from_columns(cols)


__all__ = ["MujocoEngine", "MujocoEngineSettings", "MujocoFall", "MujocoRecord"]
