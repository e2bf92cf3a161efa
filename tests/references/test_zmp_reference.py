"""ZMP reference of a walk (humanoid_sim/references/zmp/zmp_reference.py): sampling, the sole points against the
model's own kinematics (the foot placed by HumanoidModel.q_on_foot, its sole corners carried by the O_3 / O_1 frames as
in the contact audit), and the thesis walk's reference against its support polygons."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim import PACKAGE_DIR
from humanoid_sim.analysis.audit import FLAT, NONE, TOE, SoleGeometry, convex_hull, signed_distance, sole_polygons
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.references.zmp.errors import GaitError
from humanoid_sim.references.zmp.zmp_reference import (
    SupportInterval,
    intervals_from_trajectory,
    sample,
    sole_centre,
    toe_part_centre,
)
from humanoid_sim.scenario.schema import load_scenario

PARAMS = PACKAGE_DIR.parent / "scripts" / "params"
TIGHT = 1e-12   # m: float arithmetic on numbers of order 1


# ------------------------------------------------------------------------------------------------ sampling
def test_sample_linear_and_smoothstep_values():
    iv = [SupportInterval(0.0, 1.0, (0.0, 0.0), (0.0, 0.0)), SupportInterval(1.0, 2.0, (0.0, 0.0), (0.2, -0.4))]
    t, lin = sample(iv, 0.25, "linear")
    np.testing.assert_allclose(t, [0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0], atol=TIGHT)
    np.testing.assert_allclose(lin[4:], [[0, 0], [0.05, -0.1], [0.1, -0.2], [0.15, -0.3], [0.2, -0.4]], atol=TIGHT)
    _, smooth = sample(iv, 0.25)
    s = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    s = 3 * s ** 2 - 2 * s ** 3   # the cubic with zero rate at both ends
    np.testing.assert_allclose(smooth[4:], np.outer(s, [0.2, -0.4]), atol=TIGHT)
    np.testing.assert_allclose(smooth[:4], 0.0, atol=TIGHT)


def test_sample_end_off_the_grid_stops_at_the_last_grid_point():
    t, ref = sample([SupportInterval(-0.5, 0.33, (1.0, 2.0), (1.0, 2.0))], 0.1)
    assert t[0] == -0.5 and t[-1] == pytest.approx(0.3, abs=1e-12) and len(t) == 9
    np.testing.assert_array_equal(ref, np.tile([1.0, 2.0], (9, 1)))


@pytest.mark.parametrize("intervals, T, transfer, fragment", [
    ([], 0.01, "linear", "intervals: expected at least one"),
    ([SupportInterval(0, 1, (0, 0), (0, 0)), SupportInterval(1.1, 2, (0, 0), (0, 0))], 0.01, "linear",
     r"intervals\[1\].t0 = 1.1: expected the previous interval's end t1 = 1"),
    ([SupportInterval(0, 1, (0, 0), (0, 0))], 0.0, "linear", "T: expected a finite sample time > 0 s, got 0.0"),
    ([SupportInterval(0, 1, (0, 0), (0, 0))], 0.01, "cosine", "transfer: expected one of"),
    ([(0, 1, (0, 0), (0, 0))], 0.01, "linear", r"intervals\[0\]: expected a SupportInterval, got tuple"),
])
def test_sample_bad_inputs_are_named(intervals, T, transfer, fragment):
    with pytest.raises(GaitError, match=fragment):
        sample(intervals, T, transfer)


@pytest.mark.parametrize("args, fragment", [
    ((1.0, 1.0, (0, 0), (0, 0)), "expected t1 > t0"),
    ((0.0, float("inf"), (0, 0), (0, 0)), r"SupportInterval.t1: expected a finite time"),
    ((0.0, 1.0, (0, 0, 0), (0, 0)), r"SupportInterval.start_xy: expected 2 finite numbers"),
    ((0.0, 1.0, (0, 0), (np.nan, 0)), r"SupportInterval.end_xy: expected 2 finite numbers"),
])
def test_bad_interval_is_named(args, fragment):
    with pytest.raises(GaitError, match=fragment):
        SupportInterval(*args)


# ------------------------------------------------------------------------------------------------ sole points
def _random_foot(rng, tilt: bool) -> tuple[np.ndarray, np.ndarray]:
    p = rng.uniform([-1.0, -1.0, 0.0], [1.0, 1.0, 0.05])
    R = pin.rpy.rpyToMatrix(*(rng.uniform(-0.2, 0.2, 2) if tilt else (0.0, 0.0)), rng.uniform(-np.pi, np.pi))
    return p, R


@pytest.mark.parametrize("foot", ["R", "L"])
def test_sole_centre_is_the_centre_of_the_model_sole(hm, foot):
    """Place the foot with q_on_foot (toe point and toe-body orientation), carry SoleGeometry's corners with the
    model's O_3 / O_4 frame, and compare their mean with sole_centre; also the hull that the audit builds."""
    sole = SoleGeometry.from_model(hm)
    rng = np.random.default_rng(7)
    data = hm.model.createData()
    main = "O_3" if foot == "R" else "O_4"
    for i in range(20):
        p, R = _random_foot(rng, tilt=i % 2 == 1)
        q = hm.q_on_foot(np.zeros(26), foot, p, R)
        pin.framesForwardKinematics(hm.model, data, q)
        M = data.oMf[hm.frame_id(main)]
        corners = sole.flat_corners() @ M.rotation.T + M.translation
        # 1e-12 m: the same point through two chains of a few rigid transforms
        np.testing.assert_allclose(sole_centre(p, R, sole), corners.mean(axis=0), atol=TIGHT)
        if i % 2 == 0:   # flat foot: the audit's polygon on z = 0 is the rectangle, its centroid is the centre
            kind = np.array([[FLAT, NONE]]) if foot == "R" else np.array([[NONE, FLAT]])
            poly = sole_polygons(hm, q[None, :], kind, sole)[0][0 if foot == "R" else 1]
            np.testing.assert_allclose(sole_centre(p, R, sole)[:2], poly.mean(axis=0), atol=TIGHT)


