"""``humanoid-push``: the push-recovery benchmark of a zmp-gait scenario on MuJoCo, run on Dask.

    humanoid-push SCENARIO [--out DIR] [--workers N] [--scheduler ADDRESS] [--phase K [K ...]]
                           [--instants early mid late] [--directions N] [--max-impulse J] [--resolution R]
                           [--compare KEY=VALUE [KEY=VALUE ...]] [--no-resume] [--quiet]

(``python scripts/push_benchmark.py`` is the same command.)  For each push direction (heading frame, every
360 / N deg from forward), pushed single support and instant in it, the largest impulse of a 0.1 s push on the
pelvis that the walk survives (completes its path), found by bisection (:mod:`humanoid_sim.sweep.push`).  With
``--compare``, the same benchmark again for the scenario with those overrides (e.g. ``balance.feedback=pd``), side by
side.  Writes into ``DIR`` (default ``results/push/<scenario name>/``): ``push.parquet`` and ``push.csv`` (one row
per cell and controller), ``push.md`` (the controllers side by side), ``push.png`` (polar plots) and
``probes/<hash>.json`` (each probe walk's row).  Probes already in ``probes/`` are not walked again.

Exit status: 0 when the table is written, 1 when interrupted (Ctrl-C: the finished probes are kept, the same command
resumes) or when probes failed in the machinery (an exception, a lost worker: the table is written, and the same
command walks those probes again), 2 on bad input (the scenario, the options, a ``--compare`` override, a
cluster that cannot be started or reached): nothing is run and nothing written.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path
from typing import Any

from humanoid_sim.cli.sweep import _cores, cluster_options_error

PROG = "humanoid-push"


def _parser() -> argparse.ArgumentParser:
    from humanoid_sim.sweep.push import DEFAULT_MAX_IMPULSE_NS, DEFAULT_RESOLUTION_NS, INSTANTS

    p = argparse.ArgumentParser(prog=PROG, description="Push-recovery benchmark on MuJoCo: per push direction and "
                                "instant of single support, the largest impulse of a 0.1 s push on the pelvis that the "
                                "walk survives, found by bisection on Dask; a table and a polar figure.")
    p.add_argument("scenario", help="a shipped scenario's name (sim3_zmp) or a scenario YAML; a zmp gait")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: results/push/<scenario name>/)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the local Dask cluster (default: the number of usable cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on the existing Dask cluster of this scheduler (tcp://HOST:PORT) instead of a local one")
    p.add_argument("--phase", type=int, nargs="+", default=None, metavar="K",
                   help="single-support phase(s) to push in, numbered from 1 as summary.json's phase_log (default: "
                        "the first single support starting 2 s after the lead-in)")
    p.add_argument("--instants", nargs="+", default=None, metavar="NAME",
                   help=f"instants of the single support: {', '.join(f'{k} ({v:g})' for k, v in INSTANTS.items())} "
                        "of its nominal window (default: all three)")
    p.add_argument("--directions", type=int, default=8, metavar="N",
                   help="push directions, every 360/N deg from forward in the heading frame (default: 8)")
    p.add_argument("--max-impulse", type=float, default=DEFAULT_MAX_IMPULSE_NS, metavar="J",
                   help=f"top of the bisection's bracket, N s (default: {DEFAULT_MAX_IMPULSE_NS:g})")
    p.add_argument("--resolution", type=float, default=DEFAULT_RESOLUTION_NS, metavar="R",
                   help=f"width of the final bracket, N s (default: {DEFAULT_RESOLUTION_NS:g})")
    p.add_argument("--compare", nargs="+", default=None, metavar="KEY=VALUE",
                   help="also run the benchmark with these scenario overrides (dotted paths, e.g. "
                        "balance.feedback=pd) and write both side by side")
    p.add_argument("--no-resume", action="store_true", help="walk every probe, even those recorded in probes/")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def _fail_input(msg: str) -> int:
    print(f"{PROG}: error: {msg}", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return _main(args)
    except KeyboardInterrupt:   # before any walk started (the run handles its own interrupt)
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 1


def _main(args: argparse.Namespace) -> int:
    from humanoid_sim.sweep.push import PushError, make_benchmark

    bad = cluster_options_error(args)
    if bad is not None:
        return _fail_input(bad)
    try:
        bench = make_benchmark(args.scenario, args.phase, args.directions, args.instants, args.compare,
                               args.max_impulse, args.resolution)
    except PushError as exc:
        return _fail_input(str(exc))
    out = args.out if args.out is not None else Path("results") / "push" / bench.name
    if out.exists() and not out.is_dir():
        return _fail_input(f"--out: {out} exists and is not a folder")
    workers = args.workers if args.workers is not None else _cores()
    where = (f"the cluster at {args.scheduler}" if args.scheduler else
             f"a local Dask cluster of {workers} worker process{'es' if workers != 1 else ''} (127.0.0.1)")
    n_cells = len(bench.cells)
    steps = _steps(bench)
    print(f"{bench.source}: {n_cells} cells ({len(bench.docs)} controller(s) x {_shape(bench)}), about "
          f"{n_cells * steps + len(bench.docs)} walks (bisection in [0, {bench.max_impulse_Ns:g}] N s to "
          f"{bench.resolution_Ns:g} N s: {steps} probes a cell, and one unpushed walk per controller) on {where}",
          file=sys.stderr)
    t0 = time.perf_counter()
    try:
        outcome = _run(args, bench, out, workers, n_cells * steps + len(bench.docs))
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; the finished probes are in {out / 'probes'} (run the same command again to "
              "resume)", file=sys.stderr)
        return 1
    if isinstance(outcome, int):
        return outcome
    _write(bench, outcome, out)
    print(f"{outcome.walked} walks in {time.perf_counter() - t0:.0f} s ({outcome.resumed} probes resumed from "
          f"{out / 'probes'})")
    print(f"  results in {out}/ (push.parquet, push.csv, push.md, push.png, probes/)")
    if outcome.machinery:
        reasons = sorted(set(outcome.machinery))
        print(f"{PROG}: {len(outcome.machinery)} probes failed in the machinery, not by a fall (counted as not "
              f"survived), e.g. {reasons[0]}; run the same command again to walk them again", file=sys.stderr)
        return 1
    return 0


def _steps(bench: Any) -> int:
    from humanoid_sim.sweep.push import Bisection

    return Bisection(bench.max_impulse_Ns, bench.resolution_Ns).steps


def _shape(bench: Any) -> str:
    """"1 phase x 3 instants x 8 directions" """
    first = [c for c in bench.cells if c.controller == bench.cells[0].controller]
    n = [len({c.phase for c in first}), len({c.instant for c in first}), len({c.direction_deg for c in first})]
    return " x ".join(f"{k} {w}{'s' if k != 1 else ''}" for k, w in zip(n, ("phase", "instant", "direction")))


def _build(bench: Any) -> None:
    """Fill numba's caches (the balance controller's parts, the MuJoCo engine's ground reads) once, here, before the
    local workers start: otherwise each worker compiles them itself, all at once.  A failed build is reported and
    left to the workers."""
    import tempfile

    import yaml

    from humanoid_sim import kernel
    from humanoid_sim.engines.mujoco import compiled
    from humanoid_sim.robot.model import load_model
    from humanoid_sim.scenario.schema import parse_scenario
    from humanoid_sim.sim import builds

    for doc in bench.docs.values():
        sc = parse_scenario(doc, bench.source)
        parts = builds.parts_for(sc)
        if kernel.AVAILABLE and not builds.cache_ready(parts):
            print(f"{PROG}: compiling the simulation kernel (first run after an install or an edit of a compiled "
                  "module: ~20 s, cached for later runs)", file=sys.stderr)
            with tempfile.TemporaryDirectory(prefix="humanoid_push_build_") as tmp:
                path = Path(tmp) / "walk.yaml"
                path.write_text(yaml.safe_dump(doc))
                try:
                    builds.build(path, parts)
                except builds.KernelBuildError as exc:
                    print(f"{PROG}: warning: {exc}; the workers compile it instead", file=sys.stderr)
        if not compiled.cache_ready():
            print(f"{PROG}: compiling the MuJoCo engine's ground reads (~5 s, cached for later runs)",
                  file=sys.stderr)
            builds.build_mujoco_reads(load_model(), sc)


def _run(args: argparse.Namespace, bench: Any, out: Path, workers: int, expected: int) -> Any:
    """Start or reach the cluster and run the benchmark: its Outcome, or an exit status."""
    from humanoid_sim.sweep import push, runner

    if args.scheduler is None:
        _build(bench)
    with contextlib.ExitStack() as stack:
        try:
            client = stack.enter_context(runner.dask_client(workers=workers if args.scheduler is None else None,
                                                            scheduler=args.scheduler))
        except Exception as exc:  # noqa: BLE001 - OSError, TimeoutError, Dask's RuntimeError("... failed to start")
            what = f"reach the scheduler at {args.scheduler}" if args.scheduler else "start the local Dask cluster"
            return _fail_input(f"cannot {what}: {type(exc).__name__}: {exc}")
        try:
            runner.setup_workers(client, push.ENGINE, bench.docs[push.BASE_LABEL])
        except Exception as exc:  # noqa: BLE001 - what a worker raised while setting up
            return _fail_input(f"the workers cannot run walks: {type(exc).__name__}: {exc} (do they have "
                               "humanoid_sim installed?)")
        out.mkdir(parents=True, exist_ok=True)
        bar = None
        if not args.quiet:
            from tqdm import tqdm

            bar = stack.enter_context(tqdm(total=expected, unit="walk", file=sys.stderr, desc="probes"))
        fell = {"n": 0}

        def on_probe(row: dict) -> None:
            if bar is not None:
                fell["n"] += not row["completed"]
                if bar.n >= bar.total:   # a cell that survived every probe walks the maximum too
                    bar.total += 1
                bar.set_postfix_str(f"not survived {fell['n']}", refresh=False)
                bar.update(1)

        return push.run(client, bench, out, on_probe=on_probe, resume=not args.no_resume)


def _write(bench: Any, outcome: Any, out: Path) -> None:
    from humanoid_sim.interfaces.log import atomic_write_text
    from humanoid_sim.sweep import push_report as report

    rows = report.table_rows(bench, outcome)
    report.write_table(rows, out)
    text = report.side_by_side(rows)
    atomic_write_text(out / "push.md", f"# Push recovery: {bench.name} on MuJoCo\n\n"
                      f"Largest impulse survived of a 0.1 s push on the pelvis (whole-body delta-v), bisection in "
                      f"[0, {bench.max_impulse_Ns:g}] N s to {bench.resolution_Ns:g} N s.\n\n{text}")
    report.plot_polar(rows, out / "push.png", title=f"{bench.name} on MuJoCo: largest push survived\n"
                      "(0.1 s on the pelvis; radius: whole-body delta-v, m/s)")
    for c, row in outcome.nominal.items():
        if not row.get("completed"):
            print(f"{PROG}: warning: [{c}] the walk without a push did not complete ({row.get('reason')}); the "
                  "bisection assumes it does", file=sys.stderr)
    print(text, end="")


if __name__ == "__main__":
    sys.exit(main())
