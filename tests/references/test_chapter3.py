"""Tests of humanoid_sim.references.chapter3 (thesis chapter 3) against independent computations.

Independent references used here: plane geometry (distances, cross products, tangents), the
closed-form cubic Hermite basis (instead of the thesis's 4x4 solves), the literal per-direction thesis
equations 3.8-3.16 / 3.20-3.41 (instead of the generator's unified form), central finite differences,
mirror symmetry of the left/right formulas, and the numbers of shared/reference/sim1.yaml `derived:`
(computed independently by the reference extractor; copied below with their printed precision).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from humanoid_sim.outputs.plots.thesis import plot_reference
from humanoid_sim.references.chapter3 import PathParamError, PathParams, ReferenceTrajectory, TrajectoryError
from humanoid_sim.references.chapter3.geometry import arc_centre, wrap_pi

ROOT = Path(__file__).resolve().parents[2]
SCEN = ROOT / "scripts" / "params"
SIMS = ("sim1", "sim2", "sim3")


def _path_dict(name: str) -> dict:
    return yaml.safe_load((SCEN / f"{name}.yaml").read_text())["path"]


@pytest.fixture(scope="module")
def trajs() -> dict[str, ReferenceTrajectory]:
    return {n: ReferenceTrajectory(PathParams.from_dict(_path_dict(n), where=n)) for n in SIMS}


def _mirrored_sim1() -> dict:
    """Sim 1 mirrored about the world y-z plane (x -> -x): left and right turns and feet swap."""
    d = _path_dict("sim1")
    m = dict(d)
    m["Phip"] = [[-x, y, z] for x, y, z in d["Phip"]]
    m["T_dir"] = [-t for t in d["T_dir"]]
    m["toe_R0"] = [-d["toe_L0"][0], d["toe_L0"][1], d["toe_L0"][2]]
    m["toe_L0"] = [-d["toe_R0"][0], d["toe_R0"][1], d["toe_R0"][2]]
    # mirrored body frame: x and z axes reflected, y axis (left) kept pointing left -> S R M, det +1
    S, M = np.diag([-1.0, 1.0, 1.0]), np.diag([1.0, -1.0, 1.0])
    m["foot_R0"] = (S @ np.array(d["foot_L0"], float) @ M).tolist()
    m["foot_L0"] = (S @ np.array(d["foot_R0"], float) @ M).tolist()
    m["first_phase"] = "RFFSSP"
    return m


def _hermite(T: float, p0: float, p1: float, v0: float, v1: float, t: float) -> tuple[float, float, float]:
    """Closed-form cubic Hermite interpolation: value, first and second derivative at t."""
    s = t / T
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
    e00, e10, e01, e11 = 12 * s - 6, 6 * s - 4, -12 * s + 6, 6 * s - 2
    p = h00 * p0 + h10 * T * v0 + h01 * p1 + h11 * T * v1
    v = (d00 * p0 + d10 * T * v0 + d01 * p1 + d11 * T * v1) / T
    a = (e00 * p0 + e10 * T * v0 + e01 * p1 + e11 * T * v1) / T**2
    return p, v, a


def _signed_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Signed angle (rad, counter-clockwise positive) from 2-D vector a to b."""
    return math.atan2(a[0] * b[1] - a[1] * b[0], a[0] * b[0] + a[1] * b[1])


def _all_sims(trajs):
    mirrored = ReferenceTrajectory(PathParams.from_dict(_mirrored_sim1()))
    return [(n, trajs[n]) for n in SIMS] + [("sim1_mirrored", mirrored)]


# ================================================================================ geometry (3.2.1-3.2.2)
def test_arc_centre_is_equidistant_and_on_the_turning_side():
    rng = np.random.default_rng(1)
    for _ in range(200):
        p = rng.uniform(-2, 2, 2)
        q = p + rng.uniform(-0.5, 0.5, 2)
        chord = np.linalg.norm(q - p)
        r = chord / 2 * rng.uniform(1.001, 20)
        for t_dir in (1, -1):
            o = arc_centre(p, q, r, t_dir)
            # 1e-12 m: pure floating-point round-off on metre-sized numbers
            assert abs(np.linalg.norm(o - p) - r) < 1e-12 and abs(np.linalg.norm(o - q) - r) < 1e-12
            cross = (q - p)[0] * (o - p)[1] - (q - p)[1] * (o - p)[0]
            assert np.sign(cross) == t_dir      # T_dir = +1: centre to the left of P_k -> P_k+1 (Fig. 3.4)


