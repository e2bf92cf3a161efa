"""The one stepping loop (humanoid_sim.sim.loop.run) driven with a scripted engine: no physics, so every count,
time, reason and phase change below is known by hand."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

from humanoid_sim.errors import SimulationError
from humanoid_sim.interfaces.controller import Observation
from humanoid_sim.interfaces.engine import Engine
from humanoid_sim.interfaces.log import SimLog
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.robot.phases import Phase
from humanoid_sim.sim.loop import run
from humanoid_sim.sim.status import RunStatus
from tests.conftest import ROOT

NV = 32


@pytest.fixture(scope="module")
def sc(sim1):
    return sim1


@pytest.fixture()
def traj(sc):
    return ReferenceTrajectory(sc.path)  # fresh: a touchdown teaches the trajectory its landing


class ScriptedEngine:
    """The engine interface with scripted kinematics: the hip stays at ``hip``, the swing toe in the air until
    ``land_after`` steps, then exactly on the planned end point (flat-toe height)."""

    name = "scripted"
    constraints = None

    def __init__(self, hip=(0.0, 0.0, 0.9), land_after: int | None = None, signal=None, check=None) -> None:
        self.model = SimpleNamespace(nv=NV)
        self.hip = np.array(hip, dtype=float)
        self.land_after = land_after
        self.steps = 0
        self.commands, self.touchdowns, self.entered = [], [], []
        self.closed = 0
        self.rows = None
        self.checks = None
        if signal is not None:
            self.touchdown_signal = signal
        if check is not None:
            self.check = check

    def start(self, q0, phase):
        self.q, self.v, self.started = np.array(q0, dtype=float), np.zeros(NV), phase

    def step(self, t, h, k, control, checks):
        self.checks = checks
        self.commands.append(control(Observation(t, k, checks.phase, self.q, self.v, None, 0, checks.plan_delay)))
        self.steps += 1
        return ("record", self.steps)

    def state_vectors(self):
        return self.q, self.v

    def hip_com(self):
        return self.hip.copy()

    def toe_point(self, foot):
        if self.checks is not None and self.land_after is not None and self.steps >= self.land_after:
            end = np.array(self.checks.targets.swing_toe_end, dtype=float)
            return np.array([end[0], end[1], 0.015])   # flat on the ground (toe_flat_height_m)
        return np.array([0.0, 0.0, 0.3])                # in the air above the origin

    def toe_rotation(self, foot):
        return np.eye(3)

    def touchdown(self, t, phase, foot, key):
        self.touchdowns.append((t, phase, foot, key))

    def enter(self, phase):
        self.entered.append(phase)

    def build_log(self, rows):
        self.rows = rows
        return SimLog()

    def close(self):
        self.closed += 1


class Constant:
    """Returns the same 26 joint torques every call (or raises ``exc`` at call ``fail_at``)."""

    name = "constant"

    def __init__(self, exc: BaseException | None = None, fail_at: int = 0) -> None:
        self.exc, self.fail_at, self.calls, self.landings = exc, fail_at, 0, 0

    def __call__(self, obs):
        self.calls += 1
        if self.exc is not None and self.calls > self.fail_at:
            raise self.exc
        return np.arange(26.0)

    def landing(self):
        self.landings += 1


def test_the_scripted_engine_offers_the_engine_interface() -> None:
    assert isinstance(ScriptedEngine(), Engine)   # so these tests drive the loop as a real engine would


def test_runs_to_the_requested_stop_and_logs_every_step(sc, traj) -> None:
    h = sc.simulation.step_s
    eng, ctrl = ScriptedEngine(), Constant()
    res = run(eng, ctrl, traj, sc, np.zeros(33), t_end=5 * h)
    assert res.steps == 5 and res.stage_evaluations == 5 and ctrl.calls == 5
    assert not res.completed and res.reason == f"stopped at t = {5 * h:.3f} s (requested stop time)"
    assert res.status is RunStatus.STOPPED and res.error is None
    assert res.sim_time == pytest.approx(5 * h, abs=1e-12)
    assert eng.started is Phase(traj.phases[0].name) and eng.closed == 1
    t = np.array([r.t for r in eng.rows])
    np.testing.assert_allclose(t, h * np.arange(5), atol=1e-12)
    assert [r.k for r in eng.rows] == [0] * 5 and {r.phase for r in eng.rows} == {Phase.LFFSSP}
    for r in eng.rows:  # the nominal references at t and the engine's record, side by side
        np.testing.assert_array_equal(r.reference.hip_p, traj.sample_global(r.t).hip_p)
        np.testing.assert_array_equal(r.hip_ctrl_ref, traj.hip_reference(0, r.t)[0])
    assert [r.record for r in eng.rows] == [("record", i) for i in range(1, 6)]
    assert len(res.phases) == 1 and res.phases[0].t_end == pytest.approx(5 * h)
    assert res.phase_names == [p.name for p in traj.phases]
    assert res.extra["engine"] == "scripted" and res.extra["controller"] == "constant"


def test_joint_torques_become_generalized_forces(sc, traj) -> None:
    eng = ScriptedEngine()
    run(eng, Constant(), traj, sc, np.zeros(33), t_end=sc.simulation.step_s)
    tau = eng.commands[0].tau
    assert tau.shape == (NV,)
    np.testing.assert_array_equal(tau, np.concatenate([np.zeros(6), np.arange(26.0)]))  # base rows unactuated


def test_a_raising_controller_ends_the_run_with_its_name(sc, traj) -> None:
    h = sc.simulation.step_s
    eng = ScriptedEngine()
    res = run(eng, Constant(ZeroDivisionError("boom"), fail_at=2), traj, sc, np.zeros(33), t_end=10 * h)
    assert not res.completed and res.steps == 2
    assert res.reason == f"controller 'constant' raised ZeroDivisionError at t = {2 * h:.3f} s: boom"
    assert res.status is RunStatus.FAILED and isinstance(res.error.__cause__, ZeroDivisionError)
    assert len(eng.rows) == 2 and eng.closed == 1  # the log up to the failure is kept, the engine closed


def test_ctrl_c_is_a_reason_not_a_crash(sc, traj) -> None:
    h = sc.simulation.step_s
    eng = ScriptedEngine()
    res = run(eng, Constant(KeyboardInterrupt(), fail_at=3), traj, sc, np.zeros(33), t_end=10 * h)
    assert res.reason == f"interrupted by the user at t = {3 * h:.3f} s" and res.steps == 3 and eng.closed == 1
    assert res.status is RunStatus.INTERRUPTED


def test_engine_check_and_fall_end_the_run(sc, traj) -> None:
    h = sc.simulation.step_s

    def check(t):
        if t > 1.5 * h:
            raise SimulationError(f"fell over at t = {t:.3f} s")

    res = run(ScriptedEngine(check=check), Constant(), traj, sc, np.zeros(33), t_end=10 * h)
    assert res.reason == f"fell over at t = {2 * h:.3f} s" and res.steps == 2 and res.status is RunStatus.FAILED
    low = sc.simulation.fall_height_m - 0.01
    res = run(ScriptedEngine(hip=(0.0, 0.0, low)), Constant(), traj, sc, np.zeros(33), t_end=10 * h)
    assert res.steps == 1 and res.reason.startswith(f"fall: hip CoM height {low:.3f} m below")
    assert res.status is RunStatus.FELL


def test_touchdown_switches_to_double_support(sc, traj) -> None:
    h = sc.simulation.step_s
    first = Phase(traj.phases[0].name)
    eng, ctrl = ScriptedEngine(land_after=2), Constant()
    res = run(eng, ctrl, traj, sc, np.zeros(33), t_end=4 * h)
    assert first is Phase.LFFSSP and first.swing_foot == "R"
    assert len(eng.touchdowns) == 1
    t, phase, foot, key = eng.touchdowns[0]
    assert (phase, foot, key) == (Phase.LFFSSP, "R", "Wadj_qdot_LFFSSP_to_RFFDSP") and t == pytest.approx(2 * h)
    assert eng.entered == [Phase.RFFDSP] and ctrl.landings == 1
    assert [p.name for p in res.phases] == ["LFFSSP", "RFFDSP"]
    assert res.phases[0].t_end == pytest.approx(2 * h) and res.phases[1].t_start == pytest.approx(2 * h)
    assert res.phases[0].touchdown_error_m == pytest.approx(0.0, abs=1e-12)  # landed on the planned point
    assert res.phases[0].landing_tilt_rad == pytest.approx(0.0, abs=1e-12)   # toe body level (identity)
    assert [r.k for r in eng.rows] == [0, 0, 1, 1]


def test_a_sensed_contact_replaces_the_height_rule_but_not_the_travel_guard(sc, traj) -> None:
    h = sc.simulation.step_s
    # on the planned point, but the engine senses no contact: no touchdown
    eng = ScriptedEngine(land_after=1, signal=lambda foot: False)
    run(eng, Constant(), traj, sc, np.zeros(33), t_end=3 * h)
    assert eng.touchdowns == []
    # contact sensed while the toe has not travelled (still above its start): the travel guard holds it back
    eng = ScriptedEngine(signal=lambda foot: True)
    run(eng, Constant(), traj, sc, np.zeros(33), t_end=3 * h)
    assert eng.touchdowns == []
    # both: touchdown at the first step boundary
    eng = ScriptedEngine(land_after=1, signal=lambda foot: True)
    run(eng, Constant(), traj, sc, np.zeros(33), t_end=3 * h)
    assert [td[2] for td in eng.touchdowns] == ["R"] and eng.touchdowns[0][0] == pytest.approx(h)


def test_hold_stays_in_one_phase(sc, traj) -> None:
    h = sc.simulation.step_s
    eng = ScriptedEngine(land_after=0)   # the toe on its target from the start: would switch without hold
    res = run(eng, Constant(), traj, sc, np.zeros(33), t_end=4 * h, hold=Phase.RFFDSP)
    assert eng.started is Phase.RFFDSP and eng.touchdowns == [] and eng.entered == []
    assert res.steps == 4 and res.phase_names[0] == "RFFDSP" and [p.name for p in res.phases] == ["RFFDSP"]
    assert {r.phase for r in eng.rows} == {Phase.RFFDSP}


def test_one_stepping_loop():
    """Only humanoid_sim/sim/loop.py applies the phase selector's switching rule and advances phases (the selector
    defines them)."""
    users = []
    for f in (ROOT / "humanoid_sim").rglob("*.py"):
        src = f.read_text()
        if "should_switch(" in src or ".advance(t" in src:
            users.append(f.relative_to(ROOT / "humanoid_sim").as_posix())
    assert sorted(users) == ["interfaces/selector.py", "sim/loop.py"], users


def test_the_touchdown_guard_measures_against_a_moved_landing() -> None:
    """A swing whose landing the controller moved back (step adjustment): a toe that covered 0.07 m of the 0.316 m
    planned travel is short of the guard's 30 % against the plan's end point and past it against the moved one."""
    from humanoid_sim.robot.phases import SwitchThresholds
    from humanoid_sim.sim.loop import _travelled

    sel = SimpleNamespace(thresholds=SwitchThresholds(), toe_start=np.array([0.159, 0.595, 0.015]),
                          targets=SimpleNamespace(swing_toe_end=np.array([0.16, 0.911, 0.015])))
    toe = np.array([0.217, 0.648, 0.015])
    assert not _travelled(sel, toe)
    assert _travelled(sel, toe, np.array([0.22, 0.66, 0.015]))


@pytest.mark.parametrize("hook, value, expected", [
    ("plan_jump", float("nan"), r"plan_jump returned nan at t = 0.020 s, expected a time >= 0 s"),
    ("plan_jump", -0.1, r"plan_jump returned -0.1 .* expected a time >= 0 s"),
    ("swing_landing", (1.0, 2.0), r"swing_landing returned \(1.0, 2.0\) .* expected None or a world point"),
    ("swing_landing", ZeroDivisionError("boom"), r"swing_landing raised ZeroDivisionError at t = 0.010 s: boom"),
])
def test_a_bad_hook_answer_ends_the_run_naming_the_controller(sc, traj, hook, value, expected) -> None:
    """A controller's optional hooks (plan_jump, swing_landing) answer at a sensed touchdown: a wrong answer or a
    failure ends the run with a ControllerError naming the controller and the hook, not a corrupt clock."""
    h = sc.simulation.step_s
    ctrl = Constant()

    def answer(k):
        if isinstance(value, BaseException):
            raise value
        return value

    setattr(ctrl, hook, answer)
    eng = ScriptedEngine(land_after=2, signal=lambda foot: True)
    res = run(eng, ctrl, traj, sc, np.zeros(33), t_end=4 * h)
    assert res.status is RunStatus.FAILED and "controller 'constant'" in res.reason, res.reason
    assert re.search(expected, res.reason), res.reason
