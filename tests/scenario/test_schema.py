"""Scenario validation (humanoid_sim/scenario/schema.py): every class of malformed input gives a ScenarioError whose
message names the file, the field path with its index, the value and the expectation.

Most cases go through ``parse_scenario`` on a mutated copy of scripts/params/sim1.yaml (fast); the file-level
cases (empty, not YAML, missing, object tags, duplicate keys) through ``load_scenario``.  The exit status and
the absence of output are checked through walk.py in tests/cli/test_walk.py.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from humanoid_sim.scenario.schema import ScenarioError, load_scenario, parse_scenario
from humanoid_sim.scenario.thesis_controller import CONTROLLER_SCHEMA

ROOT = Path(__file__).resolve().parents[2]
SIM1 = ROOT / "scripts" / "params" / "sim1.yaml"
SRC = "bad.yaml"


@functools.lru_cache(maxsize=1)
def _sim1() -> dict:
    return yaml.safe_load(SIM1.read_text())


def _set(path: str, value: Any) -> Callable[[dict], None]:
    """Mutator: set ``doc[a][b]...`` (dotted path; integer parts index lists)."""
    parts = [int(p) if p.lstrip("-").isdigit() else p for p in path.split(".")]

    def fn(doc: dict) -> None:
        node = doc
        for p in parts[:-1]:
            node = node[p]
        node[parts[-1]] = value
    return fn


def _del(path: str) -> Callable[[dict], None]:
    parts = path.split(".")

    def fn(doc: dict) -> None:
        node = doc
        for p in parts[:-1]:
            node = node[p]
        del node[parts[-1]]
    return fn


def _rename(path: str, new: str) -> Callable[[dict], None]:
    parts = path.split(".")

    def fn(doc: dict) -> None:
        node = doc
        for p in parts[:-1]:
            node = node[p]
        node[new] = node.pop(parts[-1])
    return fn


def _shorten(path: str, by: int = 1) -> Callable[[dict], None]:
    parts = path.split(".")

    def fn(doc: dict) -> None:
        node = doc
        for p in parts[:-1]:
            node = node[p]
        node[parts[-1]] = node[parts[-1]][:-by] if by > 0 else node[parts[-1]] + node[parts[-1]][:(-by)]
    return fn


def _both(*fns: Callable[[dict], None]) -> Callable[[dict], None]:
    def fn(doc: dict) -> None:
        for f in fns:
            f(doc)
    return fn


# (id, mutator, field prefix the message must start with after "bad.yaml: ", substrings it must contain)
CASES: list[tuple[str, Callable[[dict], None], str, tuple[str, ...]]] = [
    # ---- wrong type
    ("type-R-string", _set("path.R.2", "abc"), "path.R[2]", ("expected an arc radius in m > 0", "'abc'", "string")),
    ("type-Vhip-bool", _set("path.Vhip.0", True), "path.Vhip[0]", ("speed magnitude in m/s", "True", "boolean")),
    ("type-weights-scalar", _set("controller.Wp_fa_LFFSSP", "1000"), "controller.Wp_fa_LFFSSP",
     ("expected a list of 3 weights", "'1000'", "without quotes")),
    ("type-time-list", _set("controller.Delta_t1_LFFSSP", [0.1]), "controller.Delta_t1_LFFSSP",
     ("expected a prediction time in s in (0, 5]", "[0.1]", "a list")),
    ("type-yaml11-exponent", _set("controller.WpTetha18", "3e2"), "controller.WpTetha18",
     ("'3e2'", "YAML 1.1", "1.0e+3")),
    ("type-step-string", _set("simulation.step_s", "0.01"), "simulation.step_s", ("a step in s", "'0.01'")),
    ("type-waypoint-scalar", _set("path.Phip.1", 5), "path.Phip[1]", ("expected a waypoint [x, y, z] in m", "5")),
    ("type-reset-scalar", _set("reset.Wadj_qdot_LFFSSP_to_RFFDSP", 3), "reset.Wadj_qdot_LFFSSP_to_RFFDSP",
     ("expected a list of 14", "got 3 (an int)")),
    ("type-section-list", _set("path", [1, 2]), "path", ("expected a mapping", "list")),
    ("type-name-int", _set("name", 5), "name", ("non-empty string usable as a folder name", "5")),
    ("type-name-slash", _set("name", "a/b"), "name", ("folder name", "'a/b'")),
    ("type-method", _set("simulation.method", "ode45"), "simulation.method", ("one of ode3, rk4, euler", "'ode45'")),
    ("type-first-phase", _set("path.first_phase", "LFFDSP"), "path.first_phase", ("LFFSSP, RFFSSP", "'LFFDSP'")),
    ("type-nan", _set("path.Vhip.4", float("nan")), "path.Vhip[4]", ("speed", "nan")),
    # ---- wrong length
    ("len-Vhip", _shorten("path.Vhip"), "path.Vhip", ("2n-1 = 17 speeds for n = 9 waypoints", "got 16")),
    ("len-R", _shorten("path.R"), "path.R", ("n-1 = 8 entries, one per segment", "got 7")),
    ("len-T_dir-long", _shorten("path.T_dir", -1), "path.T_dir", ("n-1 = 8 entries", "got 9")),
    ("len-t_SSP", _shorten("path.t_SSP", 2), "path.t_SSP", ("n-1 = 8 entries", "got 6")),
    ("len-Wv_fa", _shorten("controller.Wv_fa_LFFSSP"), "controller.Wv_fa_LFFSSP", ("expected 6 entries", "got 5")),
    ("len-Wact", _shorten("controller.Wact_LFFDSP"), "controller.Wact_LFFDSP", ("expected 96 entries", "got 95")),
    ("len-WqH", _shorten("controller.WqH_R_LFFSSP"), "controller.WqH_R_LFFSSP", ("expected 8 entries", "got 7")),
    ("len-reset", _shorten("reset.Wadj_qdot_RFFSSP_to_LFFDSP"), "reset.Wadj_qdot_RFFSSP_to_LFFDSP",
     ("expected 14 entries", "got 13")),
    ("len-toe", _set("path.toe_R0", [0.16, 0.1876]), "path.toe_R0", ("expected 3 entries", "got 2")),
    ("len-rot-row", _set("path.foot_L0.1", [1, 0]), "path.foot_L0[1]", ("expected 3 entries", "got 2")),
    ("len-Phip-single", _set("path.Phip", [[0.0, 0.0, 0.93]]), "path.Phip", ("n >= 2 waypoints",)),
    ("len-Phip-2d", _set("path.Phip.3", [0.28, 0.35]), "path.Phip[3]", ("[x, y, z]", "[0.28, 0.35]")),
    # ---- out of range
    ("range-Vhip-negative", _set("path.Vhip.3", -0.1), "path.Vhip[3]", ("speed magnitude in m/s in [0, 5]", "-0.1")),
    ("range-t_SSP-zero", _set("path.t_SSP.2", 0), "path.t_SSP[2]", ("single-support duration in s in (0, 10]", "0")),
    ("range-k_SH-one", _set("path.k_SH.0", 1.0), "path.k_SH[0]", ("fraction of t_SSP in (0, 1)", "1.0")),
    ("range-k_Adj", _set("path.k_Adj.1", 0.9), "path.k_Adj[1]", ("ratio t_SSP/t_z in [1, 100]", "0.9")),
    ("range-T_dir-zero", _set("path.T_dir.4", 0), "path.T_dir[4]", ("turn direction, one of 1, -1", "got 0")),
    ("range-SH-low", _set("path.SH.0", 0.01), "path.SH[0]", ("flat-toe height", "0.01")),
    ("range-hip-height", _set("path.Phip.0.2", -0.5), "path.Phip[0][2]", ("hip height in m in (0, 2]", "-0.5")),
    ("range-weight-negative", _set("controller.Wa_a_LFFSSP.2", -1), "controller.Wa_a_LFFSSP[2]",
     ("expected a weight >= 0", "-1")),
    ("range-time-zero", _set("controller.Delta_t2_LFFSSP", 0), "controller.Delta_t2_LFFSSP",
     ("prediction time in s in (0, 5]", "got 0")),
    ("range-reset-zero", _set("reset.Wadj_qdot_LFFSSP_to_RFFDSP.5", 0), "reset.Wadj_qdot_LFFSSP_to_RFFDSP[5]",
     ("expected a weight > 0", "got 0")),
    ("range-mu", _set("contact", {"friction_coefficient": 0}), "contact.friction_coefficient",
     ("friction coefficient in (0, 5]", "got 0")),
    ("range-step", _set("simulation.step_s", 0.5), "simulation.step_s", ("step in s in [1e-05, 0.05]", "0.5")),
    ("range-fraction", _set("phase_switch.min_horizontal_progress_fraction", 1.5),
     "phase_switch.min_horizontal_progress_fraction", ("fraction in [0, 1]", "1.5")),
    ("range-rot-entry", _set("path.foot_R0.0.0", 2), "path.foot_R0[0][0]", ("rotation-matrix entry", "got 2")),
    # ---- impossible geometry (cross-field checks of PathParams)
    ("arc-too-small", _set("path.R.0", 0.05), "path.R[0]", ("arc cannot exist", "half the chord", "0.05")),
    ("arc-coincident", _both(lambda d: _set("path.Phip.1", list(d["path"]["Phip"][0]))(d)), "path.Phip[1]",
     ("coincide",)),
    ("hip-height-varies", _set("path.Phip.2.2", 1.25), "path.Phip[2]", ("constant hip height", "1.25")),
    ("step-wider-than-arc", _both(_set("path.R.3", 0.2), _set("path.SW.3", 0.5)), "path.SW[3]",
     ("half the step width must be below the radius", "0.5")),
    ("not-a-rotation", _set("path.foot_R0", [[1, 0, 0], [0, 1, 0], [0, 0, -1]]), "path.foot_R0",
     ("not a rotation matrix",)),
    # ---- unknown keys (closest valid name suggested at every level)
    ("unknown-top", _rename("controller", "controler"), "controler", ("unknown key", "did you mean 'controller'")),
    ("unknown-path", _rename("path.Vhip", "Vhips"), "path.Vhips", ("unknown key", "did you mean 'Vhip'")),
    ("unknown-controller", _rename("controller.Wp_fa_LFFSSP", "Wp_fa_LFSSP"), "controller.Wp_fa_LFSSP",
     ("unknown key", "did you mean 'Wp_fa_LFFSSP'")),
    ("unknown-simulation", _set("simulation.stepsize", 0.01), "simulation.stepsize",
     ("unknown key", "did you mean 'step_s'")),
    ("unknown-reset", _rename("reset.Wadj_qdot_LFFSSP_to_RFFDSP", "Wadj_qdot_LFFSSP_to_RFFDS"),
     "reset.Wadj_qdot_LFFSSP_to_RFFDS", ("did you mean 'Wadj_qdot_LFFSSP_to_RFFDSP'",)),
    ("unknown-phase-switch", _set("phase_switch.dsp_hip_distance", 0.05), "phase_switch.dsp_hip_distance",
     ("did you mean 'dsp_hip_distance_m'",)),
    ("unknown-contact-no-match", _set("contact", {"mu": 0.5}), "contact.mu", ("unknown key", "allowed: "
                                                                             "friction_coefficient")),
    # ---- missing keys
    ("missing-section", _del("controller"), "controller", ("missing section", "the thesis controller runs this walk")),
    ("missing-path-key", _del("path.SW"), "path.SW", ("missing",)),
    ("missing-controller-key", _del("controller.Wp_fa_RFFDSP"), "controller.Wp_fa_RFFDSP",
     ("missing", "3 values, a weight >= 0")),
    ("missing-reset-key", _del("reset.Wadj_qdot_RFFSSP_to_LFFDSP"), "reset.Wadj_qdot_RFFSSP_to_LFFDSP", ("missing",)),
]


@pytest.mark.parametrize("case_id, mutate, field, needles", CASES, ids=[c[0] for c in CASES])
def test_malformed_field(case_id, mutate, field, needles):
    doc = copy.deepcopy(_sim1())
    mutate(doc)
    with pytest.raises(ScenarioError) as err:
        parse_scenario(doc, SRC)
    msg = str(err.value)
    assert msg.startswith(f"{SRC}: {field}:"), msg
    for needle in needles:
        assert needle in msg, (needle, msg)
    assert "\n" not in msg  # one line


def test_at_least_thirty_cases_cover_every_class():
    classes = {c[0].split("-")[0] for c in CASES}
    assert len(CASES) >= 30 and classes == {"type", "len", "range", "arc", "hip", "step", "not", "unknown",
                                            "missing"}


# --------------------------------------------------------------------------------------------- file level
FILE_CASES = [
    ("empty", "", "the file is empty"),
    ("comment-only", "# nothing here\n", "the file is empty"),
    ("not-yaml", "path: [1, 2\nreset: {", "not valid YAML at line"),
    ("tabs", "path:\n\t- 1\n", "not valid YAML at line 2"),
    ("top-level-list", "- 1\n- 2\n", "top level: expected a mapping"),
    ("python-tag", "name: !!python/object/apply:os.system ['true']\n", "could not determine a constructor"),
    ("python-name", "name: !!python/name:os.system\n", "tags that construct objects are refused"),
    ("duplicate-key", "name: a\nname: b\n", "duplicate key 'name'"),
]


@pytest.mark.parametrize("case_id, text, needle", FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_malformed_file(tmp_path, case_id, text, needle):
    p = tmp_path / f"{case_id}.yaml"
    p.write_text(text)
    with pytest.raises(ScenarioError) as err:
        load_scenario(p)
    msg = str(err.value)
    assert msg.startswith(f"{p}: ") and needle in msg, msg


def test_missing_file_directory_and_binary(tmp_path):
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario(tmp_path / "nope.yaml")
    with pytest.raises(ScenarioError, match="not a regular file"):
        load_scenario(tmp_path)
    p = tmp_path / "latin1.yaml"
    p.write_bytes(b"name: caf\xe9\n")
    with pytest.raises(ScenarioError, match="cannot read as UTF-8"):
        load_scenario(p)


# --------------------------------------------------------------------------------------------- valid input
@pytest.mark.parametrize("name", ["sim1", "sim2", "sim3"])
def test_shipped_scenarios_load(name):
    sc = load_scenario(ROOT / "scripts" / "params" / f"{name}.yaml")
    assert sc.name == name and sc.contact.friction_coefficient == 0.8  # default of ContactSettings
    assert sc.path.Vhip.shape == (2 * sc.path.n_waypoints - 1,)


def test_optional_and_overridden_fields():
    doc = copy.deepcopy(_sim1())
    for k in ("Wact_LFFDSP", "Wact_RFFDSP", "Delta_t2_LFFDSP", "Delta_t2_RFFDSP"):
        del doc["controller"][k]  # read by no engine (errata ): optional
    doc["contact"] = {"friction_coefficient": 0.5}
    doc["simulation"]["t_end_s"] = None
    doc["controller"]["WpTetha18"] = 1.0e+3  # YAML "1.0e+3" is a float: accepted
    sc = parse_scenario(doc, SRC)
    assert sc.contact.friction_coefficient == 0.5 and sc.simulation.t_end_s is None
    assert sc.controller.upper_Wp[0] == 1000.0


def test_schema_sizes_match_the_shipped_files():
    """The controller schema's sizes equal the vector lengths of every shipped scenario (Appendix B)."""
    for name in ("sim1", "sim2", "sim3"):
        ctrl = yaml.safe_load((ROOT / "scripts" / "params" / f"{name}.yaml").read_text())["controller"]
        assert set(ctrl) == set(CONTROLLER_SCHEMA)
        for k, v in ctrl.items():
            assert np.size(v) == CONTROLLER_SCHEMA[k][0], (name, k)
