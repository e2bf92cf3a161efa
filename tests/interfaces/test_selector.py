"""The shared phase selector: failure checks and phase bookkeeping (thesis 6.1.1)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from humanoid_sim.interfaces.selector import DIVERGED_RATE, PhaseSelector, SimulationError
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.robot.phases import SwitchThresholds
from humanoid_sim.scenario.schema import SimulationSettings, load_scenario

SIM1 = Path(__file__).resolve().parents[2] / "scripts" / "params" / "sim1.yaml"


@pytest.fixture()
def sel():
    sc = load_scenario(SIM1)
    traj = ReferenceTrajectory(sc.path)
    return PhaseSelector(traj, SwitchThresholds(), SimulationSettings(fall_height_m=0.5, max_phase_overtime=2.0),
                         np.array(sc.path.toe_R0))


def test_failure_checks_name_the_cause(sel):
    ok = np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 0.9])
    sel.check_state(0.1, *ok)  # a healthy state passes
    with pytest.raises(SimulationError, match=r"non-finite state at t = 0.100 s in phase 1 \(LFFSSP\)"):
        sel.check_state(0.1, np.array([np.nan]), np.zeros(3), ok[2])
    with pytest.raises(SimulationError, match=r"diverged at t = 0.100 s .* velocity component 2 is -150"):
        sel.check_state(0.1, np.zeros(3), np.array([0.0, 1.0, -1.5 * DIVERGED_RATE]), ok[2])
    with pytest.raises(SimulationError, match=r"fall: hip CoM height 0.400 m below 0.5 m"):
        sel.check_state(0.1, np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 0.4]))
    # the first SSP is nominally 0.8 s long: 2 x 0.8 = 1.6 s is the limit
    sel.check_state(1.6, *ok)
    with pytest.raises(SimulationError, match=r"phase 1 \(LFFSSP\) has lasted 1.61 s, more than 2 x its nominal "
                                              r"0.800 s \(the swing foot never touched down\)"):
        sel.check_state(1.61, *ok)


def test_phase_bookkeeping(sel):
    toe_end = sel.targets.swing_toe_end
    assert sel.info.swing_foot == "R" and not sel.is_last
    # toe still high: no touchdown; toe down at its planned end: touchdown
    assert not sel.should_switch(0.5, np.zeros(3), toe_end + [0, 0, 0.05])
    assert sel.should_switch(0.78, np.zeros(3), toe_end)
    key = sel.record_touchdown(toe_end + [0.003, 0.004, 0.0], np.eye(3))
    assert key == "Wadj_qdot_LFFSSP_to_RFFDSP"
    assert sel.records[0].touchdown_error_m == pytest.approx(0.005, abs=1e-12)  # 3-4-5 triangle, mm
    assert sel.records[0].landing_tilt_rad == 0.0
    sel.end_phase(0.78)
    sel.advance(0.78, None)
    assert (sel.k, sel.phase.value, sel.records[1].t_start) == (1, "RFFDSP", 0.78)
    # a DSP ends once it has lasted 1.1 t_DSP even with the hip far from its target
    far = sel.targets.hip_p_end + [1.0, 0.0, 0.0]
    t_dsp = sel.info.duration
    assert not sel.should_switch(0.78 + t_dsp, far, None)
    assert sel.should_switch(0.78 + 1.1 * t_dsp + 0.01, far, None)
    sel.close(0.9)
    assert sel.records[-1].t_end == 0.9


def test_the_plans_delay_counts_late_touchdowns_only(sel):
    """``plan_delay``: a double support (a touchdown) that starts late delays the plan's clock by its lateness; an
    early one does not move it forward; a later, smaller lateness keeps the larger delay; a single support's start
    (on the step grid, up to half a step after its planned end) counts for nothing.  Times from the sim 1 schedule."""
    ph = sel.traj.phases
    assert ph[0].swing_foot is not None and ph[1].swing_foot is None     # sim 1: LFFSSP, RFFDSP, RFFSSP, ...
    expected = 0.0
    for k, lateness in ((1, -0.02), (2, 0.004), (3, 0.07), (4, 0.075), (5, 0.05), (6, 0.004), (7, 0.2)):
        sel.advance(ph[k].t_start + lateness, None)
        assert sel.k == k
        if ph[k].swing_foot is None:
            expected = max(expected, lateness)
        assert sel.plan_delay == pytest.approx(expected, abs=1e-12)
    assert expected == 0.2


def test_messages_name_the_joint_and_its_body(hm):
    """With the model's names, a diverging or non-finite component is named as its thesis angle and body (v index
    21 is theta9, the right shank's angle, body 9), a base component by what it is."""
    from humanoid_sim.interfaces.selector import CoordinateNames

    sc = load_scenario(SIM1)
    names = CoordinateNames.of(hm)
    sel = PhaseSelector(ReferenceTrajectory(sc.path), SwitchThresholds(),
                        SimulationSettings(fall_height_m=0.5, max_phase_overtime=2.0), np.array(sc.path.toe_R0), names)
    i9 = int(hm.theta_v_idx[list(hm.spec.theta_order).index("theta9")])
    assert names.v[i9] == "theta9 (right shank, body 9)" and names.v[0] == "base linear velocity x"
    assert names.v[5] == "base angular velocity z" and names.q[6] == "base quaternion w"
    q = np.zeros(hm.model.nq)
    v = np.zeros(hm.model.nv)
    v[i9] = -3.91e9
    with pytest.raises(SimulationError, match=r"velocity component theta9 \(right shank, body 9\) is -3.91e\+09"):
        sel.check_state(0.03, q, v, np.array([0.0, 0.0, 0.9]))
    v[:] = 0.0
    v[1] = np.nan
    with pytest.raises(SimulationError, match=r"\(integration stage 2\) .*velocity component base linear velocity y "
                                              r"is nan"):
        sel.check_stage(0.03, q, v, 2)
    a = np.zeros(hm.model.nv)
    a[i9] = np.inf
    with pytest.raises(SimulationError, match=r"acceleration component theta9 \(right shank, body 9\) is inf"):
        sel.check_acceleration(0.03, a)
    th = np.zeros(26)                       # the oracle engine's stage states are thesis angles
    th[list(hm.spec.theta_order).index("theta17r")] = np.nan
    with pytest.raises(SimulationError, match=r"position component theta17r \(lower trunk, body 17\) is nan"):
        sel.check_stage(0.03, th, np.zeros(26), 0)