# sim1 `derived:` numbers of shared/reference/sim1.yaml (independent extractor), printed to 5 decimals
# (m) and 3 decimals (deg)
SIM1_DERIVED = [  # chord, centre x, centre y, theta_CS deg, theta_htotal deg, heading jump deg
    (0.16401, -1.21653, 1.03926, 49.493, 5.876, -40.507),
    (0.14422, 1.13666, -0.47444, 59.755, 6.890, 4.386),
    (0.14142, 1.00621, -0.47621, 48.686, 7.371, -4.179),
    (0.13892, 0.77444, -0.35976, 34.862, 9.212, -6.452),
    (0.13928, 0.85908, -0.57962, 24.667, 7.260, -0.983),
    (0.15811, 1.07868, -0.92605, 21.456, 6.042, 4.048),
    (0.16125, 0.89607, -0.55857, 11.328, 8.406, -4.086),
    (0.15008, 0.95490, -0.65449, 5.494, 7.171, 2.573),
]
SIM1_T_DSP = [0.133333, 0.15, 0.133333, 0.116667, 0.1, 0.116667, 0.116667, 0.116667]
SIM1_T_END = [0.8, 0.933333, 1.833333, 1.983333, 2.783333, 2.916667, 3.616667, 3.733333, 4.333333, 4.433333,
              5.133333, 5.25, 5.95, 6.066667, 6.766667, 6.883333]


def test_sim1_derived_numbers_match_the_independent_extraction(trajs):
    tr = trajs["sim1"]
    P = tr.params.Phip
    prev_end = math.pi / 2   # the robot's initial heading (C0 = Rz(90 deg)), as in the extractor
    for i, (chord, ox, oy, cs, htot, jump) in enumerate(SIM1_DERIVED):
        g = tr.segment_geometry(i)
        # 6e-6 m / 6e-4 deg: half a unit of the last printed digit plus round-off
        assert abs(np.linalg.norm(P[i + 1, :2] - P[i, :2]) - chord) < 6e-6
        assert np.allclose(g["O"], (ox, oy), atol=6e-6)
        assert abs(math.degrees(wrap_pi(g["theta_cs"])) - cs) < 6e-4
        assert abs(math.degrees(g["theta_htotal"]) - htot) < 6e-4
        assert abs(math.degrees(wrap_pi(g["theta_cs"] - prev_end)) - jump) < 1.2e-3  # two rounded values
        prev_end = g["theta_cs"] + g["T_dir"] * g["theta_htotal"]
        assert abs(g["t_dsp"] - SIM1_T_DSP[i]) < 6e-7
    assert [ph.name for ph in tr.phases[:4]] == ["LFFSSP", "RFFDSP", "RFFSSP", "LFFDSP"]
    assert len(tr.phases) == 16
    for ph, t_end in zip(tr.phases, SIM1_T_END):
        assert abs(ph.t_end - t_end) < 6e-7            # printed to 6 decimals
    assert abs(tr.duration - 6.883333) < 6e-7


def test_hip_passes_through_waypoints_on_arcs_of_radius_R(trajs):
    for name, tr in _all_sims(trajs):
        P = tr.params.Phip
        for ph in tr.phases:
            i = ph.segment
            g = tr.segment_geometry(i)
            if ph.is_ssp:
                # 1e-9 m: round-off only (the hip passes exactly through P_k, thesis 3.1.1)
                assert np.allclose(tr.sample(ph.index, 0.0).hip_p, P[i], atol=1e-9), (name, ph)
            else:
                assert np.allclose(tr.phase_end(ph.index).hip_p, P[i + 1], atol=1e-9), (name, ph)
            for t in np.linspace(0, ph.duration, 7):
                hp = tr.sample(ph.index, t).hip_p
                assert abs(np.linalg.norm(hp[:2] - g["O"]) - g["R"]) < 1e-9
                assert hp[2] == P[0, 2]


# ================================================================================ boundary conditions
def test_hip_polynomial_boundary_conditions(trajs):
    """theta_h: 0 -> theta_h,SSP -> theta_htotal with rates V_k/R, V_k,k+1/R, V_k+1/R (L1341-1360)."""
    for _name, tr in _all_sims(trajs):
        p = tr.params
        for i in range(p.n_segments):
            g = tr.segment_geometry(i)
            s, O = g["T_dir"], g["O"]
            r0 = p.Phip[i, :2] - O
            ssp, dsp = tr.phases[2 * i], tr.phases[2 * i + 1]

            def arc_angle_of(x):  # angle travelled from P_k, positive along the direction of travel
                return s * _signed_angle(r0, x[:2] - O)

            end_ssp = tr.phase_end(ssp.index)
            expected_hssp = g["theta_htotal"] - (p.dtheta_PLN[i] + p.dtheta_ADJ[i])   # L1328
            # 1e-12 rad / 1e-9 m/s: round-off
            assert abs(arc_angle_of(tr.sample(ssp.index, 0).hip_p)) < 1e-12
            assert abs(arc_angle_of(end_ssp.hip_p) - expected_hssp) < 1e-12
            assert abs(arc_angle_of(tr.phase_end(dsp.index).hip_p) - g["theta_htotal"]) < 1e-12
            for smp, v in ((tr.sample(ssp.index, 0), p.Vhip[2 * i]), (end_ssp, p.Vhip[2 * i + 1]),
                           (tr.sample(dsp.index, 0), p.Vhip[2 * i + 1]),
                           (tr.phase_end(dsp.index), p.Vhip[2 * i + 2])):
                assert abs(np.linalg.norm(smp.hip_v) - v) < 1e-9
                # velocity is tangent to the arc, pointing along the travel direction
                radial = smp.hip_p[:2] - O
                assert abs(np.dot(smp.hip_v[:2], radial)) < 1e-9
                assert s * (radial[0] * smp.hip_v[1] - radial[1] * smp.hip_v[0]) >= -1e-12


