"""The balance controller's base twist filter (``controllers.balance.estimate``) against the closed-form response
of a first-order system, and the noisy walk it makes possible."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from humanoid_sim.controllers.balance.estimate import TwistFilter, low_pass_gain
from humanoid_sim.scenario.balance import BalanceSettings, parse_balance
from humanoid_sim.scenario.fields import ScenarioError

ROOT = Path(__file__).resolve().parents[2]
DT = 0.002


def test_a_step_is_followed_as_a_first_order_lag():
    f = TwistFilter(10.0)
    f(0.0, np.zeros(32))                              # starts at the first measurement
    v = np.zeros(32)
    v[:6] = 1.0
    v[6:] = 7.0
    n = 25
    for i in range(1, n + 1):
        out = f(i * DT, v)
    # the exact discretisation of z' = 2 pi f (1 - z): 1 - e^{-2 pi f t}; round-off only
    np.testing.assert_allclose(out[:6], 1.0 - math.exp(-2 * math.pi * 10.0 * n * DT), atol=1e-12)
    np.testing.assert_array_equal(out[6:], 7.0)       # the joint rates pass unfiltered


def test_a_repeated_time_does_not_advance_the_filter():
    f = TwistFilter(10.0)
    f(0.0, np.zeros(32))
    v = np.ones(32)
    a = f(DT, v)[:6].copy()
    np.testing.assert_array_equal(f(DT, v)[:6], a)    # an integration stage at the same time
    assert low_pass_gain(0.0, 10.0) == 0.0 and low_pass_gain(-1.0, 10.0) == 0.0


def test_a_commanded_ramp_passes_without_lag_and_noise_is_attenuated():
    rng = np.random.default_rng(3)
    f = TwistFilter(10.0)
    acc = np.array([0.5, -0.2, 0.0, 1.0, 0.0, 0.3])   # the controller's base acceleration, m/s^2, rad/s^2
    f.acc = acc
    v = np.zeros(32)
    f(0.0, v)
    errs = []
    for i in range(1, 5001):
        t = i * DT
        v[:6] = acc * t + rng.normal(0.0, 0.02, 6)
        errs.append(f(t, v)[:6] - acc * t)
    errs = np.array(errs[500:])
    a = low_pass_gain(DT, 10.0)
    # a ramp the prediction knows has no steady-state error: the mean is the noise's, ~0.02 / sqrt(4500) / 0.25
    np.testing.assert_allclose(errs.mean(axis=0), 0.0, atol=2e-3)
    # white noise through z += a (x - z): sigma sqrt(a / (2 - a)); 4500 correlated samples: 10 % sampling error
    np.testing.assert_allclose(errs.std(axis=0), 0.02 * math.sqrt(a / (2 - a)), rtol=0.1)


def test_base_velocity_settings_are_validated():
    s = BalanceSettings()
    assert s.base_velocity == "filtered" and s.base_velocity_filter_hz == 30.0
    assert parse_balance("f.yaml", {"base_velocity": "measured"}).base_velocity == "measured"
    with pytest.raises(ScenarioError, match="balance.base_velocity = 'kalman'"):
        parse_balance("f.yaml", {"base_velocity": "kalman"})
    with pytest.raises(ScenarioError, match="balance.base_velocity_filter_hz"):
        parse_balance("f.yaml", {"base_velocity_filter_hz": 0})
    with pytest.raises(ValueError, match="cutoff_hz"):
        TwistFilter(0.0)


@pytest.mark.slow
def test_a_walk_with_noise_on_the_sensed_base_twist_completes_on_mujoco(hm, tmp_path):
    """0.02 m/s and 0.02 rad/s of white noise on the base twist at every call (terrain suite's noise, flat ground):
    the walk completes with the stance foot within 1 deg (as measured, unfiltered, it tipped over at 1.1 s)."""
    pytest.importorskip("mujoco")
    import yaml

    from humanoid_sim.scenario.schema import load_scenario
    from humanoid_sim.sim.simulate import Simulator

    doc = {"base": str(ROOT / "scripts/params/sim3_zmp.yaml"), "name": "noise",
           "disturbances": {"sensing": {"base_linear_velocity_mps": 0.02, "base_angular_velocity_radps": 0.02,
                                        "seed": 1}}}
    f = tmp_path / "noise.yaml"
    f.write_text(yaml.safe_dump(doc))
    res = Simulator(hm, load_scenario(f), engine="mujoco").run()
    assert res.completed, res.reason
