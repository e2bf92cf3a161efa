"""The external force estimate (controllers/balance/force.py) against Newton's law and the LIPM's statics, and the
feet's force sensors (``Observation.foot_wrenches``) against the momentum MuJoCo's robot gains."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from humanoid_sim.controllers.balance.dcm import G, lipm_omega
from humanoid_sim.controllers.balance.force import ForceEstimate, lean_offset
from humanoid_sim.scenario.balance import BalanceSettings, parse_balance
from humanoid_sim.scenario.fields import ScenarioError

ROOT = Path(__file__).resolve().parents[2]
DT = 0.002   # the MuJoCo engine's control period, s


def _point_mass(m: float, f_ext, t_end: float, ground=lambda t: (0.0, 0.0), cutoff: float = 0.5,
                limit: float = math.inf):
    """A point mass under an external force f_ext(t) and a ground force ground(t) (N, x and y), integrated exactly
    per period (piecewise constant forces: the velocity is linear in them), seen by the estimate.  Returns the times
    and the estimates."""
    est = ForceEstimate(m, cutoff, limit)
    v = np.zeros(2)
    ts, out = [], []
    est.update(0.0, np.zeros(3), np.zeros((2, 6)))
    for i in range(1, int(round(t_end / DT)) + 1):
        t0 = (i - 1) * DT
        F = np.array(ground(t0))
        v = v + DT * (F + np.array(f_ext(t0))) / m
        w = np.zeros((2, 6))
        w[0, :2] = 0.4 * F       # the feet share the ground force: the estimate reads their sum
        w[1, :2] = 0.6 * F
        ts.append(i * DT)
        out.append(est.update(i * DT, np.array([v[0], v[1], 0.0]), w))
    return np.array(ts), np.array(out)


def test_a_constant_force_is_found_as_a_critically_damped_second_order_response():
    """Two first-order stages of rate L: the step response is 1 - e^{-L t} (1 + L t) (a constant force on a mass
    that the ground does not hold)."""
    f = (12.0, -30.0)
    ts, est = _point_mass(55.0, lambda t: f, 3.0)
    L = 2 * math.pi * 0.5
    ref = 1.0 - np.exp(-L * ts) * (1.0 + L * ts)
    # the discrete filters lag the continuous response by about one period: |d/dt of the response| * DT < 0.01
    np.testing.assert_allclose(est / np.array(f), np.column_stack([ref, ref]), atol=0.01)
    np.testing.assert_allclose(est[-1], f, rtol=2e-3)     # after 3 s: 1 - e^{-9.4} (10.4) = 99.9 %


def test_a_force_the_ground_holds_is_found_and_the_ground_force_itself_is_not():
    """On a slope the ground holds the robot still: m c_ddot = 0 = F_ground + f_ext.  The estimate finds f_ext from
    the sensed ground force alone; a ground force that only accelerates the robot (no external force) gives none."""
    f = (0.0, 28.2)
    _, est = _point_mass(55.0, lambda t: f, 3.0, ground=lambda t: (-f[0], -f[1]))
    np.testing.assert_allclose(est[-1], f, rtol=2e-3)
    _, est = _point_mass(55.0, lambda t: (0.0, 0.0), 3.0, ground=lambda t: (20.0 * math.sin(6 * t), 5.0))
    np.testing.assert_allclose(est, 0.0, atol=1e-9)      # Newton's law holds exactly: only round-off remains


def test_a_short_push_passes_as_the_two_stages_response_to_a_pulse():
    """A 0.1 s push of 275 N (27.5 N s): the estimate is the step response s(t) = 1 - e^{-L t} (1 + L t) of the push
    minus the same 0.1 s later; its peak, ~F T L / e, is a tenth of the force."""
    F, t0, T = 275.0, 1.0, 0.1
    ts, est = _point_mass(55.0, lambda t: (0.0, F if t0 <= t < t0 + T else 0.0), 4.5)
    L = 2 * math.pi * 0.5

    def s(t):
        t = np.maximum(t, 0.0)
        return 1.0 - np.exp(-L * t) * (1.0 + L * t)

    np.testing.assert_allclose(est[:, 1], F * (s(ts - t0) - s(ts - t0 - T)), atol=0.01 * F)   # as in the step test
    assert np.max(est[:, 1]) == pytest.approx(F * T * L / math.e, rel=0.15)   # the short-pulse limit of the peak


def test_a_push_beyond_the_limit_is_dropped_and_a_slope_below_it_is_found():
    """Limit 48 N (the lean's 0.08 m on 55 kg at omega^2 = 10.8): a 3 deg slope's pull (28.3 N) is found as without
    a limit; a 0.1 s push of 350 N (35 N s), which the unlimited estimate spreads into a ~40 N bump, moves the
    estimate by under 1 N once the push is known: the observer drops the impulse once its reading departs from the
    estimate by more than the limit, and for 0.25 s, and the estimate steps back to where it stood before the push
    showed."""
    limit = 0.08 * 55.0 * 10.8
    pull = 55.0 * G * math.sin(math.radians(3.0))
    _, free = _point_mass(55.0, lambda t: (0.0, pull), 3.0, ground=lambda t: (0.0, -pull))
    _, held = _point_mass(55.0, lambda t: (0.0, pull), 3.0, ground=lambda t: (0.0, -pull), limit=limit)
    np.testing.assert_array_equal(held, free)             # never beyond the limit: the same arithmetic
    push = lambda t: (0.0, -350.0 if 1.0 <= t < 1.1 else 0.0)   # noqa: E731
    _, free = _point_mass(55.0, push, 4.0)
    ts, held = _point_mass(55.0, push, 4.0, limit=limit)
    assert np.min(free[:, 1]) < -35.0                      # F T L / e = 40 N
    # before the push is known (the reading passes 48 N ~50 ms in) the second stage takes L times the reading's
    # integral, pi x (48 N x 50 ms / 2) = 3.8 N; after, what remains reached it before the reading left half the
    # limit (~25 ms in): pi x (24 N x 25 ms / 2) = 0.9 N at most
    assert -4.5 < np.min(held[:, 1]) < -3.0
    assert -1.0 < np.min(held[ts >= 1.06, 1]) < 0.0
    assert abs(held[-1, 1]) < 0.1


def test_the_lean_is_the_slopes_statics_and_is_clamped():
    """On a slope of angle a the ground tilts gravity by a: f = m g sin a; the lean f / (m omega^2) is z_c sin a
    (the CoM above the CoP along the tilted gravity)."""
    z_c, m, a = 0.8, 55.0, math.radians(3.0)
    om = lipm_omega(z_c)
    bx, by = lean_offset((0.0, m * G * math.sin(a)), m, om, 1.0)
    assert bx == 0.0 and by == pytest.approx(z_c * math.sin(a), rel=1e-12)
    bx, by = lean_offset((300.0, -400.0), m, om, 0.08)
    assert math.hypot(bx, by) == pytest.approx(0.08, rel=1e-12) and bx / by == pytest.approx(-0.75, rel=1e-12)


def test_bad_arguments_and_settings_are_refused():
    with pytest.raises(ValueError, match="mass"):
        ForceEstimate(0.0, 0.5)
    with pytest.raises(ValueError, match="cutoff_hz"):
        ForceEstimate(55.0, 0.0)
    with pytest.raises(ValueError, match="limit"):
        ForceEstimate(55.0, 0.5, 0.0)
    s = BalanceSettings()
    assert s.external_force and s.external_force_filter_hz == 0.5 and s.lean_max_m == 0.08
    with pytest.raises(ScenarioError, match="balance.external_force_filter_hz"):
        parse_balance("f.yaml", {"external_force_filter_hz": 0})
    with pytest.raises(ScenarioError, match="balance.external_force"):
        parse_balance("f.yaml", {"external_force": "yes"})


def _incline_run(tmp_path, direction: str, until: float | None, balance: dict | None = None,
                 sensing: dict | None = None, gait: dict | None = None):
    pytest.importorskip("mujoco")
    import yaml

    from humanoid_sim.api import run_walk

    doc = {"base": str(ROOT / "scripts/params/sim3_zmp.yaml"), "name": f"incline_{direction}",
           "disturbances": {"incline": {"angle_deg": 3, "direction": direction}}}
    if sensing:
        doc["disturbances"]["sensing"] = sensing
    if balance:
        doc["balance"] = balance
    if gait:
        doc["gait"] = gait      # laid over sim3_zmp's gait section, key by key
    f = tmp_path / f"incline_{direction}.yaml"
    f.write_text(yaml.safe_dump(doc))
    return run_walk(f, "mujoco", until=until)


@pytest.mark.slow
def test_the_feet_sensors_and_the_estimate_obey_newtons_law_on_a_mujoco_incline(tmp_path, monkeypatch):
    """3 deg downhill on MuJoCo: over the lead-in, the momentum the robot gained equals the sensed ground impulse
    plus gravity's (the engine's, tilted); after 2 s the estimate is gravity's downhill pull m g sin 3 deg."""
    from humanoid_sim.controllers.balance import force as F

    seen: list[tuple[float, np.ndarray, np.ndarray, float]] = []
    orig = F.ForceEstimate.update

    def spy(self, t, c_dot, w):
        if w is not None and (not seen or t > seen[-1][0]):
            seen.append((t, np.array(c_dot[:2]), w[:, :2].sum(axis=0), self.mass))
        return orig(self, t, c_dot, w)

    monkeypatch.setattr(F.ForceEstimate, "update", spy)
    run = _incline_run(tmp_path, "down", 2.0)
    assert run.result.sim_time >= 2.0 - 1e-9, run.result.reason
    m = seen[0][3]
    pull = m * G * math.sin(math.radians(3.0))       # downhill = the heading, +y
    t = np.array([s[0] for s in seen])
    P = m * np.array([s[1] for s in seen])
    Fg = np.array([s[2] for s in seen])
    # momentum balance over [t_0, t_j]: the sensed mean force of a period reaches the next call (its impulse)
    i1 = int(np.searchsorted(t, 1.0))
    impulse = np.sum(Fg[1:i1 + 1] * np.diff(t[:i1 + 1])[:, None], axis=0)
    gained = P[i1] - P[0]
    # the engine's robot is the model's (same masses); what remains is the base-twist filter's lag and the
    # discretisation of the momentum (MuJoCo's semi-implicit step): 1 N s is 3.5 % of the pull's impulse
    np.testing.assert_allclose(gained, impulse + np.array([0.0, pull * (t[i1] - t[0])]), atol=1.0)
    est = run.result.extra.get("balance_external_force_N")
    assert est is not None
    np.testing.assert_allclose(est, (0.0, pull), atol=0.1 * pull)