def test_hip_yaw_follows_the_path_tangent(trajs):
    """C^(0,17) = e^(u3 (theta_CS +- theta_h)) in the SSP: the body x axis is the arc tangent; the DSP
    yaw polynomial ends at the tangent of the next arc at P_k+1 (or of the last arc, decision D3)."""
    for _name, tr in _all_sims(trajs):
        p = tr.params
        for i in range(p.n_segments):
            for t in np.linspace(0, p.t_SSP[i], 5):
                smp = tr.sample(2 * i, t)
                g = tr.segment_geometry(i)
                radial = smp.hip_p[:2] - g["O"]
                tangent = g["T_dir"] * np.array((-radial[1], radial[0]))   # CCW for a left turn
                heading = math.atan2(tangent[1], tangent[0])
                assert abs(wrap_pi(smp.hip_yaw - heading)) < 1e-12        # round-off, rad
            end = tr.phase_end(2 * i + 1)
            j = min(i + 1, p.n_segments - 1)
            gj = tr.segment_geometry(j)
            radial = p.Phip[i + 1, :2] - gj["O"]
            tangent = gj["T_dir"] * np.array((-radial[1], radial[0]))
            assert abs(wrap_pi(end.hip_yaw - math.atan2(tangent[1], tangent[0]))) < 1e-12
            # rate at the DSP end = the next SSP's initial rate s V_k+1 / R_k+1 (L1449-1450)
            assert abs(end.hip_w[2] - gj["T_dir"] * p.Vhip[2 * i + 2] / gj["R"]) < 1e-12


def test_swing_toe_boundary_conditions_left_and_right_turns(trajs):
    """R_gen reaches R_f at t_z; z = 0.015 m at both ends with zero velocity, SH at k_SH t_SSP; foot yaw
    at rest at both ends and tangent to the arc at landing; toe lands at theta_htotal - ADJ (L1505)."""
    seen_turns = set()
    for _name, tr in _all_sims(trajs):
        p = tr.params
        for i in range(p.n_segments):
            ph = tr.phases[2 * i]
            g = tr.segment_geometry(i)
            s, O, T = g["T_dir"], g["O"], p.t_SSP[i]
            foot = ph.swing_foot
            seen_turns.add((s, foot))
            toe = (lambda smp: smp.toe_R_p) if foot == "R" else (lambda smp: smp.toe_L_p)
            vel = (lambda smp: smp.toe_R_v) if foot == "R" else (lambda smp: smp.toe_L_v)
            yaw = (lambda smp: smp.foot_R_yaw) if foot == "R" else (lambda smp: smp.foot_L_yaw)
            wz = (lambda smp: smp.foot_R_w[2]) if foot == "R" else (lambda smp: smp.foot_L_w[2])
            inner = (s == 1 and foot == "L") or (s == -1 and foot == "R")   # inside foot of the turn
            R_f = p.R[i] - p.SW[i] / 2 if inner else p.R[i] + p.SW[i] / 2   # eqs. 3.32/3.33
            t_z = T / p.k_Adj[i]
            a, b, m = tr.sample(ph.index, 0.0), tr.sample(ph.index, T), tr.sample(ph.index, p.k_SH[i] * T)
            # 1e-12 m, 1e-10 m/s, 1e-10 rad/s: round-off of polynomials evaluated at t ~ 1 s
            assert abs(toe(a)[2] - 0.015) < 1e-12 and abs(toe(b)[2] - 0.015) < 1e-12
            assert abs(toe(m)[2] - p.SH[i]) < 1e-12
            assert np.allclose(vel(a), 0, atol=1e-10) and np.allclose(vel(b), 0, atol=1e-10)
            assert abs(wz(a)) < 1e-10 and abs(wz(b)) < 1e-10
            for t in (t_z, 0.5 * (t_z + T), T):
                assert abs(np.linalg.norm(toe(tr.sample(ph.index, t))[:2] - O) - R_f) < 1e-12
            # start radius R_o = distance of the start toe (eqs. 3.30/3.31); radius at rest at 0 and t_z
            start = tr.phase_targets(ph.index).swing_toe_start
            assert abs(np.linalg.norm(toe(a)[:2] - O) - np.linalg.norm(start[:2] - O)) < 1e-12
            h = 1e-6
            rad = lambda t: np.linalg.norm(toe(tr.sample(ph.index, t))[:2] - O)  # noqa: E731
            # one-sided FD of a function with zero slope: error ~ h * R'' ~ 1e-6 * 1 m/s^2
            assert abs(rad(h) - rad(0)) / h < 1e-5 and abs(rad(t_z) - rad(t_z - h)) / h < 1e-5
            # landing angle theta_h,SSP + PLN = theta_htotal - ADJ, measured from P_k
            ang = s * _signed_angle(p.Phip[i, :2] - O, toe(b)[:2] - O)
            assert abs(ang - (g["theta_htotal"] - p.dtheta_ADJ[i])) < 1e-12
            # landed foot yaw = arc tangent at the landing point (eqs. 3.48/3.49)
            radial = toe(b)[:2] - O
            tangent = s * np.array((-radial[1], radial[0]))
            assert abs(wrap_pi(yaw(b) - math.atan2(tangent[1], tangent[0]))) < 1e-12
    assert seen_turns == {(1, "R"), (1, "L"), (-1, "R"), (-1, "L")}   # both feet, both turn directions


