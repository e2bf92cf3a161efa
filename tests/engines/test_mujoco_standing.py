"""Issue 15 acceptance, standing: the robot holds still for 5 s in its initial double-support posture on MuJoCo's
ground (no fall, sole slip < 1 mm, hip drift < 5 mm), under joint-space PD + gravity compensation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.engines.mujoco import MujocoSettings, MujocoSim
from humanoid_sim.engines.mujoco.standing import StandingController, held_pd_spectral_radius, run_standing
from humanoid_sim.references.initial import initial_configuration
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.scenario.schema import load_scenario

SIM1 = "scripts/params/sim1.yaml"


@pytest.fixture(scope="module")
def q0(hm: HumanoidModel) -> np.ndarray:
    return initial_configuration(hm, load_scenario(SIM1).path)


def test_stands_still_for_5_s(hm: HumanoidModel, q0: np.ndarray) -> None:
    sim = MujocoSim(hm, MujocoSettings.from_scenario(load_scenario(SIM1)))
    r = run_standing(sim, q0, duration=5.0)
    assert r.duration == pytest.approx(5.0, abs=1e-9) and not r.fell
    # The bounds (measured: drift 0.96 mm, slip 0.005 mm, tilt 0.08 deg, penetration 0.29 mm).
    assert r.hip_drift_max < 5e-3
    assert max(r.slip_max.values()) < 1e-3
    assert max(r.tilt_max.values()) < np.radians(1.0)
    assert r.penetration_max < 1e-3
    # Newton at the end: the ground carries the weight; the residual is m |a_com| of the slow sway (< 1 %).
    mass = pin.computeTotalMass(hm.model)
    np.testing.assert_allclose(r.force_final, [0.0, 0.0, mass * 9.81], atol=0.01 * mass * 9.81)
    # Each foot's CoP inside its sole: within 0.045 m of the foot's line and between heel and toe tip.
    for foot, x in (("R", 0.16), ("L", -0.16)):
        cop = r.cop_final[foot]
        assert abs(cop[0] - x) < 0.045 and -0.0384 < cop[1] < 0.1876


def test_gravity_compensation_is_static_equilibrium(hm: HumanoidModel, q0: np.ndarray) -> None:
    """tau_g and the reference foot wrenches balance gravity exactly at q_ref (RNEA with a = 0, v = 0)."""
    c = StandingController(hm, q0, 1e-3)
    model, data = hm.model, hm.model.createData()
    pin.computeJointJacobians(model, data, q0)
    pin.updateFramePlacements(model, data)
    Jc = np.vstack([pin.getFrameJacobian(model, data, hm.frame_id(f), pin.ReferenceFrame.LOCAL)
                    for f in ("O_3", "O_4")])
    g = pin.rnea(model, data, q0, np.zeros(model.nv), np.zeros(model.nv))
    # 1e-9 N (m): a least-squares solve and products on forces of ~500 N.
    np.testing.assert_allclose(c.tau_g + Jc.T @ c.foot_wrenches_ref, g, atol=1e-9)
    assert np.all(c.tau_g[:6] == 0.0)
    # The weight is shared by the feet: vertical forces (LOCAL z = world z at the flat-foot posture) sum to m g.
    assert c.foot_wrenches_ref[2] + c.foot_wrenches_ref[8] == pytest.approx(pin.computeTotalMass(model) * 9.81)


def test_held_pd_is_stable_in_free_flight(hm: HumanoidModel, q0: np.ndarray) -> None:
    """The gain caps make the held PD loop stable at its period; without them it is not (so the cap matters)."""
    model, data = hm.model, hm.model.createData()
    M = pin.crba(model, data, q0)
    W = np.linalg.inv(np.triu(M) + np.triu(M, 1).T)[6:, 6:]
    for h in (1e-3, 2e-3, 5e-3):
        c = StandingController(hm, q0, h)
        assert held_pd_spectral_radius(W, c.kp[6:], c.kd[6:], h) < 1.0
        assert held_pd_spectral_radius(W, np.full(26, 2000.0), np.full(26, 20.0), h) > 1.0
    # Cross-check the spectral radius by running the same linear loop: it grows with the uncapped gains and
    # decays with the capped ones.
    h = 1e-3
    c = StandingController(hm, q0, h)

    def run(kp: np.ndarray, kd: np.ndarray, steps: int) -> float:
        x, v = np.full(26, 1e-6), np.zeros(26)
        for _ in range(steps):
            v = v + h * (W @ (-kp * x - kd * v))
            x = x + h * v
        return float(np.abs(x).max())

    assert run(np.full(26, 2000.0), np.full(26, 20.0), 40) > 1e-4  # grew >= 100x in 40 steps (rho ~ 1.7)
    assert run(c.kp[6:], c.kd[6:], 5000) < 1e-6
