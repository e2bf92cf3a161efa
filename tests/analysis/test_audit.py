"""Contact-feasibility audit (humanoid_sim/analysis/audit.py) on synthetic inputs with hand-computed answers, on the
model's sole geometry, and its figure (humanoid_sim/outputs/plots/audit.py)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
import yaml

from humanoid_sim import PACKAGE_DIR
from humanoid_sim.analysis.audit import (
    FLAT,
    NONE,
    TOE,
    AuditError,
    SoleGeometry,
    audit_contacts,
    audit_results,
    contact_kinds,
    convex_hull,
    signed_distance,
    sole_polygons,
)

MODEL_YAML = PACKAGE_DIR.parent / "models" / "thesis_humanoid.yaml"
UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])  # unit square, CCW, m
TIGHT = 1e-12  # m or N: pure float arithmetic on numbers of order 1 (a few roundings)


def wrench_at(p: tuple[float, float], f: tuple[float, float, float]) -> np.ndarray:
    """Wrench [f; moment about the world origin] of force f applied at the ground point p = (x, y, 0)."""
    f = np.asarray(f, dtype=float)
    return np.concatenate([f, np.cross([p[0], p[1], 0.0], f)])


def one_foot(wrenches: list[np.ndarray], polygon: np.ndarray = UNIT, mu: float = 0.8, phase: str = "RFFSSP"):
    """Audit of a right foot held flat on ``polygon`` for a sequence of wrenches."""
    n = len(wrenches)
    W = np.zeros((n, 2, 6))
    W[:, 0] = wrenches
    kind = np.tile([FLAT, NONE], (n, 1))
    return audit_contacts(np.arange(n) * 0.01, [phase] * n, W, kind, [[polygon, None] for _ in range(n)], mu)


# --------------------------------------------------------------------------------------------- geometry
def test_signed_distance_known_points():
    assert signed_distance([0.5, 0.5], UNIT) == pytest.approx(0.5, abs=TIGHT)
    assert signed_distance([0.9, 0.5], UNIT) == pytest.approx(0.1, abs=TIGHT)
    assert signed_distance([2.0, 0.5], UNIT) == pytest.approx(-1.0, abs=TIGHT)
    assert signed_distance([2.0, 2.0], UNIT) == pytest.approx(-math.sqrt(2.0), abs=TIGHT)
    assert signed_distance([1.0, 0.3], UNIT) == pytest.approx(0.0, abs=TIGHT)   # on an edge
    assert math.isnan(signed_distance([np.nan, 0.0], UNIT))


def test_convex_hull_drops_interior_and_collinear_points_and_is_ccw():
    pts = np.array([[1, 1], [0, 0], [0.5, 0.5], [1, 0], [0, 1], [0.5, 0.0], [0.2, 0.7]], dtype=float)
    h = convex_hull(pts)
    assert len(h) == 4 and {tuple(p) for p in h} == {(0, 0), (1, 0), (1, 1), (0, 1)}
    x, y = h[:, 0], h[:, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) == pytest.approx(1.0, abs=TIGHT)  # +area: CCW


def test_sole_geometry_matches_model_yaml_and_toe_frame(hm):
    """Corners against the numbers in models/thesis_humanoid.yaml and the model's own P_tpR frame."""
    fs = {k: v["value"] for k, v in yaml.safe_load(MODEL_YAML.read_text())["foot_sole"].items()}
    sole = SoleGeometry.from_model(hm)
    flat = sole.flat_corners()
    assert flat[:, 0].max() - flat[:, 0].min() == pytest.approx(fs["length"], abs=1e-9)  # yaml rounds to 0.1 mm
    assert flat[:, 1].max() - flat[:, 1].min() == pytest.approx(fs["width"], abs=TIGHT)
    assert flat[:, 0].min() == fs["heel_back_x"] and np.all(flat[:, 2] == fs["sole_z"])
    # the toe part ends at the toe point P_tpR; its z is the ground plane seen from O_1
    data = hm.model.createData()
    pin.framesForwardKinematics(hm.model, data, pin.neutral(hm.model))
    tp = data.oMf[hm.model.getFrameId("O_1")].actInv(data.oMf[hm.model.getFrameId("P_tpR")]).translation
    toe = sole.toe_corners()
    assert toe[:, 0].max() == pytest.approx(tp[0], abs=1e-9)  # the URDF stores lengths to ~1e-10 m
    assert toe[:, 0].min() == 0.0
    # toe point 0.015 m above the ground (thesis L1590): the sole is 0.015 m below the toe point in O_1
    assert toe[0, 2] == pytest.approx(tp[2] - 0.015, abs=1e-9)


