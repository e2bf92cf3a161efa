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
from humanoid_sim.controllers.balance.steps import clamp_offset, predicted_offset
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


def test_feedback_settings_are_validated():
    assert BalanceSettings().feedback == "dcm"
    assert parse_balance("f.yaml", {"feedback": "pd", "dcm_gain": 5}).dcm_gain == 5.0
    with pytest.raises(ScenarioError, match="balance.feedback = 'lqr'"):
        parse_balance("f.yaml", {"feedback": "lqr"})
    with pytest.raises(ScenarioError, match="balance.dcm_gain"):
        parse_balance("f.yaml", {"dcm_gain": -1})
    with pytest.raises(ScenarioError, match="balance.step_adjustment"):
        parse_balance("f.yaml", {"step_adjustment": 1})


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
    h = 1e-5
    for tt in (0.333, 1.017):
        p, v, a, z = ZmpPreviewTrajectory.com_targets(traj, 0, tt)
        pp, pm = (ZmpPreviewTrajectory.com_targets(traj, 0, tt + s)[0] for s in (h, -h))
        # central difference of a cubic: O(h^2) ~ 1e-10 plus round-off / h ~ 1e-11
        np.testing.assert_allclose(v, (pp - pm) / (2 * h), atol=1e-7)
        np.testing.assert_allclose(z[1], 0.5 * 0.2 * tt, atol=1e-12)   # linear in a linear signal: exact


@pytest.mark.slow
def test_a_lateral_push_toward_the_stance_foot_is_survived_on_mujoco(hm, tmp_path):
    """0.3 m/s (16.5 N s on 55 kg) toward the stance foot at mid single support of phase 8 (RFFSSP: toward the
    right), 0.1 s on the pelvis: the walk completes."""
    pytest.importorskip("mujoco")
    import yaml

    from humanoid_sim.scenario.schema import load_scenario
    from humanoid_sim.sim.simulate import Simulator

    doc = {"base": str(ROOT / "scripts/params/sim3_zmp.yaml"), "name": "push_stance",
           "disturbances": {"pushes": [{"body": 17, "impulse_Ns": 16.5, "direction_deg": 270, "frame": "heading",
                                        "start": {"phase": 8, "fraction": 0.5}, "duration_s": 0.1}]}}
    f = tmp_path / "push.yaml"
    f.write_text(yaml.safe_dump(doc))
    res = Simulator(hm, load_scenario(f), engine="mujoco").run()
    assert res.completed, res.reason