@pytest.mark.slow
def test_the_lead_in_held_flat_walks_3_deg_uphill_with_noise(tmp_path):
    """3 deg uphill (gravity turned) with 0.02 m/s and 0.02 rad/s of noise on the sensed base twist.  From the first
    instant the CoP must sit z_c tan(3 deg) = 48 mm behind the CoM; the lead-in's polygon with the trailing foot on
    its toe leaves 30 mm, and that walk fell in the lead-in (the hip below 0.5 m at 1.44 s).  With the trailing foot
    held flat on its heel box until its toe-off (flat_lead_in, the default), the walk completes, the stance feet
    within 1 deg and 5 mm of slip."""
    noise = {"base_linear_velocity_mps": 0.02, "base_angular_velocity_radps": 0.02, "seed": 1}
    run = _incline_run(tmp_path, "up", None, sensing=noise)
    assert run.result.completed, run.result.reason
    s = run.summary
    assert s["stance_tilt_max_rad"] <= math.radians(1.0) and s["foot_slip_max_m"] <= 0.005, s
    fell = _incline_run(tmp_path, "up", 2.0, {"flat_lead_in": False}, sensing=noise)   # held by its toe
    assert not fell.result.completed and "fall" in fell.result.reason, fell.result.reason


@pytest.mark.slow
def test_the_planned_stop_walks_3_deg_downhill_to_its_end_with_noise(tmp_path):
    """3 deg downhill with the terrain suite's noise (seed 1).  A plan that stops dead over the last landed sole
    (``lead_out_s: 0``) puts the ZMP on that sole as the CoM arrives with the walk's speed; the foot rocked onto its
    inner edge 24 ms before the walk's end (sole tilt 4.4 deg).  With the stop the preview sees coming (the
    default), the walk reaches its end with the stance feet within 2 deg of the ground: the level of the lead-in's
    switch to the trailing toe under this noise (1.9 deg on flat ground; 1.3 deg measured here)."""
    noise = {"base_linear_velocity_mps": 0.02, "base_angular_velocity_radps": 0.02, "seed": 1}
    run = _incline_run(tmp_path, "down", None, sensing=noise)
    assert run.result.completed, run.result.reason
    assert run.summary["stance_tilt_max_rad"] <= math.radians(2.0), run.summary
    dead = _incline_run(tmp_path, "down", None, sensing=noise, gait={"lead_out_s": 0.0})
    assert not dead.result.completed and "edge" in dead.result.reason, dead.result.reason
