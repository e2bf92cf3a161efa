"""Rows of a sweep (humanoid_sim/sweep/walk.py, table.py): a walk's summary flattened into columns without losing
a number, RMS torques against an independent formula, the Parquet and CSV files giving back the exact numbers,
and the sink that writes them as rows arrive.  One short walk in-process, no Dask."""

from __future__ import annotations

import copy
import csv
import json
import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml

from humanoid_sim.robot.actuators import T_NAMES
from humanoid_sim.sweep.table import CSV, PARQUET, TableSink, column_order, read_rows, write_table
from humanoid_sim.sweep.walk import flatten_summary, run_walk, torque_rms, walk_row

ROOT = Path(__file__).resolve().parents[2]
SIM3 = yaml.safe_load((ROOT / "scripts" / "params" / "sim3.yaml").read_text())


@pytest.fixture(scope="module")
def short_walk() -> tuple[dict, dict]:
    """sim3 cut at 0.8 s (one single support, the first touchdown): its document and run_walk's summary."""
    doc = copy.deepcopy(SIM3)
    doc["simulation"]["t_end_s"] = 0.8
    return doc, run_walk(doc, "pinocchio")


def _leaves(d: dict, prefix: str = ""):
    """(column name, value) of every scalar leaf, names joined with '_' (the documented flattening rule)."""
    for k, v in d.items():
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            yield from _leaves(v, name + "_")
        elif not isinstance(v, list):
            yield name, v


def test_flattening_keeps_every_summary_number(short_walk):
    doc, summary = short_walk
    cols = flatten_summary(summary)
    expected = {}
    for k, v in summary.items():
        if k in ("scenario", "engine", "completed", "status", "reason", "phase_log", "provenance"):
            continue
        if k == "contact":
            v = {ck: cv for ck, cv in v.items() if ck != "per_phase"}
        expected.update(_leaves({k: v}))
    expected["all_phases_completed"] = summary["completed"]
    assert cols == expected
    # the columns the issue asks for
    for name in T_NAMES:
        assert cols[f"torque_peak_Nm_{name}"] == summary["torque_peak_Nm"][name]
        assert cols[f"torque_rms_Nm_{name}"] == summary["torque_rms_Nm"][name]
    for key in ("hip_com_error_rms_m", "hip_yaw_error_rms_rad", "saturated_fraction", "contact_infeasible_fraction",
                "contact_cop_outside_fraction_R", "contact_friction_exceeded_fraction_L",
                "contact_zmp_outside_fraction", "design_walk_work_positive_J",
                "design_joints_theta11_speed_peak_rad_s", "design_joints_theta3_power_peak_W", "wall_time_s"):
        assert key in cols


def test_walk_row_status_of_a_walk_cut_at_its_stop_time(short_walk):
    doc, summary = short_walk
    out = walk_row(doc, "pinocchio")
    row = out["row"]
    assert summary["reason"] == "stopped at t = 0.800 s (requested stop time)"
    assert row["completed"] is True and row["all_phases_completed"] is False   # cut short on purpose: completed
    assert row["failure_kind"] is None and row["failure_time_s"] is None
    assert row["task_wall_time_s"] > 0 and row["worker"].endswith(f":{__import__('os').getpid()}")
    # deterministic, except when and how long it ran (the run's provenance records its date)
    when = ("wall_time_s", "real_time_factor", "provenance")
    assert {k: v for k, v in out["summary"].items() if k not in when} == \
           {k: v for k, v in summary.items() if k not in when}


def test_walk_row_of_failures():
    bad = copy.deepcopy(SIM3)
    bad["simulation"]["t_end_s"] = 1.5
    for k, v in bad["controller"].items():   # no hip (Body-17) tracking: diverges at the first touchdown
        if k.startswith(("Wp_fa_", "Wv_fa_", "Wor_fa_")):
            bad["controller"][k] = [0] * len(v)
    row = walk_row(bad, "pinocchio")["row"]
    assert row["completed"] is False and row["failure_kind"] == "simulation"
    assert row["reason"].startswith(("diverged at t = ", "fall: hip CoM height"))
    assert 0.5 < row["failure_time_s"] < 1.5
    assert row["failure_time_s"] == pytest.approx(float(row["reason"].split("at t = ")[1].split(" s")[0]), abs=1e-3)
    broken = copy.deepcopy(SIM3)
    broken["path"]["SW"] = "wide"
    res = walk_row(broken, "pinocchio", "test")
    assert res["summary"] is None and res["row"]["failure_kind"] == "exception"
    assert res["row"]["reason"].startswith("ScenarioError: test: path.SW: expected a list of 8")
    assert walk_row(SIM3, "bullet")["row"]["reason"] == ("ValueError: engine: 'bullet' is not one of "
                                                         "pinocchio, thesis, mujoco")


