"""Robot variants (humanoid_sim.robot.variant): the generated body table and model, checked against physics and
against the body table read independently."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from humanoid_sim.robot.model import DEFAULT_SPEC, DEFAULT_URDF
from humanoid_sim.robot.variant import (
    Payload,
    RobotVariant,
    stretched_inertia,
    variant_doc,
    variant_files,
    variant_model,
)
from humanoid_sim.scenario.robot import parse_robot
from tests.conftest import VARIANT_DOC

BASE = yaml.safe_load(DEFAULT_SPEC.read_text())


def _v(x):
    return x["value"] if isinstance(x, dict) else x


def _masses() -> dict[str, float]:
    """Body name -> mass of the shipped body table, read from the YAML directly (kg)."""
    return {b["name"]: float(_v(b["mass"])) for b in BASE["bodies"] if not b.get("virtual")}


def _frame(hm, name):
    data = hm.model.createData()
    pin.framesForwardKinematics(hm.model, data, hm.initial_q())
    return data.oMf[hm.frame_id(name)]


def test_the_nominal_variant_is_the_shipped_model() -> None:
    """No section, or one whose every factor is 1: the shipped URDF itself; and the generator, given factors of 1,
    writes the shipped URDF's lines (only its name and the comment naming its source differ)."""
    assert variant_files(RobotVariant()) == (DEFAULT_SPEC, DEFAULT_URDF)
    assert variant_model(None).urdf_path == DEFAULT_URDF
    ones = RobotVariant(length_scale=(("shank", 1.0),), mass_scale=(("all", 1.0),), payload=Payload(0.0))
    assert ones.is_nominal and variant_files(ones) == (DEFAULT_SPEC, DEFAULT_URDF)


def test_identity_factors_regenerate_the_shipped_urdf(tmp_path: Path) -> None:
    _, urdf = variant_files(RobotVariant(length_scale=(("shank", 1.0),)), folder=tmp_path)
    new = [ln for ln in urdf.read_text().splitlines() if "<robot name" not in ln and "<!-- variant" not in ln]
    old = [ln for ln in DEFAULT_URDF.read_text().splitlines() if "<robot name" not in ln]
    assert new == old


def test_model_mass_is_the_table_scaled_plus_the_payload(variant_hm) -> None:
    """Pinocchio's total mass of the generated model against the body table's masses times VARIANT_DOC's factors
    (all 1.1, the trunk bodies 0.9, the right thigh 1.2) plus the payload; 1e-12 kg: float printing in the URDF."""
    m = _masses()
    expected = sum(m.values()) * 1.1
    expected += (0.9 - 1.0) * 1.1 * (m["lower_trunk"] + m["upper_trunk"]) + (1.2 - 1.0) * 1.1 * m["right_thigh"]
    expected += 4.0
    assert pin.computeTotalMass(variant_hm.model) == pytest.approx(expected, abs=1e-12)


def test_a_stretched_cylinder_has_the_inertia_of_the_longer_cylinder() -> None:
    """A solid cylinder (mass m, radius r, length L along z): I = m (3 r^2 + L^2) / 12 across, m r^2 / 2 along.
    Stretched by s along z with its mass scaled by f it is the cylinder of mass f m and length s L."""
    m, r, L, s, f = 2.0, 0.04, 0.32, 1.3, 0.8
    cyl = lambda m, r, L: np.diag([m * (3 * r * r + L * L) / 12, m * (3 * r * r + L * L) / 12, m * r * r / 2])
    np.testing.assert_allclose(stretched_inertia(cyl(m, r, L), f, np.array([1.0, 1.0, s])), cyl(f * m, r, s * L),
                               rtol=1e-14, atol=0)


