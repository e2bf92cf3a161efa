"""``humanoid-sweep``: run a parameter sweep of walks on Dask and write its table and figures.

    humanoid-sweep SWEEP.yaml [--out DIR] [--workers N] [--scheduler ADDRESS] [--engine NAME]
                              [--retry-failed] [--no-plots] [--quiet]

(``python scripts/sweep.py`` is the same command.)  Writes into ``DIR`` (default ``results/sweeps/<sweep file
name>/``): ``sweep.parquet`` and ``sweep.csv`` (one row per walk, rewritten as rows arrive), ``walks/<hash>.yaml``
(each generated scenario) and ``walks/<hash>-<engine>.json`` (each walk's full summary), ``sizing.png`` and
``feasibility.png``.  Walks whose row is already in ``sweep.parquet`` (same scenario hash and engine) are not run
again.

Exit status: 0 when every walk has its row (failed walks included: a failure is a result), 1 when interrupted
(Ctrl-C; the finished rows are kept) or when walks were left without a row (the cluster was lost), 2 on bad input
(the sweep file, a generated scenario, the options, an unreadable existing table, a cluster that cannot be started
or reached): nothing is run and nothing written.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import sys
from pathlib import Path

from humanoid_sim.sweep.walk import ENGINE_NAMES

PROG = "humanoid-sweep"
_ADDRESS = re.compile(r"^(?:[a-z][a-z0-9+]*://)?[^\s/:]+:\d{1,5}$")
RETRY_KINDS = ("exception", "worker_lost")
"""Failure kinds ``--retry-failed`` runs again (a walk the simulator stopped would only fail the same way)."""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description="Run a parameter sweep of walks (many variants of one "
                                "scenario) on Dask: one row per walk in sweep.parquet / sweep.csv, actuator-sizing "
                                "and feasibility figures.")
    p.add_argument("sweep", type=Path, help="sweep YAML: base scenario, grid and/or random parameters")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: results/sweeps/<sweep name>/)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the local Dask cluster (default: the number of usable cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on the existing Dask cluster of this scheduler (tcp://HOST:PORT) instead of a local "
                        "one; its workers need humanoid_sim installed")
    p.add_argument("--engine", choices=ENGINE_NAMES, default=ENGINE_NAMES[0],
                   help="dynamics engine of every walk (as walk.py --engine)")
    p.add_argument("--retry-failed", action="store_true",
                   help="run again the walks whose row records a lost worker or an exception (not those the "
                        "simulator stopped: they would fail the same way)")
    p.add_argument("--no-plots", action="store_true", help="do not write sizing.png and feasibility.png")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def _fail_input(msg: str) -> int:
    print(f"{PROG}: error: {msg}", file=sys.stderr)
    return 2


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return _main(args)
    except KeyboardInterrupt:   # before any walk started (the sweep itself handles its own interrupt)
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 1


def cluster_options_error(args: argparse.Namespace) -> str | None:
    """What is wrong with the ``--workers`` / ``--scheduler`` options (the commands that run walks on Dask share
    them), or None."""
    if args.workers is not None and args.scheduler is not None:
        return "--workers: applies to the local cluster only; the cluster of --scheduler has its own workers"
    if args.workers is not None and args.workers < 1:
        return f"--workers: expected a number of worker processes >= 1, got {args.workers}"
    if args.scheduler is not None and not _ADDRESS.match(args.scheduler):
        return (f"--scheduler: expected a scheduler address PROTOCOL://HOST:PORT (e.g. tcp://127.0.0.1:8786), got "
                f"{args.scheduler!r}")
    return None


def _main(args: argparse.Namespace) -> int:
    bad = cluster_options_error(args)
    if bad is not None:
        return _fail_input(bad)
    from humanoid_sim.sweep.spec import SweepError, load_sweep
    from humanoid_sim.sweep.table import TableError, TableSink, read_rows, row_key

    try:
        spec = load_sweep(args.sweep)
        walks = spec.expand()
    except SweepError as exc:
        return _fail_input(str(exc))
    from humanoid_sim.sweep.checks import noop_axes

    for msg in noop_axes(spec, walks):   # before any walk: an axis that changes no walk of some group
        print(f"{PROG}: warning: {msg}", file=sys.stderr)
    out = args.out if args.out is not None else Path("results") / "sweeps" / args.sweep.stem
    if out.exists() and not out.is_dir():
        return _fail_input(f"--out: {out} exists and is not a folder")
    try:
        previous = read_rows(out)
    except TableError as exc:
        return _fail_input(str(exc))
    engine = args.engine
    done = {row_key(r): r for r in previous}
    current = {(w.scenario_hash, engine) for w in walks}
    renumbered = False
    for w in walks:   # a row found by its scenario takes this sweep's walk index and parameter columns
        row = done.get((w.scenario_hash, engine))
        if row is not None and any(row.get(k) != v for k, v in {"walk": w.index, **w.params}.items()):
            row.update(walk=w.index, **w.params)
            renumbered = True
    to_run = [w for w in walks if (w.scenario_hash, engine) not in done
              or (args.retry_failed and done[(w.scenario_hash, engine)].get("failure_kind") in RETRY_KINDS)]
    params = [a.column for a in spec.axes]
    sink = TableSink(out, previous, params, current)
    sink.dirty = renumbered
    workers = args.workers if args.workers is not None else _cores()
    where = (f"the cluster at {args.scheduler}" if args.scheduler else
             f"a local Dask cluster of {workers} worker process{'es' if workers != 1 else ''} (127.0.0.1)")
    print(f"{args.sweep}: {len(walks)} walks ({_shape(spec)}), "
          f"{len(walks) - len(to_run)} already in {out / 'sweep.parquet'}, {len(to_run)} to run on {where}, "
          f"engine {engine}", file=sys.stderr)
    stats = None
    try:
        if to_run:
            stats = _run(args, spec, to_run, engine, out, sink, workers)
            if isinstance(stats, int):
                return stats
        sink.flush()
    except KeyboardInterrupt:
        sink.flush()
        kept = sum(1 for r in sink.rows if row_key(r) in current)
        print(f"{PROG}: interrupted; {kept} of {len(walks)} walks have their row in {out / 'sweep.parquet'} (run the "
              "same command again to resume)", file=sys.stderr)
        return 1
    rows = [r for r in sink.rows if row_key(r) in current]
    if not args.no_plots and rows:
        _plots(spec, rows, out)
    _print_summary(rows, len(walks), stats, out)
    if stats is not None and stats.not_run:
        print(f"{PROG}: {stats.not_run} walks have no row (cancelled: the cluster or the connection was lost, or "
              "interrupted on a worker); run the same command again to run them", file=sys.stderr)
        return 1
    return 0


def _shape(spec) -> str:
    """"4 path.Vhip:scale x 2 path.SW x 8 random samples of path.SH" """
    parts = [f"{len(a.values)} {a.column}" for a in spec.grid]
    if spec.random:
        parts.append(f"{spec.n} random samples of {', '.join(a.column for a in spec.random)}")
    return " x ".join(parts)


def _build_kernel(to_run, prog: str = PROG) -> None:
    """Fill numba's cache of the compiled parts the walks call (the thesis controller's stages, the balance
    controller's QP path, or both) once, here, before the local workers start: otherwise each worker compiles them
    itself, all at once.  A failed build is reported and left to the workers."""
    from humanoid_sim import kernel

    if not kernel.AVAILABLE:
        return
    import tempfile

    import yaml

    from humanoid_sim.scenario.schema import parse_scenario
    from humanoid_sim.sim import builds as build

    needed: dict[tuple[str, ...], dict] = {}
    for w in to_run:
        needed.setdefault(build.parts_for(parse_scenario(w.doc, "<sweep walk>")), w.doc)
    missing = {parts: doc for parts, doc in needed.items() if not build.cache_ready(parts)}
    if not missing:
        return
    print(f"{prog}: compiling the simulation kernel (first run after an install or an edit of "
          "a compiled module: ~20 s, cached for later runs)", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="humanoid_sweep_build_") as tmp:
        for i, (parts, doc) in enumerate(missing.items()):
            path = Path(tmp) / f"walk{i}.yaml"
            path.write_text(yaml.safe_dump(doc))
            try:
                build.build(path, parts)
            except build.KernelBuildError as exc:
                print(f"{prog}: warning: {exc}; the workers compile it instead", file=sys.stderr)


def _build_mujoco(doc: dict, prog: str = PROG) -> None:
    """Fill numba's cache of the MuJoCo engine's compiled ground reads once, here, by a short walk of one of the
    sweep's scenarios (:func:`humanoid_sim.sim.builds.build_mujoco_reads`), before the local workers start."""
    from humanoid_sim.engines.mujoco import compiled
    from humanoid_sim.sim.builds import build_mujoco_reads

    if compiled.cache_ready():
        return
    from humanoid_sim.robot.model import load_model
    from humanoid_sim.scenario.schema import parse_scenario

    print(f"{prog}: compiling the MuJoCo engine's ground reads (~5 s, cached for later runs)", file=sys.stderr)
    build_mujoco_reads(load_model(), parse_scenario(doc, "<sweep walk>"))


