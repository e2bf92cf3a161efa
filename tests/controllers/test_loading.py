"""User controllers (humanoid_sim.controllers.loading): a user's controller on every engine, a scenario's
``controller_class``, bad controllers and what they are told."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.simulate import Simulator

ROOT = Path(__file__).resolve().parents[2]
SIM1 = ROOT / "scripts" / "params" / "sim1.yaml"
PKG = ROOT / "humanoid_sim"


def _standing_pd():
    sys.path.insert(0, str(ROOT / "scripts" / "examples"))
    try:
        from standing_pd import StandingPD
    finally:
        sys.path.pop(0)
    return StandingPD


@pytest.mark.parametrize("engine", ["pinocchio", "mujoco"])
def test_standing_pd_holds_the_hip_on_both_engines(hm, engine):
    """The template controller (kp 200 N m/rad, kd 20 N m s/rad) keeps the hip within 5 mm of its start for 3 s in
    double support, on the weld engine and on MuJoCo, at a user controller's control period (1 ms)."""
    sim = Simulator(hm, load_scenario(SIM1), engine=engine, controller=_standing_pd()())
    result = sim.run(t_end=3.0, hold=Phase.RFFDSP)
    assert result.reason.startswith("stopped at t = 3.000"), result.reason
    log = result.log.arrays()
    assert len(log["t"]) == 300 and (log["basic_phase"] == 1).all()
    drift = np.linalg.norm(log["hip_p"] - log["hip_p"][0], axis=1).max()
    assert drift < 5e-3, drift
    # the controller's torques, not a weld, hold the posture: the joints carry the weight (knee torque tens of N m)
    assert np.abs(log["tau"][:, 6:]).max() > 10.0


@pytest.mark.slow
def test_standing_pd_script_writes_a_playback(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, str(ROOT / "scripts" / "examples" / "standing_pd.py"), "--out",
                           str(tmp_path), "--seconds", "0.5"], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "hip drift max" in proc.stdout
    assert (tmp_path / "playback.html").stat().st_size > 10_000 and (tmp_path / "results.npz").exists()


BAD = {
    "nan": "return np.full(26, np.nan) if obs.t > 0.05 else np.zeros(26)",
    "shape": "return np.zeros(7)",
    "raises": "raise RuntimeError('my bug')",
}


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(BAD))
def test_bad_user_controller_stops_the_run_with_its_name(tmp_path, kind):
    """A controller named in the scenario that returns NaN, a wrong shape or raises: exit 1, a message naming it,
    partial results kept."""
    (tmp_path / "badctl.py").write_text(textwrap.dedent(f"""
        import numpy as np
        class Bad:
            name = "bad_{kind}"
            def setup(self, ctx):
                pass
            def __call__(self, obs):
                {BAD[kind]}
        """))
    scen = tmp_path / "scen.yaml"
    scen.write_text(SIM1.read_text() + "\ncontroller_class: badctl:Bad\n")
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{tmp_path}"}
    proc = subprocess.run([sys.executable, str(ROOT / "scripts" / "walk.py"), str(scen), "--out", str(out),
                           "--no-plots", "--no-html", "--quiet"], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert f"controller 'bad_{kind}'" in proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"] is False and f"bad_{kind}" in summary["reason"]
    assert (out / "results.npz").exists()
    if kind == "nan":  # five good steps before the NaN: kept
        assert summary["steps"] >= 5


@pytest.mark.slow
def test_unknown_controller_class_is_bad_input(tmp_path):
    scen = tmp_path / "scen.yaml"
    scen.write_text(SIM1.read_text() + "\ncontroller_class: no_such_module_xyz:Ctl\n")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(ROOT / "scripts" / "walk.py"), str(scen), "--out", str(out),
                           "--quiet"], capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)},
                          timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "controller_class" in proc.stderr and "no_such_module_xyz" in proc.stderr
    assert not out.exists() or not any(out.iterdir())


# --------------------------------------------------------------------------------------------- load_controller
class _NotAController:
    pass


class _Unnamed:
    def setup(self, ctx):
        pass

    def __call__(self, obs):
        return np.zeros(26)


class _Raises:
    def __init__(self):
        raise RuntimeError("needs a licence file")


def test_load_controller_builds_the_named_class():
    from humanoid_sim.controllers.loading import load_controller

    obj = load_controller(f"{__name__}:_Unnamed")
    assert type(obj).__name__ == "_Unnamed" and type(obj).__module__ == __name__
    assert obj.name == f"{__name__}:_Unnamed"     # a controller without a name is called by its spec


@pytest.mark.parametrize("spec, message", [
    ("no_colon", r"controller_class: expected 'package.module:ClassName', got 'no_colon'"),
    ("a.b:C:D", r"expected 'package.module:ClassName'"),
    ("no_such_module_xyz:Ctl", r"cannot import module 'no_such_module_xyz' \(ModuleNotFoundError"),
    (f"{__name__}:Missing", rf"module '{__name__}' has no 'Missing'"),
    (f"{__name__}:_Raises", r"_Raises\(\) failed \(RuntimeError: needs a licence file\)"),
    (f"{__name__}:_NotAController", r"is not a controller: it needs a setup\(ctx\) method"),
])
def test_load_controller_names_what_is_wrong(spec, message):
    from humanoid_sim.controllers.loading import ControllerLoadError, load_controller
    from humanoid_sim.errors import InputError

    with pytest.raises(ControllerLoadError, match=message) as info:
        load_controller(spec)
    assert isinstance(info.value, InputError)   # bad input: exit status 2