@pytest.mark.parametrize("foot", ["R", "L"])
def test_toe_part_centre_is_the_centre_of_the_model_toe_sole_at_any_toe_angle(hm, foot):
    sole = SoleGeometry.from_model(hm)
    rng = np.random.default_rng(11)
    data = hm.model.createData()
    toe_body, point = ("O_1", "P_tpR") if foot == "R" else ("O_2", "P_tpL")
    for _ in range(10):
        theta = np.zeros(26)
        theta[hm.theta_index("theta3" if foot == "R" else "theta4")] = rng.uniform(-0.6, 0.6)
        p, R = _random_foot(rng, tilt=False)
        q = hm.q_on_foot(theta, foot, p, R)
        pin.framesForwardKinematics(hm.model, data, q)
        np.testing.assert_allclose(data.oMf[hm.frame_id(point)].translation, p, atol=TIGHT)
        M = data.oMf[hm.frame_id(toe_body)]
        corners = sole.toe_corners() @ M.rotation.T + M.translation
        np.testing.assert_allclose(toe_part_centre(p, R, sole), corners.mean(axis=0), atol=TIGHT)


def test_sole_points_reject_bad_input(hm):
    sole = SoleGeometry.from_model(hm)
    with pytest.raises(GaitError, match="toe_point: expected 3 finite"):
        sole_centre([0.0, 0.0], np.eye(3), sole)
    with pytest.raises(GaitError, match="R_foot: expected a 3x3 rotation"):
        toe_part_centre([0.0, 0.0, 0.0], 2 * np.eye(3), sole)


# ------------------------------------------------------------------------------------------------ thesis walks
def _foot_polygon(hm, sole: SoleGeometry, foot: str, p: np.ndarray, R: np.ndarray, kind: int) -> np.ndarray:
    """World polygon (z = 0) of one foot's contact, from the model: the foot placed by q_on_foot (toe joint 0 for
    a flat foot; for a toe contact the toe body alone matters) and the audit's own polygon builder."""
    q = hm.q_on_foot(np.zeros(26), foot, p, R)
    kinds = np.array([[kind, NONE]]) if foot == "R" else np.array([[NONE, kind]])
    return sole_polygons(hm, q[None, :], kinds, sole)[0][0 if foot == "R" else 1]


