"""The stepping loop: one loop for every engine and every controller (thesis chapter 6).

    scenario -> references (chapter 3) -> controller -> engine -> log -> outputs

Per step of h (the scenario's ``simulation.step_s``) the engine advances the state under the current phase's
contacts, calling the controller whenever it needs torques (:mod:`humanoid_sim.engines`,
:mod:`humanoid_sim.controllers`).  At each step boundary the loop

- logs the step (the nominal references at t, the controller's clamped hip reference, the engine's record);
- checks the state (:class:`humanoid_sim.interfaces.selector.PhaseSelector`: non-finite or diverging, a fall, a phase
  lasting far beyond its nominal duration);
- applies the phase selector of 6.1.1: SSP -> DSP on touchdown of the swing toe (the engine applies its touchdown
  law, the trajectory learns the actual landing), DSP -> SSP on the hip-distance or overtime rule;
- reports progress.

A failure (a :class:`SimulationError`, an engine's contact or command error, a controller that raises or returns
bad torques) or Ctrl-C ends the run with a one-line reason; the log up to that point is kept
(:class:`SimResult`).

Decisions where the thesis is silent:
- Logged references (``hip_p_ref``, ``toe_*_ref``, ``hip_yaw_ref``) are the planned motion at time t on the
  nominal schedule, the reference the user designed and the viewer draws; tracking errors are measured against it.
  The thesis controller tracks the current phase's reference clamped to the phase's nominal window (6.1.1,
  errata T-3), logged as ``hip_p_ctrl_ref``.  The two differ while a phase runs ahead of or behind its nominal
  window: with the thesis's 0.05 m double-support rule a DSP ends one or two steps after touchdown, so the next
  SSP's reference is held at its start for up to t_DSP.
- P_i of the SSP switching rule is the actual swing toe point at the phase start (thesis 6.1.1.1 wording).
- An engine that senses contact (optional hooks of :class:`humanoid_sim.interfaces.engine.Engine`) decides touchdown
  with ``touchdown_signal(foot)``; the geometric rule's travel clause stays as the guard.  Its ``check(t)`` may end
  the run after a step (a fall on real ground), and its ``run_info()`` adds to ``SimResult.extra``.
"""

from __future__ import annotations

import math
import time
import traceback as tb
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from humanoid_sim.controllers.thesis.command import CommandError
from humanoid_sim.dynamics.contact import ContactError
from humanoid_sim.errors import FallError
from humanoid_sim.interfaces.controller import Command, Controller, ControllerError, Observation, as_command
from humanoid_sim.interfaces.engine import Engine, StepRow
from humanoid_sim.interfaces.log import SimLog
from humanoid_sim.interfaces.selector import CoordinateNames, PhaseRecord, PhaseSelector, SimulationError
from humanoid_sim.interfaces.trace import Trace, trace_of_log
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.robot.phases import Phase, SwitchThresholds, ssp_should_end
from humanoid_sim.scenario.schema import Scenario
from humanoid_sim.sim.disturbances import sensed, summary_entry
from humanoid_sim.sim.status import RunStatus

RUN_ERRORS: tuple[type[BaseException], ...] = (SimulationError, ControllerError, ContactError, CommandError,
                                                 np.linalg.LinAlgError)
"""Failures that end a run with a reason (the engines add their own, ``Engine.errors``)."""


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
    phase_names: list[str] = field(default_factory=list)
    """The name of each phase index the log's ``phase`` column holds: the trajectory's planned phases, except that a
    held run (``run(hold=...)``, which never leaves index 0) names the phase it held.  Save and audit the log with
    these (``log.save(path, result.phase_names)``)."""
    status: RunStatus = RunStatus.FAILED
    """How the run ended (:class:`RunStatus`); ``reason`` says it in words."""
    error: BaseException | None = None
    """The exception that ended the run, or None."""
    traceback: str | None = None
    """The formatted traceback of :attr:`error` (where a controller or the simulation failed), or None."""
    trace: Trace | None = None
    """The signals at every integration step of the engine (:mod:`humanoid_sim.interfaces.trace`), or None when
    nothing was logged."""


def thresholds_of(scenario: Scenario) -> SwitchThresholds:
    """The phase selector's thresholds from the scenario's ``switch`` section."""
    sw = scenario.switch
    return SwitchThresholds(sw.toe_flat_height_m, sw.touchdown_tolerance_m, sw.min_horizontal_progress_fraction,
                            sw.dsp_hip_distance_m, sw.dsp_overtime_fraction)


class _Checked:
    """The controller as the engine calls it: counted, its output checked (:func:`as_command`), its unexpected
    exceptions turned into :class:`ControllerError` naming it."""

    def __init__(self, controller: Controller, nv: int, names: CoordinateNames | None = None) -> None:
        self.controller = controller
        self.name = getattr(controller, "name", type(controller).__name__)
        self.nv = nv
        self.names = names
        self.calls = 0

    def __call__(self, obs: Observation) -> Command:
        self.calls += 1
        try:
            out = self.controller(obs)
        except RUN_ERRORS + (KeyboardInterrupt,):
            raise
        except Exception as exc:  # a user's controller: any failure ends the run with its name
            raise ControllerError(f"controller {self.name!r} raised {type(exc).__name__} at t = {obs.t:.3f} s: "
                                  f"{exc}") from exc
        return as_command(out, self.nv, self.name, self.names)


