"""The balance controller's DCM feedback (``controllers.balance.dcm``) and step adjustment
(``controllers.balance.steps``) against the linear inverted pendulum integrated numerically, and its settings."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from humanoid_sim.controllers.balance.dcm import ZmpShift, ZmpWindow, capture_point, dcm_acceleration, lipm_omega
from humanoid_sim.controllers.balance.steps import StepAdjuster, clamp_offset, predicted_offset
from humanoid_sim.controllers.balance.swing import swing_targets
from humanoid_sim.scenario.balance import BalanceSettings, parse_balance
from humanoid_sim.scenario.fields import ScenarioError

ROOT = Path(__file__).resolve().parents[2]
Z_C, MASS = 0.75, 55.04
OM = lipm_omega(Z_C)


def lipm(p_of):
    """The LIPM c'' = omega^2 (c - p(t, c, c')) in the plane, as an ODE right-hand side of y = [c (2), c' (2)]."""
    def rhs(t, y):
        c, cd = y[:2], y[2:]
        return np.concatenate([cd, OM * OM * (c - p_of(t, c, cd))])
    return rhs


def test_a_push_moves_the_capture_point_by_delta_v_over_omega():
    c, cd = np.array([0.01, 0.3]), np.array([0.05, 0.2])
    J = np.array([16.5, 0.0])                     # N s, lateral
    jump = capture_point(c, cd + J / MASS, OM) - capture_point(c, cd, OM)
    # exact arithmetic of the definition: round-off only
    np.testing.assert_allclose(jump, J / MASS / math.sqrt(9.81 / Z_C), atol=1e-12)


def test_the_law_is_englsbergers_cmp_law_and_the_error_decays_at_rate_k():
    k = 4.0
    p_ref = np.array([0.1, 0.2])                  # a stationary plan: c_ref = xi_ref = p_ref, no acceleration
    c0, cd0 = p_ref + np.array([0.01, -0.02]), np.array([0.15, 0.1])

    def p_cmd(t, c, cd):                          # the ZMP the law's acceleration implies: p = c - c'' / omega^2
        acc = dcm_acceleration(c, capture_point(c, cd, OM), p_ref, p_ref, np.zeros(2), OM, k)
        return c - acc / OM ** 2

    xi0 = capture_point(c0, cd0, OM)
    # Englsberger et al. 2015: p = p_ref + (1 + k / omega) (xi - xi_ref)
    np.testing.assert_allclose(p_cmd(0.0, c0, cd0), p_ref + (1.0 + k / OM) * (xi0 - p_ref), atol=1e-12)
    T = 0.5
    sol = solve_ivp(lipm(p_cmd), (0.0, T), np.concatenate([c0, cd0]), rtol=1e-10, atol=1e-12)
    xi_T = capture_point(sol.y[:2, -1], sol.y[2:, -1], OM)
    # the integrator's tolerance 1e-10 relative: 1e-8 m leaves it margin
    np.testing.assert_allclose(xi_T - p_ref, (xi0 - p_ref) * math.exp(-k * T), atol=1e-8)


def test_the_zmp_shift_is_the_backward_recursion_of_its_windows():
    sh = ZmpShift(OM)
    sh.windows += [ZmpWindow(0.4, 1.2, np.array([0.05, -0.02])), ZmpWindow(1.0, 1e9, np.array([0.0, 0.1]))]

    def p(s):
        return sum((w.d for w in sh.windows if w.t0 <= s < w.t1), np.zeros(2))

    for t in (0.0, 0.5, 1.1, 2.0):
        want = [quad(lambda s, i=i: OM * math.exp(-OM * (s - t)) * p(s)[i], t, t + 40.0, points=[0.4, 1.0, 1.2],
                     limit=200)[0] for i in (0, 1)]
        dp, dxi = sh.at(t)
        # adaptive quadrature to ~1e-10; the tail beyond 40 s is e^-145
        np.testing.assert_allclose(dxi, want, atol=1e-8)
        np.testing.assert_allclose(dp, p(t), atol=0.0)


def test_the_moved_foothold_captures_a_pushed_pendulum():
    """Single support on a stance CoP p0 with the plan's DCM at rest over the next foothold f (0.2 m ahead at
    touchdown); a push adds a DCM error.  With the foothold moved by the predicted error the LIPM's DCM, once the
    CoP is on the new foothold, stays there (captured); on the planned foothold it runs away."""
    T_r = 0.35
    f = np.array([0.0, 0.2])
    p0 = np.zeros(2)
    xi_ref0 = p0 + (f - p0) * math.exp(-OM * T_r)   # the plan: the DCM reaches f at touchdown
    push = np.array([0.0, 0.3])                     # m/s forward
    c0 = np.array([0.0, 0.02])
    cd0 = (xi_ref0 - c0) * OM + push
    err = capture_point(c0, cd0, OM) - xi_ref0
    d = predicted_offset(err, OM, T_r, 0.0)
    y = solve_ivp(lipm(lambda t, c, cd: p0), (0.0, T_r), np.concatenate([c0, cd0]), rtol=1e-10, atol=1e-12).y[:, -1]
    for foothold, captured in ((f + d, True), (f, False)):
        sol = solve_ivp(lipm(lambda t, c, cd, fh=foothold: fh), (0.0, 1.0), y, rtol=1e-10, atol=1e-12)
        drift = np.linalg.norm(capture_point(sol.y[:2, -1], sol.y[2:, -1], OM) - foothold)
        # captured: the integrator's error grown by e^{omega 1 s} ~ 37; not captured: centimetres
        assert (drift < 1e-6) == captured, (foothold, drift)


def test_the_offset_keeps_the_dead_band_the_reach_and_no_crossing():
    np.testing.assert_allclose(predicted_offset(np.array([0.005, -0.004]), OM, 0.0, 0.02), [0.0, 0.0])
    np.testing.assert_allclose(predicted_offset(np.array([0.03, -0.03]), OM, 0.0, 0.02), [0.01, -0.01], atol=1e-15)
    s = BalanceSettings(step_forward_m=0.2, step_backward_m=0.15, step_outward_m=0.15, step_min_width_m=0.12)
    # left swing foot 0.2 m from the stance foot: inward (-y) at most 0.08 m, outward at most 0.15 m
    np.testing.assert_allclose(clamp_offset(np.array([0.5, -0.5]), 1.0, 0.2, s), [0.2, -0.08])
    np.testing.assert_allclose(clamp_offset(np.array([-0.5, 0.5]), 1.0, 0.2, s), [-0.15, 0.15])
    # right swing foot: outward is -y
    np.testing.assert_allclose(clamp_offset(np.array([0.0, -0.5]), -1.0, 0.2, s), [0.0, -0.15])
    np.testing.assert_allclose(clamp_offset(np.array([0.0, 0.5]), -1.0, 0.2, s), [0.0, 0.08])


def _one_step(settings: BalanceSettings, forward: float = 0.3) -> StepAdjuster:
    """A step adjuster on a one-step plan: single support 0 over [0, 0.7] s and a 0.1 s double support, the left
    foot swinging to (``forward``, 0.2) while the right one stands at the origin; heading +x (forward), left +y."""
    ph = [SimpleNamespace(t_start=0.0, t_end=0.7, duration=0.7, swing_foot="L"),
          SimpleNamespace(t_start=0.7, t_end=0.8, duration=0.1, swing_foot=None)]
    end = np.array([forward, 0.2, 0.0])
    traj = SimpleNamespace(phases=ph, phase_targets=lambda k: SimpleNamespace(swing_toe_end=end),
                           toe_reference=lambda k, t, foot: (np.zeros(3), np.zeros(6), np.eye(3)))
    return StepAdjuster(traj, ZmpShift(OM), settings)


def test_step_timing_lands_when_the_error_still_fits_the_reach():
    """A forward DCM error whose predicted offset at the planned touchdown (e e^{omega T_r} - dead band) exceeds the
    0.2 m reach: the swing's clock speeds up so that the foot lands after T = ln((reach + band) / e) / omega, when
    the pendulum's DCM error (integrated on the stance CoP) has grown to exactly reach + band."""
    s = BalanceSettings()
    st = _one_step(s)
    e = 0.1
    st.update(0, 0.35, np.array([e, 0.0]), OM, np.eye(3))
    T = math.log((s.step_forward_m + s.step_deadband_m) / e) / OM
    assert T > s.step_min_time_s
    # the closed form of the rate: remaining planned swing over T (round-off only)
    assert st.clock_rate == pytest.approx(0.35 / T, rel=1e-12)
    # no measured DCM given: the whole time gained (the planned swing left, 0.35 s), up to step_max_jump_s
    assert st.shortened == 1 and st.plan_jump(0) == min(0.35, s.step_max_jump_s) and st.plan_jump(1) == 0.0
    t_sw, rate = st.swing_clock(0, 0.35)
    assert (t_sw, rate) == (0.35, st.clock_rate)
    st.update(0, 0.36, np.array([e, 0.0]), OM, np.eye(3))           # 10 ms later the swing is 10 ms x rate on
    assert st.swing_clock(0, 0.36)[0] == pytest.approx(0.36 + 0.01 * (st.clock_rate - 1.0), abs=1e-15)
    # the pendulum on the stance CoP p = 0 from a DCM error e: after T its DCM error is reach + band
    c0, cd0 = np.zeros(2), np.array([e * OM, 0.0])
    sol = solve_ivp(lipm(lambda t, c, cd: np.zeros(2)), (0.0, T), np.concatenate([c0, cd0]), rtol=1e-11, atol=1e-13)
    # the integrator's tolerance, 1e-11 relative
    assert capture_point(sol.y[:2, -1], sol.y[2:, -1], OM)[0] == pytest.approx(
        s.step_forward_m + s.step_deadband_m, abs=1e-8)


