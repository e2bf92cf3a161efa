"""The designer's numbers against independent computations: Pinocchio's inverse dynamics on the logged motion, an
independent recording of every MuJoCo step, the work-energy theorem, and rainflow counts of series whose cycles
are known."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import humanoid_sim as hs
from humanoid_sim.analysis.design import rainflow_table, walk_distance
from humanoid_sim.dynamics.joint_loads import fext_from_body_wrenches
from humanoid_sim.engines.mujoco.sim import MujocoSim


def _rnea_gap(run: hs.Run, columns: dict, stride: int = 1) -> tuple[float, float]:
    """Largest |RNEA(q, v, a, logged ground wrenches) - logged tau| over the joints, and over the free base (whose
    generalized force must be zero: nothing actuates it), N m / N."""
    model = run.hm.model
    data = model.createData()
    fext = fext_from_body_wrenches(model, columns["body_force"], columns["body_moment"])
    joints = base = 0.0
    for i in range(0, len(columns["t"]), stride):
        tau = pin.rnea(model, data, columns["q"][i], columns["v"][i], columns["a"][i],
                       [pin.Force(f) for f in fext[i]])
        joints = max(joints, float(np.abs(tau[6:] - columns["tau"][i, 6:]).max()))
        base = max(base, float(np.abs(tau[:6]).max()))
    return joints, base


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["sim1", "sim3", "sim1_zmp", "sim3_zmp"])
def test_logged_torques_are_what_the_motion_and_ground_require_on_welds(scenario: str) -> None:
    """Inverse dynamics of the logged motion under the logged ground wrenches returns the logged joint torques.
    1e-6 N m: the weld engine's contact solution is exact up to round-off (measured: 4e-11 on the thesis gait,
    4e-13 on the zmp gait); a toe torque absorbed by the lock and not given to the ground would miss by ~22 N m."""
    run = hs.run_walk(scenario, verbose=False)
    joints, base = _rnea_gap(run, run.log)
    print(f"{scenario}: joints {joints:.2e} N m, base {base:.2e}")
    assert joints <= 1e-6 and base <= 1e-6


@pytest.mark.slow
def test_mujoco_full_rate_peaks_and_inverse_dynamics() -> None:
    """sim3_zmp on MuJoCo.  (1) An independent recording of every MuJoCo step (MuJoCo's own contact forces through
    ``mj_contactForce`` and its knee motor's force, read after each ``mj_step``) has the same maxima as the summary:
    peak total vertical ground force (design section: the walk's and the start-up settling's) and peak knee torque
    T9 (torque_peak_Nm), to 1e-9 relative (the same numbers read two ways: round-off).  (2) Inverse dynamics of the
    full-rate trace closes on the joints to 1e-2 N m: MuJoCo's soft-contact solver leaves a residual in its own
    equations of motion (measured 3.4e-3 N m; the weld engine's is 1e-11)."""
    seen = {"fz": [], "knee": []}
    advance = MujocoSim.advance

    def recording_advance(self: MujocoSim, n: int) -> None:
        for _ in range(n):
            advance(self, 1)
            m, d = self.model, self.data
            fz = 0.0
            f6 = np.zeros(6)
            for c in range(d.ncon):
                con = d.contact[c]
                mujoco.mj_contactForce(m, d, c, f6)
                fz += float((con.frame.reshape(3, 3).T @ f6[:3])[2])
            seen["fz"].append(fz)
            knee = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "theta11")
            seen["knee"].append(abs(float(d.actuator_force[knee])))

    mp = pytest.MonkeyPatch()
    mp.setattr(MujocoSim, "advance", recording_advance)
    try:
        run = hs.run_walk("sim3_zmp", engine="mujoco", verbose=False)
    finally:
        mp.undo()
    assert run.status.value == "completed"
    design = run.summary["design"]
    fz_summary = max(design["walk"]["ground_force_vertical_peak_N"], design["settling"]["ground_force_vertical_peak_N"])
    print("peak Fz: summary", fz_summary, "recorded", max(seen["fz"]), "over", len(seen["fz"]), "steps;",
          "knee: summary", run.summary["torque_peak_Nm"]["T9"], "recorded", max(seen["knee"]))
    assert len(seen["fz"]) == len(run.result.trace)
    assert fz_summary == pytest.approx(max(seen["fz"]), rel=1e-9)
    assert run.summary["torque_peak_Nm"]["T9"] == pytest.approx(max(seen["knee"]), rel=1e-9)
    assert fz_summary > 1.05 * float(run.log["foot_wrench"][:, :, 2].sum(axis=1).max())   # the 10 ms log misses it
    joints, base = _rnea_gap(run, run.result.trace.columns, stride=2)
    print(f"MuJoCo trace inverse dynamics: joints {joints:.2e} N m, base {base:.2e}")
    assert joints <= 1e-2 and base <= 1e-2


@pytest.mark.slow
def test_joint_work_equals_the_change_of_mechanical_energy_in_single_support() -> None:
    """Work-energy theorem on welds (the welded foot does no work, nothing else acts but gravity): over a single
    support of the thesis gait, the sum of every joint's work (the design card's power, integrated by the card's
    trapezoidal rule) equals the change of kinetic plus potential energy (Pinocchio's).  1 % of the energy swing:
    the trapezoidal rule's error at 10 ms steps (measured 0.04 %; holding each step's power instead misses by 17 %).
    The card's walk totals are the same integral over the whole run."""
    run = hs.run_walk("sim1", verbose=False, until=3.0)
    log, card = run.log, run.design
    assert card is not None
    model, data = run.hm.model, run.hm.model.createData()
    phase = log["phase"]
    ssp = [k for k in np.unique(phase) if run.result.phase_names[k].endswith("SSP")]
    k = ssp[1]
    rows = np.flatnonzero(phase == k)
    i0, i1 = rows[2], rows[-2]

    def energy(i: int) -> float:
        q, v = log["q"][i], log["v"][i]
        kinetic = 0.5 * v @ pin.crba(model, data, q) @ v
        potential = -pin.computeTotalMass(model) * model.gravity.linear @ pin.centerOfMass(model, data, q)
        return float(kinetic + potential)

    dt = card.rates["trace_period_s"]
    power = card.series["power"].sum(axis=1)
    work = float(dt * (power[i0:i1 + 1].sum() - 0.5 * (power[i0] + power[i1])))
    swing = max(abs(energy(i) - energy(i0)) for i in range(i0, i1 + 1))
    print(f"phase {run.result.phase_names[k]}: joint work {work:.3f} J, energy change {energy(i1) - energy(i0):.3f} J, "
          f"swing {swing:.3f} J")
    assert abs(work - (energy(i1) - energy(i0))) <= 0.01 * max(swing, 1.0)
    net = card.walk["work_positive_J"] + card.walk["work_negative_J"]
    assert net == pytest.approx(float(np.trapezoid(power, dx=dt)), rel=1e-9, abs=1e-9)


def test_rainflow_counts_known_cycles() -> None:
    """A series of 50 full cycles of range 4 and 10 of range 1 (a small cycle inside each of 10 big ones): ASTM
    E1049 counts 50 cycles in the top bin and 10 in the bin holding range 1 (exact counts); per_km scales them."""
    big = np.tile([0.0, 4.0], 50)
    series = np.concatenate([big, [0.0]])
    for i in range(10):                       # a 2 -> 1 -> 2 excursion on the way up of cycle i
        j = 1 + 4 * i
        series = np.insert(series, j, [2.0, 1.0])
    table = rainflow_table(series, per_km=2.0, bins=4)
    assert [round(lo, 9) for lo, _, _ in table] == [0.0, 1.0, 2.0, 3.0]
    counts = [n / 2.0 for _, _, n in table]
    assert counts[3] == pytest.approx(50.0) and counts[1] == pytest.approx(10.0) and counts[0] == 0.0
    assert rainflow_table(np.zeros(20), per_km=1.0) == []


def test_walk_distance_follows_the_footholds_not_the_sway() -> None:
    """Toe points stepping 0.2 m forward per phase while swaying sideways: the distance is the forward travel of
    their midpoint (three steps: 0.6 m), whatever the lateral offsets."""
    n_phase, per = 4, 5
    phase = np.repeat(np.arange(n_phase), per)
    y = np.repeat(0.2 * np.arange(n_phase), per)
    sway = 0.05 * np.sin(np.arange(len(y)))
    log = {"t": np.arange(len(y)) * 0.01, "phase": phase,
           "toe_R_p": np.stack([0.1 + sway, y, 0 * y], axis=1), "toe_L_p": np.stack([-0.1 - sway, y, 0 * y], axis=1)}
    assert walk_distance(log) == pytest.approx(0.6)   # midpoints at phase changes: 0, 0.2, 0.4, 0.6 m
