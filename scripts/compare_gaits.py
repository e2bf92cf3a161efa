#!/usr/bin/env python
"""Two (or more) walks side by side: ``python scripts/compare_gaits.py RUN_DIR RUN_DIR ... [--out DIR]``.

Each RUN_DIR is a ``walk.py`` output folder (results.npz, summary.json).  Writes into ``--out`` (default: the
current folder) ``gait_comparison.png`` (centre-of-pressure traces inside the sole outlines, one row per run,
:func:`humanoid_sim.outputs.plots.compare.gait_comparison_figure`) and ``torques.md`` (peak and RMS |T| per actuator),
and prints the table.  The audit's friction coefficient is each run's (summary.json ``contact``), else 0.8.
Exit status 0 on success, 2 on bad input (nothing written).

    python scripts/walk.py scripts/params/sim3.yaml --out results/sim3
    python scripts/walk.py scripts/params/sim3_zmp.yaml --out results/sim3_zmp
    python scripts/compare_gaits.py results/sim3 results/sim3_zmp --out results/compare
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="compare_gaits.py", description=__doc__.splitlines()[0])
    p.add_argument("runs", type=Path, nargs="+", help="walk.py output folders (results.npz + summary.json)")
    p.add_argument("--out", type=Path, default=Path("."), help="output folder (default: the current folder)")
    args = p.parse_args(argv)
    for d in args.runs:
        for name in ("results.npz", "summary.json"):
            if not (d / name).is_file():
                print(f"compare_gaits.py: error: {d}: expected a walk.py output folder with {name}, not found",
                      file=sys.stderr)
                return 2
    from humanoid_sim.interfaces.log import atomic_write_bytes, atomic_write_text, load_results
    from humanoid_sim.outputs.plots.compare import gait_comparison_figure, torque_table
    from humanoid_sim.outputs.plots.thesis import PlotError, audit_of
    from humanoid_sim.robot.actuators import T_NAMES
    from humanoid_sim.robot.model import load_model

    hm = load_model()
    runs = []
    try:
        for d in args.runs:
            summary = json.loads((d / "summary.json").read_text(encoding="utf-8"))
            r = load_results(d / "results.npz")
            mu = float((summary.get("contact") or {}).get("friction_coefficient", 0.8))
            runs.append((str(summary.get("scenario", d.name)), r, audit_of(r, mu, hm)))
    except (PlotError, ValueError, KeyError, OSError) as exc:   # unreadable npz, inconsistent log
        print(f"compare_gaits.py: error: {exc}", file=sys.stderr)
        return 2
    import io

    fig = gait_comparison_figure(runs, hm)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    table = torque_table([(lab, r) for lab, r, _ in runs], T_NAMES)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(args.out / "gait_comparison.png", buf.getvalue())
    atomic_write_text(args.out / "torques.md", table + "\n")
    print(table)
    print(f"wrote {args.out / 'gait_comparison.png'} and {args.out / 'torques.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