def _support_margins(hm, traj: ReferenceTrajectory, times: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Signed distance (m) of the reference to the support polygon of the thesis's contacts at each time:
    both feet flat before 0, the stance foot in a single support, the landed foot flat and the trailing foot's
    toe part in a double support."""
    sole = SoleGeometry.from_model(hm)
    out = np.empty(len(times))
    for k, t in enumerate(times):
        s = traj.sample_global(max(float(t), 0.0))
        feet = {"R": (s.toe_R_p, s.foot_R_R), "L": (s.toe_L_p, s.foot_L_R)}
        if t < 0:
            contacts = {"R": FLAT, "L": FLAT}
        else:
            ph = traj.phases[traj.phase_at(float(t))]
            if ph.is_ssp:
                contacts = {"L" if ph.swing_foot == "R" else "R": FLAT}
            else:
                contacts = {ph.landed_foot: FLAT, "L" if ph.landed_foot == "R" else "R": TOE}
        hull = convex_hull(np.vstack([_foot_polygon(hm, sole, f, *feet[f], kind) for f, kind in contacts.items()]))
        out[k] = signed_distance(ref[k], hull)
    return out


@pytest.fixture(scope="module")
def sim3_traj() -> ReferenceTrajectory:
    return ReferenceTrajectory(load_scenario(PARAMS / "sim3.yaml").path)


def test_thesis_walk_reference_stays_inside_the_support_polygon(hm, sim3_traj):
    sole = SoleGeometry.from_model(hm)
    iv = intervals_from_trajectory(sim3_traj, sole, lead_in_s=1.0)
    times, ref = sample(iv, 0.01)
    assert times[0] == pytest.approx(-1.0) and times[-1] == pytest.approx(sim3_traj.duration, abs=0.01)
    margin = _support_margins(hm, sim3_traj, times, ref)
    # the toe-part centre is 37 mm from the toe part's edges (74 mm long, 90 mm wide); the reference never comes
    # closer to an edge than that: 30 mm leaves room for the transfer's path across the double support
    assert margin.min() > 0.030
    # continuous: the largest step between samples is a transfer's peak rate (1.5 x 0.36 m / 0.117 s) x 0.01 s
    assert np.max(np.linalg.norm(np.diff(ref, axis=0), axis=1)) < 0.05


def test_whole_sole_trailing_point_leaves_the_double_support_polygon(hm, sim3_traj):
    """Why the default is the toe part: from the trailing foot's whole-sole centre the reference starts each
    double support outside the support polygon (the trailing heel is off the ground)."""
    sole = SoleGeometry.from_model(hm)
    times, ref = sample(intervals_from_trajectory(sim3_traj, sole, lead_in_s=0.0, trailing="sole"), 0.01)
    margin = _support_margins(hm, sim3_traj, times, ref)
    assert margin.min() < -0.02 and np.mean(margin < 0) > 0.01


def test_intervals_follow_the_schedule(hm, sim3_traj):
    sole = SoleGeometry.from_model(hm)
    iv = intervals_from_trajectory(sim3_traj, sole, lead_in_s=1.0, lead_out_s=0.5, start_xy=(0.0, 0.014))
    assert len(iv) == 2 + sim3_traj.n_phases + 1
    assert iv[0].start_xy == (0.0, 0.014) and iv[0].end_xy == (0.0, 0.014)
    for ph, x in zip(sim3_traj.phases, iv[2:]):
        assert (x.t0, x.t1) == (ph.t_start, ph.t_end)
        s = sim3_traj.sample(ph.index, 0.0)
        if ph.is_ssp:   # starts on the stance sole centre
            stance = ("L", s.toe_L_p, s.foot_L_R) if ph.swing_foot == "R" else ("R", s.toe_R_p, s.foot_R_R)
            np.testing.assert_allclose(x.start_xy, sole_centre(stance[1], stance[2], sole)[:2], atol=TIGHT)
        else:           # ends on the landed foot's sole centre
            p, R = (s.toe_R_p, s.foot_R_R) if ph.landed_foot == "R" else (s.toe_L_p, s.foot_L_R)
            np.testing.assert_allclose(x.end_xy, sole_centre(p, R, sole)[:2], atol=TIGHT)
    last = sim3_traj.phase_end(sim3_traj.n_phases - 1)
    mid = 0.5 * (sole_centre(last.toe_R_p, last.foot_R_R, sole) + sole_centre(last.toe_L_p, last.foot_L_R, sole))
    np.testing.assert_allclose(iv[-1].end_xy, mid[:2], atol=TIGHT)


def test_intervals_bad_options_are_named(hm, sim3_traj):
    sole = SoleGeometry.from_model(hm)
    with pytest.raises(GaitError, match="trailing: expected one of"):
        intervals_from_trajectory(sim3_traj, sole, trailing="heel")
    with pytest.raises(GaitError, match="lead_in_s: expected a finite duration >= 0 s, got -1"):
        intervals_from_trajectory(sim3_traj, sole, lead_in_s=-1)
    with pytest.raises(GaitError, match="start_xy: expected 2 finite numbers"):
        intervals_from_trajectory(sim3_traj, sole, start_xy=(0.0, 0.0, 0.0))
