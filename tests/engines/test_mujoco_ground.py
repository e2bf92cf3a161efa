"""The ground meters' settling window and sliding events (humanoid_sim/engines/mujoco/ground.py): the friction reads
against MuJoCo's own contact force and object velocity, the sliding events on synthetic reads with hand-computed
answers, the settling window on a robot put down on MuJoCo's ground, and the contact audit of the feasible gait on
real ground (slow).  The meters' loads, slips, tilts and penetration against each other: test_mujoco_compiled.py."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from humanoid_sim.engines.mujoco import MujocoSettings, MujocoSim
from humanoid_sim.engines.mujoco.ground import (
    MERGE_GAP_S,
    ON_CONE_TOL,
    SETTLING_TIME_CONSTANTS,
    GroundMeter,
    ReferenceGroundMeter,
    SlideMeter,
    settling_time,
    sole_friction,
)
from humanoid_sim.engines.mujoco.model import FEET
from humanoid_sim.engines.mujoco.standing import StandingController
from humanoid_sim.references.initial import initial_configuration
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.scenario.schema import load_scenario

ROOT = Path(__file__).resolve().parents[2]
DT = 0.002  # s, the engine's control period: the meters read once per update
TIGHT = 1e-12  # m, N: sums and products of a few numbers of order 1


@pytest.fixture(scope="module")
def q0(hm: HumanoidModel) -> np.ndarray:
    return initial_configuration(hm, load_scenario(ROOT / "scripts" / "params" / "sim1.yaml").path)


# --------------------------------------------------------------------------------------------- friction reads
def _sliding_state(hm: HumanoidModel, q0: np.ndarray, cone: str) -> MujocoSim:
    """The initial posture standing (0.1 s under the standing PD), then the whole robot given 0.3 m/s sideways (x):
    both feet slide on the ground; MuJoCo's derived quantities at that state (mj_forward)."""
    sim = MujocoSim(hm, replace(MujocoSettings(), cone=cone))
    ctrl = StandingController(hm, q0, sim.timestep)
    sim.set_state(q0, np.zeros(hm.model.nv))
    m, d = sim.model, sim.data
    for _ in range(100):
        q, v = sim.state()
        d.ctrl[:] = sim.map.ctrl_from_tau(ctrl(q, v))
        mujoco.mj_step(m, d)
    d.qvel[0] += 0.3          # the free joint's linear velocity, world frame
    mujoco.mj_forward(m, d)
    return sim


def _by_hand(sim: MujocoSim) -> list[tuple[float, float, float]]:
    """sole_friction's numbers from mj_contactForce (contact frame) and mj_objectVelocity (the sole geom's body
    velocity, moved to the contact point and projected on the contact plane), contact by contact."""
    mm, m, d = sim.mm, sim.model, sim.data
    pyramidal = m.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    geoms = {g: i for i, f in enumerate(FEET) for g in mm.sole_geoms[f]}
    sums = np.zeros((2, 3))
    f6, vel = np.zeros(6), np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        sole = int(c.geom[1]) if int(c.geom[1]) in geoms else int(c.geom[0])
        mujoco.mj_contactForce(m, d, i, f6)
        mu = c.friction[0]
        fn = f6[0]
        used = (abs(f6[1]) + abs(f6[2])) / mu if pyramidal else math.hypot(f6[1], f6[2]) / mu
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_GEOM, sole, vel, 0)   # [w; v] at the geom, world axes
        v_point = vel[3:] + np.cross(vel[:3], c.pos - d.geom_xpos[sole])
        frame = c.frame.reshape(3, 3)
        speed = float(np.hypot(frame[1] @ v_point, frame[2] @ v_point))
        sums[geoms[sole]] += (fn, used, fn * speed)
    return [(n, u / n, s / n) for n, u, s in sums]