# ================================================================================ literal thesis equations
def test_unified_formulas_equal_the_literal_per_direction_thesis_equations(trajs):
    """Hip eqs. 3.8-3.16 and toe eqs. 3.20-3.41 typed per turning direction, with theta_h, R_c,
    theta_rot from the closed-form Hermite basis, against the generator's unified implementation."""
    for name, tr in _all_sims(trajs):
        p = tr.params
        for i in range(p.n_segments):
            g = tr.segment_geometry(i)
            Ox, Oy = g["O"]
            cs, s, R = g["theta_cs"], g["T_dir"], p.R[i]
            T, TD = p.t_SSP[i], p.t_SSP[i] / p.PTR[i]
            V0, V01, V1 = p.Vhip[2 * i:2 * i + 3]
            hssp = g["theta_htotal"] - p.dtheta_PLN[i] - p.dtheta_ADJ[i]
            foot = tr.phases[2 * i].swing_foot
            start = tr.phase_targets(2 * i).swing_toe_start
            # eqs. 3.20/3.21 and 3.23/3.24 (3.25-3.29 for the left toe are the same formulas)
            KRx = (start[0] - Ox) * math.cos(cs) + (start[1] - Oy) * math.sin(cs)
            KRy = (start[1] - Oy) * math.cos(cs) - (start[0] - Ox) * math.sin(cs)
            th_ri = math.atan2(KRx, -KRy) if s == 1 else math.atan2(KRx, KRy)
            R_o = math.hypot(Ox - start[0], Oy - start[1])
            R_f = g["R_f"]
            t_z = T / p.k_Adj[i]
            rot_f = hssp + p.dtheta_PLN[i] - th_ri                      # theta_Rrot / theta_Lrot
            for phase, dur in ((2 * i, T), (2 * i + 1, TD)):
                for t in np.linspace(0, dur, 6):
                    smp = tr.sample(phase, t)
                    if phase % 2 == 0:
                        th, thd, _ = _hermite(T, 0.0, hssp, V0 / R, V01 / R, t)
                    else:
                        th, thd, _ = _hermite(TD, hssp, g["theta_htotal"], V01 / R, V1 / R, t)
                    if s == 1:   # eqs. 3.8-3.11
                        hp = (Ox + R * math.sin(th + cs), Oy - R * math.cos(th + cs))
                        hv = (R * thd * math.cos(th + cs), R * thd * math.sin(th + cs))
                    else:        # eqs. 3.13-3.16
                        hp = (Ox + R * math.sin(th - cs), Oy + R * math.cos(th - cs))
                        hv = (R * thd * math.cos(th - cs), -R * thd * math.sin(th - cs))
                    # 1e-10: round-off of two implementations (m, m/s)
                    assert np.allclose(smp.hip_p[:2], hp, atol=1e-10), (name, phase, t)
                    assert np.allclose(smp.hip_v[:2], hv, atol=1e-10), (name, phase, t)
                    if phase % 2:
                        continue
                    Rg, Rgd, _ = _hermite(t_z, R_o, R_f, 0.0, 0.0, t) if t <= t_z else (R_f, 0.0, 0.0)
                    rot, rotd, _ = _hermite(T, 0.0, rot_f, 0.0, 0.0, t)
                    a = th_ri + rot
                    if s == 1:   # eqs. 3.34/3.35 (right toe), 3.36/3.37 (left toe)
                        tp = (Rg * math.sin(a + cs) + Ox, -Rg * math.cos(a + cs) + Oy)
                        tv = (Rgd * math.sin(a + cs) + Rg * rotd * math.cos(a + cs),
                              -Rgd * math.cos(a + cs) + Rg * rotd * math.sin(a + cs))
                    else:        # eqs. 3.38/3.39, 3.40/3.41
                        tp = (Rg * math.sin(a - cs) + Ox, Rg * math.cos(a - cs) + Oy)
                        tv = (Rgd * math.sin(a - cs) + Rg * rotd * math.cos(a - cs),
                              Rgd * math.cos(a - cs) - Rg * rotd * math.sin(a - cs))
                    toe_p = smp.toe_R_p if foot == "R" else smp.toe_L_p
                    toe_v = smp.toe_R_v if foot == "R" else smp.toe_L_v
                    assert np.allclose(toe_p[:2], tp, atol=1e-10), (name, phase, t)
                    assert np.allclose(toe_v[:2], tv, atol=1e-10), (name, phase, t)


