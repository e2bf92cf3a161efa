"""The balance controller (humanoid_sim/controllers/balance.py) against independent computations: the weld engine's
own forward dynamics, Newton's law for the whole robot, the audit's sole polygons, the actuator map; and the issue
#13 acceptance on sim 3's zmp walk, judged by the contact audit."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.analysis.audit import FLAT, SoleGeometry, signed_distance, sole_polygons
from humanoid_sim.analysis.summary import contact_audit, summarize
from humanoid_sim.controllers.balance.controller import BalanceController, BalanceSettings
from humanoid_sim.interfaces.controller import ControlContext, Observation
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.phases import FOOT_SPECS, Phase
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.simulate import Simulator

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def sc():
    return load_scenario(ROOT / "scripts" / "params" / "sim3_zmp.yaml")


def _state_at(hm, sc, t_end):
    """A zmp walk stopped at t_end: the simulator and the observation its controller would get next."""
    sim = Simulator(hm, sc)
    assert isinstance(sim.controller, BalanceController)      # the zmp gait's default executor
    res = sim.run(t_end=t_end)
    k = len(res.phases) - 1
    eng = sim.engine
    obs = Observation(t=res.sim_time, k=k, phase=Phase(res.phases[-1].name), q=eng.q.copy(), v=eng.v.copy(),
                      anchors=eng.anchors)
    return sim, obs


@pytest.fixture(scope="module", params=[2.9, 1.72], ids=["single_support", "double_support"])
def state(request, hm, sc):
    sim, obs = _state_at(hm, sc, request.param)
    assert obs.phase.is_double_support == (request.param == 1.72)
    return sim, obs


def test_torques_reproduce_the_motion_through_the_engines_forward_dynamics(state):
    sim, obs = state
    cmd = sim.controller(obs)
    a, lam = cmd.motion
    fwd = sim.engine.dyn.forward(obs.phase.contacts, obs.anchors, obs.q, obs.v, cmd.tau)
    # 1e-7: the KKT solve's round-off on accelerations of ~10 m/s^2 and multipliers of ~500 N
    np.testing.assert_allclose(fwd.a, a, rtol=0, atol=1e-7)
    np.testing.assert_allclose(fwd.lam, lam, rtol=0, atol=1e-6)
    assert np.all(cmd.tau[:6] == 0.0)


def test_ground_forces_obey_newton_for_the_whole_robot(hm, state):
    sim, obs = state
    cmd = sim.controller(obs)
    a, lam = cmd.motion
    model, d = hm.model, hm.model.createData()
    pin.centerOfMass(model, d, obs.q, obs.v, a)
    mass = sum(model.inertias[j].mass for j in range(1, model.njoints))
    pin.framesForwardKinematics(model, d, obs.q)
    force = np.zeros(3)
    for i, frame in enumerate(obs.phase.contacts.welds):
        force += d.oMf[hm.frame_id(frame)].rotation @ lam[6 * i:6 * i + 3]
    # 1e-6 N: the same round-off, on forces of ~540 N
    np.testing.assert_allclose(force, mass * (d.acom[0] - model.gravity.linear), rtol=0, atol=1e-6)


def test_heel_and_toe_box_wrenches_are_the_welds_generalized_force(hm, state):
    """A flat foot's two box wrenches (heel box on the main body, toe box on the toe body), each pushed through its
    own body's Jacobian, give the generalized force the weld and the toe lock apply: J_main^T W_m + J_toe^T W_t =
    J_weld^T lam_weld + e_toe lam_lock.  Checks the wrench transport X and the lock's share independently."""
    sim, obs = state
    cmd = sim.controller(obs)
    lam = cmd.motion[1]
    boxes = cmd.extra["box_wrenches"]
    assert boxes                                           # every phase has a flat foot
    model, d = hm.model, hm.model.createData()
    pin.computeJointJacobians(model, d, obs.q)
    pin.updateFramePlacements(model, d)
    welds, locks = obs.phase.contacts.welds, list(obs.phase.contacts.locks)
    for frame, (Wm, Wt) in boxes.items():
        foot = "R" if frame == "O_3" else "L"
        spec = FOOT_SPECS[foot]
        i, k = welds.index(frame), locks.index(spec.toe_joint)
        Jm = pin.getFrameJacobian(model, d, hm.frame_id(frame), pin.ReferenceFrame.LOCAL)
        Jt = pin.getFrameJacobian(model, d, hm.frame_id(spec.toe_frame), pin.ReferenceFrame.LOCAL)
        lhs = Jm.T @ Wm + Jt.T @ Wt
        rhs = Jm.T @ lam[6 * i:6 * i + 6]
        rhs[hm.model.joints[hm.model.getJointId(spec.toe_joint)].idx_v] += lam[6 * len(welds) + k]
        # 1e-8 N m: round-off of 6 x 32 products of ~500 N forces and ~1 m levers
        np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-8)
        assert Wt[2] >= -1e-9 and Wm[2] >= -1e-9              # both boxes push