class _Driven:
    """The checked controller's commands passed through the motors (``run``'s ``drive``)."""

    def __init__(self, checked: Callable[[Observation], Command],
                 drive: Callable[[Command, Observation], Command]) -> None:
        self.checked = checked
        self.drive = drive

    def __call__(self, obs: Observation) -> Command:
        return self.drive(self.checked(obs), obs)


def _call_hook(name: str, hook: str, fn: Callable[[int], object], k: int, t: float) -> object:
    """``fn(k)``, a controller's optional hook, its failure a :class:`ControllerError` naming the controller."""
    try:
        return fn(k)
    except RUN_ERRORS + (KeyboardInterrupt,):
        raise
    except Exception as exc:
        raise ControllerError(f"controller {name!r}: {hook} raised {type(exc).__name__} at t = {t:.3f} s: "
                              f"{exc}") from exc


def _plan_jump(name: str, fn: Callable[[int], object], k: int, t: float) -> float:
    """The controller's ``plan_jump(k)``: a time >= 0 s, or a :class:`ControllerError` saying what it returned."""
    out = _call_hook(name, "plan_jump", fn, k, t)
    if isinstance(out, (int, float, np.floating, np.integer)) and not isinstance(out, bool) and \
            math.isfinite(out) and out >= 0:
        return float(out)
    raise ControllerError(f"controller {name!r}: plan_jump returned {out!r} at t = {t:.3f} s, expected a time "
                          ">= 0 s")


def _swing_landing(name: str, fn: Callable[[int], object], k: int, t: float) -> np.ndarray | None:
    """The controller's ``swing_landing(k)``: None or a world point (3,) m, or a :class:`ControllerError`."""
    out = _call_hook(name, "swing_landing", fn, k, t)
    if out is None:
        return None
    arr = np.asarray(out, dtype=float) if isinstance(out, (np.ndarray, list, tuple)) else None
    if arr is None or arr.shape != (3,) or not np.isfinite(arr).all():
        raise ControllerError(f"controller {name!r}: swing_landing returned {out!r} at t = {t:.3f} s, expected "
                              "None or a world point of 3 finite numbers (m)")
    return arr


def _travelled(sel: PhaseSelector, toe: np.ndarray, end: np.ndarray | None = None) -> bool:
    """The guard of a sensed touchdown: the swing toe has covered more than the geometric rule's share of its
    planned horizontal travel (6.1.1.1's second clause; its height clause is what the sensed contact replaces).
    ``end``: where the controller lands the swing when it moved the foothold (None: the plan's end point)."""
    th = replace(sel.thresholds, touchdown_tolerance=math.inf)
    return ssp_should_end(toe, sel.toe_start, sel.targets.swing_toe_end if end is None else end, th)