def test_mirror_symmetry_of_left_and_right_formulas(trajs):
    """Mirroring the path (x -> -x) must mirror every reference and swap the feet."""
    tr, mi = trajs["sim1"], ReferenceTrajectory(PathParams.from_dict(_mirrored_sim1()))
    S, M = np.diag([-1.0, 1.0, 1.0]), np.diag([1.0, -1.0, 1.0])   # see _mirrored_sim1
    assert [p.name for p in mi.phases[:4]] == ["RFFSSP", "LFFDSP", "LFFSSP", "RFFDSP"]
    for ph in tr.phases:
        for t in np.linspace(0, ph.duration, 5):
            a, b = tr.sample(ph.index, t), mi.sample(ph.index, t)
            # 1e-10: round-off (m, m/s, m/s^2, rad/s)
            for x, y in ((a.hip_p, b.hip_p), (a.hip_v, b.hip_v), (a.hip_a, b.hip_a),
                         (a.toe_R_p, b.toe_L_p), (a.toe_R_v, b.toe_L_v), (a.toe_L_a, b.toe_R_a)):
                assert np.allclose(S @ x, y, atol=1e-10)
            assert np.allclose(S @ a.hip_R @ M, b.hip_R, atol=1e-10)
            assert np.allclose(S @ a.foot_R_R @ M, b.foot_L_R, atol=1e-10)
            assert abs(a.hip_w[2] + b.hip_w[2]) < 1e-10 and abs(a.foot_L_alpha[2] + b.foot_R_alpha[2]) < 1e-10


# ================================================================================ derivatives
def _rot_fd(Rp: np.ndarray, Rm: np.ndarray, h: float) -> np.ndarray:
    """World angular velocity from R(t+h) R(t-h)^T = exp(2h [w]x)."""
    return Rotation.from_matrix(Rp @ Rm.T).as_rotvec() / (2 * h)


FIELDS = [("hip_p", "hip_v"), ("hip_v", "hip_a"), ("toe_R_p", "toe_R_v"), ("toe_R_v", "toe_R_a"),
          ("toe_L_p", "toe_L_v"), ("toe_L_v", "toe_L_a"), ("hip_w", "hip_alpha"), ("foot_R_w", "foot_R_alpha"),
          ("foot_L_w", "foot_L_alpha")]
ROTS = [("hip_R", "hip_w"), ("foot_R_R", "foot_R_w"), ("foot_L_R", "foot_L_w")]


@pytest.mark.parametrize("name", SIMS)
def test_velocities_and_accelerations_equal_central_differences(trajs, name):
    """h = 1e-5 s: truncation error h^2/6 |x'''| < 2e-11 * |jerk| (jerks here < 1e3), round-off
    eps |x| / h < 3e-8 even with the 1000 m arc centre of sim3; tolerance 1e-6 bounds both with margin.
    Times within 2h of t_z are skipped: R_gen'' jumps there by design (the cubic R_c meets a constant)."""
    tr = trajs[name]
    h = 1e-5
    worst = 0.0
    for ph in tr.phases:
        t_z = tr.segment_geometry(ph.segment)["t_z"] if ph.is_ssp else None
        for t in np.linspace(2 * h, ph.duration - 2 * h, 9):
            if t_z is not None and abs(t - t_z) < 2 * h:
                continue
            a, p, m = tr.sample(ph.index, t), tr.sample(ph.index, t + h), tr.sample(ph.index, t - h)
            for f, df in FIELDS:
                fd = (getattr(p, f) - getattr(m, f)) / (2 * h)
                err = np.max(np.abs(fd - getattr(a, df)))
                worst = max(worst, err)
                assert err < 1e-6, (name, ph.name, t, f)
            for f, df in ROTS:
                err = np.max(np.abs(_rot_fd(getattr(p, f), getattr(m, f), h) - getattr(a, df)))
                assert err < 1e-6, (name, ph.name, t, f)
            assert abs((p.hip_yaw - m.hip_yaw) / (2 * h) - a.hip_w[2]) < 1e-6
    assert worst < 1e-6


