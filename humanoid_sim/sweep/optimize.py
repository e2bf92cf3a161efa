"""Design optimisation: Optuna proposes robots and actuators, full walks on the sweeps' Dask cluster score them.

One study per output folder (:func:`optimise`):

- ``study.journal``: Optuna's journal (every trial's parameters, values and constraints).  Running the command
  again on the same folder resumes: trials already walked stay, trials cut off by Ctrl-C or a crash are marked
  failed and proposed anew, and the study goes on until ``budget.trials`` candidates have rows.  A resumed
  study's sampler is seeded again, so its later proposals differ from those an uninterrupted run would have made.
- ``candidates.parquet`` / ``.csv``: one row per candidate (``trial``; the baseline, the base scenario itself,
  is trial -1): its parameters, its objectives and constraint values (``objective:<label>``,
  ``constraint:<name>``, <= 0 is met), ``meets_constraints``, and the whole sweep row of its walk (the sizing card's
  numbers, :func:`humanoid_sim.sweep.walk.flatten_summary`).  ``candidates/<trial>.yaml`` and ``.json`` hold each
  candidate's scenario and summary.
- ``pareto.png``: the candidates in the plane of the first two objectives (a single objective: against the trial),
  the feasible front, the baseline and the designs written out.
- ``best/trial_<n>/``: the best feasible designs (the front, spread along the first objective): the scenario,
  the robot's body table and URDF (``robot.yaml``, ``robot.urdf``), and the outputs of the design walked again
  in this process (``summary.json``, ``design.csv``, ...; ``reproduction.json`` compares that walk's numbers
  with the optimiser's row).

A walk that fails, falls or raises is a row like any other (infeasible, or without objectives: a failed trial);
nothing of one walk stops the study.  Every walk runs in a Dask worker (:func:`humanoid_sim.sweep.walk.walk_row`),
as many at a time as the cluster has workers; the sampler is told each result as it arrives.
"""

from __future__ import annotations

import fnmatch
import io
import json
import math
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from humanoid_sim.interfaces.log import atomic_write_bytes, atomic_write_text
from humanoid_sim.sweep.design_file import DesignStudy
from humanoid_sim.sweep.walk import flatten_summary, walk_row

JOURNAL = "study.journal"
PARQUET = "candidates.parquet"
CSV = "candidates.csv"
BASELINE = -1
ACCEPTED = "meets_constraints"
"""The column saying a candidate has its objectives and meets every constraint (the walk's own ``feasible`` is the
contact audit's verdict)."""
MARGINS = ("torque", "speed", "current", "rms", "temperature")
"""The per-motor margins of the sizing card that ``motors_pass`` requires >= 0."""
NOT_COMPARED = ("task_wall_time_s", "worker", "wall_time_s", "real_time_factor")
"""Row columns that differ between two walks of one design by the machine's timing, not by the walk."""


@dataclass
class StudyReport:
    """What :func:`optimise` did: candidates walked now and in all, feasible ones, the best written out."""

    walked: int = 0
    total: int = 0
    feasible: int = 0
    best: list[dict[str, Any]] = field(default_factory=list)
    wall_s: float = 0.0
    baseline: dict[str, Any] | None = None


def objective_value(row: dict[str, Any], column: str, aggregate: str | None) -> float | None:
    """An objective's value in a row: the column, or ``aggregate`` over the columns a pattern with ``*`` matches;
    None when missing or not a finite number."""
    if aggregate is None:
        vals = [row.get(column)]
    else:
        vals = [v for k, v in row.items() if fnmatch.fnmatchcase(k, column)]
        if not vals:
            return None
    nums = [float(v) for v in vals if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)]
    if len(nums) != len(vals):
        return None
    return {"min": min, "max": max, "sum": sum, None: lambda x: x[0]}[aggregate](nums)