def test_an_early_touchdown_the_controller_planned_runs_the_plan_ahead(sel):
    """``advance(..., jump)`` (a swing the controller shortened): the plan's clock moves on by up to ``jump``
    toward the double support's start (plan_delay < 0), no further; a later late touchdown delays it again.  A
    double support on schedule that started early may last until its planned end without tripping the overtime
    check."""
    ph = sel.traj.phases
    sel.advance(ph[1].t_start - 0.13, None, jump=0.5)        # the whole 0.13 s, not beyond the start
    assert sel.plan_delay == pytest.approx(-0.13, abs=1e-12)
    sel.advance(ph[2].t_start, None)
    sel.advance(ph[3].t_start - 0.13 - 0.2, None, jump=0.1)  # 0.2 s early again: the clock moves on 0.1 s
    assert sel.plan_delay == pytest.approx(-0.23, abs=1e-12)
    sel.advance(ph[4].t_start + 0.05, None)          # an SSP start counts for nothing
    sel.advance(ph[5].t_start + 0.02, None)          # a late touchdown: the clock waits again
    assert sel.plan_delay == pytest.approx(0.02, abs=1e-12)
    sel.advance(ph[6].t_start, None)
    sel.advance(ph[7].t_start - 0.2, None)           # early, not planned: the plan waits (delay kept)
    assert sel.plan_delay == pytest.approx(0.02, abs=1e-12)
    sel.dsp_on_schedule = True
    ok = np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 0.9])
    # 2 x the phase's own duration has passed, but its planned end (plan clock) is later: no overtime yet
    t_dsp = ph[7].duration
    assert 0.2 + t_dsp > 2.0 * t_dsp > 0.2
    sel.check_state(ph[7].t_start - 0.2 + 2.0 * t_dsp + 1e-3, *ok)
    # the planned end: 0.2 s early plus the 0.02 s delay plus the phase, times max_phase_overtime 2
    with pytest.raises(SimulationError, match=rf"has lasted .* nominal {0.2 + 0.02 + t_dsp:.3f} s"):
        sel.check_state(ph[7].t_start - 0.2 + 2.0 * (0.2 + t_dsp + 0.02) + 1e-3, *ok)