def test_actuator_component_map_equals_the_thesis_torques(hm):
    act = Actuators(hm)
    rng = np.random.default_rng(3)
    q = pin.randomConfiguration(hm.model, -0.5 * np.ones(hm.model.nq), 0.5 * np.ones(hm.model.nq))
    q[3:7] /= np.linalg.norm(q[3:7])
    v, a, tau = (rng.normal(0, 1, hm.model.nv) for _ in range(3))
    tau[:6] = 0.0
    P, exact = act.component_map(q)
    assert exact.sum() == 22 and not exact[[19, 20, 21, 22]].any()   # the two universal shoulders are read off RNEA
    # 1e-9: 3 x 3 block inverses against the thesis_torques' solves, torques of ~1 N m
    np.testing.assert_allclose((P @ tau)[exact], act.thesis_torques(q, v, a, tau)[exact], rtol=0, atol=1e-9)


class _Pushed:
    """The walk's trajectory with the hip reference moved 0.1 m sideways: a demand no sole can carry."""

    def __init__(self, traj, dx):
        self._traj, self._dx = traj, np.array([dx, 0.0, 0.0])

    def __getattr__(self, name):
        return getattr(self._traj, name)

    def hip_reference(self, k, t):
        p, v, R = self._traj.hip_reference(k, t)
        return p + self._dx, v, R


def _world_cop_margin(hm, q, frame, lam6):
    """The weld's ground wrench as the audit sees it: world force and moment, CoP on z = 0, distance to the
    sole's world polygon (audit.sole_polygons).  Also returns how far that can differ from the controller's CoP on
    the sole's own plane: the sole plane's height above z = 0 times |f_t| / f_z (the CoP of a wrench moves along
    the force's line between the two planes), plus the tilt's effect (second order, < 1e-5 m here)."""
    d = hm.model.createData()
    pin.framesForwardKinematics(hm.model, d, q)
    M = d.oMf[hm.frame_id(frame)]
    f = M.rotation @ lam6[:3]
    n = M.rotation @ lam6[3:] + np.cross(M.translation, f)
    cop = np.array([-n[1] / f[2], n[0] / f[2]])
    kind = np.array([[FLAT, 0] if frame == "O_3" else [0, FLAT]])
    poly = [p for p in sole_polygons(hm, q[None], kind)[0] if p is not None][0]
    sole_z = (M.act(np.array([0.0, 0.0, SoleGeometry.from_model(hm).sole_z])))[2]
    return signed_distance(cop, poly), abs(sole_z) * math.hypot(f[0], f[1]) / f[2] + 1e-5