def test_the_plan_clock_moves_to_where_its_lateral_dcm_meets_the_measured_one():
    """At an early touchdown of a shortened swing the plan's clock moves on by the candidate move whose plan DCM
    (c + c_dot / omega, sideways in the heading frame) is nearest the measured DCM.  The plan's CoM sways left at
    0.3 m/s; the measured DCM equals the plan's 5/16 of the time gained ahead, so that candidate is chosen exactly.
    A forward offset of the measured DCM does not count."""
    s = BalanceSettings(step_max_jump_s=1.0)
    st = _one_step(s)
    vy = 0.3
    st.traj.com_targets = lambda k, t: (np.array([0.0, vy * t]), np.array([0.0, vy]), np.zeros(2), np.zeros(2))
    gained = 0.7 - 0.35
    t_star = 0.35 + gained * 5 / 16
    xi = (0.9, vy * t_star + vy / OM)          # 0.9 m ahead: the forward error that shortened the swing
    st.update(0, 0.35, np.array([0.1, 0.0]), OM, np.eye(3), xi)
    assert st.clock_rate > 1.0
    assert st.plan_jump(0) == pytest.approx(gained * 5 / 16, abs=1e-15)
    # step_max_jump_s bounds the candidates: the nearest is then the largest allowed move
    st = _one_step(BalanceSettings(step_max_jump_s=0.05))
    st.traj.com_targets = lambda k, t: (np.array([0.0, vy * t]), np.array([0.0, vy]), np.zeros(2), np.zeros(2))
    st.update(0, 0.35, np.array([0.1, 0.0]), OM, np.eye(3), xi)
    assert st.plan_jump(0) == 0.05
    # a swing step timing left alone: the plan does not move on
    st = _one_step(s)
    st.update(0, 0.35, np.array([0.0, 0.0]), OM, np.eye(3), xi)
    assert st.clock_rate == 1.0 and st.plan_jump(0) == 0.0