# ================================================================================ continuity
def _state(s, fields):
    return [np.atleast_1d(np.asarray(getattr(s, f), dtype=float)).ravel() for f in fields]


POS = ["hip_p", "hip_R", "hip_yaw", "toe_R_p", "toe_L_p", "foot_R_R", "foot_L_R", "foot_R_yaw", "foot_L_yaw"]
VEL_ALWAYS = ["hip_w", "toe_R_v", "toe_L_v", "foot_R_w", "foot_L_w"]


def test_continuity_across_phase_boundaries(trajs):
    """Positions, orientations (and the unwrapped yaw scalars), angular velocities and toe velocities
    are continuous at every boundary (1e-9, round-off).  The hip CoM velocity is continuous at every
    SSP->DSP boundary; at DSP->SSP only where consecutive arcs are tangent (sims 2 and 3).  In sim 1 the
    arcs meet at an angle (the heading jumps of sim1.yaml `derived:`): there the speed is continuous and
    the velocity turns by exactly that jump (thesis property, not an implementation defect)."""
    for name, tr in _all_sims(trajs):
        for k in range(tr.n_phases - 1):
            a, b = tr.phase_end(k), tr.sample(k + 1, 0.0)
            for x, y, f in zip(_state(a, POS + VEL_ALWAYS), _state(b, POS + VEL_ALWAYS), POS + VEL_ALWAYS):
                assert np.allclose(x, y, atol=1e-9), (name, k, f)
            if tr.phases[k].is_ssp or name in ("sim2", "sim3"):
                assert np.allclose(a.hip_v, b.hip_v, atol=1e-9), (name, k)
            else:
                i = tr.phases[k].segment
                gi, gj = tr.segment_geometry(i), tr.segment_geometry(i + 1)
                jump = wrap_pi(gj["theta_cs"] - (gi["theta_cs"] + gi["T_dir"] * gi["theta_htotal"]))
                assert abs(np.linalg.norm(a.hip_v) - np.linalg.norm(b.hip_v)) < 1e-9
                if np.linalg.norm(a.hip_v) > 1e-6:
                    assert abs(_signed_angle(a.hip_v[:2], b.hip_v[:2]) - jump) < 1e-9, (name, k)


def test_acceleration_jumps_are_those_of_the_thesis_cubics(trajs):
    """The thesis's cubics match position and rate only, so theta_h'' jumps at the SSP->DSP switch.
    The measured tangential hip acceleration jump must equal R (theta_D''(0) - theta_S''(t_SSP)) from
    the closed-form Hermite cubics; the radial component (R theta'^2) is continuous."""
    for _name, tr in _all_sims(trajs):
        p = tr.params
        worst = 0.0
        for i in range(p.n_segments):
            g = tr.segment_geometry(i)
            R, T, TD = p.R[i], p.t_SSP[i], p.t_SSP[i] / p.PTR[i]
            V0, V01, V1 = p.Vhip[2 * i:2 * i + 3]
            hssp = g["theta_htotal"] - p.dtheta_PLN[i] - p.dtheta_ADJ[i]
            aS = _hermite(T, 0.0, hssp, V0 / R, V01 / R, T)[2]
            aD = _hermite(TD, hssp, g["theta_htotal"], V01 / R, V1 / R, 0.0)[2]
            end, start = tr.phase_end(2 * i), tr.sample(2 * i + 1, 0.0)
            tang = np.array((math.cos(end.hip_yaw), math.sin(end.hip_yaw), 0.0))
            jump = end.hip_a - start.hip_a
            # 1e-9 m/s^2: round-off
            assert abs(np.dot(start.hip_a - end.hip_a, tang) - R * (aD - aS)) < 1e-9
            assert np.linalg.norm(jump - np.dot(jump, tang) * tang) < 1e-9
            worst = max(worst, abs(R * (aD - aS)))
        assert worst > 0.0   # the discontinuity exists: a test that assumed C2 would be wrong