def test_torque_rms_against_the_norm():
    rng = np.random.default_rng(0)
    T = rng.normal(0, 50, (641, 26))
    # ||T_i||_2 / sqrt(N) is the RMS by another route (LAPACK-style scaled norm, other summation order):
    # agreement to a few ulps, 1e-14 relative
    np.testing.assert_allclose(torque_rms(T), np.linalg.norm(T, axis=0) / math.sqrt(len(T)), rtol=1e-14)
    assert torque_rms(np.full((4, 26), -3.0)).tolist() == [3.0] * 26   # |constant| exactly
    assert np.all(np.isnan(torque_rms(np.zeros((0, 26)))))


# --------------------------------------------------------------------------------------------- files
def test_parquet_and_csv_give_back_the_exact_rows(tmp_path):
    rows = [
        {"walk": 1, "scenario_hash": "b" * 16, "engine": "pinocchio", "path.SW": 0.3, "completed": True,
         "status": "completed", "failure_kind": None, "reason": 'all 16 phases, "quoted", with, commas',
         "failure_time_s": None,
         "x": 1 / 3, "tiny": 5e-324, "steps": 641},
        {"walk": 0, "scenario_hash": "a" * 16, "engine": "pinocchio", "path.SW": 0.28, "completed": False,
         "status": "failed", "failure_kind": "simulation", "reason": "diverged", "failure_time_s": 0.75,
         "only_here": "yes"},
    ]
    write_table(rows, tmp_path, ["path.SW"])
    cols = column_order(rows, ["path.SW"])
    assert cols[:9] == ["walk", "scenario_hash", "engine", "path.SW", "completed", "status", "failure_kind", "reason",
                        "failure_time_s"]
    back = read_rows(tmp_path)
    assert back == [{c: r.get(c) for c in cols} for r in rows]   # absent cells are nulls, floats bit for bit
    assert pq.read_table(tmp_path / PARQUET).schema.field("steps").type == "int64"
    with open(tmp_path / CSV, newline="") as fh:
        text_rows = list(csv.DictReader(fh))
    assert list(text_rows[0]) == cols
    for r, t in zip(rows, text_rows):
        for c in ("x", "tiny", "failure_time_s", "path.SW"):
            if r.get(c) is not None:
                assert float(t[c]) == r[c]   # shortest round-trip text: the same double
        assert t["reason"] == r["reason"] and t["completed"] == str(r["completed"]).lower()
    assert not list(tmp_path.glob(".*.tmp"))   # atomic writes leave no temporaries


def test_a_process_that_read_a_table_exits_cleanly(tmp_path):
    """A command that only reads a table (a resumed sweep with nothing left to run) exits with status 0.  Reading
    through a Python buffer made about 70 % of such processes abort at interpreter exit ("terminate called without
    an active exception": one of Arrow's threads released the buffer after the interpreter had stopped): twelve
    fresh interpreters all exiting cleanly would happen by chance once in ~1e6 with that defect."""
    import subprocess
    import sys

    write_table([{"walk": 0, "scenario_hash": "a" * 16, "engine": "pinocchio", "completed": True, "x": 0.5}],
                tmp_path, [])
    code = ("import sys; from pathlib import Path; from humanoid_sim.sweep.table import read_rows; "
            "assert read_rows(Path(sys.argv[1]))[0]['x'] == 0.5")
    codes = [subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True)
             for _ in range(12)]
    assert [c.returncode for c in codes] == [0] * 12, [c.stderr for c in codes if c.returncode]


def test_sink_writes_as_rows_arrive_and_sorts_this_sweeps_rows_first(tmp_path):
    now = {"t": 0.0}
    old = {"walk": 7, "scenario_hash": "f" * 16, "engine": "pinocchio", "completed": True}
    sink = TableSink(tmp_path, [old], ["p"], current={("a" * 16, "pinocchio"), ("b" * 16, "pinocchio")},
                     interval=1.0, clock=lambda: now["t"])

    def row(walk: int, h: str, completed: bool) -> dict:
        return {"walk": walk, "scenario_hash": h * 16, "engine": "pinocchio", "p": walk / 10, "completed": completed}

    sink.add(row(1, "b", False))            # the first row is written at once
    assert [r["walk"] for r in read_rows(tmp_path)] == [1, 7]
    now["t"] = 0.5
    sink.add(row(0, "a", True))              # within the interval: held
    assert len(read_rows(tmp_path)) == 2
    now["t"] = 1.6
    sink.add(row(1, "b", True))              # replaces walk 1's row; due: written
    back = read_rows(tmp_path)
    assert [(r["walk"], r["completed"]) for r in back] == [(0, True), (1, True), (7, True)]
    sink.add(row(0, "a", False))
    sink.flush()
    assert read_rows(tmp_path)[0]["completed"] is False
    assert json.loads(json.dumps(read_rows(tmp_path)))  # plain values


