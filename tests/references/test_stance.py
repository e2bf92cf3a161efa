"""The zmp gait's ready stance (humanoid_sim/references/zmp/stance.py) against hand geometry and the audit's
distances."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from humanoid_sim.analysis.audit import signed_distance
from humanoid_sim.references.initial import initial_configuration
from humanoid_sim.references.zmp.errors import GaitError
from humanoid_sim.references.zmp.stance import deepest_point_near, lead_in_polygon
from humanoid_sim.references.zmp.zmp_walk import initial_state
from humanoid_sim.scenario.schema import load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[2]
SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@pytest.mark.parametrize("point, expected", [
    ((0.5, 0.5), (0.5, 0.5)),          # deep enough already: unchanged
    ((0.5, 0.05), (0.5, 0.1)),         # below the bottom band: straight up to it
    ((-1.0, 0.5), (0.1, 0.5)),         # outside on the left: onto the shrunk left edge
    ((-1.0, -1.0), (0.1, 0.1)),        # outside a corner: the shrunk square's corner
])
def test_deepest_point_near_a_square(point, expected):
    # 1e-7: SLSQP's tolerance (ftol 1e-14 on squared distances of order 1)
    np.testing.assert_allclose(deepest_point_near(np.array(point), SQUARE, 0.1), expected, atol=1e-7)


def test_a_margin_wider_than_the_polygon_is_an_error():
    with pytest.raises(GaitError, match="ready stance: no point 0.6 m inside"):
        deepest_point_near(np.array([0.5, 0.5]), SQUARE, 0.6)


@pytest.fixture(scope="module")
def sim1_zmp():
    return load_scenario(ROOT / "scripts" / "params" / "sim1_zmp.yaml")   # over its base sim1.yaml


def test_ready_stance_puts_the_com_its_margin_inside_and_keeps_the_feet(hm, sim1_zmp):
    model, d = hm.model, hm.model.createData()
    q0 = initial_configuration(hm, sim1_zmp.path)
    q = initial_state(hm, sim1_zmp)
    poly = lead_in_polygon(hm, q0, "L")
    before = signed_distance(pin.centerOfMass(model, d, q0)[:2], poly)
    after = signed_distance(pin.centerOfMass(model, d, q)[:2], poly)
    assert before < 0.005                                  # chapter 3's stance: on the edge (1.4 mm inside)
    assert after == pytest.approx(sim1_zmp.gait.ready_margin_m, abs=1e-6)   # ready_stance's tol is 1e-7 m
    frames = {}
    for qq in (q0, q):
        pin.framesForwardKinematics(model, d, qq)
        frames[id(qq)] = {f: d.oMf[hm.frame_id(f)].copy() for f in ("P_tpR", "P_tpL", "O_1", "O_2", "O_17", "Pc_17")}
    a, b = frames[id(q0)], frames[id(q)]
    for f in ("P_tpR", "P_tpL", "O_1", "O_2"):      # the feet where they were (1e-9: the IK's tolerance is 1e-12)
        assert a[f].isApprox(b[f], 1e-9), f
    np.testing.assert_allclose(b["O_17"].rotation, a["O_17"].rotation, atol=1e-9)   # Body 17 still upright
    assert b["Pc_17"].translation[2] == pytest.approx(a["Pc_17"].translation[2], abs=1e-9)   # same height
    assert np.linalg.norm(b["Pc_17"].translation[:2] - a["Pc_17"].translation[:2]) > 0.01     # the hip moved


def test_thesis_gait_and_zero_margin_keep_chapter_3s_stance(hm, sim1_zmp):
    doc = yaml.safe_load((ROOT / "scripts" / "params" / "sim1.yaml").read_text())
    thesis = parse_scenario(doc, "sim1")
    assert np.array_equal(initial_state(hm, thesis), initial_configuration(hm, thesis.path))
    doc["gait"] = {"hip_reference": "zmp_preview", "ready_margin_m": 0.0}
    zero = parse_scenario(doc, "sim1")
    assert np.array_equal(initial_state(hm, zero), initial_configuration(hm, zero.path))