def _run(args: argparse.Namespace, spec, to_run, engine: str, out: Path, sink, workers: int):
    """Start or reach the cluster, write the scenario files, run the walks; the RunStats, or an exit status."""
    from humanoid_sim.sweep import runner

    if args.scheduler is None and engine in ("pinocchio", "mujoco"):
        _build_kernel(to_run)
    if args.scheduler is None and engine == "mujoco":
        _build_mujoco(to_run[0].doc)
    with contextlib.ExitStack() as stack:
        try:
            client = stack.enter_context(runner.dask_client(workers=workers if args.scheduler is None else None,
                                                            scheduler=args.scheduler))
        except Exception as exc:  # noqa: BLE001 - OSError, TimeoutError, Dask's RuntimeError("... failed to start")
            what = f"reach the scheduler at {args.scheduler}" if args.scheduler else "start the local Dask cluster"
            return _fail_input(f"cannot {what}: {type(exc).__name__}: {exc}")
        try:
            runner.setup_workers(client, engine, to_run[0].doc)
        except Exception as exc:  # noqa: BLE001 - what a worker raised while setting up
            return _fail_input(f"the workers cannot run walks: {type(exc).__name__}: {exc} (do they have "
                               "humanoid_sim installed?)")
        out.mkdir(parents=True, exist_ok=True)
        runner.write_scenarios(out, to_run)
        bar = None
        if not args.quiet:
            from tqdm import tqdm

            bar = stack.enter_context(tqdm(total=len(to_run), unit="walk", file=sys.stderr, desc="walks"))
        failed = {"n": 0}

        def on_row(row: dict) -> None:
            if bar is not None:
                failed["n"] += not row["completed"]
                bar.set_postfix_str(f"failed {failed['n']}", refresh=False)
                bar.update(1)

        try:
            return runner.execute(client, to_run, engine, str(args.sweep), out, sink, on_row=on_row)
        except KeyboardInterrupt:
            sink.flush()   # before stopping the cluster, which takes a moment
            raise


