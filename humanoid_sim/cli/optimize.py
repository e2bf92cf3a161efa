"""``humanoid-optimize``: search robot and actuator designs with Optuna, every candidate scored by a full walk.

    humanoid-optimize DESIGN.yaml [--out DIR] [--workers N] [--scheduler ADDRESS] [--trials N] [--no-best]
                                  [--quiet]

The design file (:mod:`humanoid_sim.sweep.design_file`) names the walk, the parameters (robot and actuators), the
objectives and the constraints.  Writes into ``DIR`` (default ``results/designs/<design file name>/``; see
:mod:`humanoid_sim.sweep.optimize`): ``study.journal``, ``candidates.parquet`` / ``.csv``, ``candidates/``,
``pareto.png`` and ``best/trial_<n>/`` (scenario, robot.urdf, robot.yaml, the sizing card of the design walked
again, and how well that walk reproduces the optimiser's row).  Running it again on the same folder resumes.

Exit status: 0 when the budget is walked (infeasible and failed candidates included: they are results), 1 when
interrupted (Ctrl-C; the rows and the journal are kept, the same command resumes), 2 on bad input (the design file,
a candidate's scenario, the options, a cluster that cannot be started): nothing is run and nothing written.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

PROG = "humanoid-optimize"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description="Search robot and actuator designs (Optuna; every candidate "
                                "a full walk on Dask): candidates.parquet, pareto.png, the best designs' URDFs and "
                                "sizing cards.")
    p.add_argument("design", type=Path, help="design YAML (base scenario, parameters, objectives, constraints), or "
                   "the name of a shipped one (sim3_zmp_gearboxes)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: results/designs/<design name>/)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the local Dask cluster (default: the number of usable cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on the existing Dask cluster of this scheduler (tcp://HOST:PORT)")
    p.add_argument("--trials", type=int, default=None, metavar="N", help="candidates to walk (default: the design "
                   "file's budget.trials); a resumed study walks up to this many in all")
    p.add_argument("--no-best", action="store_true", help="do not write the best designs (nor walk them again)")
    p.add_argument("--quiet", action="store_true", help="no line per candidate")
    return p


def _fail_input(msg: str) -> int:
    print(f"{PROG}: error: {msg}", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return _main(args)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; the candidates walked so far are kept (run the same command again to resume)",
              file=sys.stderr)
        return 1


def _main(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from humanoid_sim.cli.sweep import _build_kernel, _build_mujoco, _cores, cluster_options_error
    from humanoid_sim.sweep.design_file import MAX_TRIALS, DesignFileError, load_design

    bad = cluster_options_error(args)
    if bad is not None:
        return _fail_input(bad)
    if args.trials is not None and not 1 <= args.trials <= MAX_TRIALS:
        return _fail_input(f"--trials: expected a number of candidates in [1, {MAX_TRIALS}], got {args.trials}")
    from humanoid_sim.paths import DESIGNS_DIR

    if not args.design.exists() and args.design.suffix == "" and (DESIGNS_DIR / f"{args.design}.yaml").is_file():
        args.design = DESIGNS_DIR / f"{args.design}.yaml"   # a shipped design file by its name
    try:
        study = load_design(args.design)
    except DesignFileError as exc:
        return _fail_input(str(exc))
    if args.trials is not None:
        study = replace(study, trials=args.trials)
    out = args.out if args.out is not None else Path("results") / "designs" / args.design.stem
    if out.exists() and not out.is_dir():
        return _fail_input(f"--out: {out} exists and is not a folder")
    workers = args.workers if args.workers is not None else _cores()

    class _Walk:   # what the kernel builders read of a walk
        def __init__(self, doc: dict) -> None:
            self.doc = doc

    probe = [_Walk(study.candidate_doc(study.midpoint(), "probe"))]
    if args.scheduler is None and study.engine in ("pinocchio", "mujoco"):
        _build_kernel(probe, PROG)
    if args.scheduler is None and study.engine == "mujoco":
        _build_mujoco(probe[0].doc, PROG)
    from humanoid_sim.sweep import runner
    from humanoid_sim.sweep.optimize import optimise, read_candidates, write_best
    from humanoid_sim.sweep.pareto import plot_pareto

    where = args.scheduler or f"a local Dask cluster of {workers} worker processes (127.0.0.1)"
    print(f"{args.design}: {study.trials} candidates ({len(study.parameters)} parameters, "
          f"{len(study.objectives)} objective{'s' if len(study.objectives) > 1 else ''}, sampler {study.sampler}) "
          f"on {study.engine}, on {where}; output in {out}", file=sys.stderr)

    def on_row(row: dict) -> None:
        if args.quiet:
            return
        objs = ", ".join(f"{k.removeprefix('objective:')} = " + (f"{v:.4g}" if isinstance(v, float) else "-")
                         for k, v in row.items() if k.startswith("objective:"))
        what = "baseline" if row["trial"] < 0 else f"trial {row['trial']}"
        verdict = "feasible" if row["meets_constraints"] else ("infeasible: " + (
            str(row.get("reason")) if not row.get("completed") else
            ", ".join(k.removeprefix("constraint:") for k, v in row.items()
                      if k.startswith("constraint:") and v > 0)))
        print(f"  {what}: {objs}; {verdict}", file=sys.stderr)

    with contextlib.ExitStack() as stack:
        try:
            client = stack.enter_context(runner.dask_client(workers=workers if args.scheduler is None else None,
                                                            scheduler=args.scheduler))
        except Exception as exc:  # noqa: BLE001 - OSError, TimeoutError, Dask's RuntimeError
            return _fail_input(f"cannot start or reach the Dask cluster: {type(exc).__name__}: {exc}")
        n = workers if args.scheduler is None else max(1, len(client.scheduler_info()["workers"]))
        out.mkdir(parents=True, exist_ok=True)
        report = optimise(study, out, client, n, on_row)
    rows = read_candidates(out)
    written = [] if args.no_best else write_best(study, out, rows, say=lambda s: print(f"{PROG}: {s}",
                                                                                        file=sys.stderr))
    plot_pareto(study, rows, [w["trial"] for w in written], out / "pareto.png")
    print(f"{report.walked} candidates walked now in {report.wall_s:.0f} s ({report.total} in all, "
          f"{sum(1 for r in rows if r['trial'] >= 0 and r['meets_constraints'])} feasible); results in {out}/ "
          "(candidates.parquet, candidates.csv, pareto.png, best/)")
    base = report.baseline
    if base is not None:
        print("  baseline: " + ", ".join(f"{k.removeprefix('objective:')} = {v:.4g}" for k, v in base.items()
                                         if k.startswith("objective:") and isinstance(v, float))
              + ("" if base["meets_constraints"] else " (infeasible: " + ", ".join(
                  k.removeprefix("constraint:") for k, v in base.items()
                  if k.startswith("constraint:") and v > 0) + ")"))
    for w in written:
        objs = ", ".join(f"{k.removeprefix('objective:')} = {v:.4g}" for k, v in w.items()
                         if k.startswith("objective:") and isinstance(v, float))
        print(f"  best: trial {w['trial']}: {objs}; walked again: largest difference from its row "
              f"{w['max_abs_difference']:.3g} over {w['columns_compared']} columns ({w['folder']})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
