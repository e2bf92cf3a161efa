"""The landing audit (humanoid_sim/engines/landing.py) against independent computations: the sole geometry rotated by
hand, Newton for impulses (the whole-body momentum change equals the sum of the ground impulses), and the
friction-cone ratio on hand-made impulses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from humanoid_sim.analysis.audit import SoleGeometry
from humanoid_sim.engines.impact import touchdown
from humanoid_sim.engines.landing import cone_ratio, landing_record, landing_summary
from humanoid_sim.references.initial import initial_configuration
from humanoid_sim.robot.phases import FOOT_SPECS, Phase
from humanoid_sim.scenario.schema import parse_scenario

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def q0(hm):
    sc = parse_scenario(yaml.safe_load((ROOT / "scripts" / "params" / "sim3.yaml").read_text()), "sim3")
    return initial_configuration(hm, sc.path)


def _record(hm, q, v, law="inelastic"):
    res = touchdown(hm.model, q, v, Phase.LFFSSP, law,
                    w_adj=np.ones(14) if law == "thesis" else None)
    return landing_record(hm.model, hm.model.createData(), q, res, 1.0, "R", SoleGeometry.from_model(hm)), res


def _corners_by_hand(hm, q, foot):
    """World sole corners of ``foot`` from the frame placements, composed by hand (rotation and translation)."""
    model, data = hm.model, hm.model.createData()
    pin.framesForwardKinematics(model, data, q)
    sole = SoleGeometry.from_model(hm)
    out = []
    for frame, pts in ((FOOT_SPECS[foot].main_frame, sole.heel_corners()),
                       (FOOT_SPECS[foot].toe_frame, sole.toe_corners())):
        M = data.oMf[model.getFrameId(frame)]
        out += [M.rotation @ p + M.translation for p in pts]
    return np.array(out)


def test_tilt_and_lowest_corner_of_a_tilted_robot(hm, q0):
    flat, _ = _record(hm, q0, np.zeros(hm.model.nv))
    assert flat.tilt_rad < 1e-9                   # the initial stance has flat feet (round-off of the posture solve)
    assert abs(flat.lowest_corner_m) < 1e-9       # and its soles on z = 0
    # rotate the whole robot by a about the world x axis through the origin: every frame turns by a
    a = np.radians(2.0)
    Ra = pin.rpy.rpyToMatrix(a, 0.0, 0.0)
    q = q0.copy()
    base = pin.XYZQUATToSE3(q0[:7])
    q[:7] = pin.SE3ToXYZQUAT(pin.SE3(Ra, np.zeros(3)) * base)
    rec, _ = _record(hm, q, np.zeros(hm.model.nv))
    assert rec.tilt_rad == pytest.approx(a, abs=1e-9)   # 1e-9 rad: round-off of arccos near 2 deg
    world = (Ra @ _corners_by_hand(hm, q0, "R").T).T
    assert rec.lowest_corner_m == pytest.approx(world[:, 2].min(), abs=1e-12)   # same points, another composition


def test_momentum_change_is_the_sum_of_the_ground_impulses(hm, q0):
    """Newton for an impulse: m (v_com+ - v_com-) = sum of the ground impulses (the lock rows are internal)."""
    rng = np.random.default_rng(7)
    v = rng.normal(0.0, 0.3, hm.model.nv)
    rec, res = _record(hm, q0, v)
    assert res.impulse is not None and set(rec.impulses_Ns) == {"R", "L"}
    total = sum(rec.impulses_Ns.values())
    # 1e-9 N s: the impulses solve a well-conditioned KKT system; the momentum comes from centerOfMass
    np.testing.assert_allclose(rec.momentum_change_Ns, total, rtol=0, atol=1e-9)
    assert np.linalg.norm(rec.momentum_change_Ns) > 1.0   # a real impact at 0.3 rad/s rates, not a trivial zero


def test_thesis_law_has_no_per_foot_impulse_but_a_momentum_change(hm, q0):
    rng = np.random.default_rng(8)
    rec, res = _record(hm, q0, rng.normal(0.0, 0.3, hm.model.nv), law="thesis")
    assert res.impulse is None and rec.impulses_Ns == {}
    mass = sum(hm.model.inertias[j].mass for j in range(1, hm.model.njoints))
    # the CoM velocity another way: the mass-weighted sum of the body CoM velocities, each from its own frame
    d = hm.model.createData()

    def vcom(v):
        pin.forwardKinematics(hm.model, d, q0, v)
        return sum(hm.model.inertias[j].mass * (d.oMi[j].rotation @ (d.v[j].linear + np.cross(
            d.v[j].angular, hm.model.inertias[j].lever))) for j in range(1, hm.model.njoints)) / mass

    # 1e-9 N s: round-off of two sums over 27 bodies at ~10 N s
    np.testing.assert_allclose(rec.momentum_change_Ns, mass * (vcom(res.v_plus) - vcom(res.v_minus)), rtol=0,
                               atol=1e-9)


def test_cone_ratio_and_summary_counts():
    assert cone_ratio(np.array([0.3, 0.4, 1.0])) == pytest.approx(0.5)
    assert cone_ratio(np.array([0.3, 0.4, -1.0])) == np.inf        # pulls
    assert cone_ratio(np.array([1e-4, 0.0, -1e-4])) == 0.0           # below IMPULSE_TOL_NS: no impulse
    from humanoid_sim.engines.landing import Landing

    ok = Landing(0.0, "R", "inelastic", 0.001, 0.001, 0.0, np.array([0.1, 0.0, 1.0]),
                 {"R": np.array([0.1, 0.0, 1.0]), "L": np.zeros(3)})
    slips = Landing(1.0, "L", "inelastic", 0.002, 0.001, -0.002, np.array([1.0, 0.0, 1.0]),
                    {"L": np.array([1.0, 0.0, 1.0]), "R": np.array([0.0, 0.0, -0.01])})
    s = landing_summary([ok, slips], mu=0.8)
    assert s["count"] == 2 and s["inside_cone"] == 1 and s["foot_impulses_pulling"] == 1
    assert s["foot_impulse_pulling_max_Ns"] == pytest.approx(0.01)
    assert s["foot_impulse_cone_ratio_max"] == pytest.approx(1.0) and s["lowest_corner_m"] == -0.002
    assert s["tilt_max_rad"] == 0.002
