"""Partial footholds (controllers/balance/foothold.py): the sole CoP against the force-weighted contact points, the
cuts against the geometry of a foot turning about an edge, the QP's cut boxes, and walks over a bar on MuJoCo."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.controllers.balance.boxes import box_rows
from humanoid_sim.controllers.balance.foothold import FootholdTracker, sole_cop
from humanoid_sim.dynamics.contact.constraints import Anchors
from humanoid_sim.robot.phases import FOOT_SPECS
from humanoid_sim.robot.sole import SoleGeometry
from humanoid_sim.scenario.balance import BalanceSettings

ROOT = Path(__file__).resolve().parents[2]


def _wrench_at(points: np.ndarray, forces: np.ndarray) -> np.ndarray:
    """The resultant [force; moment about the world origin] of point forces."""
    return np.concatenate([forces.sum(axis=0), np.cross(points, forces).sum(axis=0)])


def test_the_sole_cop_is_the_normal_force_weighted_mean_of_the_contact_points():
    """Point forces on a tilted sole plane: the CoP is the mean of the points weighted by their normal forces; the
    tangential forces, applied in the plane, do not move it."""
    rng = np.random.default_rng(3)
    R = pin.rpy.rpyToMatrix(0.05, -0.08, 1.2)
    o = np.array([0.16, 0.4, 0.01])
    local = rng.uniform(-0.05, 0.1, (5, 2))
    points = o + local @ R[:, :2].T
    normal = rng.uniform(10.0, 100.0, 5)
    forces = normal[:, None] * R[:, 2] + rng.uniform(-5.0, 5.0, (5, 2)) @ R[:, :2].T
    cop = sole_cop(R, o, _wrench_at(points, forces), f_min=20.0)
    np.testing.assert_allclose(cop, normal @ local / normal.sum(), atol=1e-12)
    assert sole_cop(R, o, _wrench_at(points, forces * 0.01), f_min=20.0) is None   # 2-5 N in all: unloaded


@pytest.fixture()
def stance(hm):
    """The right foot flat at the initial configuration, the settings, a tracker, and a helper that turns the
    anchor by ``rot`` (sole-frame rotation vector, rad) and puts a 400 N normal force at sole point (x, y)."""
    from humanoid_sim.references.initial import initial_configuration
    from humanoid_sim.scenario.schema import load_scenario

    sc = load_scenario(ROOT / "scripts/params/sim3.yaml")
    q = initial_configuration(hm, sc.path)
    s = BalanceSettings()
    sole = SoleGeometry.from_model(hm)
    model = hm.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    M = data.oMf[model.getFrameId(FOOT_SPECS["R"].main_frame)]

    def seen(rot, x, y, toe_angle=0.0):
        # the anchor is the foot turned back by rot: the foot is then turned by rot from its anchor
        anchors = Anchors()
        anchors.placements["O_3"] = pin.SE3(M.rotation @ pin.exp3(-np.asarray(rot, float)), M.translation.copy())
        anchors.joint_positions["theta3"] = toe_angle
        o = M.translation + sole.sole_z * M.rotation[:, 2]
        p = o + M.rotation[:, :2] @ np.array([x, y])
        f = 400.0 * M.rotation[:, 2]
        w = np.zeros((2, 6))
        w[0] = np.concatenate([f, np.cross(p, f)])
        return anchors, w

    return SimpleNamespace(hm=hm, q=q, s=s, sole=sole, seen=seen, tracker=FootholdTracker(model, sole, s))


T_READ = 1.0 + BalanceSettings().foothold_settle_s
"""When the stances below, begun at t = 1 s, are read for cuts: at the end of their settling window."""


def _read(st, tracker, anchors, w):
    """The foothold after a stance's first update at t = 1 s and a second at :data:`T_READ`, the same reading."""
    tracker.update(1.0, "R", anchors, st.q, None, w)
    return tracker.update(T_READ, "R", anchors, st.q, None, w)


def test_a_foot_rolling_about_an_inner_line_is_cut_there(stance):
    """Turned 2 deg about its sole x axis (its +y side up: the -y side found no ground) with its CoP at y = 10 mm:
    the supported part is y >= 10 + 5 mm; the toe box stays loaded."""
    st = stance
    anchors, w = st.seen((math.radians(2.0), 0.0, 0.0), 0.05, 0.01)
    hold = _read(st, st.tracker, anchors, w)
    assert hold.y_lo == pytest.approx(0.015, abs=1e-9) and hold.y_hi == math.inf
    assert hold.x_lo == -math.inf and hold.x_hi == math.inf and hold.toe_loaded and not hold.whole
    assert st.tracker.history == [hold] and hold.cuts == [(T_READ, "y", hold.y_lo)]
    # the same turn the other way: the +y side dropped, the support is below the CoP
    anchors, w = st.seen((-math.radians(2.0), 0.0, 0.0), 0.05, 0.01)
    hold = _read(st, FootholdTracker(st.hm.model, st.sole, st.s), anchors, w)
    assert hold.y_hi == pytest.approx(0.005, abs=1e-9) and hold.y_lo == -math.inf