# ================================================================================ schedule and clamping
def test_schedule_phase_at_and_clamping(trajs):
    tr = trajs["sim1"]
    for ph in tr.phases:
        assert tr.phase_at(ph.t_start) == ph.index
        assert tr.phase_at(0.5 * (ph.t_start + ph.t_end)) == ph.index
        assert ph.number == ph.index + 1
    assert tr.phase_at(-1.0) == 0 and tr.phase_at(tr.duration + 5) == tr.n_phases - 1
    k = 4
    ph = tr.phases[k]
    late = tr.sample_global(ph.t_end + 0.4, phase=k)      # phase lasts longer: held at its end (L4011)
    early = tr.sample_global(ph.t_start - 0.3, phase=k)   # phase started early: held at its start
    end, start = tr.phase_end(k), tr.sample(k, 0.0)
    for f in ("hip_p", "hip_v", "hip_a", "toe_R_p", "toe_L_p", "foot_R_R"):
        assert np.array_equal(getattr(late, f), getattr(end, f))
        assert np.array_equal(getattr(early, f), getattr(start, f))
    mid = tr.sample_global(ph.t_start + 0.3)
    assert mid.phase == k and abs(mid.t_phase - 0.3) < 1e-12
    with pytest.raises(TrajectoryError, match=r"phase: index .* \(value: 99\)"):
        tr.sample(99, 0.0)


def test_phase_targets(trajs):
    tr = trajs["sim1"]
    P = tr.params.Phip
    for ph in tr.phases:
        tg = tr.phase_targets(ph.index)
        if not ph.is_ssp:
            assert np.allclose(tg.hip_p_end, P[ph.segment + 1], atol=1e-12) and tg.swing_foot is None
            continue
        nxt = tr.sample(ph.index + 1, 0.0)
        landed = nxt.toe_R_p if ph.swing_foot == "R" else nxt.toe_L_p
        assert np.allclose(tg.swing_toe_end, landed, atol=1e-12)       # DSP holds the planned landing
        d = tg.swing_toe_end[:2] - tg.swing_toe_start[:2]
        assert abs(tg.planned_horizontal_travel - math.hypot(*d)) < 1e-12 and tg.planned_horizontal_travel > 0.05
        assert abs(tg.duration - ph.duration) < 1e-15


# ================================================================================ touchdown data
def test_set_landing_moves_the_next_swing_start_only():
    tr = ReferenceTrajectory(PathParams.from_dict(_path_dict("sim1")))
    ref = ReferenceTrajectory(PathParams.from_dict(_path_dict("sim1")))
    planned = tr.phase_targets(0).swing_toe_end
    actual = planned + np.array((0.012, -0.02, 0.0004))
    R_act = Rotation.from_euler("zyx", (tr.phase_end(0).foot_R_yaw + 0.05, 0.01, -0.02)).as_matrix()
    tr.set_landing("R", 0, actual, R_act)
    # the DSP and the next SSP hold the right foot where it actually landed (thesis L4024)
    for k in (1, 2, 3):
        smp = tr.sample(k, 0.5 * tr.phases[k].duration)
        assert np.array_equal(smp.toe_R_p, actual) and np.array_equal(smp.foot_R_R, R_act)
    # the next right swing (phase 4) starts there, with the actual yaw, and lands where planned
    s4 = tr.sample(4, 0.0)
    assert np.allclose(s4.toe_R_p[:2], actual[:2], atol=1e-12) and abs(s4.toe_R_p[2] - 0.015) < 1e-15
    assert abs(wrap_pi(s4.foot_R_yaw - math.atan2(R_act[1, 0], R_act[0, 0]))) < 1e-12
    assert np.allclose(tr.phase_end(4).toe_R_p, ref.phase_end(4).toe_R_p, atol=1e-12)
    assert np.allclose(tr.phase_targets(4).swing_toe_start, actual)
    # everything else is unchanged
    for k in (0, 2, 5, 6, 7, 15):
        for t in (0.0, 0.37 * tr.phases[k].duration, tr.phases[k].duration):
            a, b = tr.sample(k, t), ref.sample(k, t)
            assert np.array_equal(a.hip_p, b.hip_p) and np.array_equal(a.toe_L_p, b.toe_L_p)
            if k not in (1, 2, 3):
                assert np.array_equal(a.toe_R_p, b.toe_R_p)
    # the DSP phase index of the same segment is accepted too; the wrong foot is rejected
    tr.set_landing("right", 1, actual, R_act)
    with pytest.raises(TrajectoryError, match="lands the R foot, not 'L'"):
        tr.set_landing("L", 0, actual, R_act)
    with pytest.raises(TrajectoryError, match="foot: must be"):
        tr.set_landing("X", 0, actual, R_act)
    with pytest.raises(TrajectoryError, match="R_foot"):
        tr.set_landing("R", 0, actual, 2 * np.eye(3))