# --------------------------------------------------------------------------------------------- figures
def test_feasibility_cells_count_and_average_by_hand(tmp_path):
    from humanoid_sim.sweep.plots import feasibility_cells, plot_feasibility, plot_sizing
    from humanoid_sim.sweep.spec import load_sweep

    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"base": str(ROOT / "scripts" / "params" / "sim3.yaml"),
                                     "grid": {"path.Vhip": {"scale": [0.9, 1.1]}, "path.SW": [0.28, 0.3, 0.32],
                                              "path.SH": [0.07, 0.08]}}, sort_keys=False))
    spec = load_sweep(sweep)
    walks = spec.expand()
    rows = []
    for w in walks:   # walk k: completed unless k % 3 == 0; saturated fraction k / 100; one audit missing
        rows.append({**w.params, "walk": w.index, "completed": w.index % 3 != 0,
                     "saturated_fraction": w.index / 100, "contact_infeasible_fraction": None if w.index == 4 else 0.5})
    xs, ys, n, ok, (sat, inf) = feasibility_cells(rows, *spec.axes[:2])
    assert xs == [0.9, 1.1] and ys == [0.28, 0.3, 0.32]
    # cell (x, y) pools the two path.SH walks: indices 6 i + 2 j and 6 i + 2 j + 1
    for i in range(2):
        for j in range(3):
            ks = [6 * i + 2 * j, 6 * i + 2 * j + 1]
            done = [k for k in ks if k % 3 != 0]
            assert n[j, i] == 2 and ok[j, i] == len(done)
            assert sat[j, i] == pytest.approx(np.mean([k / 100 for k in done]), abs=1e-15)   # mean of 1-2 values
            has = [k for k in done if k != 4]
            assert (np.isnan(inf[j, i]) and not has) or inf[j, i] == 0.5
    plot_feasibility(rows, spec.axes, tmp_path / "grid.png")
    plot_feasibility(rows, spec.axes[:1], tmp_path / "one_axis.png")
    plot_sizing([], T_NAMES, [1.0] * 26, tmp_path / "none.png")   # no completed walk: an empty, labelled figure
    for name in ("grid.png", "one_axis.png", "none.png"):
        assert (tmp_path / name).stat().st_size > 10_000


def test_sizing_figure_splits_the_walks_by_gait(tmp_path):
    """A sweep with a gait axis draws one box per gait: each box holds exactly that gait's completed walks'
    peaks / limit (built by hand here), and the failed walk is in none."""
    from humanoid_sim.sweep.plots import plot_sizing, sizing_group
    from humanoid_sim.sweep.spec import load_sweep

    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"base": str(ROOT / "scripts" / "params" / "sim3.yaml"),
                                     "grid": {"path.Vhip": {"scale": [0.9, 1.1]},
                                              "gait.hip_reference": ["thesis", "zmp_preview"]}}, sort_keys=False))
    spec = load_sweep(sweep)
    assert sizing_group(spec.axes) == "gait.hip_reference"
    assert sizing_group(spec.axes[:1]) is None
    limits = np.linspace(10.0, 150.0, 26)
    rows = []
    for w in spec.expand():
        g = w.params["gait.hip_reference"]
        peak = (0.9 if g == "thesis" else 0.3) * limits * (1.0 + w.index / 100)
        rows.append({**w.params, "walk": w.index, "completed": w.index != 3,
                     **{f"torque_peak_Nm_{n}": float(peak[i]) for i, n in enumerate(T_NAMES)},
                     **{f"torque_cmd_peak_Nm_{n}": float(peak[i]) for i, n in enumerate(T_NAMES)},
                     **{f"saturated_fraction_per_actuator_{n}": 0.0 for n in T_NAMES}})
    drawn = plot_sizing(rows, T_NAMES, limits, tmp_path / "sizing.png", group="gait.hip_reference")
    assert (tmp_path / "sizing.png").stat().st_size > 10_000
    by_gait = {k.split(" = ")[1]: v for k, v in drawn.items()}
    for g, scale in (("thesis", 0.9), ("zmp_preview", 0.3)):
        idx = [r["walk"] for r in rows if r["gait.hip_reference"] == g and r["completed"]]
        expect = np.array([[scale * (1.0 + k / 100)] * 26 for k in idx])
        np.testing.assert_allclose(by_gait[g], expect, rtol=1e-13)   # peak / limit: one division, round-off
    assert set(plot_sizing(rows, T_NAMES, limits, tmp_path / "pooled.png")) == {""}


def test_the_thesis_engine_runs_the_walk(hm):
    """--engine thesis reaches the thesis oracle (two steps of it: ~0.3 s), with the same summary as running it
    directly."""
    from humanoid_sim.analysis.summary import summarize_with_audit
    from humanoid_sim.scenario.schema import parse_scenario
    from humanoid_sim.sim.simulate import Simulator

    doc = copy.deepcopy(SIM3)
    doc["simulation"]["t_end_s"] = 0.02
    s = run_walk(doc, "thesis")
    sc = parse_scenario(doc)
    sim = Simulator(hm, sc, engine="thesis")
    res = sim.run()
    direct = summarize_with_audit(res, sc, "thesis", hm, [p.name for p in sim.traj.phases])
    assert s["engine"] == "thesis" and s["steps"] == 2 and "compiled_stages" not in s
    wall = ("wall_time_s", "real_time_factor", "torque_rms_Nm", "provenance")
    assert {k: v for k, v in s.items() if k not in wall} == {k: v for k, v in direct.items() if k not in wall}
