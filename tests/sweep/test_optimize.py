"""humanoid-optimize: the design file, the scoring of a candidate, the Pareto front, and a small study on MuJoCo
(rows, resume, the best design's URDF and its walk reproducing the optimiser's row)."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from humanoid_sim.cli import optimize as cli
from humanoid_sim.sweep.design_file import Constraint, DesignStudy, Objective, load_design
from humanoid_sim.sweep.optimize import ACCEPTED, motors_violation, objective_value, pareto_front, pick_best, score
from tests.conftest import ROOT

SHIPPED = ROOT / "scripts" / "designs" / "sim3_zmp_gearboxes.yaml"
PARAMS = ROOT / "scripts" / "params"


def _design(tmp_path: Path, **changes) -> Path:
    doc = yaml.safe_load(SHIPPED.read_text())
    doc["base"] = str(PARAMS / "sim3_zmp_motors.yaml")
    doc.update(changes)
    p = tmp_path / "design.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def test_the_shipped_design_file_loads() -> None:
    study = load_design(SHIPPED)
    assert study.engine == "mujoco" and study.trials >= 20 and len(study.objectives) == 2
    doc = study.candidate_doc({p.name: v for p, v in zip(study.parameters, [0.9, 100.0, 90.0, 50.0, 12.0])}, "c")
    assert doc["robot"]["mass_scale"]["all"] == 0.9
    assert doc["actuators"]["gear_ratio"]["theta15"] == doc["actuators"]["gear_ratio"]["theta16"] == 100.0
    assert doc["actuators"]["joints"]["all"] == "mini_cheetah_knee"   # the base's own entries stay


@pytest.mark.parametrize("changes, words", [
    ({"parameters": {"robot.mass_scale.all": {"low": 1.2, "high": 0.8}}}, ["robot.mass_scale.all", "must be below"]),
    ({"parameters": {"robot.length_scale.shin": {"low": 0.9, "high": 1.1}}},
     ["robot.length_scale.shin: unknown key", "shank"]),
    ({"parameters": {"robot.mass_scale.all": {"low": 0.05, "high": 1.0}}},
     ["robot.mass_scale.all: expected a mass factor in [0.1, 10], got 0.05"]),
    ({"objectives": [{"column": "design_*_speed_margin", "direction": "maximize"}]}, ["objectives[0]", "aggregate"]),
    ({"objectives": [{"column": "x", "direction": "down"}]}, ["objectives[0].direction = 'down'"]),
    ({"constraints": ["no_fall"]}, ["constraints[0] = 'no_fall'", "completed"]),
    ({"budget": {"trials": 0}}, ["budget.trials = 0"]),
    ({"sampler": "cma"}, ["sampler = 'cma'", "tpe"]),
    ({"engines": "mujoco"}, ["engines: unknown key", "engine"]),
])
def test_a_bad_design_file_exits_2_naming_the_field(tmp_path: Path, changes: dict, words: list[str]) -> None:
    path = _design(tmp_path, **changes)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "humanoid_sim.cli.optimize", str(path), "--out", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    for w in words:
        assert w in proc.stderr, proc.stderr
    assert not out.exists()


def test_objectives_aggregate_the_columns_a_pattern_matches() -> None:
    row = {"a_theta3_speed_margin": 0.4, "a_theta5_speed_margin": -0.1, "a_theta5_rms_margin": -3.0, "cot": 1.5}
    assert objective_value(row, "a_*_speed_margin", "min") == -0.1
    assert objective_value(row, "a_*_speed_margin", "max") == 0.4
    assert objective_value(row, "a_*_speed_margin", "sum") == pytest.approx(0.3, abs=1e-15)
    assert objective_value(row, "cot", None) == 1.5
    assert objective_value(row, "missing", None) is None and objective_value(row, "b_*", "min") is None
    assert objective_value({"x": float("nan")}, "x", None) is None


def test_motors_pass_needs_every_margin_and_no_cut_after_settling() -> None:
    row = {f"design_actuators_joints_theta{k}_{m}_margin": 0.2 for k in (3, 5) for m in
           ("torque", "speed", "current", "rms", "temperature")}
    settle = {"design": {"settling": {"window_s": 0.05}, "actuators": {"envelope_shortfalls": [
        {"joint": "theta5", "first_s": 0.002, "last_s": 0.002}]}}}
    assert motors_violation(row, settle) == pytest.approx(-0.2)     # a cut during settling does not count
    late = {"design": {"settling": {"window_s": 0.05}, "actuators": {"envelope_shortfalls": [
        {"joint": "theta5", "first_s": 0.002, "last_s": 2.5}]}}}
    assert motors_violation(row, late) == pytest.approx(0.8)        # -0.2 + 1 for the cut
    assert motors_violation({**row, "design_actuators_joints_theta5_rms_margin": -0.3}, settle) == pytest.approx(0.3)
    assert motors_violation({"completed": True}, None) == 1.0        # no motors: cannot pass


COMPLETED = (Constraint("completed"),)


def _study(objectives: tuple[Objective, ...], constraints=COMPLETED, best: int = 3) -> DesignStudy:
    return DesignStudy(Path("d.yaml"), Path("b.yaml"), {}, "", "mujoco", 10, 0, "tpe", (), objectives, constraints,
                       best)


def test_score_and_front_against_brute_force() -> None:
    """The front of random candidates equals the brute-force set of feasible points no feasible point dominates
    (minimise x, maximise y), and a column constraint's violation is its distance outside the bounds."""
    study = _study((Objective("x"), Objective("y", "maximize")))
    rng = np.random.default_rng(3)
    rows = []
    for i in range(60):
        x, y, ok = float(rng.uniform()), float(rng.uniform()), bool(rng.uniform() < 0.7)
        rows.append({"trial": i, "objective:x": x, "objective:y": y, ACCEPTED: ok})
    rows.append({"trial": -1, "objective:x": 0.0, "objective:y": 2.0, ACCEPTED: True})   # the baseline is no candidate
    feas = [r for r in rows if r[ACCEPTED] and r["trial"] >= 0]
    brute = {r["trial"] for r in feas if not any(o["objective:x"] <= r["objective:x"] and
                                                  o["objective:y"] >= r["objective:y"] and o is not r for o in feas)}
    front = pareto_front(study, rows)
    assert {r["trial"] for r in front} == brute
    assert [r["objective:x"] for r in front] == sorted(r["objective:x"] for r in front)
    picked = pick_best(study, rows)
    assert picked[0] is front[0] and picked[-1] is front[-1] and len(picked) == min(3, len(front))
    bounded = _study((Objective("x"),), (Constraint("c", "m", 1.0, 2.0),))
    assert score(bounded, {"x": 1.0, "m": 2.5}, None) == ([1.0], {"c": 0.5})
    assert score(bounded, {"x": 1.0, "m": 0.25}, None) == ([1.0], {"c": 0.75})
    assert score(bounded, {"x": 1.0, "m": 1.5}, None)[1]["c"] < 0