def test_the_collision_bound_counts_the_earlier_offsets():
    """After an earlier step moved the walk 0.15 m to the right (the stance foot landed there), the left foot's
    inward move is bounded against where the stance foot is, not against its nominal place: the toe points stay
    step_min_width_m apart sideways."""
    s = BalanceSettings()
    st = _one_step(s)
    st.shift.windows.append(ZmpWindow(-1.0, 1e9, np.array([0.0, -0.15])))   # heading +x: right is -y
    st.traj.toe_reference = lambda k, t, foot: (np.array([0.0, -0.15, 0.0]), np.zeros(6), np.eye(3))
    # a huge error to the right (inward for the left foot): the bound binds.  The offset moves at most
    # max_speed (1.5 m/s), 7.5 mm per 5 ms call: 0.3 s of calls reach it
    for i in range(61):
        st.update(0, 0.1 + 0.005 * i, np.array([0.0, -5.0]), OM, np.eye(3))
    landing_y = 0.2 - 0.15 + st.d[1]                # nominal + the earlier offset + this one
    assert landing_y - (-0.15) == pytest.approx(s.step_min_width_m, abs=1e-12)


def test_each_step_takes_back_part_of_the_earlier_offsets():
    """After earlier steps moved the walk 0.12 m to the right and 0.03 m forward (the stance foot landed there), a
    step with no DCM error moves its foothold step_return_m (0.05 m) back toward the planned one, along the offsets'
    direction; a smaller offset is taken back whole; step_return_m = 0 keeps it."""
    total = np.array([0.03, -0.12])          # heading +x: right is -y
    for ret, expected in ((0.05, -0.05 * total / np.linalg.norm(total)), (0.2, -total), (0.0, np.zeros(2))):
        st = _one_step(BalanceSettings(step_return_m=ret))
        st.shift.windows.append(ZmpWindow(-1.0, 1e9, total.copy()))
        st.traj.toe_reference = lambda k, t, foot: (np.array([0.03, -0.12, 0.0]), np.zeros(6), np.eye(3))
        # the offset moves at most max_speed (1.5 m/s), 7.5 mm per 5 ms call: 17 calls reach 0.124 m
        for i in range(40):
            st.update(0, 0.1 + 0.005 * i, np.zeros(2), OM, np.eye(3))
        np.testing.assert_allclose(st.d, expected, rtol=0, atol=1e-15)     # sums of a few floats
        landing = st.landing(0)
        assert landing is not None and np.allclose(landing[:2], np.array([0.33, 0.08]) + expected, rtol=0,
                                                   atol=1e-15)