@pytest.mark.slow
def test_a_demand_beyond_the_sole_puts_the_cop_on_the_margin(hm, sc):
    sim, obs = _state_at(hm, sc, 2.9)
    assert obs.phase in (Phase.LFFSSP, Phase.RFFSSP)
    frame = "O_4" if obs.phase is Phase.LFFSSP else "O_3"
    ctrl = sim.controller
    free, _ = _world_cop_margin(hm, obs.q, frame, ctrl(obs).motion[1][:6])
    assert free > 0.02                                   # the walk itself: well inside
    ctx = ControlContext(hm, sc, _Pushed(sim.traj, 0.1), sim.q0, "pinocchio", sim.engine.constraints)
    # friction at the full cone (friction_safety 1): the default 0.3 binds the pushed sole's tangential force
    # before its CoP reaches the edge (measured 1.8 mm inside), and this test is about the CoP rows.  The hip PD
    # (feedback pd) pulls to the displaced hip reference; the DCM law follows the CoM plan, which is not displaced
    pushed = BalanceController(BalanceSettings(friction_safety=1.0, feedback="pd"))
    pushed.setup(ctx)
    lam = pushed(obs).motion[1]
    margin, tol = _world_cop_margin(hm, obs.q, frame, lam[:6])
    assert tol < 1e-3                                    # the sole sits < 1 mm above the ground: a sharp check
    assert margin == pytest.approx(BalanceSettings().cop_margin_ssp_m, abs=tol)   # on the shrunk boundary
    loose = BalanceController(BalanceSettings(cop_margin_ssp_m=0.0, friction_safety=1.0, feedback="pd"))
    loose.setup(ctx)
    margin, tol = _world_cop_margin(hm, obs.q, frame, loose(obs).motion[1][:6])
    assert margin == pytest.approx(0.0, abs=tol)         # no margin asked: on the sole's edge


@pytest.mark.slow
def test_the_unloading_weight_acts_on_the_trailing_toes_normal_force(hm, sc):
    """w_unload adds w u^2 fz^2 to the QP's cost, fz the trailing toe's normal force (u the double support's
    progress).  For a convex QP, adding w x^2 to the cost cannot raise x^2 at the optimum, and lowers it when the
    rest of the cost pulls x away from 0: so fz must fall as w grows, if the weight sits on that variable."""
    sim, obs = _state_at(hm, sc, 1.78)                  # sim 3's first double support after a step, u ~ 0.7
    assert obs.phase.is_double_support
    ctx = ControlContext(hm, sim.sc, sim.traj, sim.q0, "pinocchio", sim.engine.constraints)
    i = next(j for j, f in enumerate(obs.phase.contacts.welds) if f in ("O_1", "O_2"))   # the trailing toe's weld
    info = sim.traj.phases[obs.k]
    assert 0.3 < (obs.t - info.t_start) / info.duration < 1.0       # late enough in the phase for u^2 to weigh
    fz = []
    for w in (0.0, 1e-3, 1e-2, 1e-1):
        # time_shift off: a controller first called mid-phase would take the phase for 0.08 s late (u = 0)
        ctrl = BalanceController(BalanceSettings(w_unload=w, time_shift=False))
        ctrl.setup(ctx)
        fz.append(float(ctrl(obs).motion[1][6 * i + 2]))
    assert fz[0] > 20.0                                  # without the weight the trailing toe carries load here
    assert all(b < a for a, b in zip(fz, fz[1:])), fz    # strictly falling: the weight is on fz and only lowers it


