"""disturbances.model: the engine's robot differs from the model the controller is given."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from humanoid_sim import api
from humanoid_sim.scenario.schema import parse_scenario, read_scenario_doc
from tests.conftest import ROOT

SIM3_ZMP = ROOT / "scripts" / "params" / "sim3_zmp.yaml"


def _scenario(model: dict):
    doc = read_scenario_doc(SIM3_ZMP)
    return parse_scenario({**doc, "disturbances": {"model": model}}, "heavier.yaml")


@pytest.mark.parametrize("engine", ["pinocchio", pytest.param("mujoco", marks=pytest.mark.slow)])
def test_the_ground_carries_the_engines_robot_and_the_controller_keeps_its_own(engine: str) -> None:
    """Every mass 25 % above the controller's model: the controller's model weighs 55.04 kg, the engine's 68.81 kg,
    and the ground carries the engine's.  Over the standing lead-in (0.2-1 s) the mean vertical ground force / g
    is the engine's mass: Newton's law, up to the CoM's vertical acceleration as the plan shifts the weight
    (measured 0.5 % on both engines; 2 % is a quarter of the way to the controller's mass)."""
    sim = api.prepare(_scenario({"mass_scale": {"all": 1.25}}), engine)
    m_ctrl = sum(i.mass for i in sim.controller.hm.model.inertias)
    m_eng = sum(i.mass for i in sim.engine.hm.model.inertias)
    assert m_ctrl == pytest.approx(55.044, abs=1e-9) and m_eng == pytest.approx(1.25 * 55.044, abs=1e-9)
    res = sim.run(t_end=1.0)
    a = res.log.arrays()
    steady = a["t"] > 0.2
    fz = a["foot_wrench"][steady, :, 2].sum(axis=1)
    assert float(np.mean(fz)) / 9.81 == pytest.approx(m_eng, rel=0.02)
    assert res.extra["disturbances"]["model"]["engine_mass_kg"] == pytest.approx(m_eng, abs=1e-9)


@pytest.mark.parametrize("model, words", [
    ({"payload": {"mass_kg": -1}}, ["disturbances.model.payload.mass_kg", "expected a mass in kg"]),
    ({"friction": 0}, ["disturbances.model.friction", "friction coefficient"]),
    ({"mass": 1.2}, ["disturbances.model.mass", "unknown key"]),
])
def test_a_bad_model_entry_exits_2_naming_the_field(tmp_path: Path, model: dict, words: list[str]) -> None:
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump({"base": str(SIM3_ZMP), "disturbances": {"model": model}}))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(ROOT / "scripts" / "walk.py"), str(tmp_path / "bad.yaml"), "--out",
                           str(out), "--quiet"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    for w in words:
        assert w in proc.stderr, proc.stderr
    assert not out.exists()


def test_two_payloads_are_refused() -> None:
    from humanoid_sim.errors import InputError

    doc = read_scenario_doc(SIM3_ZMP)
    sc = parse_scenario({**doc, "robot": {"payload": {"mass_kg": 5}},
                         "disturbances": {"model": {"payload": {"mass_kg": 5}}}}, "two.yaml")
    with pytest.raises(InputError, match="disturbances.model.payload: the scenario's robot already carries"):
        api.prepare(sc, "pinocchio")


@pytest.mark.parametrize("direction", ["down", "sideways"])
@pytest.mark.parametrize("engine", ["pinocchio", pytest.param("mujoco", marks=pytest.mark.slow)])
def test_an_incline_turns_the_engines_gravity_and_newton_holds(engine: str, direction: str) -> None:
    """3 deg incline: the engine's gravity is g turned by 3 deg toward downhill (the walk's heading +y for sim 3:
    forward for ``down``, toward the right, +x, for ``sideways``), the controller's stays vertical.  Over the
    standing lead-in (0.2-0.99 s) the ground's impulse plus M g_engine T equals the change of the whole robot's
    momentum M (cdot1 - cdot0) (Pinocchio's CoM velocity of the logged states): Newton's law with the turned
    gravity, to 2e-3 of M g T (trapezoids over the 10 ms log rows: measured 3.5e-4 to 5.6e-4); with the vertical
    gravity the law would miss by sin 3 deg = 5.2e-2."""
    import math

    import pinocchio as pin

    sc = parse_scenario({**read_scenario_doc(SIM3_ZMP),
                         "disturbances": {"incline": {"angle_deg": 3, "direction": direction}}}, "incline.yaml")
    sim = api.prepare(sc, engine)
    g = sim.engine.hm.model.gravity.linear
    downhill = {"down": np.array([0.0, 1.0, 0.0]), "sideways": np.array([1.0, 0.0, 0.0])}[direction]
    np.testing.assert_allclose(g, 9.81 * (math.sin(math.radians(3)) * downhill - [0, 0, math.cos(math.radians(3))]),
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(sim.controller.hm.model.gravity.linear, [0.0, 0.0, -9.81])
    res = sim.run(t_end=1.0)
    a = res.log.arrays()
    model = sim.engine.hm.model
    data, M = model.createData(), pin.computeTotalMass(model)

    def momentum(i: int) -> np.ndarray:
        pin.centerOfMass(model, data, a["q"][i], a["v"][i])
        return M * data.vcom[0]

    i0, i1 = int(np.searchsorted(a["t"], 0.2)), len(a["t"]) - 1
    t, F = a["t"][i0:i1 + 1], a["foot_wrench"][i0:i1 + 1, :, :3].sum(axis=1)
    impulse = np.trapezoid(F, t, axis=0) + M * g * (t[-1] - t[0])
    scale = M * 9.81 * (t[-1] - t[0])
    assert float(np.abs(impulse - (momentum(i1) - momentum(i0))).max()) <= 2e-3 * scale
    assert res.extra["disturbances"]["incline"]["gravity_mps2"] == pytest.approx(list(g), abs=1e-15)
