"""MujocoSim, the engine object (issue 15): state in Pinocchio's convention, zero-order-hold torque steps."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.engines.mujoco import MujocoSettings, MujocoSim
from humanoid_sim.engines.mujoco.sim import MujocoSimError
from humanoid_sim.engines.mujoco.standing import StandingController
from humanoid_sim.references.initial import initial_configuration
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.scenario.schema import load_scenario


@pytest.fixture(scope="module")
def q0(hm: HumanoidModel) -> np.ndarray:
    return initial_configuration(hm, load_scenario("scripts/params/sim1.yaml").path)


@pytest.fixture(scope="module")
def sim(hm: HumanoidModel) -> MujocoSim:
    return MujocoSim(hm, MujocoSettings())


def test_state_round_trip(hm: HumanoidModel, sim: MujocoSim) -> None:
    rng = np.random.default_rng(4)
    q = pin.randomConfiguration(hm.model, -np.ones(hm.model.nq), np.ones(hm.model.nq))
    q[2] += 2.0
    v = rng.normal(size=hm.model.nv)
    sim.set_state(q, v)
    q1, v1 = sim.state()
    np.testing.assert_array_equal(q1, q)
    np.testing.assert_allclose(v1, v, atol=1e-12)  # one rotation and back: round-off


def test_zero_order_hold(hm: HumanoidModel, q0: np.ndarray) -> None:
    """step(tau, 10 ms) = ten step(tau, 1 ms) with the same tau, bit for bit; the clock advances by h."""
    a, b = MujocoSim(hm), MujocoSim(hm)
    ctrl = StandingController(hm, q0, 1e-3)
    for s in (a, b):
        s.set_state(q0, np.zeros(hm.model.nv))
        s.time = 0.0
    for _ in range(5):
        tau = ctrl(*a.state())
        a.step(tau, 0.01)
        for _ in range(10):
            b.step(tau, 0.001)
    assert a.time == pytest.approx(0.05, abs=1e-12) and a.time == b.time
    np.testing.assert_array_equal(a.data.qpos, b.data.qpos)
    np.testing.assert_array_equal(a.data.qvel, b.data.qvel)


def test_reading_wrenches_does_not_change_the_run(hm: HumanoidModel, q0: np.ndarray) -> None:
    """foot_wrenches() brings MuJoCo's derived data to the current state; the trajectory stays bit for bit."""
    a, b = MujocoSim(hm), MujocoSim(hm)
    ctrl = StandingController(hm, q0, 1e-3)
    for s in (a, b):
        s.set_state(q0, np.zeros(hm.model.nv))
    for _ in range(30):
        a.step(ctrl(*a.state()), 0.002)
        b.step(ctrl(*b.state()), 0.002)
        fw = a.foot_wrenches()
        assert fw["R"].normal > 0 and fw["L"].normal > 0
    np.testing.assert_array_equal(a.data.qpos, b.data.qpos)
    np.testing.assert_array_equal(a.data.qvel, b.data.qvel)


def test_base_rows_of_tau_are_ignored(hm: HumanoidModel, q0: np.ndarray) -> None:
    a, b = MujocoSim(hm), MujocoSim(hm)
    tau = StandingController(hm, q0, 1e-3)(q0, np.zeros(hm.model.nv))
    tau_base = tau.copy()
    tau_base[:6] = [100.0, -50.0, 30.0, 5.0, 6.0, 7.0]
    for s, t in ((a, tau), (b, tau_base)):
        s.set_state(q0, np.zeros(hm.model.nv))
        s.step(t, 0.005)
    np.testing.assert_array_equal(a.data.qpos, b.data.qpos)