def test_segment_lengths_and_coms_follow_their_scales(variant_hm, hm) -> None:
    """Knee-to-ankle and hip-to-knee distances, and the shank's CoM from the knee, of the variant's model at the
    zero posture equal the thesis's times VARIANT_DOC's factors (shank 1.1, thigh 0.93); the foot's toe point
    ahead of the ankle (x of the foot's frame) times 1.08, its height below the ankle kept (the foot's length
    scales, not its height).  1e-12 m: float printing in the URDF."""
    d = lambda h, a, b: float(np.linalg.norm(_frame(h, a).translation - _frame(h, b).translation))
    for (a, b), f in ((("O_9", "O_3"), 1.1), (("O_11", "O_9"), 0.93), (("O_9", "Pc_9"), 1.1)):
        assert d(variant_hm, a, b) == pytest.approx(f * d(hm, a, b), abs=1e-12), (a, b)
    toe = lambda h: _frame(h, "O_3").actInv(_frame(h, "P_tpR").translation)
    np.testing.assert_allclose(toe(variant_hm), toe(hm) * [1.08, 1.0, 1.0], rtol=0, atol=1e-12)


def test_payload_is_merged_by_the_parallel_axis_theorem() -> None:
    """The upper trunk with a 4 kg point mass off its centre against Pinocchio's own sum of spatial inertias
    (pin.Inertia + pin.Inertia): mass, CoM and rotational inertia; 1e-12 relative (round-off)."""
    v = RobotVariant(payload=Payload(4.0, "upper_trunk", (0.06, 0.03, -0.1)))
    doc = variant_doc(BASE, v)
    body = next(b for b in BASE["bodies"] if b["name"] == "upper_trunk")
    c20 = float(_v(BASE["dimensions"]["c20"]))
    jxx, jyy, jzz, jxy, jxz, jyz = _v(body["inertia"])
    I0 = np.array([[jxx, jxy, jxz], [jxy, jyy, jyz], [jxz, jyz, jzz]])
    total = pin.Inertia(float(_v(body["mass"])), np.array([0.0, 0.0, -c20]), I0) + \
        pin.Inertia(4.0, np.array([0.06, 0.03, -0.1]), np.zeros((3, 3)))
    new = next(b for b in doc["bodies"] if b["name"] == "upper_trunk")
    jxx, jyy, jzz, jxy, jxz, jyz = _v(new["inertia"])
    assert _v(new["mass"]) == pytest.approx(total.mass, rel=1e-14)
    np.testing.assert_allclose(_v(new["com"]), total.lever, rtol=0, atol=1e-15)
    np.testing.assert_allclose([[jxx, jxy, jxz], [jxy, jyy, jyz], [jxz, jyz, jzz]], total.inertia, rtol=1e-12)


def test_whole_body_com_moves_by_the_payload(hm) -> None:
    """Without length changes, the whole robot's CoM with a payload p on body 20 is (M c + m_p p) / (M + m_p), p
    placed by the thesis model's own kinematics (Pinocchio's centerOfMass of both models at the zero posture)."""
    v = RobotVariant(payload=Payload(7.5, "upper_trunk", (0.05, -0.02, -0.2)))
    hv = variant_model(v)
    q = hm.initial_q()
    c0 = pin.centerOfMass(hm.model, hm.model.createData(), q)
    M = pin.computeTotalMass(hm.model)
    p = _frame(hm, "O_20").act(np.array([0.05, -0.02, -0.2]))
    np.testing.assert_allclose(pin.centerOfMass(hv.model, hv.model.createData(), q), (M * c0 + 7.5 * p) / (M + 7.5),
                               rtol=0, atol=1e-12)


def test_sole_follows_the_section(variant_hm) -> None:
    """Sole 0.25 m x 0.11 m: the heel moved, the toe tip kept (foot 1.08 x the thesis's 0.1876 m from the ankle)."""
    fs = variant_hm.spec.foot_sole
    assert fs["length"] == 0.25 and fs["width"] == 0.11
    assert fs["toe_front_x"] == pytest.approx(1.08 * 0.1876, abs=1e-12)
    assert fs["toe_front_x"] - fs["heel_back_x"] == pytest.approx(0.25, abs=1e-12)