def test_step_timing_leaves_small_backward_and_disabled_cases_alone():
    s = BalanceSettings()
    for err, settings in (((0.02, 0.0), s), ((-0.2, 0.0), s), ((0.0, 0.1), s),
                          ((0.1, 0.0), BalanceSettings(step_timing=False))):
        st = _one_step(settings)
        st.update(0, 0.35, np.array(err), OM, np.eye(3))
        assert st.clock_rate == 1.0 and st.plan_jump(0) == 0.0, err
    # before step_timing_after of the swing: nothing
    st = _one_step(BalanceSettings(step_timing_after=0.4))
    st.update(0, 0.2, np.array([1.0, 0.0]), OM, np.eye(3))
    assert 0.2 / 0.7 < 0.4 and st.clock_rate == 1.0
    # a huge error: the shortest remaining time, then the fastest clock
    st = _one_step(BalanceSettings(step_max_rate=3.0))
    st.update(0, 0.35, np.array([1.0, 0.0]), OM, np.eye(3))
    assert st.clock_rate == pytest.approx(0.35 / s.step_min_time_s, rel=1e-12)
    fast = BalanceSettings(step_min_time_s=0.15)
    st = _one_step(fast)
    st.update(0, 0.3, np.array([1.0, 0.0]), OM, np.eye(3))
    assert 0.4 / fast.step_min_time_s > fast.step_max_rate and st.clock_rate == fast.step_max_rate
    # a fast plan (0.9 m in 0.8 s) catches up with a 0.1 m error in 0.089 s: no more time is gained than that
    st = _one_step(s, forward=0.9)
    st.update(0, 0.35, np.array([0.1, 0.0]), OM, np.eye(3))
    assert st.clock_rate == pytest.approx(0.35 / (0.35 - 0.1 / (0.9 / 0.8)), rel=1e-12)