def _plots(spec, rows: list[dict], out: Path) -> None:
    from humanoid_sim.analysis.design import joint_limits
    from humanoid_sim.robot.actuators import T_NAMES, Actuators
    from humanoid_sim.sweep.plots import actuator_labels, plot_feasibility, plot_sizing, sizing_group
    from humanoid_sim.sweep.walk import model

    limits = Actuators(model()).limits
    name = spec.source.name
    plot_sizing(rows, T_NAMES, limits, out / "sizing.png",
                title=f"{name}: actuator sizing over {sum(1 for r in rows if r['completed'])} completed walks "
                      f"(of {len(rows)})", labels=actuator_labels(),
                group=sizing_group(spec.axes), joints=[th for name in T_NAMES for th, (tn, _) in joint_limits().items()
                                                       if tn == name])
    plot_feasibility(rows, spec.axes, out / "feasibility.png", title=f"{name}: completion and contact feasibility",
                     base_doc=spec.base_doc)


def _print_summary(rows: list[dict], n_walks: int, stats, out: Path) -> None:
    ok = sum(1 for r in rows if r["completed"])
    kinds: dict[str, int] = {}
    for r in rows:
        if not r["completed"]:
            kinds[str(r.get("failure_kind"))] = kinds.get(str(r.get("failure_kind")), 0) + 1
    failed = ", ".join(f"{v} {k}" for k, v in sorted(kinds.items()))
    ran = f"; {stats.recorded} run in {stats.walks_s:.1f} s" if stats is not None else ""
    print(f"{len(rows)} of {n_walks} walks: {ok} completed, {len(rows) - ok} failed"
          + (f" ({failed})" if failed else "") + ran)
    print(f"  results in {out}/ (sweep.parquet, sweep.csv, walks/, sizing.png, feasibility.png)")


if __name__ == "__main__":
    sys.exit(main())