@pytest.mark.parametrize("field, value, message", [
    ("hip_omega", 0.0, "BalanceSettings.hip_omega = 0.0: expected a finite number > 0"),
    ("w_hip", -1.0, "BalanceSettings.w_hip = -1.0: expected a finite number >= 0"),
    ("friction_safety", 1.5, "BalanceSettings.friction_safety = 1.5: expected a finite number > 0 and <= 1"),
    ("cop_margin_ssp_m", float("nan"), "BalanceSettings.cop_margin_ssp_m = nan"),
    ("time_shift", 1, "BalanceSettings.time_shift = 1: expected true or false"),
    ("lazy_torque_limits", "yes", "BalanceSettings.lazy_torque_limits = 'yes': expected true or false"),
])
def test_bad_settings_are_named(field, value, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        BalanceSettings(**{field: value})


def test_references_are_read_on_the_plans_clock(hm, sc, state):
    """A late touchdown (``Observation.plan_delay``, the phase selector's) delays every reference: the command at t
    with a delay d is the command at t - d with none; with ``time_shift`` off the delay is ignored."""
    from dataclasses import replace

    sim, obs = state
    ctl = sim.controller
    d = 0.03
    late = ctl(replace(obs, plan_delay=d)).tau
    assert np.array_equal(late, ctl(replace(obs, t=obs.t - d, plan_delay=0.0)).tau)
    assert not np.allclose(late, ctl(obs).tau, rtol=0, atol=1e-3)      # 30 ms of the plan moves the torques
    off = BalanceController(BalanceSettings(time_shift=False))
    off.setup(ControlContext(hm, sc, sim.traj, sim.q0, sim.engine.name, sim.engine.constraints))
    assert np.array_equal(off(replace(obs, plan_delay=d)).tau, off(obs).tau)
def test_toe_off_ramps_from_the_double_supports_start(hm, sc, state):
    """The trailing heel's lift target (double support's toe-off) starts at zero when the double support starts,
    also after an early touchdown (the plan's clock does not wait for one: the phase then starts before its planned
    start), and rises monotonically to ``heel_lift_rad``."""
    sim, obs = state
    settings = BalanceSettings()
    for early in (0.0, 0.06):
        ctl = _with(hm, sc, sim)
        k = next(i for i, ph in enumerate(ctl.traj.phases) if i > 0 and ph.swing_foot is None)   # after the lead-in
        info = ctl.traj.phases[k]
        phase = next(p for p in Phase if p.name == info.name)
        times = info.t_start - early + np.linspace(0.0, early + min(info.duration, settings.heel_lift_time_s), 40)
        lift = [ctl._targets(Observation(t, k, phase, obs.q, obs.v, obs.anchors)).heel[1] for t in times]
        assert lift[0] == 0.0
        assert np.all(np.diff(lift) >= 0.0)
        assert lift[-1] == pytest.approx(settings.heel_lift_rad, abs=1e-12)


def _with(hm, sc, sim, **settings) -> BalanceController:
    ctl = BalanceController(BalanceSettings(**settings))
    ctl.setup(ControlContext(hm, sc, sim.traj, sim.q0, sim.engine.name, sim.engine.constraints))
    return ctl


def test_lazy_torque_limits_give_the_full_qps_optimum(hm, sc, state):
    """The actuator-limit rows left out of the first solve (``lazy_torque_limits``) change nothing: without a
    binding limit the command equals the one solved with every row from the start; with limits tightened until
    one binds (torque_margin below the state's largest |T| / limit), the controller solves again with the rows and
    again equals the full QP, with every bounded component at or inside its limit."""
    sim, obs = state
    eager, lazy = _with(hm, sc, sim, lazy_torque_limits=False), _with(hm, sc, sim)
    ce, cl = eager(obs), lazy(obs)
    assert (eager.torque_rows, lazy.torque_rows) == (1, 0)
    # 1e-6 N m: the two QPs differ by rows that are inactive at the optimum; DAQP ends at its 1e-6 feasibility
    # tolerance on rows scaled ~1..500, and the optima of the walk's QPs agree to ~1e-9 relative (torques ~100 N m)
    np.testing.assert_allclose(cl.tau, ce.tau, rtol=0, atol=1e-6)
    exact = lazy._exact
    ratio = np.max(np.abs(cl.T_cmd[exact]) / lazy.act.limits[exact])
    assert 0.2 < ratio < 0.98                             # well inside the default limits, so 0.9 ratio binds
    eager, lazy = (_with(hm, sc, sim, lazy_torque_limits=flag, torque_margin=0.9 * ratio) for flag in (False, True))
    ce, cl = eager(obs), lazy(obs)
    assert (eager.torque_rows, lazy.torque_rows) == (1, 1)   # the first solve broke a limit: solved again
    np.testing.assert_allclose(cl.tau, ce.tau, rtol=0, atol=1e-6)
    bound = 0.9 * ratio * lazy.act.limits[exact]
    # 1e-4 N m: DAQP's primal tolerance (1e-6) on rows T = P tau whose entries are ~1..100
    assert np.all(np.abs(cl.T_cmd[exact]) <= bound + 1e-4)
    assert np.max(np.abs(cl.T_cmd[exact]) - bound) > -1e-4   # and one of them sits on its bound


def test_saturation_of_the_compiled_path_is_the_actuators(hm, sc, state):
    """A command whose thesis torques break an actuator limit is clipped as ``Actuators.saturate`` clips it, on the
    compiled path (whose finish checks the limits and skips ``saturate`` when nothing binds) and the reference."""
    sim, obs = state
    cmds = []
    for compiled in (True, False):
        ctl = BalanceController(compiled=compiled)
        ctl.setup(ControlContext(hm, sc, sim.traj, sim.q0, sim.engine.name, sim.engine.constraints))
        T = ctl(obs).T_cmd
        # limits at 0.8 |T| on the five largest components (and the rest untouched): those five must clip
        big = np.argsort(-np.abs(T))[:5]
        ctl.act.limits = ctl.act.limits.copy()
        ctl.act.limits[big] = 0.8 * np.abs(T[big])
        ctl._exact_limits = ctl.act.limits[ctl._exact] * 10.0    # the QP's own limit rows far away: T stays
        cmd = ctl(obs)
        expect_T, expect_sat = ctl.act.saturate(cmd.T_cmd)
        np.testing.assert_array_equal(cmd.saturated, expect_sat)
        np.testing.assert_array_equal(cmd.T, expect_T)
        assert set(np.flatnonzero(cmd.saturated)) == set(big)
        cmds.append(cmd)
    # the two paths' torques agree to DAQP's round-off (1e-8 N m, as tests/test_balance_compiled.py measures)
    np.testing.assert_allclose(cmds[0].T, cmds[1].T, rtol=0, atol=1e-8)


@pytest.mark.slow
def test_zmp_walk_is_feasible_on_welded_feet(hm, sc):
    """Issue #13's acceptance on sim 3 with only the gait lines added, judged by the contact audit."""
    sim = Simulator(hm, sc)
    res = sim.run()
    assert res.completed, res.reason
    s = summarize(res, sc.name, "pinocchio")
    c, rep = contact_audit(res, sc, hm, res.phase_names)
    assert c["zmp_outside_fraction"] <= 0.01
    assert max(c["cop_outside_fraction"].values()) <= 0.01
    single = np.array([str(p).endswith("SSP") for p in rep.phase_name])
    loaded = rep.loaded & single[:, None]
    assert np.min(rep.cop_margin[loaded]) >= 0.010                      # 10 mm in single support
    assert s["saturated_fraction"] == 0.0
    assert max(s["torque_peak_Nm"]["T3"], s["torque_peak_Nm"]["T4"]) <= 75.0
    assert s["hip_com_error_rms_m"] <= 0.015 and s["hip_com_error_max_m"] <= 0.040
    landing = c["landing"]
    assert landing["tilt_max_rad"] <= math.radians(0.5) and landing["lowest_corner_m"] >= -0.001
    assert landing["inside_cone"] == landing["count"] == 8
    assert sim.controller.run_info()["balance_relaxed_cop"] == 0


def test_the_qp_optimum_is_quadprogs(state, monkeypatch):
    """DAQP (the controller's solver) against quadprog (Goldfarb-Idnani, an independent dual active-set code) on the
    controller's own QPs, in single and double support: the same optimum, and it satisfies every constraint."""
    import quadprog  # the independent QP solver, a test dependency
    sim, obs = state
    ctl = sim.controller
    seen = []
    original = ctl._solve

    def spy(G, g, C, lo, ne, cop_rows):
        out = original(G, g, C, lo, ne, cop_rows)
        seen.append((G, g, C[:ne], lo[:ne], C[ne:], lo[ne:], out))
        return out

    monkeypatch.setattr(ctl, "_solve", spy)
    ctl(obs)
    (G, g, Ceq, beq, Cin, bin_, (x, level)), = seen
    assert level == 0                                      # a feasible state: no constraint relaxed
    ref = quadprog.solve_qp(G, g, np.vstack([Ceq, Cin]).T, np.concatenate([beq, bin_]), len(beq))[0]
    scale = np.abs(ref).max()
    # 1e-7 of the largest variable (multipliers of ~500 N): DAQP stops at a primal feasibility of 1e-6 on rows
    # scaled ~1..500; measured on 236 QPs of sim 1's walk, the two optima agree to 4e-10 relative
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-7 * scale)
    # the equalities hold and no inequality is violated beyond DAQP's primal tolerance (1e-6) times the row scale
    row_scale = np.abs(Ceq).max(axis=1) * scale
    assert np.all(np.abs(Ceq @ x - beq) <= 1e-6 * np.maximum(row_scale, 1.0))
    assert np.all(Cin @ x - bin_ >= -1e-6 * np.maximum(np.abs(Cin).max(axis=1) * scale, 1.0))
