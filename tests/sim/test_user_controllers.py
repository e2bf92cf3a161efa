"""A user's controller (not the shipped thesis or balance controller): the rate it runs at on each engine, the
example PD (scripts/examples/standing_pd.py, kp 200 N m/rad, kd 20 N m s/rad) standing on welds and on MuJoCo, and a
failing helper's traceback kept to the line."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from humanoid_sim.controllers.thesis.controller import ThesisController
from humanoid_sim.robot.phases import Phase
from humanoid_sim.sim.simulate import USER_ARMATURE_KG_M2, USER_CONTROL_PERIOD_S, Simulator, user_engine_options
from humanoid_sim.sim.status import RunStatus
from tests.conftest import ROOT


def _standing_pd() -> type:
    spec = importlib.util.spec_from_file_location("standing_pd", ROOT / "scripts" / "examples" / "standing_pd.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.StandingPD


class Counter:
    """Zero joint torques, counting the calls and remembering their times."""

    name = "counter"

    def setup(self, ctx):
        self.t = []

    def __call__(self, obs):
        self.t.append(obs.t)
        return np.zeros(26)


def test_user_controllers_get_a_control_period_and_shipped_ones_keep_theirs(hm, sim1) -> None:
    assert user_engine_options("pinocchio", Counter()) == {"control_period_s": USER_CONTROL_PERIOD_S}
    assert user_engine_options("mujoco", Counter()) == {"control_period_s": USER_CONTROL_PERIOD_S,
                                                        "armature_kg_m2": USER_ARMATURE_KG_M2}
    assert user_engine_options("thesis", Counter()) == {}
    assert user_engine_options("pinocchio", ThesisController(compiled=False)) == {}
    assert user_engine_options("mujoco", ThesisController(compiled=False)) == {}
    assert Simulator(hm, sim1, compiled=False).engine.control_period_s is None          # thesis: every stage
    mj = Simulator(hm, sim1, engine="mujoco", compiled=False).engine
    assert mj.settings.control_period_s == 0.002 and mj.settings.armature_kg_m2 == 0.0
    assert (mj.mm.model.dof_armature == 0.0).all()
    mj = Simulator(hm, sim1, engine="mujoco", controller=Counter()).engine
    assert (mj.mm.model.dof_armature[6:] == USER_ARMATURE_KG_M2).all() and (mj.mm.model.dof_armature[:6] == 0).all()


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco"])
def test_a_user_controller_is_called_once_per_control_period(hm, sim1, engine) -> None:
    c = Counter()
    r = Simulator(hm, sim1, engine=engine, controller=c).run(t_end=0.05, hold=Phase.RFFDSP)
    assert r.steps == 5 and r.stage_evaluations == len(c.t) == 50, (r.reason, len(c.t))
    np.testing.assert_allclose(c.t, USER_CONTROL_PERIOD_S * np.arange(50), atol=1e-12)


class PushedPD:
    """The example PD with a push: 5 N m more on every joint for the first 0.1 s (so the PD must bring the robot
    back, not merely sit in the equilibrium it starts at)."""

    def __init__(self) -> None:
        self.pd = _standing_pd()()
        self.name = "pushed_pd"

    def setup(self, ctx):
        self.pd.setup(ctx)

    def __call__(self, obs):
        return self.pd(obs) + (5.0 if obs.t < 0.1 else 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["pinocchio", "mujoco"])
@pytest.mark.parametrize("pushed", [False, True])
def test_the_example_pd_stands_3_s(hm, sim1, engine, pushed) -> None:
    """kp 200, kd 20 with gravity compensation through the contacts, the engines' defaults for a user controller.

    Bounds on the hip (Body-17 CoM) drift.  Without a push the PD starts in its equilibrium, so only the soles'
    settling into MuJoCo's soft contact moves the hip: 5 mm (the soles sink < 1 mm; measured 0.39 mm on MuJoCo,
    ~1e-13 m on welds).  The push (5 N m more on every joint for 0.1 s) deflects each joint by at most its static
    deflection 5 / kp = 25 mrad, which at the stance ankle alone moves the hip, 0.8 m above it, by 20 mm: the bound
    (measured 8.4 mm on welds, 7.8 mm on MuJoCo).  After the push the PD brings the hip back through a lightly damped
    sway about the ankles (period ~2 s): at 3 s the drift is below half its largest (measured 1.6 and 1.5 mm)."""
    ctrl = PushedPD() if pushed else _standing_pd()()
    r = Simulator(hm, sim1, engine=engine, controller=ctrl).run(t_end=3.0, hold=Phase.RFFDSP)
    assert r.status is RunStatus.STOPPED and r.reason.startswith("stopped at t = 3.000"), r.reason
    a = r.log.arrays()
    assert len(a["t"]) == 300 and r.stage_evaluations == 3000
    hip = a["hip_p"]
    drift = np.linalg.norm(hip - hip[0], axis=1)
    assert hip[:, 2].min() > sim1.simulation.fall_height_m
    if pushed:
        assert 1e-3 < drift.max() < 20e-3, drift.max()              # the push moved it, within the bound
        assert drift[-1] < drift.max() / 2, (drift[-1], drift.max())
    else:
        assert drift.max() < 5e-3, drift.max()
    if engine == "mujoco":
        assert not r.extra["ground"]["fell"]
        if not pushed:                                         # at rest; the armature is in the residual's RNEA
            assert a["dynamics_residual"].max() < 1e-6


HELPER = '''
def lookup(table, i):
    return table[i]            # raises IndexError past the end
'''

CONTROLLER = '''
import numpy as np

from deep_helper import lookup


class Failing:
    name = "failing"

    def setup(self, ctx):
        self.table = [0.0, 0.0]

    def __call__(self, obs):
        lookup(self.table, 0 if obs.t < 0.0045 else 7)
        return np.zeros(26)
'''


@pytest.fixture()
def failing_module(tmp_path, monkeypatch):
    (tmp_path / "deep_helper.py").write_text(textwrap.dedent(HELPER))
    (tmp_path / "failing_ctrl.py").write_text(textwrap.dedent(CONTROLLER))
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def test_a_helpers_error_keeps_its_file_and_line(hm, sim1, failing_module) -> None:
    from failing_ctrl import Failing

    r = Simulator(hm, sim1, controller=Failing()).run(t_end=0.1)
    assert r.status is RunStatus.FAILED
    assert "controller 'failing' raised IndexError at t = 0.005 s" in r.reason, r.reason
    assert isinstance(r.error.__cause__, IndexError)
    helper = str(failing_module / "deep_helper.py")
    assert f'File "{helper}", line 3, in lookup' in r.traceback, r.traceback


def test_walk_prints_the_helpers_file_and_line(failing_module) -> None:
    sc = (ROOT / "scripts" / "params" / "sim1.yaml").read_text()
    scenario = failing_module / "failing.yaml"
    scenario.write_text(sc + "\ncontroller_class: failing_ctrl:Failing\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(failing_module), str(ROOT)])}
    proc = subprocess.run([sys.executable, str(ROOT / "scripts" / "walk.py"), str(scenario), "--until", "0.1",
                           "--out", str(failing_module / "out"), "--no-plots", "--no-html", "--quiet"],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 1, (proc.returncode, proc.stdout, proc.stderr)
    assert f'File "{failing_module / "deep_helper.py"}", line 3, in lookup' in proc.stderr, proc.stderr
    assert "IndexError" in proc.stderr


class _FailsAtOnce:
    name = "fails_at_once"

    def setup(self, ctx):
        pass

    def __call__(self, obs):
        raise KeyError("theta99")


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco"])
def test_a_controller_failing_at_its_first_call_is_summarised(hm, sim1, engine) -> None:
    """A controller that raises at its very first call (a new controller's usual first run) ends the run with its
    reason, and the run is summarised like any other.  On real ground the summary's audit once crashed on the
    missing full-rate trace (an AttributeError instead of the controller's message)."""
    from humanoid_sim import api

    sim = Simulator(hm, sim1, engine=engine, controller=_FailsAtOnce())
    run = api.finish(sim, sim.run(t_end=0.1))
    assert run.result.status is RunStatus.FAILED
    assert "controller 'fails_at_once' raised KeyError at t = 0.000 s: 'theta99'" in run.result.reason
    assert run.summary["status"] == "failed" and "KeyError" in run.summary["reason"]
    assert run.summary["contact"]["rate"]["source"] == "log"


class _StoppedByCtrlC:
    name = "stopped"

    def setup(self, ctx):
        pass

    def __call__(self, obs):
        if obs.t >= 0.02:
            raise KeyboardInterrupt
        return np.zeros(26)


def test_a_walk_interrupted_on_real_ground_is_summarised(hm, sim1) -> None:
    """Ctrl-C during a MuJoCo walk: the summary is made from the log (the full-rate trace is not audited after an
    interrupt); it raised AttributeError, as a first-call failure did."""
    from humanoid_sim import api

    sim = Simulator(hm, sim1, engine="mujoco", controller=_StoppedByCtrlC())
    run = api.finish(sim, sim.run(t_end=0.1))
    assert run.result.status is RunStatus.INTERRUPTED
    assert run.summary["status"] == "interrupted" and run.summary["contact"]["rate"]["source"] == "log"
