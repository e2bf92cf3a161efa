"""The MuJoCo engine (``--engine mujoco``, issue 15): a user controller standing, the control-rate convergence that
justifies the default 500 Hz, a Newton check of MuJoCo's contact forces against the whole-body CoM, and the thesis
gait ending as physics says (a fall, named by foot and edge)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco  # noqa: F401
import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.analysis.summary import summarize
from humanoid_sim.engines import ENGINE_NAMES, make_engine
from humanoid_sim.engines.mujoco import MujocoModelError, MujocoSettings, MujocoSimError
from humanoid_sim.engines.mujoco.engine import MujocoEngine, MujocoEngineSettings
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.loop import run
from humanoid_sim.sim.simulate import Simulator

ROOT = Path(__file__).resolve().parents[2]
SIM1 = ROOT / "scripts" / "params" / "sim1.yaml"


class FlatFeetPD:
    """A standing PD that scales its gains by the joints' inertia: gravity compensation carried by both feet's main
    bodies (O_3, O_4), where the robot really stands, plus M_j (w^2 (q0 - q) - 2 w v) on the 26 joints (M_j: the
    joints' block of the mass matrix, every joint motion critically damped at w rad/s)."""

    name = "flat_feet_pd"

    def __init__(self, w: float = 4.0) -> None:
        self.w = w  # rad/s

    def setup(self, ctx):
        self.model, self.q_ref = ctx.hm.model, ctx.q0.copy()
        self.data = self.model.createData()
        self.fid = ctx.hm.frame_id

    def __call__(self, obs):
        model, data, q = self.model, self.data, obs.q
        g = pin.computeGeneralizedGravity(model, data, q)
        J = np.vstack([pin.computeFrameJacobian(model, data, q, self.fid(f), pin.LOCAL_WORLD_ALIGNED)
                       for f in ("O_3", "O_4")])
        lam = np.linalg.lstsq(J[:, :6].T, g[:6], rcond=None)[0]
        tau = g[6:] - J[:, 6:].T @ lam
        M = pin.crba(model, data, q)[6:, 6:]
        M = np.triu(M) + np.triu(M, 1).T
        return tau + M @ (self.w ** 2 * pin.difference(model, q, self.q_ref)[6:] - 2.0 * self.w * obs.v[6:])


@pytest.fixture(scope="module")
def sc():
    return load_scenario(SIM1)


def _hold(hm: HumanoidModel, sc, controller, t_end: float, drop: float = 0.0, **engine_options):
    """Run ``controller`` on the MuJoCo engine in double support (RFFDSP held) from sim 1's initial posture raised
    by ``drop`` m; returns (result, engine)."""
    sim = Simulator(hm, sc, engine="mujoco", controller=controller, compiled=False)
    eng = MujocoEngine(hm, sc, **engine_options) if engine_options else sim.engine
    q0 = sim.q0.copy()
    q0[2] += drop
    return run(eng, sim.controller, sim.traj, sc, q0, t_end=t_end, hold=Phase.RFFDSP), eng


def test_registered_and_checked(hm: HumanoidModel, sc) -> None:
    assert "mujoco" in ENGINE_NAMES
    eng = make_engine("mujoco", hm, sc, None, control_period_s=0.001)
    assert eng.name == "mujoco" and eng.constraints is None and eng.settings.control_period_s == 0.001
    with pytest.raises(MujocoModelError, match="control_period_s = -0.002"):
        MujocoEngineSettings(control_period_s=-0.002)
    with pytest.raises(MujocoModelError, match="unknown setting"):
        MujocoEngine(hm, sc, control_periods=0.001)
    with pytest.raises(MujocoSimError, match="0.0015"):  # not a whole number of 1 ms MuJoCo steps
        MujocoEngine(hm, sc, control_period_s=0.0015)
    with pytest.raises(ValueError, match=r"'pinocchio' takes no options \['timestep_s'\]"):
        make_engine("pinocchio", hm, sc, None, timestep_s=0.001)        # the weld engine takes a control period only
    with pytest.raises(ValueError, match=r"'thesis' takes no options \['control_period_s'\]"):
        make_engine("thesis", hm, sc, None, control_period_s=0.001)


def test_touchdown_signal_reads_the_sole_force(hm: HumanoidModel, sc) -> None:
    """Both feet on the ground carry about half the weight each (> 20 N); 5 cm above it, nothing."""
    r, eng = _hold(hm, sc, FlatFeetPD(), t_end=0.05)
    assert eng.touchdown_signal("R") and eng.touchdown_signal("L")
    r, eng = _hold(hm, sc, FlatFeetPD(), t_end=0.01, drop=0.05)
    assert not eng.touchdown_signal("R") and not eng.touchdown_signal("L")


def test_user_controller_stands_5_s(hm: HumanoidModel, sc) -> None:
    """Issue 15's standing acceptance through the engine and the loop, with a user controller."""
    r, eng = _hold(hm, sc, FlatFeetPD(), t_end=5.0)
    assert r.reason.startswith("stopped at t = 5.000"), r.reason
    g = r.extra["ground"]
    assert not g["fell"]
    a = r.log.arrays()
    drift = np.linalg.norm(a["hip_p"] - a["hip_p"][0], axis=1).max()
    # The bounds (measured: drift 0.17 mm, slip 0.004 mm, penetration 0.33 mm).
    assert drift < 5e-3
    assert g["foot_slip_max_m"] < 1e-3
    assert g["penetration_max_m"] < 1e-3
    # Newton at rest (the last 0.5 s): the two feet carry the weight; 0.5 % for the slow residual sway.
    mass = pin.computeTotalMass(hm.model)
    fz = a["foot_wrench"][-50:, :, 2].sum(axis=1)
    np.testing.assert_allclose(fz, mass * hm.spec.gravity, rtol=5e-3)
    # The engine's dynamics residual: Pinocchio's RNEA with MuJoCo's acceleration and constraint forces (the two
    # models' inertias agree to ~1e-13; 1e-6 N m leaves room for the accelerations' round-off).
    assert a["dynamics_residual"].max() < 1e-6


def test_control_rate_converges(hm: HumanoidModel, sc) -> None:
    """Justifies the default control period (2 ms, 500 Hz).  A 5 mm drop onto both feet, then standing under a
    PD of 10 rad/s bandwidth (a walking controller's order: the thesis's retuned hip gain is ~9 rad/s): the hip
    path at control periods 10, 5 and 2 ms against 1 ms (the MuJoCo timestep, control at every step).

    Measured (0.6 s): 10 ms diverges within 0.05 s (the zero-order hold destabilises the light joints), 5 ms is
    0.18 mm off, 2 ms 0.044 mm: first-order convergence, and 2 ms is within 0.1 mm of the limit."""
    paths = {}
    for period in (0.01, 0.005, 0.002, 0.001):
        r, _ = _hold(hm, sc, FlatFeetPD(w=10.0), t_end=0.6, drop=0.005, control_period_s=period)
        paths[period] = (r, r.log.arrays()["hip_p"])
    ref = paths[0.001][1]
    err = {p: float(np.linalg.norm(h - ref[:len(h)], axis=1).max()) for p, (r, h) in paths.items()}
    assert not paths[0.01][0].reason.startswith("stopped") or err[0.01] > 0.5e-3, (paths[0.01][0].reason, err)
    for p in (0.005, 0.002):
        assert paths[p][0].reason.startswith("stopped at t = 0.600"), paths[p][0].reason
    # First order: 2.5 x shorter period -> ~2.5 x smaller error; at least 2 x (measured 4.1 x).
    assert err[0.002] < err[0.005] / 2, err
    # The default's error: below 0.1 mm (measured 0.044 mm), 1/50 of the 5 mm tracking bounds of the walks.
    assert err[0.002] < 1e-4, err


def test_newton_contact_forces_vs_com(hm: HumanoidModel, sc) -> None:
    """The summed MuJoCo contact forces (``foot_wrench``, from ``mj_contactForce``) equal m (a_com - g), a_com the
    central second difference of the whole-body CoM (Pinocchio, from the logged q), logged at every MuJoCo step
    dt along a 5 mm drop onto both feet (impact, then standing).

    Bound: MuJoCo's semi-implicit Euler gives v_{n+1} = v_n + dt a_n, q_{n+1} = q_n + dt v_{n+1}; expanding the CoM
    map to second order, (c_{n+1} - 2 c_n + c_{n-1}) / dt^2 = J_c a_n + Jdot_c v_n + O(dt |v| |a|) -- and
    m (J_c a_n + Jdot_c v_n) is exactly the sum of the external forces at state n.  So the residual is a
    first-order discretization error: it must halve when dt halves, vanish at rest, and stay far below the error a
    wrong force would leave (one foot missing: ~half the weight).  Measured (max / rms, N): dt 1 ms 6.7 / 0.52,
    0.5 ms 3.2 / 0.23; at rest (after 0.1 s) < 5e-4 N."""
    mass = pin.computeTotalMass(hm.model)
    weight = mass * hm.spec.gravity
    d = hm.model.createData()
    out = {}
    for dt in (0.001, 0.0005):
        sc_dt = dataclasses.replace(sc, simulation=dataclasses.replace(sc.simulation, step_s=dt))
        r, _ = _hold(hm, sc_dt, FlatFeetPD(w=10.0), t_end=0.3, drop=0.005, control_period_s=dt,
                     contact=MujocoSettings.from_scenario(sc, timestep=dt))
        a = r.log.arrays()
        c = np.array([pin.centerOfMass(hm.model, d, q) for q in a["q"]])
        acc = (c[2:] - 2 * c[1:-1] + c[:-2]) / dt ** 2
        F = a["foot_wrench"][1:-1, :, :3].sum(axis=1)
        res = np.linalg.norm(mass * acc - (F + mass * np.array([0.0, 0.0, -hm.spec.gravity])), axis=1)
        assert np.linalg.norm(F, axis=1).max() > 3 * weight  # the impact is in the window
        out[dt] = (res, a["t"][1:-1])
    res1, t1 = out[0.001]
    res2, _ = out[0.0005]
    rms1, rms2 = np.sqrt(np.mean(res1 ** 2)), np.sqrt(np.mean(res2 ** 2))
    # first order: the ratio is 2 up to the change of the impact itself with dt (measured 2.25)
    assert 1.5 < rms1 / rms2 < 3.0, (rms1, rms2)
    # 5 % of the weight (27 N): a missing foot or a sign error would leave >= 50 %
    assert res1.max() < 0.05 * weight, res1.max()
    # at rest the O(dt |v| |a|) term vanishes: 1e-2 N (2e-5 of the weight) leaves room for the residual sway
    assert res1[t1 > 0.1].max() < 1e-2, res1[t1 > 0.1].max()


@pytest.mark.parametrize("compiled", [False, None])
def test_thesis_gait_tips_over_sideways(hm: HumanoidModel, sc, compiled) -> None:
    """Sim 1's thesis gait on real ground: its first single support asks the left foot for a centre of pressure
    ~0.12 m inward of the foot's centre (the contact audit), 0.08 m beyond the sole's inner edge.  MuJoCo
    rolls the foot over that edge at once.  Measured: a fall at t = 0.006 s, the left foot tipped onto its heel and
    inner edges (17 deg).  The same on the engine's compiled ground reads (``compiled=None``: the thesis controller
    and the engine compiled) and on the NumPy reference path (False)."""
    sim = Simulator(hm, sc, engine="mujoco", compiled=compiled)
    assert sim.engine.compiled is (compiled is None)
    r = sim.run(t_end=1.0)
    assert not r.completed
    s = summarize(r, sc.name, "mujoco")
    assert s["fell"] is True and s["reason"] == s["fall_reason"]
    assert 0.0 < s["fall_time_s"] < 0.02
    assert "left foot" in s["reason"] and "inner" in s["reason"], s["reason"]
    for key in ("foot_slip_max_m", "foot_tilt_max_rad", "penetration_max_m"):
        assert s[key] is not None and s[key] >= 0.0
    assert s["foot_tilt_max_rad"] > np.radians(3.0)  # the edge criterion's tilt
    # weld-engine summaries are unchanged: no ground fields there
    assert "fell" not in summarize(dataclasses.replace(r, extra={}), sc.name, "pinocchio")


@pytest.mark.slow
def test_zmp_gait_with_the_balance_controller_walks_on_real_ground(hm):
    """The feasible gait on MuJoCo's ground: the lead-in and the first two steps of sim 3's zmp walk (3 s) without
    a fall, the feet holding (slip < 5 mm: issue #15's bound per stance) and the hip on its plan."""

    from humanoid_sim.analysis.summary import summarize

    root = Path(__file__).resolve().parents[2]
    sc = load_scenario(root / "scripts" / "params" / "sim3_zmp.yaml")
    sim = Simulator(hm, sc, engine="mujoco")
    res = sim.run(t_end=3.0)
    s = summarize(res, sc.name, "mujoco")
    assert not s["fell"], s["fall_reason"]
    assert res.phases[-1].index >= 4                     # lead-in, two single and two double supports at least
    assert s["foot_slip_max_m"] < 0.005
    assert s["hip_com_error_rms_m"] < 0.020               # issue #15's tracking bound


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sim1_zmp", "sim3_fast_zmp"])
def test_zmp_walks_that_touch_down_late_complete_on_real_ground(hm, name):
    """Sim 1's curved walk and the 1.5x walk, whole, on MuJoCo: every phase without a fall, hip within issue #15's
    20 mm RMS.  Both fell (t = 6.3 s and 2.1 s) before the references waited for late touchdowns (time_shift) and
    the lifted heel returned to flat gradually; this guards those two.  Both also meet the issue's per-stance
    bounds, slip <= 5 mm and stance tilt <= 1 deg: measured 3.7 mm and 0.61 deg (sim 1; 28.7 mm and 3.5 deg while a
    double support that began with an early touchdown ended early, lifting a foot that still carried ~250 N), 2.9 mm
    and 0.63 deg (1.5x; 1.62 deg while the trailing foot lifted carrying 35-60 N).  The bounds are the issue's."""

    from humanoid_sim.analysis.summary import summarize

    root = Path(__file__).resolve().parents[2]
    sc = load_scenario(root / "scripts" / "params" / f"{name}.yaml")
    res = Simulator(hm, sc, engine="mujoco").run()
    s = summarize(res, sc.name, "mujoco")
    assert res.completed and not s["fell"], res.reason
    assert s["hip_com_error_rms_m"] < 0.020
    assert s["foot_slip_max_m"] <= 0.005
    assert s["stance_tilt_max_rad"] <= math.radians(1.0)


@pytest.mark.slow
def test_control_rate_converges_on_the_zmp_walk(hm):
    """The default 2 ms control period for the walk it serves: sim 3's zmp walk with the balance controller, lead-in
    and first step (2 s), hip path at control periods 5 and 2 ms against 1 ms (control at every MuJoCo step).
    Measured over 3 s: 5 ms is 0.45 mm off at most, 2 ms 0.11 mm (first order: 2.5 x shorter period, ~4 x
    smaller).  Bounds: 2 ms at least 2 x closer than 5 ms, and within 0.5 mm (1/40 of the issue's 20 mm hip bound)."""

    from humanoid_sim.engines import make_engine
    from humanoid_sim.interfaces.controller import ControlContext

    root = Path(__file__).resolve().parents[2]
    sc = load_scenario(root / "scripts" / "params" / "sim3_zmp.yaml")
    paths = {}
    for period in (0.005, 0.002, 0.001):
        sim = Simulator(hm, sc, engine="mujoco")
        sim.engine = make_engine("mujoco", hm, sc, sim.traj, control_period_s=period)
        sim.controller.setup(ControlContext(hm, sc, sim.traj, sim.q0, sim.engine.name, sim.engine.constraints))
        res = sim.run(t_end=2.0)
        assert res.reason.startswith("stopped at t = 2.000"), res.reason
        paths[period] = res.log.arrays()["hip_p"]
    ref = paths[0.001]
    err = {p: float(np.linalg.norm(paths[p] - ref, axis=1).max()) for p in (0.005, 0.002)}
    assert err[0.002] < err[0.005] / 2, err
    assert err[0.002] < 0.5e-3, err


def test_body_wrenches_against_per_contact_sums(hm: HumanoidModel, sc) -> None:
    """The log's ``body_force`` / ``body_moment`` (trace.body_wrenches, one pass over a foot's contacts)
    against an independent read: per contact mj_contactForce turned to the world frame, summed per sole body with
    np.cross about the body's CoM, rotated to the body frame; standing on both feet, all four sole bodies loaded."""
    from humanoid_sim.engines.mujoco.contact import foot_contacts
    from humanoid_sim.engines.mujoco.trace import body_wrenches
    from humanoid_sim.robot.model import FOOT_BODY, TOE_BODY

    _, eng = _hold(hm, sc, FlatFeetPD(), t_end=0.1)
    m, d, mm = eng.sim.model, eng.sim.data, eng.mm
    feet = foot_contacts(mm, d)
    bf, bm = np.zeros((4, 3)), np.zeros((4, 3))
    for f in "RL":
        body_wrenches(mm, d, f, feet[f], bf, bm)
    F_ref, M_ref = np.zeros((4, 3)), np.zeros((4, 3))
    for i in range(d.ncon):
        c = d.contact[i]
        f6 = np.zeros(6)
        mujoco.mj_contactForce(m, d, i, f6)
        g = int(c.geom[1])                              # MuJoCo lists the floor first
        [(foot, box)] = [(f, b) for f in "RL" for b in (0, 1) if mm.sole_geoms[f][b] == g]
        body = (TOE_BODY if box == 0 else FOOT_BODY)[foot]
        bid = mm.foot_bodies[foot][box]
        F = c.frame.reshape(3, 3).T @ f6[:3]
        F_ref[body - 1] += F
        M_ref[body - 1] += np.cross(c.pos - d.xipos[bid], F)
    for foot in "RL":
        for box, body in ((0, TOE_BODY[foot]), (1, FOOT_BODY[foot])):
            Rt = d.xmat[mm.foot_bodies[foot][box]].reshape(3, 3).T
            F_ref[body - 1], M_ref[body - 1] = Rt @ F_ref[body - 1], Rt @ M_ref[body - 1]
    assert np.all(np.abs(F_ref[:, 2]) > 1.0)              # every sole body carries load
    # 1e-9 N and N m on forces up to ~400 N: the same terms, summed in the same order, rotated by another product
    np.testing.assert_allclose(bf, F_ref, atol=1e-9, rtol=0)
    np.testing.assert_allclose(bm, M_ref, atol=1e-9, rtol=0)


def test_a_foot_on_its_toe_is_judged_by_its_toe_box(hm: HumanoidModel, sc) -> None:
    """The fall test's tilt is that of the sole box bearing the load.  With the right toe joint bent by 0.1 rad
    (the main body level, the toe box turned): bearing on its main body, the foot is level; bearing on its toe box
    alone, it is tilted by 0.1 rad.  (A toe-off is the other way round: a tilted main body on a level toe box, which
    the main body's tilt alone took for a foot tipped over.)"""
    from humanoid_sim.engines.mujoco.contact import bearing_tilt, sole_tilt

    sim = Simulator(hm, sc, engine="mujoco")
    eng = sim.engine
    q = sim.q0.copy()
    jid = hm.model.getJointId("theta3")
    q[hm.model.idx_qs[jid]] += 0.1
    eng.sim.set_state(q, np.zeros(hm.model.nv))
    eng.sim.forward()
    mm, data = eng.mm, eng.sim.data
    level = sole_tilt(mm, data, "R")
    assert level < 1e-3                                          # q0: the feet flat
    assert bearing_tilt(mm, data, "R", 300.0, 20.0) == level
    # the toe body turned by the joint's 0.1 rad about its axis (the sole's lateral axis)
    assert bearing_tilt(mm, data, "R", 5.0, 20.0) == pytest.approx(0.1, abs=level + 1e-9)