def test_bad_input_and_divergence(hm: HumanoidModel, sim: MujocoSim, q0: np.ndarray, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working directory
    sim.set_state(q0, np.zeros(hm.model.nv))
    with pytest.raises(MujocoSimError, match=r"h = 0.0015 s: expected a positive multiple of the MuJoCo timestep"):
        sim.step(np.zeros(hm.model.nv), 0.0015)
    with pytest.raises(MujocoSimError, match=r"h = 0 s"):
        sim.step(np.zeros(hm.model.nv), 0)
    tau = np.zeros(hm.model.nv)
    tau[10] = np.nan
    with pytest.raises(MujocoSimError, match="non-finite joint torques"):
        sim.step(tau, 0.001)
    tau[10] = 1e30  # MuJoCo would silently zero the control
    with pytest.raises(MujocoSimError, match="mjWARN_BADCTRL in the step from t = "):
        sim.step(tau, 0.01)
    sim.set_state(q0, np.zeros(hm.model.nv))
    sim.step(np.zeros(hm.model.nv), 0.002)
    q_good, v_good, t_good = *sim.state(), sim.time
    tau[10] = 1e9  # finite, but the accelerations blow up: MuJoCo would silently reset the state
    with pytest.raises(MujocoSimError, match="mjWARN_BAD.*diverged"):
        sim.step(tau, 0.01)
    q1, v1 = sim.state()  # the last good state is kept
    np.testing.assert_array_equal(q1, q_good)
    np.testing.assert_array_equal(v1, v_good)
    assert sim.time == t_good


@pytest.mark.parametrize("compiled", [None, False])
def test_hold_and_advance_are_step(hm: HumanoidModel, q0: np.ndarray, tmp_path, monkeypatch, compiled) -> None:
    """hold(tau) then advance(1) and advance(2) = step(tau, 3 ms), bit for bit (what the engine does to read the
    contact forces after a control update's first MuJoCo step); advance checks as step does; the same with the
    compiled state and torque maps (None) and with StateMap's (False)."""
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working directory
    a, b = MujocoSim(hm, compiled=compiled), MujocoSim(hm, compiled=compiled)
    ctrl = StandingController(hm, q0, 1e-3)
    for s in (a, b):
        s.set_state(q0, np.zeros(hm.model.nv))
    for _ in range(5):
        tau = ctrl(*a.state())
        a.step(tau, 0.003)
        b.hold(tau)
        b.advance(1)
        b.advance(2)
    assert a.time == b.time
    np.testing.assert_array_equal(a.data.qpos, b.data.qpos)
    np.testing.assert_array_equal(a.data.qvel, b.data.qvel)
    for n in (0, -1, 1.0):
        with pytest.raises(MujocoSimError, match="expected an integer >= 1"):
            b.advance(n)
    tau = np.zeros(hm.model.nv)
    tau[10] = np.inf
    with pytest.raises(MujocoSimError, match="non-finite joint torques"):
        b.hold(tau)
    tau[10] = 1e30  # MuJoCo would silently zero the control
    b.hold(tau)
    q_good, v_good, t_good = *b.state(), b.time
    with pytest.raises(MujocoSimError, match="mjWARN_BADCTRL in the step from t = "):
        b.advance(2)
    q1, v1 = b.state()  # the last good state is kept
    np.testing.assert_array_equal(q1, q_good)
    np.testing.assert_array_equal(v1, v_good)
    assert b.time == t_good


@pytest.mark.parametrize("integrator", ["euler", "implicitfast", "rk4"])
def test_advance_after_forward_is_mj_step(hm: HumanoidModel, q0: np.ndarray, integrator: str) -> None:
    """advance after forward() (or set_state) reuses the position and velocity stages MuJoCo computed for the state
    and steps from the acceleration stage on: the same run, bit for bit, as a full mj_step every time (a twin that
    is never fresh), with torques changed, a force applied on the trunk and both of them taken off between the
    forward and the step (what enters the acceleration stage only), for 200 ms on both feet; model_changed() makes
    the next step compute every stage.  For every integrator MuJoCo offers (RK4 takes the full step)."""
    a, b = (MujocoSim(hm, MujocoSettings(integrator=integrator)) for _ in range(2))
    ctrl = StandingController(hm, q0, 2e-3)
    rng = np.random.default_rng(2)
    for s in (a, b):
        s.set_state(q0, np.zeros(hm.model.nv))
    b.model_changed()
    for k in range(100):
        a.forward()
        tau = ctrl(*a.state()) + rng.normal(scale=2.0, size=hm.model.nv)
        push = rng.normal(scale=30.0, size=6) if k % 3 else np.zeros(6)
        for s in (a, b):
            s.data.xfrc_applied[1] = push
            s.hold(tau)
        assert a._fresh and not b._fresh
        for s in (a, b):
            s.advance(2)
        b.model_changed()
        for name in ("qpos", "qvel", "qacc", "qfrc_constraint", "qacc_warmstart"):
            assert getattr(a.data, name).tobytes() == getattr(b.data, name).tobytes(), (k, name)
        assert a.data.efc_force.tobytes() == b.data.efc_force.tobytes() and a.time == b.time
    assert a.foot_wrenches()["R"].normal > 0 and b.foot_wrenches()["L"].normal > 0
    a.model_changed()
    assert not a._fresh