# ================================================================================ validation
@pytest.mark.parametrize("key, index, value, pattern", [
    ("R", 3, 0.05, r"path\.R\[3\]: arc cannot exist.*\(value: 0\.05\)"),
    ("t_SSP", 2, 0.0, r"path\.t_SSP\[2\]: must be > 0 \(value: 0\.0\)"),
    ("PTR", 0, -6.0, r"path\.PTR\[0\]: must be > 0 \(value: -6\.0\)"),
    ("k_Adj", 5, 0.0, r"path\.k_Adj\[5\]: must be >= 1.*\(value: 0\.0\)"),
    ("k_SH", 1, 1.0, r"path\.k_SH\[1\]: must lie in \(0, 1\) \(value: 1\.0\)"),
    ("SH", 4, 0.01, r"path\.SH\[4\]: must exceed.*\(value: 0\.01\)"),
    ("T_dir", 6, 0.0, r"path\.T_dir\[6\]: must be \+1 \(left\) or -1 \(right\) \(value: 0\.0\)"),
    ("Vhip", 7, -0.1, r"path\.Vhip\[7\]: speeds are magnitudes.*\(value: -0\.1\)"),
    ("SW", 2, 3.0, r"path\.SW\[2\]: half the step width.*\(value: 3\.0\)"),
])
def test_invalid_values_raise_named_errors(key, index, value, pattern):
    d = _path_dict("sim1")
    d[key] = list(d[key])
    d[key][index] = value
    with pytest.raises(PathParamError, match=pattern):
        PathParams.from_dict(d)


def test_invalid_shapes_and_keys_raise_named_errors():
    d = _path_dict("sim1")
    for key, new, pattern in (
        ("Vhip", _path_dict("sim1")["Vhip"] + [0.4], r"path\.Vhip: expected 2n-1 = 17 entries .* got 18"),
        ("SW", [0.3] * 7, r"path\.SW: expected n-1 = 8 entries .* got 7"),
        ("Phip", [[0, 0, 0.9588], [0, 0.1, 0.95]], r"path\.Phip\[1\]: z must equal"),
        ("toe_R0", [0.16, 0.1876], r"path\.toe_R0: expected 3 entries"),
        ("foot_L0", [[1, 0, 0], [0, 1, 0], [0, 0, -1]], r"path\.foot_L0: is not a rotation matrix"),
        ("first_phase", "RFFDSP", r"path\.first_phase: must be one of"),
        ("R", [1.0, "a"] + [1.0] * 6, r"path\.R: cannot be read"),
        ("t_SSP", [0.8, float("nan")] + [0.7] * 6, r"path\.t_SSP\[1\]: must be finite"),
    ):
        bad = dict(d, **{key: new})
        with pytest.raises(PathParamError, match=pattern):
            PathParams.from_dict(bad)
    with pytest.raises(PathParamError, match=r"sim9: missing key\(s\) \['SH'\]"):
        PathParams.from_dict({k: v for k, v in d.items() if k != "SH"}, where="sim9")
    with pytest.raises(PathParamError, match=r"unknown key\(s\) \['Radius'\]"):
        PathParams.from_dict(dict(d, Radius=d["R"]))
    assert issubclass(PathParamError, ValueError)
    # constructing the dataclass directly validates too
    with pytest.raises(PathParamError, match=r"path\.T_dir\[0\]"):
        PathParams(**dict(PathParams.from_dict(d).__dict__, T_dir=np.array([2.0] + [1.0] * 7)))


# ================================================================================ performance and plots
def test_queries_never_rebuild_the_trajectory(trajs, monkeypatch):
    """A query reads the tables built at construction; an accidental per-call rebuild (milliseconds a call) would
    show up here.  (Query speed itself is bench.py's business, not a timed test's.)"""
    from humanoid_sim.references.chapter3 import generator

    tr = trajs["sim1"]

    def rebuild(*a, **k):
        raise AssertionError("a query rebuilt part of the trajectory")

    for name in ("_build_swing", "_planned_landing", "__init__"):
        monkeypatch.setattr(generator.ReferenceTrajectory, name, rebuild)
    for t in np.linspace(0, tr.duration, 200):
        tr.sample_global(float(t))
        k = tr.phase_at(float(t))
        tr.hip_reference(k, float(t))


@pytest.mark.parametrize("name", SIMS)
def test_plot_reference_writes_pngs(trajs, name, tmp_path):
    paths = plot_reference(trajs[name], tmp_path / name, dt=0.02)
    assert [p.name for p in paths] == ["reference_iso.png", "reference_xy.png", "reference_xz.png"]
    for p in paths:
        data = p.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000   # a real, non-empty figure