def motors_violation(row: dict[str, Any], summary: dict[str, Any] | None) -> float:
    """How far the worst motor margin is below 0 (a fraction of its limit), plus 1 when the drive cut a command
    after the start-up settling; <= 0 when every motor passes.  1 when the walk has no motors' card."""
    margins = [float(v) for k, v in row.items() if k.startswith("design_actuators_joints_")
               and any(k.endswith(f"_{m}_margin") for m in MARGINS) and isinstance(v, (int, float))]
    if not margins:
        return 1.0
    viol = -min(margins)
    design = (summary or {}).get("design") or {}
    window = float((design.get("settling") or {}).get("window_s", 0.0))
    cuts = [s for s in (design.get("actuators") or {}).get("envelope_shortfalls", []) if s["last_s"] > window]
    return viol + (1.0 if cuts else 0.0)


def score(study: DesignStudy, row: dict[str, Any], summary: dict[str, Any] | None
          ) -> tuple[list[float] | None, dict[str, float]]:
    """(objective values, or None when one is missing; constraint name -> violation, <= 0 when met)."""
    values = [objective_value(row, o.column, o.aggregate) for o in study.objectives]
    cons: dict[str, float] = {}
    for c in study.constraints:
        if c.name == "completed":
            cons[c.name] = 0.0 if row.get("completed") else 1.0
        elif c.name == "motors_pass":
            cons[c.name] = motors_violation(row, summary)
        else:
            x = objective_value(row, str(c.column), None)
            if x is None:
                cons[c.name] = 1.0
            else:
                cons[c.name] = max(c.min - x if c.min is not None else -math.inf,
                                   x - c.max if c.max is not None else -math.inf)
    return (None if any(v is None for v in values) else [float(v) for v in values]), cons  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------- the table
def read_candidates(out: Path) -> list[dict[str, Any]]:
    """The rows of ``out/candidates.parquet`` ([] when there is none)."""
    import pyarrow.parquet as pq

    path = Path(out) / PARQUET
    return pq.read_table(path).to_pylist() if path.exists() else []