def test_sole_polygons_at_the_initial_posture(hm):
    """Both feet flat at the start: the left sole spans x = -0.16 +- 0.045 m, y = toe tip - 0.226 .. toe tip."""
    q = hm.initial_q()
    data = hm.model.createData()
    pin.framesForwardKinematics(hm.model, data, q)
    tipL = data.oMf[hm.model.getFrameId("P_tpL")].translation
    tipR = data.oMf[hm.model.getFrameId("P_tpR")].translation
    polys = sole_polygons(hm, q[None, :], np.array([[FLAT, FLAT]]))[0]
    for poly, tip in ((polys[1], tipL), (polys[0], tipR)):
        lo, hi = poly.min(axis=0), poly.max(axis=0)
        # 1e-9 m: the initial posture is exact to rounding; the feet point along world +y (C0 = Rz(90 deg))
        assert lo[0] == pytest.approx(tip[0] - 0.045, abs=1e-9) and hi[0] == pytest.approx(tip[0] + 0.045, abs=1e-9)
        assert hi[1] == pytest.approx(tip[1], abs=1e-9) and lo[1] == pytest.approx(tip[1] - 0.226, abs=1e-9)
    # a toe-only contact has the toe part only: 0.0743 m x 0.09 m (toe joint to toe tip, l1 of Table 2.3)
    toe = sole_polygons(hm, q[None, :], np.array([[NONE, TOE]]))[0]
    assert toe[0] is None
    x, y = toe[1][:, 0], toe[1][:, 1]
    area = 0.5 * abs(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    assert area == pytest.approx(0.0743 * 0.09, rel=1e-6)  # 1e-6: lengths stored to ~1e-10 m


def test_contact_kinds_follow_the_design_table():
    """design.md s. 4: LFFSSP left flat; RFFDSP right flat + left toe; RFFSSP right flat; LFFDSP left flat +
    right toe."""
    k = contact_kinds(["LFFSSP", "RFFDSP", "RFFSSP", "LFFDSP"])
    assert k.tolist() == [[NONE, FLAT], [FLAT, TOE], [FLAT, NONE], [TOE, FLAT]]
    with pytest.raises(AuditError, match="phase name at step 0"):
        contact_kinds(["SSP"])


# --------------------------------------------------------------------------------------------- checks
def test_cop_inside_and_outside_the_sole():
    rep = one_foot([wrench_at((0.3, 0.5), (0, 0, 500)), wrench_at((1.25, 0.5), (0, 0, 500))])
    np.testing.assert_allclose(rep.cop[:, 0], [[0.3, 0.5], [1.25, 0.5]], atol=TIGHT)
    np.testing.assert_allclose(rep.cop_margin[:, 0], [0.3, -0.25], atol=TIGHT)
    assert rep.cop_outside[:, 0].tolist() == [False, True]
    assert rep.summary()["cop_outside_fraction"]["R"] == 0.5
    assert rep.summary()["min_cop_margin_m"]["R"] == pytest.approx(-0.25, abs=TIGHT)
    assert rep.summary()["cop_outside_fraction"]["L"] is None  # the left foot never touched


def test_pulling_weld_is_infeasible_on_every_foot_check():
    rep = one_foot([wrench_at((0.5, 0.5), (0, 0, -10.0))])
    s = rep.summary()
    assert s["min_normal_force_N"]["R"] == -10.0
    assert s["pulling_fraction"]["R"] == 1.0
    assert s["cop_outside_fraction"]["R"] == 1.0 and s["friction_exceeded_fraction"]["R"] == 1.0
    assert math.isnan(rep.friction_ratio[0, 0]) and np.all(np.isnan(rep.cop[0, 0]))
    assert s["infeasible_fraction"] == 1.0


def test_friction_cone():
    rep = one_foot([wrench_at((0.5, 0.5), (30, 40, 100)),    # |f_t| = 50: ratio 0.5
                    wrench_at((0.5, 0.5), (0, -90, 100))],   # ratio 0.9 > 0.8
                   mu=0.8)
    np.testing.assert_allclose(rep.friction_ratio[:, 0], [0.5, 0.9], atol=TIGHT)
    assert rep.friction_exceeded[:, 0].tolist() == [False, True]
    s = rep.summary()
    assert s["max_friction_ratio"]["R"] == pytest.approx(0.9, abs=TIGHT)
    assert s["friction_exceeded_fraction"]["R"] == 0.5
    assert s["friction_coefficient"] == 0.8
    # the same wrenches are feasible with mu = 1
    assert not one_foot([wrench_at((0.5, 0.5), (0, -90, 100))], mu=1.0).friction_exceeded.any()


def test_unloaded_contact_violates_nothing():
    rep = one_foot([np.zeros(6)])
    assert not rep.pulling.any() and not rep.cop_outside.any() and not rep.friction_exceeded.any()
    assert rep.summary()["min_normal_force_N"]["R"] == 0.0


def test_zmp_against_the_convex_hull_of_two_feet():
    """R foot on [0,1]x[0,1], L toe on [2,3]x[0,1]: support hull [0,3]x[0,1]."""
    right, left = UNIT, UNIT + [2.0, 0.0]
    W = np.zeros((2, 2, 6))
    W[0, 0], W[0, 1] = wrench_at((0.5, 0.5), (0, 0, 100)), wrench_at((2.5, 0.5), (0, 0, 100))
    W[1, 0], W[1, 1] = wrench_at((0.5, 0.5), (0, 0, 100)), wrench_at((2.5, 3.5), (0, 0, 100))
    kind = np.array([[FLAT, TOE], [FLAT, TOE]])
    rep = audit_contacts(np.array([0.0, 0.01]), ["RFFDSP"] * 2, W, kind, [[right, left], [right, left]], 0.8)
    # step 0: ZMP (1.5, 0.5) between the feet, inside the hull 0.5 m from its long edges
    # step 1: L CoP 2.5 m beyond its sole; ZMP (1.5, 2.0) 1.0 m outside the hull
    np.testing.assert_allclose(rep.zmp, [[1.5, 0.5], [1.5, 2.0]], atol=TIGHT)
    np.testing.assert_allclose(rep.zmp_margin, [0.5, -1.0], atol=TIGHT)
    np.testing.assert_allclose(rep.cop_margin[1], [0.5, -2.5], atol=TIGHT)
    s = rep.summary()
    assert s["zmp_outside_fraction"] == 0.5 and s["infeasible_fraction"] == 0.5
    assert s["per_phase"]["RFFDSP"]["zmp_outside_fraction"] == 0.5
    assert list(s["per_phase"]) == ["RFFDSP"]


def test_per_phase_totals():
    inside, outside = wrench_at((0.5, 0.5), (0, 0, 100)), wrench_at((1.5, 0.5), (0, 0, 100))
    n = 4
    W = np.zeros((n, 2, 6))
    W[:, 0] = [inside, outside, outside, outside]
    W[2:, 1] = W[2:, 0]
    kind = np.array([[FLAT, NONE], [FLAT, NONE], [FLAT, TOE], [FLAT, TOE]])
    polys = [[UNIT, None], [UNIT, None], [UNIT, UNIT], [UNIT, UNIT]]
    rep = audit_contacts(np.arange(n) * 0.01, ["RFFSSP", "RFFSSP", "RFFDSP", "RFFDSP"], W, kind, polys, 0.8)
    s = rep.summary()
    assert s["cop_outside_fraction"]["R"] == 0.75 and s["contact_steps"] == {"R": 4, "L": 2}
    assert s["per_phase"]["RFFSSP"]["cop_outside_fraction"]["R"] == 0.5
    assert s["per_phase"]["RFFDSP"]["cop_outside_fraction"] == {"R": 1.0, "L": 1.0}
    assert s["per_phase"]["RFFSSP"]["steps"] == 2


# --------------------------------------------------------------------------------------------- edges, unloaded steps
def test_edges_are_judged_with_the_stated_tolerance():
    """A CoP or ZMP up to EDGE_TOL_M (1 mm) past the edge counts as on it; beyond, as outside; the margins keep the
    raw distance.  The feasibility verdict reads the same constant."""
    from humanoid_sim.analysis.audit import EDGE_TOL_M
    from humanoid_sim.analysis.summary import EDGE_VERDICT_TOL_M

    assert EDGE_VERDICT_TOL_M is EDGE_TOL_M and EDGE_TOL_M == 1e-3
    x = [1.0 + 0.5 * EDGE_TOL_M, 1.0 + 1.5 * EDGE_TOL_M]           # a pivoting foot's few um, then 1.5 mm out
    rep = one_foot([wrench_at((xi, 0.5), (0, 0, 500)) for xi in x])
    np.testing.assert_allclose(rep.cop_margin[:, 0], [-0.5 * EDGE_TOL_M, -1.5 * EDGE_TOL_M], atol=TIGHT)
    assert rep.cop_outside[:, 0].tolist() == [False, True] and rep.zmp_outside.tolist() == [False, True]
    s = rep.summary()
    assert s["cop_outside_fraction"]["R"] == s["zmp_outside_fraction"] == s["infeasible_fraction"] == 0.5
    assert s["min_cop_margin_m"]["R"] == pytest.approx(-1.5 * EDGE_TOL_M, abs=TIGHT)
    assert s["edge_tolerance_m"] == EDGE_TOL_M


def test_steps_before_contact_are_unloaded():
    """A double support (R flat on the unit square, L toe on it moved 2 m along x): real ground's first step (no
    force yet: no CoP, no ZMP) and a step where the feet carry 15 N in all, the left toe's 5 N far outside its sole
    (and the ZMP outside the support), between steps carrying 540 N inside.  Below a 27 N bound those two are
    unloaded: counted apart and judged by no check (no fraction, extremum or mask counts them), while the steps
    are still counted; without the bound they fail the ZMP check and the light one the left CoP check."""
    right, left = UNIT, UNIT + [2.0, 0.0]
    inside = [wrench_at((0.5, 0.5), (0, 0, 270)), wrench_at((2.5, 0.5), (0, 0, 270))]
    W = np.array([[np.zeros(6), np.zeros(6)], inside,
                  [wrench_at((0.5, 0.5), (0, 0, 10)), wrench_at((2.5, 9.0), (0, 0, 5))], inside])
    kind = np.tile([FLAT, TOE], (4, 1))

    def audit(**kwargs):
        return audit_contacts(np.arange(4) * 0.01, ["RFFDSP"] * 4, W, kind, [[right, left]] * 4, 0.8, **kwargs)

    bare = audit().summary()
    assert bare["zmp_outside_fraction"] == 0.5 and bare["cop_outside_fraction"]["L"] == 0.25
    assert bare["unloaded_steps"] == 0 and bare["unloaded_below_N"] is None
    rep = audit(unloaded_below_N=27.0)
    assert rep.unloaded.tolist() == [True, False, True, False]
    assert not (rep.zmp_outside.any() or rep.cop_outside.any() or rep.friction_exceeded.any() or rep.pulling.any())
    s = rep.summary()
    assert s["unloaded_steps"] == 2 and s["unloaded_below_N"] == 27.0 and s["steps"] == 4
    assert s["contact_steps"] == {"R": 4, "L": 4}
    assert s["zmp_outside_fraction"] == s["infeasible_fraction"] == 0.0
    assert s["cop_outside_fraction"] == {"R": 0.0, "L": 0.0}
    assert s["min_normal_force_N"] == {"R": 270.0, "L": 270.0}             # over the loaded steps
    assert s["min_cop_margin_m"]["L"] == pytest.approx(0.5, abs=TIGHT)
    assert s["per_phase"]["RFFDSP"]["unloaded_steps"] == 2


def test_a_loaded_step_is_judged_whatever_its_feet_do():
    """The bound reads both feet's total: a foot pulling 10 N while the other pushes 300 N is a loaded step, and its
    weld pulls (infeasible); a non-finite total is not below the bound: judged, and it fails."""
    W = np.zeros((2, 2, 6))
    W[0, 0], W[0, 1] = wrench_at((0.5, 0.5), (0, 0, 300)), wrench_at((2.5, 0.5), (0, 0, -10))
    W[1, 0], W[1, 1] = wrench_at((0.5, 0.5), (0, 0, 300)), np.full(6, np.nan)
    kind = np.tile([FLAT, TOE], (2, 1))
    rep = audit_contacts(np.array([0.0, 0.01]), ["RFFDSP"] * 2, W, kind, [[UNIT, UNIT + [2.0, 0.0]]] * 2, 0.8,
                         unloaded_below_N=27.0)
    assert not rep.unloaded.any()
    s = rep.summary()
    assert s["pulling_fraction"]["L"] == 1.0 and s["infeasible_fraction"] == 1.0 and s["unloaded_steps"] == 0
    with pytest.raises(AuditError, match="unloaded_below_N"):
        audit_contacts(np.zeros(1), ["RFFSSP"], W[:1], kind[:1], [[UNIT, UNIT]], 0.8, unloaded_below_N=-1.0)


def test_audit_results_bounds_unloaded_steps_by_the_robots_weight(hm):
    """audit_results: a step is unloaded below UNLOADED_WEIGHT_FRACTION (5 %) of the robot's weight (27 N)."""
    from humanoid_sim.analysis.audit import UNLOADED_WEIGHT_FRACTION, robot_weight

    weight = robot_weight(hm)
    assert weight == pytest.approx(pin.computeTotalMass(hm.model) * 9.81, rel=1e-12)
    bound = UNLOADED_WEIGHT_FRACTION * weight
    q = np.tile(hm.initial_q(), (3, 1))
    W = np.zeros((3, 2, 6))
    W[1, 1, 2], W[2, 1, 2] = 0.99 * bound, 1.01 * bound
    res = {"t": np.arange(3) * 0.01, "phase": np.zeros(3, dtype=int), "q": q, "foot_wrench": W,
           "in_contact": np.array([[False, True]] * 3), "phase_names": np.array(["LFFSSP"])}
    rep = audit_results(res, hm, 0.8)
    assert rep.unloaded.tolist() == [True, True, False] and rep.unloaded_below_N == pytest.approx(bound, rel=1e-15)
    assert rep.summary()["unloaded_steps"] == 2


def test_inconsistent_inputs_raise():
    W = np.zeros((1, 2, 6))
    with pytest.raises(AuditError, match="polygon missing"):
        audit_contacts(np.zeros(1), ["RFFSSP"], W, np.array([[FLAT, NONE]]), [[None, None]], 0.8)
    with pytest.raises(AuditError, match="foot_wrench: expected shape"):
        audit_contacts(np.zeros(1), ["RFFSSP"], np.zeros((1, 6)), np.array([[FLAT, NONE]]), [[UNIT, None]], 0.8)
    with pytest.raises(AuditError, match="friction coefficient"):
        audit_contacts(np.zeros(1), ["RFFSSP"], W, np.array([[FLAT, NONE]]), [[UNIT, None]], 0.0)


def test_audit_results_checks_in_contact_against_the_phase(hm):
    q = hm.initial_q()[None, :]
    res = {"t": np.zeros(1), "phase": np.zeros(1, dtype=int), "q": q, "foot_wrench": np.zeros((1, 2, 6)),
           "in_contact": np.array([[True, True]]), "phase_names": np.array(["LFFSSP"])}
    with pytest.raises(AuditError, match="in_contact disagrees"):
        audit_results(res, hm, 0.8)
    res["in_contact"] = np.array([[False, True]])
    assert audit_results(res, hm, 0.8).kind.tolist() == [[NONE, FLAT]]
    empty = audit_results({k: v[:0] if k != "phase_names" else v for k, v in res.items()}, hm, 0.8)
    assert empty.summary()["steps"] == 0 and empty.summary()["infeasible_fraction"] is None


def test_figure_is_written(tmp_path):
    from humanoid_sim.outputs.plots.audit import plot_contact_audit

    rep = one_foot([wrench_at((0.3, 0.5), (10, 0, 500)), wrench_at((1.25, 0.5), (0, 0, -5))])
    out = plot_contact_audit(rep, tmp_path / "contact_audit.png", title="synthetic")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["contact_audit.png"]  # no temporary file left behind