@pytest.mark.parametrize("cone", ["elliptic", "pyramidal"])
def test_friction_reads_are_mujocos_contact_forces_and_velocities(hm: HumanoidModel, q0: np.ndarray,
                                                                  cone: str) -> None:
    """sole_friction (efc_force / efc_vel rows, decoded per cone) = mj_contactForce and mj_objectVelocity, per foot:
    normal force, cone use, slip speed, on both feet sliding sideways at 0.3 m/s and on the robot just put down.

    Sliding at 0.3 m/s, the lightly loaded contacts are on their cones and the heaviest (~160 N) inside (0.78-0.87
    of it, measured): MuJoCo's soft friction resists a slip in proportion to its speed up to the cone, so a foot's
    use is 1 only when every loaded contact is saturated, which the walks' slides are (ON_CONE_TOL)."""
    sim = _sliding_state(hm, q0, cone)
    reads, ref = sole_friction(sim.mm, sim.data), _by_hand(sim)
    for got, want in zip(reads, ref):
        # 1e-9 relative: the same numbers in another order (a pyramid's edges decoded by MuJoCo or here)
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
        n, use, speed = got
        assert n > 100 and speed == pytest.approx(0.3, rel=1e-6)   # every contact slides at the speed given
        assert 0.5 < use <= 1.0 + 1e-9                              # inside or on the cone, never outside
    standing = MujocoSim(hm, replace(MujocoSettings(), cone=cone))
    standing.set_state(q0, np.zeros(hm.model.nv))
    mujoco.mj_step(standing.model, standing.data)   # put down: the first step's forces
    mujoco.mj_forward(standing.model, standing.data)
    np.testing.assert_allclose(sole_friction(standing.mm, standing.data), _by_hand(standing), rtol=1e-9, atol=1e-12)
    assert sole_friction(sim.mm, sim.data, elliptic=cone == "elliptic") == reads


def test_friction_reads_without_contact(hm: HumanoidModel, q0: np.ndarray) -> None:
    sim = MujocoSim(hm)
    q = q0.copy()
    q[2] += 0.05                                   # 5 cm up: no contact
    sim.set_state(q, np.zeros(hm.model.nv))
    mujoco.mj_forward(sim.model, sim.data)
    assert sim.data.ncon == 0 and sole_friction(sim.mm, sim.data) == [(0.0, 0.0, 0.0)] * 2


# --------------------------------------------------------------------------------------------- sliding events
def _reads(n_r: float = 0.0, use_r: float = 0.0, v_r: float = 0.0, n_l: float = 0.0, use_l: float = 0.0,
           v_l: float = 0.0) -> list[tuple[float, float, float]]:
    return [(n_r, use_r, v_r), (n_l, use_l, v_l)]


def test_a_sliding_event_from_start_to_end() -> None:
    """The right foot on its cone at 0.004-0.008 s with 100, 50, 30 N at 10, 20, 40 mm/s: one event from 0.004 s to
    0.010 s (the first update off the cone), travel (10 + 20 + 40) mm/s x 2 ms = 0.14 mm, normal force 30-100 N;
    the left foot, loaded but inside its cone, never slides."""
    meter = SlideMeter(20.0)
    rows = [(100, 0.5, 0.001), (100, 0.5, 0.001), (100, 1.0, 0.010), (50, 1.0, 0.020), (30, 1.0, 0.040),
            (200, 0.3, 0.0), (200, 0.3, 0.0)]
    for k, r in enumerate(rows):
        meter.update(k * DT, _reads(*r, 300.0, 0.9, 0.05))
    [ev] = meter.events
    assert (ev.foot, ev.start_s, ev.end_s, ev.updates) == ("R", 2 * DT, 5 * DT, 3)
    assert ev.travel_m == pytest.approx((0.010 + 0.020 + 0.040) * DT, abs=TIGHT)
    assert (ev.normal_min_N, ev.normal_max_N) == (30.0, 100.0)
    assert ev.as_dict() == {"foot": "R", "start_s": 2 * DT, "end_s": 5 * DT, "travel_m": ev.travel_m,
                            "normal_min_N": 30.0, "normal_max_N": 100.0, "updates": 3}


