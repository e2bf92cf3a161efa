"""summary.json's numbers (humanoid_sim.analysis.summary.summarize) from a log whose statistics are known by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from humanoid_sim.analysis.summary import summarize
from humanoid_sim.interfaces.log import SIGNALS, SimLog
from humanoid_sim.interfaces.selector import PhaseRecord
from humanoid_sim.robot.actuators import T_NAMES
from humanoid_sim.sim.loop import SimResult

N = 4


def _log() -> SimLog:
    cols = {k: np.zeros(N) for k in SIGNALS}
    cols["hip_p_ref"] = np.zeros((N, 3))
    cols["hip_p"] = np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0], [0, 0, 0]], dtype=float)   # |e| = 0, 3, 4, 0
    cols["hip_p_ctrl_ref"] = cols["hip_p"] - np.array([[1, 0, 0]] * N, dtype=float)        # |e_ctrl| = 1 always
    cols["hip_yaw_ref"] = np.full(N, 2.0)
    cols["hip_yaw"] = 2.0 + np.array([0.1, -0.1, 0.1, -0.1])
    cols["T"] = np.zeros((N, 26))
    cols["T"][:, 0] = [1.0, -7.0, 3.0, 2.0]
    cols["T"][:, 25] = [0.5, 0.25, -0.75, 0.0]
    cols["T_cmd"] = 2 * cols["T"]
    cols["saturated"] = np.zeros((N, 26), dtype=bool)
    cols["saturated"][1, 3] = cols["saturated"][2, 3] = cols["saturated"][2, 5] = True
    cols["drift_position"] = np.array([1e-9, 3e-9, 2e-9, 0.0])
    cols["drift_orientation"] = np.array([0.0, 0.0, 5e-8, np.nan])   # a non-finite maximum is reported as null
    return SimLog.from_columns(cols)


def _result(**kw) -> SimResult:
    phases = [PhaseRecord(0, "LFFSSP", 0.0, 0.8, 0.0, 0.8, touchdown_error_m=0.01),
              PhaseRecord(1, "RFFDSP", 0.8, 1.0, 0.8, 1.0),
              PhaseRecord(2, "RFFSSP", 1.0, 1.2, 1.0, 1.8, touchdown_error_m=0.03)]
    args = dict(log=_log(), phases=phases, phases_planned=16, completed=False, reason="stopped", sim_time=1.2,
                wall_time=0.4, steps=N, stage_evaluations=12, extra={})
    args.update(kw)
    return SimResult(**args)


def test_tracking_torque_and_drift_statistics() -> None:
    s = summarize(_result(), "unit", "pinocchio")
    assert s["hip_com_error_rms_m"] == pytest.approx(np.sqrt((9 + 16) / 4))   # 2.5 m
    assert s["hip_com_error_max_m"] == pytest.approx(4.0)
    assert s["hip_com_error_vs_controller_reference_rms_m"] == pytest.approx(1.0)
    assert s["hip_yaw_error_rms_rad"] == pytest.approx(0.1)
    assert len(T_NAMES) == 26
    assert s["torque_peak_Nm"][T_NAMES[0]] == 7.0 and s["torque_peak_Nm"][T_NAMES[25]] == 0.75
    assert s["torque_cmd_peak_Nm"][T_NAMES[0]] == 14.0 and s["torque_peak_Nm"][T_NAMES[1]] == 0.0
    assert s["saturated_fraction"] == 0.5                        # rows 1 and 2 of 4 have a clipped actuator
    assert s["saturated_fraction_per_actuator"][T_NAMES[3]] == 0.5
    assert s["saturated_fraction_per_actuator"][T_NAMES[5]] == 0.25
    assert s["constraint_drift_max_m"] == 3e-9
    assert s["constraint_drift_max_rad"] is None
    json.dumps(s, allow_nan=False)                               # a strict-JSON document


def test_run_bookkeeping() -> None:
    s = summarize(_result(), "unit", "pinocchio")
    assert (s["scenario"], s["engine"], s["completed"], s["reason"], s["steps"]) == \
        ("unit", "pinocchio", False, "stopped", N)
    assert s["phases_planned"] == 16
    assert s["phases_completed"] == 2               # the last phase was cut short by the stop: not completed
    assert s["real_time_factor"] == pytest.approx(3.0)  # 1.2 s simulated in 0.4 s
    assert s["toe_touchdown_error_max_m"] == 0.03
    assert [p["phase"] for p in s["phase_log"]] == [1, 2, 3]
    assert s["phase_log"][2]["nominal_end"] == 1.8 and s["phase_log"][1]["touchdown_error_m"] is None
    assert "compiled_stages" not in s and "fell" not in s
    assert summarize(_result(completed=True), "u", "p")["phases_completed"] == 3
    assert summarize(_result(wall_time=0.0), "u", "p")["real_time_factor"] is None


def test_kernel_counts_and_ground_measures() -> None:
    ground = {"fell": True, "fall_time_s": 0.9, "fall_reason": "left foot tipped", "foot_slip_max_m": 0.02,
              "foot_tilt_max_rad": 0.1, "stance_tilt_max_rad": 0.05, "penetration_max_m": 0.001,
              "control_period_s": 0.002}
    s = summarize(_result(extra={"compiled_stages": 9, "ground": ground}), "u", "mujoco")
    assert s["compiled_stages"] == 9 and s["reference_stages"] == 12 - 9
    assert s["fell"] is True and s["fall_reason"] == "left foot tipped" and s["foot_slip_max_m"] == 0.02
    assert s["control_period_s"] == 0.002


def test_an_empty_log_has_no_statistics() -> None:
    s = summarize(_result(log=SimLog(), steps=0), "u", "p")
    assert "hip_com_error_rms_m" not in s and s["steps"] == 0


def _contact(margin_R: float, pull: float = 0.0, friction: float = 0.0) -> dict:
    return {"steps": 10, "friction_coefficient": 0.8, "pulling_fraction": {"R": pull, "L": 0.0},
            "friction_exceeded_fraction": {"R": friction, "L": 0.0}, "min_cop_margin_m": {"R": margin_R, "L": 0.02},
            "cop_outside_fraction": {"R": 0.5 if margin_R < 0 else 0.0, "L": 0.0}}


def test_the_feasibility_verdict_reads_the_audit_with_its_edge_tolerance() -> None:
    from humanoid_sim.analysis.summary import EDGE_VERDICT_TOL_M, feasibility

    assert feasibility({"contact": _contact(0.01)}) == {
        "feasible": True, "feasibility_reason": "every ground reaction inside its sole and friction cone"}
    # a foot pivoting on its edge: just past it, inside the stated tolerance
    assert feasibility({"contact": _contact(-0.5 * EDGE_VERDICT_TOL_M)})["feasible"] is True
    v = feasibility({"contact": _contact(-0.272)})
    assert v["feasible"] is False and "foot R's centre of pressure lies outside its sole in 50 %" in \
        v["feasibility_reason"] and "up to 272 mm" in v["feasibility_reason"]
    assert "pulls on the ground in 20 %" in feasibility({"contact": _contact(0.01, pull=0.2)})["feasibility_reason"]
    assert "more friction than mu = 0.8 in 10 %" in \
        feasibility({"contact": _contact(0.01, friction=0.1)})["feasibility_reason"]
    # real ground: feasible unless it fell, whatever the (soft-contact) audit says
    assert feasibility({"fell": True, "fall_reason": "foot R rolled", "contact": _contact(-0.3)}) == {
        "feasible": False, "feasibility_reason": "fell on real ground: foot R rolled"}
    assert feasibility({"fell": False, "contact": _contact(-0.3)})["feasible"] is True
    assert feasibility({"contact": {"error": "bad log"}})["feasible"] is None


# --------------------------------------------------------------------------------------------- provenance
def test_provenance_says_what_made_the_run():
    import datetime

    import numpy

    import humanoid_sim
    from humanoid_sim.analysis.summary import PROVENANCE_PACKAGES, provenance

    p = provenance(["walk.py", "--until", "1"])
    assert set(p) == {"version", "git_commit", "packages", "date", "command"}
    assert p["version"] == humanoid_sim.__version__
    assert p["git_commit"] is None or (isinstance(p["git_commit"], str) and len(p["git_commit"]) == 40)
    assert tuple(p["packages"]) == PROVENANCE_PACKAGES == ("pin", "mujoco", "numpy", "numba", "scipy")
    assert p["packages"]["numpy"] == numpy.__version__
    assert all(v is None or isinstance(v, str) for v in p["packages"].values())
    date = datetime.datetime.fromisoformat(p["date"])
    assert date.utcoffset() == datetime.timedelta(0)
    assert p["command"] == ["walk.py", "--until", "1"]
    assert provenance("python API: run_walk('sim1')")["command"] == "python API: run_walk('sim1')"
    assert json.loads(json.dumps(p)) == p


def test_git_commit_is_none_outside_a_checkout_or_without_git(tmp_path, monkeypatch):
    from humanoid_sim.analysis.summary import git_commit

    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path.parent))
    assert git_commit(tmp_path) is None                       # not a git checkout
    monkeypatch.setenv("PATH", str(tmp_path))                 # no git on PATH
    assert git_commit() is None