def run(engine: Engine, controller: Controller, traj: ReferenceTrajectory, scenario: Scenario, q0: np.ndarray,
        t_end: float | None = None, progress: Callable[[float, int], None] | None = None,
        hold: Phase | None = None, drive: Callable[[Command, Observation], Command] | None = None) -> SimResult:
    """Simulate ``scenario`` on ``engine`` driven by ``controller`` (already set up) from rest at ``q0`` until every
    planned phase is done, ``t_end`` (s), the scenario's end time, or a failure.

    ``hold``: stay in this contact phase for the whole run instead of walking the schedule (e.g. ``Phase.RFFDSP`` to
    test a standing controller in double support); the run then ends at ``t_end``.  ``drive``: the motors between the
    controller and the engine (:class:`humanoid_sim.sim.drive.Drive`: each command clipped to their envelopes), or
    None; its ``report()`` goes into ``SimResult.extra["actuators"]``."""
    h = scenario.simulation.step_s
    n_phases = traj.n_phases
    nominal_end = traj.phases[-1].t_end
    t_stop = t_end if t_end is not None else (scenario.simulation.t_end_s or np.inf)
    errors = RUN_ERRORS + tuple(getattr(engine, "errors", ()))
    hm = getattr(engine, "hm", None)
    names = None if hm is None else CoordinateNames.of(hm)  # joints named in the messages
    checked = _Checked(controller, engine.model.nv, names)
    seen = sensed(scenario, checked, engine, h)   # a scenario's sensing noise and delay, else checked itself
    control: Callable[[Observation], Command] = seen if drive is None else _Driven(seen, drive)
    t = 0.0
    engine.start(q0, hold if hold is not None else Phase(traj.phases[0].name))
    first_swing = traj.phases[0].swing_foot
    engine.hip_com()
    sel = PhaseSelector(traj, thresholds_of(scenario), scenario.simulation,
                        None if first_swing is None else engine.toe_point(first_swing), names)
    if hold is not None:
        sel.hold_in(hold)
    rows: list[StepRow] = []
    completed, reason = False, ""
    status, error, trace_text = RunStatus.FAILED, None, None
    steps = 0
    on_landing = getattr(controller, "landing", None)
    plan_jump = getattr(controller, "plan_jump", None)          # step timing: the plan runs ahead of schedule
    landing_of = getattr(controller, "swing_landing", None)    # step adjustment: the swing lands elsewhere
    check = getattr(engine, "check", None)                  # optional engine hooks (engines.base.Engine)
    touch_signal = getattr(engine, "touchdown_signal", None)
    wall0 = time.perf_counter()
    try:
        try:
            while True:
                if t >= t_stop - 1e-12:
                    reason = f"stopped at t = {t:.3f} s (requested stop time)"
                    status = RunStatus.STOPPED
                    break
                k, phase = sel.k, sel.phase
                record = engine.step(t, h, k, control, sel)
                rows.append(StepRow(t, k, phase, traj.sample_global(t), traj.hip_reference(k, t)[0], record))
                t += h
                steps += 1
                if progress is not None:
                    progress(t, k)
                hip = engine.hip_com()
                if check is not None:
                    check(t)
                sel.check_state(t, *engine.state_vectors(), hip)
                swing = sel.phase.swing_foot if hold is not None else sel.info.swing_foot
                toe = engine.toe_point(swing) if swing is not None else None
                # an engine that senses touchdown decides it, the geometric rule's travel clause as the guard
                signal = touch_signal(swing) if touch_signal is not None and swing is not None and hold is None \
                    else None
                if not (sel.should_switch(t, hip, toe) if signal is None else signal and _travelled(
                        sel, toe, None if landing_of is None else
                        _swing_landing(checked.name, landing_of, k, t))):
                    continue
                sel.end_phase(t)
                if sel.is_last:
                    completed, reason = True, f"all {n_phases} phases completed at t = {t:.3f} s"
                    status = RunStatus.COMPLETED
                    break
                if swing is not None:  # touchdown: SSP -> DSP
                    R_toe = engine.toe_rotation(swing)
                    key = sel.record_touchdown(toe, R_toe)
                    engine.touchdown(t, phase, swing, key)
                    traj.set_landing(swing, k, toe, R_toe)
                    if on_landing is not None:
                        on_landing()
                nxt = traj.phases[k + 1].swing_foot
                engine.enter(phase.next)
                jump = _plan_jump(checked.name, plan_jump, k, t) if swing is not None and plan_jump is not None \
                    else 0.0
                sel.advance(t, None if nxt is None else engine.toe_point(nxt), jump)
        except errors as exc:
            # the loop's own checks, the controller wrapper and falls word their reason whole; any other error
            # (contact, command, linear algebra, an engine's own) gets its time and phase
            own = isinstance(exc, FallError) or type(exc) in (SimulationError, ControllerError)
            reason = str(exc) if own else f"{type(exc).__name__} at t = {t:.3f} s in {sel.where()}: {exc}"
            status = RunStatus.FELL if isinstance(exc, FallError) else RunStatus.FAILED
            error, trace_text = exc, "".join(tb.format_exception(exc))
        except KeyboardInterrupt:
            reason = f"interrupted by the user at t = {t:.3f} s"
            status = RunStatus.INTERRUPTED
        sel.close(t)
        try:
            log, trace = _build(engine, rows, h)
        except KeyboardInterrupt:  # an interrupt during the post-loop pass: finish it, report the interruption
            log, trace = _build(engine, rows, h)
            if status is not RunStatus.INTERRUPTED:
                completed, reason = False, f"interrupted by the user at t = {t:.3f} s"
                status = RunStatus.INTERRUPTED
    finally:
        close = getattr(engine, "close", None)
        if close is not None:
            close()
    extra = {"nominal_end": nominal_end, "engine": engine.name, "controller": checked.name}
    if drive is not None:
        extra["actuators"] = getattr(drive, "report", dict)()
    extra.update(getattr(controller, "run_info", lambda: {})())
    extra.update(getattr(engine, "run_info", lambda: {})())
    if scenario.disturbances is not None:
        extra["disturbances"] = summary_entry(extra, seen, scenario, engine)
    names = [p.name for p in traj.phases]
    if hold is not None:
        names[0] = hold.value
    return SimResult(log=log, phases=sel.records, phases_planned=n_phases, completed=completed, reason=reason,
                     sim_time=t, wall_time=time.perf_counter() - wall0, steps=steps, stage_evaluations=checked.calls,
                     extra=extra, phase_names=names, status=status, error=error, traceback=trace_text,
                     trace=trace)


def _build(engine: Engine, rows: list[StepRow], h: float) -> tuple[SimLog, Trace | None]:
    """The run's log and its full-rate trace: the engine's own (``build_trace``) when it records one, else the log
    (every integration step of such an engine is a loop step of ``h`` s); None without a logged step."""
    log = engine.build_log(rows)
    build_trace = getattr(engine, "build_trace", None)
    trace = build_trace() if build_trace is not None else None
    if trace is None and len(log):
        trace = trace_of_log(log.arrays(), h)
    return log, trace


__all__ = ["RUN_ERRORS", "SimResult", "run", "thresholds_of"]