def write_candidates(out: Path, rows: list[dict[str, Any]]) -> None:
    """Both files, whole, atomically; rows sorted by trial."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv
    import pyarrow.parquet as pq

    rows = sorted(rows, key=lambda r: r["trial"])
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    table = pa.Table.from_pylist([{c: r.get(c) for c in cols} for r in rows])
    buf = io.BytesIO()
    pq.write_table(table, buf)
    atomic_write_bytes(Path(out) / PARQUET, buf.getvalue())
    buf = io.BytesIO()
    pa_csv.write_csv(table, buf)
    atomic_write_bytes(Path(out) / CSV, buf.getvalue())


# --------------------------------------------------------------------------------------------- the study
def _distributions(study: DesignStudy) -> dict[str, Any]:
    from optuna.distributions import CategoricalDistribution, FloatDistribution

    out: dict[str, Any] = {}
    for p in study.parameters:
        if p.choices is not None:
            out[p.name] = CategoricalDistribution(list(p.choices))
        else:
            out[p.name] = FloatDistribution(float(p.low), float(p.high), log=p.log, step=p.step)  # type: ignore[arg-type]
    return out


def _sampler(study: DesignStudy) -> Any:
    """The sampler; the constraints reach it through each trial's ``set_constraint``."""
    import optuna

    if study.sampler == "nsga2":
        return optuna.samplers.NSGAIISampler(seed=study.seed)
    if study.sampler == "random":
        return optuna.samplers.RandomSampler(seed=study.seed)
    # a few walks run at once: the liar keeps TPE from proposing the same point to every worker
    return optuna.samplers.TPESampler(seed=study.seed, constant_liar=True, multivariate=True,
                                      n_startup_trials=min(10, max(2, study.trials // 3)))


def open_study(study: DesignStudy, out: Path) -> Any:
    """The Optuna study of ``out`` (created, or loaded to resume), its cut-off trials marked failed."""
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    storage = JournalStorage(JournalFileBackend(str(Path(out) / JOURNAL)))
    st = optuna.create_study(study_name="design", storage=storage, sampler=_sampler(study), load_if_exists=True,
                             directions=[o.direction for o in study.objectives])
    for t in st.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        st.tell(t.number, state=optuna.trial.TrialState.FAIL)
    return st


def optimise(study: DesignStudy, out: Path, client: Any, workers: int,
             on_row: Callable[[dict[str, Any]], None] | None = None) -> StudyReport:
    """Walk candidates until ``study.trials`` have rows (module docstring); the baseline first.  On
    KeyboardInterrupt the walks in flight are cancelled, the rows kept, and the interrupt propagates."""
    from distributed import wait

    out = Path(out)
    (out / "candidates").mkdir(parents=True, exist_ok=True)
    st = open_study(study, out)
    rows = read_candidates(out)
    dists = _distributions(study)
    token = uuid.uuid4().hex[:8]
    report = StudyReport()
    t0 = time.perf_counter()
    flight: dict[Any, tuple[Any, dict[str, Any]]] = {}   # future -> (optuna trial or None for the baseline, params)
    name = study.base_doc.get("name", study.base.stem)

    def submit(trial: Any, params: dict[str, Any]) -> None:
        number = BASELINE if trial is None else trial.number
        doc = study.base_doc if trial is None else study.candidate_doc(params, f"{name}_trial{number}")
        atomic_write_text(out / "candidates" / f"{number}.yaml", yaml.safe_dump(doc, sort_keys=False, width=120))
        f = client.submit(walk_row, doc, study.engine, f"{study.source}: trial {number}", pure=False,
                          key=f"design-{number}-{token}")
        flight[f] = (trial, params)

    def done() -> int:
        return sum(1 for r in rows if r["trial"] != BASELINE)

    try:
        if not any(r["trial"] == BASELINE for r in rows):
            submit(None, {})
        while flight or done() + sum(1 for t, _ in flight.values() if t is not None) < study.trials:
            while len(flight) < workers and done() + sum(1 for t, _ in flight.values() if t is not None) \
                    < study.trials:
                trial = st.ask(dists)
                submit(trial, dict(trial.params))
            finished = wait(list(flight), return_when="FIRST_COMPLETED").done
            for f in finished:
                trial, params = flight.pop(f)
                res = f.result() if f.status == "finished" else {"row": {
                    "completed": False, "failure_kind": "exception", "reason": str(f.exception())}, "summary": None}
                if res.get("interrupted"):
                    if trial is not None:
                        st.tell(trial, state=_fail())
                    continue
                row = _record(study, st, trial, params, res, out)
                rows[:] = [r for r in rows if r["trial"] != row["trial"]] + [row]
                write_candidates(out, rows)
                report.walked += 1
                if on_row is not None:
                    on_row(row)
    except KeyboardInterrupt:
        client.cancel(list(flight))
        for trial, _ in flight.values():
            if trial is not None:
                st.tell(trial, state=_fail())
        raise
    finally:
        report.wall_s = time.perf_counter() - t0
    report.total = done()
    report.feasible = sum(1 for r in rows if r["trial"] != BASELINE and r[ACCEPTED])
    report.baseline = next((r for r in rows if r["trial"] == BASELINE), None)
    return report


def _fail() -> Any:
    import optuna

    return optuna.trial.TrialState.FAIL


def _record(study: DesignStudy, st: Any, trial: Any, params: dict[str, Any], res: dict[str, Any],
            out: Path) -> dict[str, Any]:
    """The candidate's row; the trial told its values and constraints (or failed without objectives)."""
    number = BASELINE if trial is None else trial.number
    walk, summary = res["row"], res.get("summary")
    values, cons = score(study, walk, summary)
    accepted = values is not None and all(v <= 0.0 for v in cons.values())
    row: dict[str, Any] = {"trial": number, **{f"param:{k}": v for k, v in params.items()}, ACCEPTED: accepted}
    for o, v in zip(study.objectives, values or [None] * len(study.objectives)):
        row[f"objective:{o.label}"] = v
    row.update({f"constraint:{k}": v for k, v in cons.items()})
    row.update({k: v for k, v in walk.items() if k not in row})
    if summary is not None:
        atomic_write_text(out / "candidates" / f"{number}.json", json.dumps(summary, indent=2) + "\n")
    if trial is not None:
        if values is None:
            st.tell(trial, state=_fail())
        else:
            for k, v in cons.items():
                trial.set_constraint(k, v)
            st.tell(trial, values)
    return row


# --------------------------------------------------------------------------------------------- the best designs
def pareto_front(study: DesignStudy, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The feasible candidates no other feasible candidate dominates, sorted by the first objective."""
    labels = [f"objective:{o.label}" for o in study.objectives]
    sign = [1.0 if o.direction == "minimize" else -1.0 for o in study.objectives]
    feas = [r for r in rows if r["trial"] != BASELINE and r[ACCEPTED]]
    key = lambda r: [s * float(r[k]) for s, k in zip(sign, labels)]

    def dominated(r: dict[str, Any]) -> bool:
        a = key(r)
        return any(all(x <= y for x, y in zip(key(o), a)) and key(o) != a for o in feas)

    front = [r for r in feas if not dominated(r)]
    return sorted(front, key=lambda r: (key(r), r["trial"]))


def pick_best(study: DesignStudy, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Up to ``study.best`` designs of the front: its ends and evenly spaced ones between."""
    front = pareto_front(study, rows)
    n = min(study.best, len(front))
    if n == 0:
        return []
    if n == 1:
        return front[:1]
    idx = sorted({round(i * (len(front) - 1) / (n - 1)) for i in range(n)})
    return [front[i] for i in idx]


def compare_rows(a: dict[str, Any], b: dict[str, Any]) -> tuple[float, list[str]]:
    """(largest |difference| of the numeric columns both rows have, the columns that differ otherwise), timing
    columns excepted."""
    worst, other = 0.0, []
    for k, x in a.items():
        if k not in b or k in NOT_COMPARED or k.endswith("wall_time_s"):
            continue
        y = b[k]
        if isinstance(x, bool) or isinstance(y, bool) or not isinstance(x, (int, float)) \
                or not isinstance(y, (int, float)):
            if x != y:
                other.append(k)
        elif math.isfinite(x) and math.isfinite(y):
            worst = max(worst, abs(float(x) - float(y)))
        elif not (math.isnan(x) and math.isnan(y)) and x != y:
            other.append(k)
    return worst, other


def write_best(study: DesignStudy, out: Path, rows: list[dict[str, Any]],
               say: Callable[[str], None] = lambda s: None) -> list[dict[str, Any]]:
    """Write each picked design (module docstring) and walk it again here; returns what each reproduction gave."""
    from humanoid_sim import api
    from humanoid_sim.robot.variant import RobotVariant, variant_files
    from humanoid_sim.scenario.schema import parse_scenario

    written = []
    for row in pick_best(study, rows):
        n = row["trial"]
        folder = Path(out) / "best" / f"trial_{n}"
        folder.mkdir(parents=True, exist_ok=True)
        doc = yaml.safe_load((Path(out) / "candidates" / f"{n}.yaml").read_text())
        text = (f"# design trial {n} of {study.source.name}: walk it with\n"
                f"#   humanoid-walk {folder / 'scenario.yaml'} --engine {study.engine}\n"
                + yaml.safe_dump(doc, sort_keys=False, width=120))
        atomic_write_text(folder / "scenario.yaml", text)
        sc = parse_scenario(doc, str(folder / "scenario.yaml"))
        body = sc.robot if sc.robot is not None else RobotVariant()
        variant_files(body, folder)
        for suffix in ("yaml", "urdf"):   # under plain names, next to the scenario
            (folder / f"robot_{body.key()}.{suffix}").replace(folder / f"robot.{suffix}")
        say(f"walking design trial {n} again to write its sizing card ({folder})")
        run = api.run_walk(sc, study.engine, out=folder, figures=False, playback=False, verbose=False)  # type: ignore[arg-type]
        again = flatten_summary(run.summary)
        worst, other = compare_rows({k: v for k, v in row.items() if k in again}, again)
        rep = {"trial": n, "folder": str(folder), "max_abs_difference": worst, "columns_compared":
               sum(1 for k in again if k in row), "differing_non_numeric": other,
               **{k: row[k] for k in row if k.startswith(("objective:", "param:"))}}
        atomic_write_text(folder / "reproduction.json", json.dumps(rep, indent=2) + "\n")
        written.append(rep)
    return written


__all__ = ["ACCEPTED", "BASELINE", "StudyReport", "compare_rows", "motors_violation", "objective_value", "open_study",
           "optimise", "pareto_front", "pick_best", "read_candidates", "score", "write_best",
           "write_candidates"]