def test_pick_best_spreads_along_the_front() -> None:
    study = _study((Objective("x"), Objective("y")), best=3)
    rows = [{"trial": i, "objective:x": float(i), "objective:y": float(10 - i), ACCEPTED: True} for i in range(11)]
    assert [r["trial"] for r in pick_best(study, rows)] == [0, 5, 10]
    assert list(itertools.islice((r["trial"] for r in pick_best(_study((Objective("x"),), best=2), rows)), 2)) == [0]


@pytest.mark.slow
def test_a_small_study_on_mujoco_resumes_and_its_best_design_reproduces(tmp_path: Path) -> None:
    """The baseline and 2 candidates on 2 workers, then resumed to 3: one more walk, the journal's trials and the
    rows agree; the best design's folder holds its scenario, its URDF (the text the walk's own model was built
    from) and its sizing card, and walking it again gives its row to the last bit (same code, same inputs)."""
    design = _design(tmp_path, budget={"trials": 2, "seed": 3}, best=1, constraints=["completed"],
                     parameters={"robot.mass_scale.all": {"low": 0.85, "high": 1.0},
                                 "actuators.gear_ratio.knee": {"low": 40, "high": 80}})
    out = tmp_path / "study"
    assert cli.main([str(design), "--out", str(out), "--workers", "2", "--quiet", "--no-best"]) == 0
    rows = _rows(out)
    assert sorted(r["trial"] for r in rows) == [-1, 0, 1]
    assert cli.main([str(design), "--out", str(out), "--workers", "2", "--quiet", "--trials", "3"]) == 0
    rows = _rows(out)
    assert sorted(r["trial"] for r in rows) == [-1, 0, 1, 2]
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    st = optuna.load_study(study_name="design", storage=JournalStorage(JournalFileBackend(str(out / "study.journal"))))
    told = {t.number: t for t in st.get_trials() if t.state == optuna.trial.TrialState.COMPLETE}
    for r in rows:
        if r["trial"] >= 0:
            assert told[r["trial"]].values[0] == r["objective:design_actuators_electrical_cost_of_transport"]
            assert told[r["trial"]].params["robot.mass_scale.all"] == r["param:robot.mass_scale.all"]
            assert r["robot_mass_kg"] == pytest.approx(55.044 * r["param:robot.mass_scale.all"], abs=1e-9)
    best = list((out / "best").iterdir())
    assert len(best) == 1
    folder = best[0]
    rep = json.loads((folder / "reproduction.json").read_text())
    assert rep["max_abs_difference"] == 0.0 and rep["differing_non_numeric"] == [] and rep["columns_compared"] > 500
    summary = json.loads((folder / "summary.json").read_text())
    from humanoid_sim.paths import cache_dir

    cached = cache_dir() / "models" / summary["robot"]["model"]
    assert (folder / "robot.urdf").read_text() == cached.read_text()
    assert (folder / "design.csv").is_file() and (out / "pareto.png").stat().st_size > 10_000


def _rows(out: Path) -> list[dict]:
    from humanoid_sim.sweep.optimize import read_candidates

    return read_candidates(out)
