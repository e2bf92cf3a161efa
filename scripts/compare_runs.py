#!/usr/bin/env python
"""Compare walks bit for bit: ``python scripts/compare_runs.py A B``.

A and B are output folders of ``walk.py`` (each with results.npz and summary.json), or folders of such folders
(compared by name). Every array of results.npz must be equal bit for bit (NaN where NaN), and every summary number
equal, except the wall time and what records when and how a run was made (``real_time_factor``,
``provenance``). Keys only in B are listed as new, not counted as differences. Exit status 0 when every walk is the
same, 1 otherwise.

To check that a change leaves the walks as they were, run the same scenarios on both commits, e.g.::

    git worktree add /tmp/before HEAD~1
    (cd /tmp/before && python scripts/walk.py scripts/params/sim1_zmp.yaml --engine mujoco --no-plots --no-html \\
        --out /tmp/runs_before/sim1_zmp_mujoco)
    python scripts/walk.py scripts/params/sim1_zmp.yaml --engine mujoco --no-plots --no-html \\
        --out /tmp/runs_after/sim1_zmp_mujoco
    python scripts/compare_runs.py /tmp/runs_before /tmp/runs_after
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

WHEN = {"wall_time_s", "real_time_factor", "task_wall_time_s", "provenance"}
"""Summary keys that record when and how fast a run was made, not what it did."""


def _same_array(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape != b.shape or a.dtype.kind != b.dtype.kind:
        return False
    if a.dtype.kind in "fc":
        return bool(np.array_equal(a, b, equal_nan=True))
    return bool(np.all(a == b))


def _compare(x: object, y: object, path: str, out: list[str], new: list[str]) -> None:
    if isinstance(x, dict) and isinstance(y, dict):
        for k in x:
            if k in WHEN:
                continue
            if k not in y:
                out.append(f"{path}.{k}: missing in B")
            else:
                _compare(x[k], y[k], f"{path}.{k}", out, new)
        new.extend(f"{path}.{k}" for k in y if k not in x and k not in WHEN)
    elif isinstance(x, list) and isinstance(y, list) and len(x) == len(y):
        for i, (a, b) in enumerate(zip(x, y)):
            _compare(a, b, f"{path}[{i}]", out, new)
    elif x != y:
        out.append(f"{path}: {x!r} != {y!r}")


def compare_walk(a: Path, b: Path) -> tuple[list[str], list[str]]:
    """The differences between two walk folders, and the keys and arrays only B has."""
    out: list[str] = []
    new: list[str] = []
    with np.load(a / "results.npz") as za, np.load(b / "results.npz") as zb:
        for k in za.files:
            if k not in zb.files:
                out.append(f"results.npz: {k} missing in B")
            elif not _same_array(za[k], zb[k]):
                out.append(f"results.npz: {k} differs")
        new.extend(f"results.npz: {k}" for k in zb.files if k not in za.files)
    _compare(json.loads((a / "summary.json").read_text()), json.loads((b / "summary.json").read_text()),
             "summary", out, new)
    return out, new


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__.splitlines()[0], file=sys.stderr)
        return 2
    a, b = Path(argv[0]), Path(argv[1])
    pairs = [(a, b)] if (a / "results.npz").is_file() else \
        [(d, b / d.name) for d in sorted(a.iterdir()) if (d / "results.npz").is_file()]
    if not pairs:
        print(f"{a}: no walk folders (with results.npz) found", file=sys.stderr)
        return 2
    failed = 0
    for x, y in pairs:
        if not (y / "results.npz").is_file():
            print(f"{x.name}: missing in B")
            failed += 1
            continue
        diffs, new = compare_walk(x, y)
        print(f"{x.name}: {'same' if not diffs else 'DIFFERENT'}" + (f" (new in B: {', '.join(new)})" if new else ""))
        for d in diffs[:20]:
            print(f"  {d}")
        failed += bool(diffs)
    print("all walks the same" if not failed else f"{failed} of {len(pairs)} walks differ")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