def test_the_cache_writes_once_and_keys_by_parameters(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("HUMANOID_SIM_CACHE", str(tmp_path))
    v = RobotVariant(length_scale=(("thigh", 1.05),))
    spec, urdf = variant_files(v)
    assert urdf.parent == tmp_path / "models" and v.key() in urdf.name
    stamp = urdf.stat().st_mtime_ns
    assert variant_files(RobotVariant(length_scale=(("thigh", 1.05),))) == (spec, urdf)
    assert urdf.stat().st_mtime_ns == stamp
    assert variant_files(RobotVariant(length_scale=(("thigh", 1.06),)))[1] != urdf


@pytest.mark.parametrize("raw, match", [
    ({"length_scale": {"shin": 1.1}}, r"robot\.length_scale\.shin: unknown key; did you mean 'shank'"),
    ({"length_scale": {"shank": 3}}, r"robot\.length_scale\.shank: expected a length factor in \[0\.5, 2\], got 3"),
    ({"mass_scale": {"trunk": -1}}, r"robot\.mass_scale\.trunk: expected a mass factor"),
    ({"payload": {"mass_kg": 5, "body": "head"}}, r"robot\.payload\.body = 'head': expected one of lower_trunk"),
    ({"payload": {"body": "upper_trunk"}}, r"robot\.payload\.mass_kg: missing"),
    ({"length_scale": {"foot": 2.0}, "sole": {"length_m": 0.12}},
     r"robot\.sole\.length_m = 0\.12: expected more than the toe body's length"),
    ({"legs": 1}, r"robot\.legs: unknown key"),
])
def test_bad_sections_name_the_field(raw, match) -> None:
    from humanoid_sim.scenario.fields import ScenarioError

    with pytest.raises(ScenarioError, match=match):
        parse_robot("s.yaml", raw)


def test_the_conftest_variant_parses_as_written() -> None:
    section = parse_robot("<test>", VARIANT_DOC)
    assert section is not None
    v = section.variant
    assert section.actuators is None and not v.is_nominal
    assert dict(v.length_scale)["shank"] == 1.1 and v.payload == Payload(4.0, "upper_trunk", (0.06, 0.03, -0.1))


def test_hip_height_change_is_the_models_own(variant_hm, hm) -> None:
    """With straight legs (the zero posture), the lower trunk's CoM (Pc_17, the path's hip point) stands higher
    above the ankle (O_3) in the variant than in the thesis robot by exactly ``hip_height_change`` (Pinocchio's
    kinematics of both models; 1e-12 m: float printing)."""
    v = parse_robot("<test>", VARIANT_DOC).variant
    rise = lambda h: float(_frame(h, "Pc_17").translation[2] - _frame(h, "O_3").translation[2])
    assert rise(variant_hm) - rise(hm) == pytest.approx(v.hip_height_change(), abs=1e-12)


def test_the_path_follows_the_legs_unless_told(sim1) -> None:
    """``hip_height: follow_legs`` (the default) raises every hip waypoint by the variant's change; ``path`` keeps
    them; the rest of the path is untouched."""
    from humanoid_sim.scenario.schema import load_scenario, parse_scenario, read_scenario_doc
    from tests.conftest import ROOT

    doc = read_scenario_doc(ROOT / "scripts" / "params" / "sim1.yaml")
    rise = parse_robot("<test>", VARIANT_DOC).variant.hip_height_change()
    follow = parse_scenario({**doc, "robot": VARIANT_DOC}, "f.yaml")
    kept = parse_scenario({**doc, "robot": {**VARIANT_DOC, "hip_height": "path"}}, "k.yaml")
    base = load_scenario(ROOT / "scripts" / "params" / "sim1.yaml")
    np.testing.assert_array_equal(np.asarray(kept.path.Phip), np.asarray(base.path.Phip))
    np.testing.assert_allclose(np.asarray(follow.path.Phip)[:, 2], np.asarray(base.path.Phip)[:, 2] + rise,
                               rtol=0, atol=1e-15)
    np.testing.assert_array_equal(np.asarray(follow.path.Phip)[:, :2], np.asarray(base.path.Phip)[:, :2])