def test_a_foot_pitching_about_an_inner_line_is_cut_there(stance):
    """Turned 2 deg about its sole y axis, toe down (the toe side dropped), CoP at x = 60 mm: x <= 55 mm."""
    anchors, w = stance.seen((0.0, math.radians(2.0), 0.0), 0.06, 0.0)
    hold = _read(stance, stance.tracker, anchors, w)
    assert hold.x_hi == pytest.approx(0.055, abs=1e-9) and hold.x_lo == -math.inf


def test_a_foot_tipping_about_its_own_edge_or_barely_turning_is_not_cut(stance):
    """A CoP 5 mm inside the sole's +y edge (45 mm) with the -y side down is a foot tipping over its edge: a cut
    would leave 5 mm, under the 15 mm minimum.  A turn of 1 deg is below the 1.5 deg that reveals a foothold."""
    st = stance
    anchors, w = st.seen((math.radians(2.0), 0.0, 0.0), 0.05, st.sole.width / 2 - 0.005)
    assert _read(st, st.tracker, anchors, w).whole
    anchors, w = st.seen((math.radians(1.0), 0.0, 0.0), 0.05, 0.01)
    assert _read(st, FootholdTracker(st.hm.model, st.sole, st.s), anchors, w).whole


def test_a_landing_foot_settling_flat_is_not_cut(stance):
    """The anchor is taken at touchdown; a foot that lands turned 2 deg settles flat onto the ground in its first
    milliseconds, which is no partial foothold (on sim1_zmp after a push: 2.0 deg at the stance's first update,
    1.3 deg 8 ms later).  Within ``foothold_settle_s`` of the stance's start its turn is not read; a turn that
    stays beyond the limit after it is cut; with no settling window the first reading cuts."""
    st = stance
    turned, w = st.seen((math.radians(2.0), 0.0, 0.0), 0.05, 0.01)
    # the foot turned 0.7 deg from the same anchor (``seen`` turns the anchor; its translation, which marks the
    # stance, is the same, so the tracker keeps the stance and its start)
    settled, _ = st.seen((math.radians(0.7), 0.0, 0.0), 0.05, 0.01)
    assert st.tracker.update(1.0, "R", turned, st.q, None, w).whole      # within the window: not read
    hold = st.tracker.update(T_READ, "R", settled, st.q, None, w)
    assert hold.whole and hold is st.tracker.hold and hold.t_start == 1.0
    hold = _read(st, FootholdTracker(st.hm.model, st.sole, st.s), turned, w)
    assert not hold.whole and hold.cuts[0][0] == T_READ                 # still turned after the window: cut
    eager = dataclasses.replace(st.s, foothold_settle_s=0.0)
    hold = FootholdTracker(st.hm.model, st.sole, eager).update(1.0, "R", turned, st.q, None, w)
    assert not hold.whole and hold.cuts[0][0] == 1.0


def test_a_foot_anchored_with_its_toe_bent_carries_nothing_on_its_toe_box(stance):
    """Toe joint at 10 deg when anchored: no load on the toe box; the bend is known from that stance on, for the
    double support that trails the foot next (a toe at 2 deg is not bent: 0)."""
    st = stance
    anchors, w = st.seen((0.0, 0.0, 0.0), 0.05, 0.0, toe_angle=math.radians(10.0))
    hold = st.tracker.update(1.0, "R", anchors, st.q, None, w)
    # from the stance on: the double support that trails the foot asks before the next stance's first update
    assert not hold.toe_loaded and not hold.whole and st.tracker.toe_bend("R") == math.radians(10.0)
    other = Anchors()
    other.placements["O_4"] = pin.SE3.Identity()
    other.joint_positions["theta4"] = math.radians(2.0)
    st.tracker.update(1.5, "L", other, st.q, None, None)                                # the next stance
    assert st.tracker.toe_bend("R") == math.radians(10.0) and st.tracker.toe_bend("L") == 0.0


def _rows(lo, hi, ylo, yhi, zs=-0.078):
    return box_rows(lo, hi, ylo, yhi, zs, 0.24, 0.02)


def _wrench(fz, cop, zs=-0.078):
    """A normal force fz at sole point (x, y) as [f; moment about the frame origin], the sole at z = zs."""
    return np.concatenate([[0.0, 0.0, fz], np.cross([cop[0], cop[1], zs], [0.0, 0.0, fz])])


