#!/usr/bin/env python
"""Redraw the figures of a run:
``python scripts/plot.py results/sim1/pinocchio/results.npz [--out DIR] [--scenario YAML] [--figures all|quick]``.

Writes the figures ``walk.py`` draws (by default the thesis's full set,
:data:`humanoid_sim.outputs.plots.thesis.FIGURES`; ``--figures quick`` the few of ``walk.py``'s default), by
:func:`humanoid_sim.outputs.plots.thesis.plot_all`, the same call, into ``--out`` (default: the folder of
results.npz).  The reference-trajectory figures (thesis Figs. 6.51-6.53) and the audit's friction coefficient come
from the scenario: pass ``--scenario``, or leave it out and the scenario named in the run's summary.json is looked up
in scripts/params/.  The engine, which words the phase timeline and the audit (welded feet or real contact), comes
from results.npz or, for runs saved without it, from summary.json.
Exit status 0 on success, 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

PARAMS_DIR = Path(__file__).resolve().parent / "params"


def _summary(results: Path) -> dict:
    """The run's summary.json beside results.npz ({} when missing)."""
    summary = results.parent / "summary.json"
    return json.loads(summary.read_text(encoding="utf-8")) if summary.is_file() else {}


def _scenario_path(results: Path, given: Path | None) -> Path | None:
    """The scenario YAML for the reference figures: ``given``, else scripts/params/<summary scenario>.yaml."""
    if given is not None:
        return given
    summary = results.parent / "summary.json"
    if summary.is_file():
        name = json.loads(summary.read_text(encoding="utf-8")).get("scenario")
        if name and (PARAMS_DIR / f"{name}.yaml").is_file():
            return PARAMS_DIR / f"{name}.yaml"
    return None


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="plot.py", description="Redraw the PNG figures of a humanoid_sim run.")
    p.add_argument("results", type=Path, help="results.npz written by walk.py")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: next to results.npz)")
    p.add_argument("--scenario", type=Path, default=None,
                   help="scenario YAML for the reference-trajectory figures (default: from summary.json)")
    p.add_argument("--figures", choices=("all", "quick"), default="all",
                   help="all (the default: the thesis's full set) or quick (walk.py's default few)")
    args = p.parse_args(argv)
    if not args.results.is_file():
        print(f"plot.py: error: results file not found: {args.results}", file=sys.stderr)
        return 2
    from humanoid_sim.outputs.plots.thesis import DEFAULT_FRICTION, FIGURE_SETS, PlotError, plot_all

    traj, mu, title = None, DEFAULT_FRICTION, ""
    scenario = _scenario_path(args.results, args.scenario)
    if scenario is not None:
        from humanoid_sim.references.chapter3 import ReferenceTrajectory
        from humanoid_sim.scenario.schema import ScenarioError, load_scenario

        try:
            sc = load_scenario(scenario)
            traj = ReferenceTrajectory(sc.path)
        except ScenarioError as exc:
            print(f"plot.py: error: {exc}", file=sys.stderr)
            return 2
        mu, title = sc.contact.friction_coefficient, sc.name
    out = args.out if args.out is not None else args.results.parent
    try:
        paths = plot_all(args.results, out, traj=traj, mu=mu, title=title, stems=FIGURE_SETS[args.figures],
                         engine=_summary(args.results).get("engine"))
    except PlotError as exc:
        print(f"plot.py: error: {args.results}: {exc}", file=sys.stderr)
        return 2
    print(f"{len(paths)} figures in {out}/" + ("" if traj is not None else " (no scenario: reference figures "
                                                                           f"skipped, audit with mu = {mu:g})"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
