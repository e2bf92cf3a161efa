"""Scenario sections per controller, and ``base:`` inheritance (humanoid_sim.scenario.schema, .balance)."""

from __future__ import annotations

import copy
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
import yaml

from humanoid_sim.scenario import BalanceSettings, ScenarioError, load_scenario, parse_scenario
from humanoid_sim.scenario.schema import read_scenario_doc

PARAMS = Path(__file__).resolve().parents[2] / "scripts" / "params"
SIM1 = yaml.safe_load((PARAMS / "sim1.yaml").read_text())


def _zmp(doc: dict) -> dict:
    d = copy.deepcopy(doc)
    d["gait"] = {"hip_reference": "zmp_preview"}
    return d


def test_the_thesis_weights_are_required_only_when_the_thesis_controller_runs() -> None:
    thesis = copy.deepcopy(SIM1)
    del thesis["controller"]
    with pytest.raises(ScenarioError, match="controller: missing section: the thesis controller runs"):
        parse_scenario(thesis, "t.yaml")
    balance = _zmp(SIM1)
    del balance["controller"], balance["reset"]     # the balance QP and the inelastic impact law need neither
    sc = parse_scenario(balance, "b.yaml")
    assert sc.controller is None and sc.W_adj == {} and not sc.runs_thesis_controller
    zmp_thesis = copy.deepcopy(balance)
    zmp_thesis["gait"]["controller"] = "thesis"
    with pytest.raises(ScenarioError, match="gait.controller: thesis"):
        parse_scenario(zmp_thesis, "z.yaml")
    user = copy.deepcopy(SIM1)
    del user["controller"]
    user["controller_class"] = "mypkg.ctl:Standing"
    assert parse_scenario(user, "u.yaml").controller is None


def test_the_reset_weights_are_required_by_the_thesis_impact_law_only() -> None:
    doc = _zmp(SIM1)
    del doc["reset"]
    doc["simulation"] = {"impact_law": "thesis"}
    with pytest.raises(ScenarioError, match="reset: missing section"):
        parse_scenario(doc, "r.yaml")


def test_balance_settings_come_from_yaml_with_their_defaults() -> None:
    doc = _zmp(SIM1)
    doc["balance"] = {"hip_omega": 10, "cop_margin_ssp_m": 0.02, "time_shift": False}
    s = parse_scenario(doc, "b.yaml").balance
    assert (s.hip_omega, s.cop_margin_ssp_m, s.time_shift) == (10.0, 0.02, False)
    default = BalanceSettings()
    for f in fields(BalanceSettings):       # every other setting keeps its documented default
        if f.name not in doc["balance"]:
            assert getattr(s, f.name) == getattr(default, f.name) == f.default, f.name
    assert parse_scenario(_zmp(SIM1), "d.yaml").balance == default


@pytest.mark.parametrize("section, match", [
    ({"hip_omaga": 10}, r"balance\.hip_omaga: unknown setting \(did you mean 'hip_omega'\?\)"),
    ({"friction_safety": 1.5}, r"balance\.friction_safety = 1\.5: expected a finite number > 0 and <= 1"),
    ({"time_shift": "yes"}, r"balance\.time_shift = 'yes': expected true or false"),
    ({"foothold_settle_s": -0.01}, r"balance\.foothold_settle_s = -0\.01: expected a finite number >= 0"),
    ([1, 2], r"balance: expected a mapping of settings, got list"),
])
def test_a_bad_balance_setting_names_the_field_and_the_value(section, match) -> None:
    doc = _zmp(SIM1)
    doc["balance"] = section
    with pytest.raises(ScenarioError, match=match):
        parse_scenario(doc, "b.yaml")


def test_a_user_controller_gets_its_own_section() -> None:
    doc = copy.deepcopy(SIM1)
    doc["controller_class"] = "mypkg.ctl:Standing"
    doc["controller_settings"] = {"kp": 200.0, "kd": 20.0}
    assert parse_scenario(doc, "u.yaml").controller_settings == {"kp": 200.0, "kd": 20.0}
    del doc["controller_class"]
    with pytest.raises(ScenarioError, match="controller_settings: given without a controller_class"):
        parse_scenario(doc, "u.yaml")


@pytest.mark.slow
def test_the_settings_reach_the_controller_through_its_context() -> None:
    from humanoid_sim.api import prepare

    class Recorder:
        name = "recorder"

        def setup(self, ctx) -> None:
            self.settings = ctx.settings

        def __call__(self, obs):
            return np.zeros(26)

    doc = copy.deepcopy(SIM1)
    doc["controller_class"] = "mypkg.ctl:Standing"     # named, but the object given below is what runs
    doc["controller_settings"] = {"kp": 200.0}
    ctl = Recorder()
    prepare(parse_scenario(doc, "u.yaml"), controller=ctl)
    assert ctl.settings == {"kp": 200.0}
    sim = prepare(parse_scenario(_zmp(SIM1) | {"balance": {"w_hip": 50.0}}, "b.yaml"))
    assert sim.controller.settings.w_hip == 50.0


@pytest.mark.parametrize("name", ["sim1", "sim2", "sim3"])
def test_a_zmp_file_over_its_base_is_the_thesis_file_with_the_gait_added(name: str) -> None:
    base = yaml.safe_load((PARAMS / f"{name}.yaml").read_text())
    inherited = read_scenario_doc(PARAMS / f"{name}_zmp.yaml")
    expected = base | {"name": f"{name}_zmp", "gait": {"hip_reference": "zmp_preview"}}
    assert inherited == expected


def test_base_merges_mappings_and_keeps_its_own_name(tmp_path: Path) -> None:
    (tmp_path / "a.yaml").write_text((PARAMS / "sim3.yaml").read_text())
    (tmp_path / "b.yaml").write_text("base: a.yaml\nsimulation: {step_s: 0.005}\npath: {SH: [0.05, 0.05, 0.05, "
                                     "0.05, 0.05, 0.05, 0.05, 0.05]}\n")
    sc = load_scenario(tmp_path / "b.yaml")
    a = load_scenario(tmp_path / "a.yaml")
    assert sc.name == "b" and a.name == "sim3"         # a name is never inherited
    assert sc.simulation.step_s == 0.005 and sc.simulation.method == a.simulation.method
    assert list(sc.path.SH) == [0.05] * 8 and list(sc.path.R) == list(a.path.R)


@pytest.mark.parametrize("text, match", [
    ("base: missing.yaml\n", r"base: 'missing.yaml': no such file"),
    ("base: 3\n", r"base: expected the path of a scenario file"),
    ("base: c.yaml\n", r"a cycle of base files"),
])
def test_a_bad_base_names_the_field(tmp_path: Path, text: str, match: str) -> None:
    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(ScenarioError, match=match):
        load_scenario(tmp_path / "c.yaml")


def test_a_document_with_an_unresolved_base_is_refused() -> None:
    with pytest.raises(ScenarioError, match="base: 'sim1.yaml' must be resolved"):
        parse_scenario({**SIM1, "base": "sim1.yaml"}, "x.yaml")