def test_a_cut_box_admits_exactly_the_cops_inside_it_and_an_empty_box_nothing():
    from scipy.optimize import linprog

    L = _rows(-0.02, 0.1, 0.015, 0.03)
    for cop, inside in (((0.0, 0.02), True), ((0.0, 0.014), False), ((0.0, 0.031), False), ((0.101, 0.02), False)):
        assert bool(np.all(L @ _wrench(300.0, cop) >= -1e-12)) is inside, cop
    # the empty box: the largest normal force its rows admit (with fz <= 1 to bound the LP) is zero
    E = _rows(1.0, 0.0, 0.0, 0.0)
    res = linprog(c=[0, 0, -1, 0, 0, 0], A_ub=np.vstack([-E, [[0, 0, 1, 0, 0, 0]]]), b_ub=[0.0] * len(E) + [1.0],
                  bounds=[(None, None)] * 6)
    assert res.status == 0 and abs(res.x[2]) < 1e-12


OUTER_BAR = {"kind": "bar", "centre": [0.185, 0.485, 0.005], "size": [0.04, 0.26, 0.01]}
"""The terrain suite's bar along the outer half of the right foot's second foothold (its toe box spans y 0.523 -
0.597 m, the sole x 0.115 - 0.205 m): the inner half of the sole finds no ground for 10 mm."""
TOE_BAR = {"kind": "bar", "centre": [0.16, 0.56, 0.005], "size": [0.12, 0.02, 0.01]}
"""The terrain suite's bar across the toe box of the same foothold."""


def _bar_walk(tmp_path, bar: dict = OUTER_BAR, balance: dict | None = None, sensing: dict | None = None):
    pytest.importorskip("mujoco")
    import yaml

    from humanoid_sim.api import run_walk

    doc = {"base": str(ROOT / "scripts/params/sim3_zmp.yaml"), "name": "bar", "disturbances": {"terrain": [bar]}}
    if sensing:
        doc["disturbances"]["sensing"] = sensing
    if balance:
        doc["balance"] = balance
    f = tmp_path / "bar.yaml"
    f.write_text(yaml.safe_dump(doc))
    return run_walk(f, "mujoco")


@pytest.mark.slow
def test_a_foot_on_a_bar_under_its_outer_half_is_cut_and_the_walk_completes_on_mujoco(tmp_path):
    run = _bar_walk(tmp_path)
    assert run.result.completed, run.result.reason
    holds = run.result.extra["balance_partial_footholds"]
    right = [h for h in holds if h["foot"] == "R" and h["cuts"]]
    assert right, holds
    # the cut keeps the CoP on the bar: the right foot's outer side is its -y side (sole frame, y left), the bar's
    # inner edge 5 mm outward of the sole's centre line
    assert all(axis == "y" and bound < 0.0 for _, axis, bound in right[0]["cuts"]), right
    fell = _bar_walk(tmp_path, balance={"footholds": False})
    assert not fell.result.completed and "fall" in fell.result.reason, fell.result.reason


@pytest.mark.slow
def test_a_foot_landing_with_its_toe_on_a_bar_stands_on_its_heel_box_and_the_walk_completes_on_mujoco(tmp_path):
    """The toe box meets the bar 10 mm up first and bends; the main body lands flat on the floor.  The stance then
    carries nothing on its toe box, and when the foot trails its heel lifts from the bend.  Without partial
    footholds the walk falls at the bar."""
    run = _bar_walk(tmp_path, TOE_BAR)
    assert run.result.completed, run.result.reason
    bent = [h for h in run.result.extra["balance_partial_footholds"] if not h["toe_loaded"]]
    assert [h["foot"] for h in bent] == ["R"], run.result.extra["balance_partial_footholds"]
    fell = _bar_walk(tmp_path, TOE_BAR, {"footholds": False})
    assert not fell.result.completed, fell.result.reason


@pytest.mark.slow
def test_a_foot_trailing_from_a_toe_on_a_bar_is_held_flat_and_the_walk_completes_with_noise(tmp_path):
    """With 0.02 m/s and 0.02 rad/s of noise on the sensed base twist, the foot whose toe stood bent on the bar
    trails next.  Held by that toe (the toe box on the bar's edge, 14 deg up, its motor limited to 30 N m), it
    tipped 18 ms into that double support and the walk fell.  Held flat on its heel box through the double
    support (flat_trail), the walk completes, with the stance feet within 1 deg and 5 mm of slip.  The lead-in holds
    its trailing foot by its toe here (flat_lead_in off), as when this was measured: with it held flat, its switch
    to the toe at the lead-in's toe-off jolts the stance foot by 1.9 deg under this noise, before the bar, which
    the maximum would read instead."""
    noise = {"base_linear_velocity_mps": 0.02, "base_angular_velocity_radps": 0.02, "seed": 1}
    run = _bar_walk(tmp_path, TOE_BAR, {"flat_lead_in": False}, sensing=noise)
    assert run.result.completed, run.result.reason
    s = run.summary
    assert s["stance_tilt_max_rad"] <= math.radians(1.0) and s["foot_slip_max_m"] <= 0.005, s
    fell = _bar_walk(tmp_path, TOE_BAR, {"flat_trail": False, "flat_lead_in": False}, sensing=noise)
    assert not fell.result.completed and "fall" in fell.result.reason, fell.result.reason
