"""Issue 6 acceptance: Simulations 1-3 walk every planned phase within the tracking bounds; runs repeat exactly."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from humanoid_sim.analysis.summary import summarize
from humanoid_sim.scenario.schema import load_scenario
from humanoid_sim.sim.simulate import Simulator

pytestmark = pytest.mark.slow  # whole walks of Simulations 1-3 and a walk.py run

ROOT = Path(__file__).resolve().parents[2]
PARAMS = ROOT / "scripts" / "params"

# Acceptance bounds of the issue (hip CoM tracking against the planned reference at time t, m).
HIP_RMS_MAX = 0.015
HIP_MAX_MAX = 0.04
TOUCHDOWN_MAX = 0.03


@pytest.fixture(scope="module")
def runs(hm):
    out = {}
    for name in ("sim1", "sim2", "sim3"):
        sc = load_scenario(PARAMS / f"{name}.yaml")
        res = Simulator(hm, sc).run()
        out[name] = (res, summarize(res, sc.name, "pinocchio"))
    return out


@pytest.mark.parametrize("name, phases", [("sim1", 16), ("sim2", 24), ("sim3", 16)])
def test_simulation_walks_every_phase_within_bounds(runs, name, phases):
    res, s = runs[name]
    assert s["completed"], s["reason"]
    assert s["phases_planned"] == phases and s["phases_completed"] == phases
    assert s["hip_com_error_rms_m"] <= HIP_RMS_MAX
    assert s["hip_com_error_max_m"] <= HIP_MAX_MAX
    assert s["toe_touchdown_error_max_m"] <= TOUCHDOWN_MAX
    # Every phase ran in the thesis's cycle order and left no gap in time.
    names = [p["name"] for p in s["phase_log"]]
    assert names == (["LFFSSP", "RFFDSP", "RFFSSP", "LFFDSP"] * 6)[:phases]
    starts = [p["start"] for p in s["phase_log"]]
    ends = [p["end"] for p in s["phase_log"]]
    assert starts[0] == 0.0 and all(abs(a - b) < 1e-9 for a, b in zip(ends[:-1], starts[1:]))
    # The welds hold: Baumgarte-stabilised drift stays far below the touchdown tolerance (1 mm).
    assert s["constraint_drift_max_m"] < 1e-3
    # Saturation is reported per actuator, as a fraction of steps.
    assert set(s["saturated_fraction_per_actuator"]) == {f"T{k}" for k in range(1, 27)}
    assert 0.0 <= s["saturated_fraction"] <= 1.0


def test_physics_holds_along_the_walk(runs):
    """Along the whole sim-1 walk the dynamics residual stays at round-off and the feet carry the weight."""
    res, _ = runs["sim1"]
    a = res.log.arrays()
    # ||M a + h - tau - J^T lambda||_inf: a KKT solve in double precision, forces of order 1e3 N.
    assert a["dynamics_residual"].max() < 1e-8
    # Total vertical ground force averages the robot's weight (55.044 kg * 9.81): the CoM height is periodic, so
    # the mean vertical acceleration over the walk is ~0; 5 % allows for the net start/stop motion.
    fz = a["foot_wrench"][:, :, 2].sum(axis=1)
    assert abs(fz.mean() / (55.044 * 9.81) - 1.0) < 0.05


def test_two_runs_are_identical(hm):
    sc = load_scenario(PARAMS / "sim1.yaml")
    a = Simulator(hm, sc).run(t_end=1.2).log.arrays()
    b = Simulator(hm, sc).run(t_end=1.2).log.arrays()
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_walk_cli_writes_results_and_summary(tmp_path):
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "walk.py"), str(PARAMS / "sim1.yaml"), "--until",
                        "0.5", "--out", str(out), "--no-plots", "--no-html", "--quiet"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "summary.json").read_text())
    for key in ("scenario", "engine", "completed", "phases_planned", "phases_completed", "sim_time_s",
                "wall_time_s", "real_time_factor", "hip_com_error_rms_m", "hip_com_error_max_m",
                "hip_yaw_error_rms_rad", "toe_touchdown_error_max_m", "torque_peak_Nm", "saturated_fraction",
                "constraint_drift_max_m", "phase_log"):
        assert key in s, key
    assert s["engine"] == "pinocchio" and s["completed"] is False and abs(s["sim_time_s"] - 0.5) < 1e-9
    with np.load(out / "results.npz") as z:
        assert z["t"].shape == (50,) and z["theta"].shape == (50, 26)
        units = json.loads(str(z["signal_units"]))
        assert units["T"]["unit"] == "N m"


def test_projection_holds_the_support_foot_exactly(hm):
    """project_on_support puts the support foot's main body at its anchor with zero twist and its toe joint at
    the anchor angle with zero rate, and leaves the joint coordinates (other than the toe) untouched."""
    import pinocchio as pin

    from humanoid_sim.dynamics.contact import record_anchors
    from humanoid_sim.robot.phases import Phase

    sc = load_scenario(PARAMS / "sim1.yaml")
    sim = Simulator(hm, sc)
    rng = np.random.default_rng(4)
    q0 = sim.q0
    anchors = record_anchors(hm.model, q0, Phase.RFFSSP.contacts)
    q = pin.integrate(hm.model, q0, rng.normal(scale=0.05, size=hm.model.nv))
    v = rng.normal(size=hm.model.nv)
    qp, vp = sim.project_on_support(Phase.RFFSSP, anchors, q, v)
    d = hm.model.createData()
    pin.forwardKinematics(hm.model, d, qp, vp)
    pin.updateFramePlacements(hm.model, d)
    fid = hm.frame_id("O_3")
    # round-off of one SE(3) composition and a 6x6 solve
    assert d.oMf[fid].isApprox(anchors.placements["O_3"], 1e-12)
    assert np.abs(pin.getFrameVelocity(hm.model, d, fid).vector).max() < 1e-12
    i = hm.theta_index("theta3")
    assert hm.theta_from_q(qp)[i] == pytest.approx(hm.theta_from_q(q0)[i], abs=1e-15)
    assert hm.theta_dot_from_v(vp)[i] == 0.0
    others = [j for j in range(26) if j != i]
    np.testing.assert_array_equal(hm.theta_from_q(qp)[others], hm.theta_from_q(q)[others])
    np.testing.assert_array_equal(hm.theta_dot_from_v(vp)[others], hm.theta_dot_from_v(v)[others])