def test_a_faster_swing_clock_scales_the_path_velocity_and_acceleration():
    """swing_targets on a swing clock t_sw = t0 + r (t - t0): the toe's velocity is the real-time derivative of its
    position, r x the path's, and its feed-forward acceleration r^2 x the path's (finite differences of an analytic
    path).  Through the trajectory interface (``own`` False: toe_reference alone); the package's trajectories
    answer the same in one query (tests/references/test_zmp_walk.py)."""
    def toe(k, t, foot):
        p = np.array([0.1 * t, 0.2 * t * t, 0.05 * math.sin(3.0 * t)])
        v = np.array([0.1, 0.4 * t, 0.15 * math.cos(3.0 * t), 0.0, 0.0, 0.0])
        return p, v, np.eye(3)

    traj = SimpleNamespace(phases=[SimpleNamespace(t_start=0.0, t_end=0.7, duration=0.7, swing_foot="L")],
                           toe_reference=toe, toe_velocity=lambda k, t, foot: toe(k, t, foot)[1])
    s = BalanceSettings()
    r, t0, t = 1.8, 0.2, 0.3
    def clock(tt):
        return t0 + r * (tt - t0)
    _, p, v, _, a, _ = swing_targets(traj, s, 0, t, "L", False, False, clock(t), r)
    h = 1e-5
    pos = [swing_targets(traj, s, 0, t + d, "L", False, False, clock(t + d), r)[1] for d in (-h, h)]
    vel = [swing_targets(traj, s, 0, t + d, "L", False, False, clock(t + d), r)[2][:3] for d in (-h, h)]
    # central differences of smooth functions: O(h^2) ~ 1e-10 plus round-off / h ~ 1e-11
    np.testing.assert_allclose(v[:3], (pos[1] - pos[0]) / (2 * h), atol=1e-7)
    # the feed-forward is itself a central difference over ff_dt_s = 1 ms: O(1e-6) of the analytic value
    np.testing.assert_allclose(a[:3], (vel[1] - vel[0]) / (2 * h), atol=1e-4)
    # (the 5 cm sine's second derivative is 0.45 x 1.8^2 = 1.5 m/s^2: the tolerance is 1e-4 of it)
    assert abs((vel[1] - vel[0])[2] / (2 * h)) > 1.0


def test_feedback_settings_are_validated():
    assert BalanceSettings().feedback == "dcm"
    assert parse_balance("f.yaml", {"feedback": "pd", "dcm_gain": 5}).dcm_gain == 5.0
    with pytest.raises(ScenarioError, match="balance.feedback = 'lqr'"):
        parse_balance("f.yaml", {"feedback": "lqr"})
    with pytest.raises(ScenarioError, match="balance.dcm_gain"):
        parse_balance("f.yaml", {"dcm_gain": -1})
    with pytest.raises(ScenarioError, match="balance.step_adjustment"):
        parse_balance("f.yaml", {"step_adjustment": 1})
    with pytest.raises(ScenarioError, match="balance.step_max_rate = 0.5"):
        parse_balance("f.yaml", {"step_max_rate": 0.5})
    with pytest.raises(ScenarioError, match="balance.step_timing"):
        parse_balance("f.yaml", {"step_timing": "yes"})


def test_the_com_plan_velocity_is_the_derivative_of_its_position():
    from humanoid_sim.references.zmp.zmp_walk import HipPlan, ZmpPreviewTrajectory

    T = 0.01
    t = np.arange(0.0, 2.0 + T / 2, T)
    xy = np.stack([0.05 * np.sin(3 * t), 0.2 * t], axis=1)
    vxy = np.stack([0.15 * np.cos(3 * t), 0.2 + 0 * t], axis=1)
    traj = SimpleNamespace(plan=HipPlan(t, xy, vxy, {}), com_plan=(xy, vxy, xy * 0.5, Z_C),
                           phases=[SimpleNamespace(t_start=0.0, duration=2.0)])
    traj._clamp = lambda k, tt: min(max(tt, 0.0), 2.0)
    traj._check = lambda k: k
    traj._grid = (0.0, traj.plan.T)                               # what set_hip_plan keeps for the queries
    traj._com_rows = tuple(a.tolist() for a in traj.com_plan[:3])
    h = 1e-5
    for tt in (0.333, 1.017):
        p, v, a, z = ZmpPreviewTrajectory.com_targets(traj, 0, tt)
        pp, pm = (ZmpPreviewTrajectory.com_targets(traj, 0, tt + s)[0] for s in (h, -h))
        # central difference of a cubic: O(h^2) ~ 1e-10 plus round-off / h ~ 1e-11
        np.testing.assert_allclose(v, (pp - pm) / (2 * h), atol=1e-7)
        np.testing.assert_allclose(z[1], 0.5 * 0.2 * tt, atol=1e-12)   # linear in a linear signal: exact


