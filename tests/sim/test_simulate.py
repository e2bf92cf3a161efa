"""Simulator (humanoid_sim.sim.simulate): how it assembles a walk, and a 0.1 s walk on welds checked against
Pinocchio's kinematics and the whole body's Newton-Euler equations."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.controllers.thesis.controller import ThesisController
from humanoid_sim.engines.oracle import OracleEngine
from humanoid_sim.engines.weld import WeldEngine
from humanoid_sim.references.zmp.zmp_walk import initial_state
from humanoid_sim.robot.phases import Phase
from humanoid_sim.sim.simulate import Simulator

G = 9.81


@pytest.fixture(scope="module")
def sc(sim1):
    return sim1


class Recorder:
    """A controller that remembers its context and returns zero joint torques."""

    name = "recorder"

    def setup(self, ctx):
        self.ctx = ctx

    def __call__(self, obs):
        return np.zeros(26)


def test_assembly_follows_the_arguments(hm, sc) -> None:
    sim = Simulator(hm, sc, compiled=False)
    assert isinstance(sim.engine, WeldEngine) and sim.engine.name == "pinocchio"
    assert isinstance(sim.controller, ThesisController)
    assert isinstance(Simulator(hm, sc, engine="thesis").engine, OracleEngine)
    rec = Recorder()
    sim = Simulator(hm, sc, controller=rec)
    assert sim.controller is rec
    ctx = rec.ctx
    assert ctx.engine == "pinocchio" and ctx.constraints is sim.engine.constraints and ctx.traj is sim.traj
    np.testing.assert_array_equal(ctx.q0, initial_state(hm, sc))
    assert ctx.scenario is sc and ctx.hm is hm
    with pytest.raises(ValueError, match="'no_such_engine' is not one of pinocchio, thesis, mujoco"):
        Simulator(hm, sc, engine="no_such_engine")


def test_a_new_trajectory_reaches_engine_and_controller(hm, sc) -> None:
    sim = Simulator(hm, sc, compiled=False)
    other = Simulator(hm, sc, compiled=False).traj
    sim.traj = other
    assert sim.engine.traj is other and sim.controller.traj is other


@pytest.fixture(scope="module")
def walk(hm, sc):
    sim = Simulator(hm, sc, compiled=False)
    return sim, sim.run(t_end=0.1)


def test_a_short_walk_logs_pinocchio_kinematics(hm, sc, walk) -> None:
    sim, res = walk
    h = sc.simulation.step_s
    a = res.log.arrays()
    n = len(res.log)
    assert n == res.steps == round(0.1 / h) and res.reason.startswith("stopped at t = 0.100 s")
    np.testing.assert_allclose(a["t"], h * np.arange(n), atol=1e-12)
    np.testing.assert_array_equal(a["q"][0], sim.q0)
    np.testing.assert_array_equal(a["v"][0], 0.0)                          # from rest
    model, d = hm.model, hm.model.createData()
    fid = {f: model.getFrameId(f) for f in ("Pc_17", "O_4", "P_tpR", "P_tpL", "O_17")}
    pin.framesForwardKinematics(model, d, sim.q0)
    foot0 = d.oMf[fid["O_4"]].copy()
    for i in range(n):
        pin.forwardKinematics(model, d, a["q"][i], a["v"][i])
        pin.updateFramePlacements(model, d)
        np.testing.assert_allclose(a["hip_p"][i], d.oMf[fid["Pc_17"]].translation, atol=1e-12)
        np.testing.assert_allclose(a["toe_R_p"][i], d.oMf[fid["P_tpR"]].translation, atol=1e-12)
        np.testing.assert_allclose(a["hip_R"][i], d.oMf[fid["O_17"]].rotation, atol=1e-12)
        assert d.oMf[fid["O_4"]].isApprox(foot0, 1e-12), i                  # the left foot stays welded
        np.testing.assert_allclose(pin.getFrameVelocity(model, d, fid["O_4"]).vector, 0.0, atol=1e-10)
    np.testing.assert_allclose(a["hip_yaw"], np.arctan2(a["hip_R"][:, 1, 0], a["hip_R"][:, 0, 0]), atol=1e-12)
    assert (a["phase"] == 0).all() and (a["in_contact"] == [False, True]).all()   # LFFSSP: left foot only
    assert Phase(res.phase_names[0]) is Phase.LFFSSP


def test_the_ground_wrench_is_the_rate_of_change_of_momentum(hm, walk) -> None:
    """Newton-Euler on the whole body: ground force = m (c'' + g), ground moment about the origin = dH_O/dt - c x
    m g, with c'' and dH_O/dt by central differences of Pinocchio's centroidal momentum (O(h^2): a few 0.01 N in
    540 N)."""
    _, res = walk
    a = res.log.arrays()
    model, d = hm.model, hm.model.createData()
    m = pin.computeTotalMass(model)
    c, vc, hg = [], [], []
    for q, v in zip(a["q"], a["v"]):
        pin.computeCentroidalMomentum(model, d, q, v)
        c.append(d.com[0].copy())
        vc.append(d.vcom[0].copy())
        hg.append(d.hg.angular.copy())
    c, vc, hg = map(np.array, (c, vc, hg))
    h = a["t"][1] - a["t"][0]
    H_O = hg + np.cross(c, m * vc)                            # angular momentum about the world origin
    force = m * ((vc[2:] - vc[:-2]) / (2 * h) + [0.0, 0.0, G])
    moment = (H_O[2:] - H_O[:-2]) / (2 * h) - np.cross(c[1:-1], [0.0, 0.0, -m * G])
    w = a["foot_wrench"][1:-1].sum(axis=1)
    np.testing.assert_allclose(w[:, :3], force, atol=0.1)       # N
    np.testing.assert_allclose(w[:, 3:], moment, atol=0.1)      # N m
    np.testing.assert_allclose(a["foot_wrench"][:, 0], 0.0, atol=1e-9)   # the right foot is in the air
    # the ZMP from that independent wrench: where the moment's horizontal part vanishes, on z = 0
    zmp = np.stack([-moment[:, 1] / force[:, 2], moment[:, 0] / force[:, 2]], axis=1)
    np.testing.assert_allclose(a["zmp"][1:-1, :2], zmp, atol=5e-4)      # m
    np.testing.assert_allclose(a["cop"][1:-1, 1, :2], zmp, atol=5e-4)   # one foot on the ground: CoP = ZMP