def test_only_a_loaded_foot_on_its_cone_slides() -> None:
    """Below f_min (a foot touching or leaving) or inside the cone by more than ON_CONE_TOL: no event; at f_min and
    within the tolerance: an event."""
    meter = SlideMeter(20.0)
    meter.update(0.0, _reads(19.99, 1.0, 0.1, 500.0, 1.0 - 2 * ON_CONE_TOL, 0.1))
    meter.update(DT, _reads(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    assert meter.events == []
    meter.update(2 * DT, _reads(20.0, 1.0 - 0.5 * ON_CONE_TOL, 0.1, 0.0, 0.0, 0.0))
    assert [(e.foot, e.start_s, e.end_s, e.updates) for e in meter.events] == [("R", 2 * DT, 2 * DT, 1)]


def test_stretches_closer_than_the_merge_gap_are_one_event() -> None:
    """Stretches of the left foot 2 updates apart merge (travel of their sliding updates only); a stretch
    MERGE_GAP_S after the last one's end is a new event; the other foot's events never merge with it."""
    meter = SlideMeter(20.0)
    pattern = [1, 1, 0, 0, 1, 0] + [0] * round(MERGE_GAP_S / DT) + [1, 0]
    for k, on in enumerate(pattern):
        meter.update(k * DT, _reads(100.0, 1.0, 0.01, 100.0, float(on), 0.02))
    left = [e for e in meter.events if e.foot == "L"]
    assert [(e.start_s, e.end_s, e.updates) for e in left] == [
        (0.0, 5 * DT, 3), ((len(pattern) - 2) * DT, (len(pattern) - 1) * DT, 1)]
    assert left[0].travel_m == pytest.approx(3 * 0.02 * DT, abs=TIGHT)
    right = [e for e in meter.events if e.foot == "R"]
    assert len(right) == 1 and right[0].end_s == (len(pattern) - 1) * DT      # still open: the last update


def test_open_events_close_and_bad_inputs_raise() -> None:
    meter = SlideMeter(20.0)
    meter.update(0.0, _reads(50.0, 1.0, 0.5))
    meter.update(DT, _reads(50.0, 1.0, 0.5))
    assert meter.closed == [] and meter.events[0].travel_m == pytest.approx(0.5 * DT, abs=TIGHT)
    meter.close(1.5 * DT)
    [ev] = meter.closed
    assert ev.end_s == 1.5 * DT and ev.travel_m == pytest.approx(0.5 * 1.5 * DT, abs=TIGHT)
    assert meter.clear() == [ev] and meter.events == []
    with pytest.raises(ValueError, match="before the last update"):
        meter.update(0.0, _reads())
    for kwargs in ({"f_min": 0.0}, {"f_min": 20.0, "tol": 1.0}, {"f_min": 20.0, "merge_gap": -1.0}):
        with pytest.raises(ValueError):
            SlideMeter(**kwargs)


# --------------------------------------------------------------------------------------------- settling window
def _put_down(hm: HumanoidModel, q0: np.ndarray, seconds: float, meters: list) -> MujocoSim:
    """The initial posture put on the ground at rest under the standing PD (as the engine starts a walk), the
    meters read at every 2 ms update right after its first MuJoCo step (as the engine reads them)."""
    sim = MujocoSim(hm)
    ctrl = StandingController(hm, q0, DT)
    sim.set_state(q0, np.zeros(hm.model.nv))
    sim.time = 0.0
    for _ in range(round(seconds / DT)):
        q, v = sim.state()
        sim.hold(ctrl(q, v))
        sim.advance(1)
        for meter in meters:
            meter.update(sim.data, -1)
        sim.advance(1)
    return sim


def test_settling_window_is_reported_apart(hm: HumanoidModel, q0: np.ndarray) -> None:
    """Put down and standing 0.3 s: the settling window (10 contact time constants, 0.05 s) holds the deepest
    penetration; after it the penetration is the standing one; the compiled and the NumPy meters report the same
    numbers to the bit; a meter whose window is 0 measures the whole run (its penetration is the larger of the
    two); a meter whose window outlasts the run reports the whole run as both."""
    sim = MujocoSim(hm)
    assert settling_time(sim.mm) == SETTLING_TIME_CONSTANTS * 0.005 == pytest.approx(0.05, abs=1e-15)
    meters: list[Any] = [GroundMeter(sim.mm, 20.0, chunk=7), ReferenceGroundMeter(sim.mm, 20.0),
              GroundMeter(sim.mm, 20.0, settling_s=0.0), ReferenceGroundMeter(sim.mm, 20.0, settling_s=1.0)]
    _put_down(hm, q0, 0.3, meters)
    compiled, ref, whole, unended = meters
    report = compiled.report()
    assert report == ref.report()
    s = report["settling"]
    assert s["ended"] is True and s["window_s"] == pytest.approx(0.05, abs=1e-15)
    assert s["penetration_max_m"] > 2 * compiled.penetration_max > 0          # the transient, then standing
    assert compiled.penetration_max < 0.5e-3                                  # issue 15's standing bound: 1 mm
    assert whole.penetration_max == max(s["penetration_max_m"], compiled.penetration_max)
    assert whole.report()["settling"]["penetration_max_m"] == 0.0            # an empty window
    assert [(m.slip_max, m.tilt_max, m.penetration_max) for m in (compiled, ref)] == [
        (compiled.slip_max, compiled.tilt_max, compiled.penetration_max)] * 2
    u = unended.report()
    assert u["settling"]["ended"] is False and u["sliding"]["events"] == [] and u["sliding"]["count"] == 0
    assert u["settling"]["penetration_max_m"] == unended.penetration_max == whole.penetration_max
    assert u["settling"]["foot_slip_max_m"] == unended.slip_max
    with pytest.raises(ValueError, match="settling_s"):
        GroundMeter(sim.mm, 20.0, settling_s=-1.0)


# --------------------------------------------------------------------------------------------- the gait on MuJoCo
@pytest.mark.slow
@pytest.mark.parametrize("name", ["sim1_zmp", "sim3_zmp"])
def test_contact_audit_of_the_feasible_gait_on_real_ground(hm: HumanoidModel, name: str) -> None:
    """The feasible gait on MuJoCo's ground, whole, judged at every MuJoCo step (the full-rate trace): the audit
    judges no step before contact (the first, 0 N: the one unloaded step) and no centre of pressure of a foot on its
    edge as outside (pivoting: 3-25 um past it; sliding on an edge at depth p: up to mu p, the stated tolerance of
    ``real_ground_edge_tol``), so no ZMP or CoP step is outside and none is infeasible; the settling is reported
    apart (its penetration, the transient of the soft contact taking the weight); the trailing feet's slides
    as they unload are listed."""
    from humanoid_sim.analysis.audit import EDGE_TOL_M
    from humanoid_sim.analysis.summary import real_ground_edge_tol, summary_and_audit
    from humanoid_sim.sim.simulate import Simulator

    sc = load_scenario(ROOT / "scripts" / "params" / f"{name}.yaml")
    sim = Simulator(hm, sc, engine="mujoco")
    res = sim.run()
    assert res.completed, res.reason
    s, report = summary_and_audit(res, sc, "mujoco", hm, res.phase_names)
    c = s["contact"]
    assert c["rate"]["source"] == "full-rate trace" and c["rate"]["rows"] == len(res.trace) > 9 * len(res.log)
    assert c["unloaded_steps"] == 1 and report.unloaded[0] and not report.unloaded[1:].any()
    assert c["zmp_outside_fraction"] == 0.0 and c["infeasible_fraction"] == 0.0
    assert c["cop_outside_fraction"] == {"R": 0.0, "L": 0.0}
    tol = real_ground_edge_tol(sc.contact.friction_coefficient, res.extra["ground"])
    assert c["edge_tolerance_m"] == tol and EDGE_TOL_M < tol < 5e-3
    assert min(c["min_cop_margin_m"].values()) >= -tol
    assert c["unloaded_below_N"] == pytest.approx(27.0, abs=0.1)
    settling, sliding = c["settling"], c["sliding"]
    # the robot starts at rest on z = 0 with no contact force: the soft contact takes its weight in a transient
    # about 1 mm deep with both soles flat, 7 times the 0.14 mm it then stands at (2.5 mm with the lead-in's
    # trailing foot on its toe, which also slid once)
    assert settling["ended"] and settling["penetration_max_m"] > 0.5e-3 and settling["sliding_count"] <= 1
    assert s["penetration_max_m"] < 5e-3 and s["foot_slip_max_m"] < 5e-3     # the walk's, after settling
    events = sliding["events"]
    assert sliding["count"] == len(events) >= 10                              # a slide per lift-off or so
    assert all(e["normal_min_N"] >= sliding["loaded_above_N"] == 20.0 for e in events)
    assert all(settling["window_s"] <= e["start_s"] < e["end_s"] <= res.sim_time for e in events)
    assert sliding["travel_max_m"] == max(e["travel_m"] for e in events) < 1e-3
    assert sliding["travel_total_m"] == pytest.approx(sum(e["travel_m"] for e in events), rel=1e-12)