def _pushed_walk(hm, tmp_path, impulse: float, direction: float, balance: dict | None = None):
    """sim3_zmp on MuJoCo with a 0.1 s push on the pelvis at mid single support of phase 8 (RFFSSP: the right foot
    stands), in the heading frame (0 forward, 90 left: toward the swing foot)."""
    pytest.importorskip("mujoco")
    import yaml

    from humanoid_sim.scenario.schema import load_scenario
    from humanoid_sim.sim.simulate import Simulator

    doc = {"base": str(ROOT / "scripts/params/sim3_zmp.yaml"), "name": "pushed",
           "disturbances": {"pushes": [{"body": 17, "impulse_Ns": impulse, "direction_deg": direction,
                                        "frame": "heading", "start": {"phase": 8, "fraction": 0.5},
                                        "duration_s": 0.1}]}}
    if balance:
        doc["balance"] = balance
    f = tmp_path / f"push_{direction:g}_{impulse:g}.yaml"
    f.write_text(yaml.safe_dump(doc))
    return Simulator(hm, load_scenario(f), engine="mujoco").run()


@pytest.mark.slow
def test_a_lateral_push_toward_the_stance_foot_is_survived_on_mujoco(hm, tmp_path):
    """0.3 m/s (16.5 N s on 55 kg) toward the stance foot: the walk completes."""
    res = _pushed_walk(hm, tmp_path, 16.5, 270)
    assert res.completed, res.reason


@pytest.mark.slow
def test_a_forward_push_is_survived_by_landing_early_on_mujoco(hm, tmp_path):
    """0.5 m/s (27.5 N s) forward: the recovery step lands early (step timing) and the walk completes its path
    ahead of schedule; without step timing the same push fells the robot (the 0.2 m reach is too short for the
    error grown until the planned touchdown)."""
    res = _pushed_walk(hm, tmp_path, 27.5, 0)
    assert res.completed, res.reason
    # the pushed step (phase 8, index 7) touched down before its planned end, by more than a loop step
    rec = res.phases[7]
    assert rec.t_end < rec.nominal_end - 0.05, (rec.t_end, rec.nominal_end)
    assert res.sim_time < res.extra["nominal_end"]
    fell = _pushed_walk(hm, tmp_path, 27.5, 0, {"step_timing": False})
    # the robot collapses after the pushed step (the hip sinking about 70 mm in 0.1 s): the run ends at the fall
    # test (the hip below 0.5 m) or, when a spinning-out joint comes first, at the divergence check
    assert not fell.completed and ("fall" in fell.reason or "diverged" in fell.reason), fell.reason


@pytest.mark.slow
def test_a_walk_pushed_off_its_path_walks_back_onto_it_on_mujoco(hm, tmp_path):
    """25 N s (0.45 m/s) to the left: the recovery step lands 147 mm beside its planned foothold.  Each later step
    takes back up to step_return_m (0.05 m) of it: the walk ends with its hip within 20 mm of the plan's sideways
    (measured 1 mm; 20 mm is a seventh of the move taken back, and over five times the hip error of an unpushed
    walk with sensing noise, 3.6 mm).  Without the return the rest of the walk kept the move: 152 mm."""
    for ret, near in ((0.05, True), (0.0, False)):
        res = _pushed_walk(hm, tmp_path, 25.0, 90, {"step_return_m": ret})
        assert res.completed, res.reason
        arr = res.log.arrays()
        lateral = abs(float(arr["hip_p"][-1, 0] - arr["hip_p_ref"][-1, 0]))     # sim3 walks along +y
        assert (lateral < 0.02) is near, (ret, lateral)
        assert res.phases[7].touchdown_error_m > 0.1                              # the recovery step moved
