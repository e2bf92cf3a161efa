"""The sweep's table: one row per walk -> ``sweep.parquet`` and ``sweep.csv``, written atomically, and back.

Columns, in order: ``walk`` (index in the sweep file's expansion), ``scenario_hash``, ``engine``, the swept
parameters (one column per axis, :attr:`humanoid_sim.sweep.spec.Axis.column`), the status columns
(``completed``, ``failure_kind``, ``reason``, ``failure_time_s``), then the walk's numbers
(:func:`humanoid_sim.sweep.walk.flatten_summary`, wall times, worker) in the order they first appear.  Rows are
sorted by walk; rows of other sweeps kept in the same folder (their hash is not one of this sweep's) come last.

Both files are rewritten whole through a temporary file and a rename
(:func:`humanoid_sim.interfaces.log.atomic_write_bytes`):
a reader, a crash or a Ctrl-C never sees a half-written table.  Floats are IEEE doubles in Parquet and their
shortest round-trip decimal text in the CSV, so both give back the exact numbers.
"""

from __future__ import annotations

import io
import json
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from humanoid_sim.errors import HumanoidSimError
from humanoid_sim.interfaces.log import atomic_write_bytes

PARQUET = "sweep.parquet"
CSV = "sweep.csv"
LEAD = ("walk", "scenario_hash", "engine")
STATUS = ("completed", "status", "failure_kind", "reason", "failure_time_s")
Key = tuple[str, str]


class TableError(HumanoidSimError, ValueError):
    """An existing sweep table that cannot be read or is not a sweep table."""


def row_key(row: dict[str, Any]) -> Key:
    """What identifies a walk's row: its scenario hash and engine."""
    return (str(row["scenario_hash"]), str(row["engine"]))


def read_rows(out: Path) -> list[dict[str, Any]]:
    """The rows of ``out/sweep.parquet`` ([] when there is none); raises :class:`TableError`."""
    path = Path(out) / PARQUET
    if not path.exists():
        return []
    try:
        # one open file read through: a sweep still running replaces the file (atomically) as rows arrive, and a
        # reader that opened it by path more than once could mix two versions.  Arrow's own file, read in this
        # thread: a table over a Python buffer, released by one of Arrow's threads during interpreter exit, aborts
        with pa.OSFile(str(path)) as f:
            rows = pq.ParquetFile(f).read(use_threads=False).to_pylist()
    except (OSError, pa.ArrowException) as exc:
        raise TableError(f"{path}: cannot read the existing sweep table ({exc}); "
                         "move it away to start afresh") from None
    for i, r in enumerate(rows):
        missing = [c for c in LEAD + ("completed",) if c not in r]
        if missing:
            raise TableError(f"{path}: row {i}: missing column(s) {', '.join(missing)}: not a sweep table written "
                             "by humanoid-sweep")
    return rows


def column_order(rows: Iterable[dict[str, Any]], params: Iterable[str]) -> list[str]:
    """LEAD, ``params``, STATUS, then every other column in first-appearance order over ``rows``."""
    cols = list(dict.fromkeys([*LEAD, *params, *STATUS]))
    seen = set(cols)
    for r in rows:
        for c in r:
            if c not in seen:
                seen.add(c)
                cols.append(c)
    return cols


def _array(values: list[Any]) -> pa.Array:
    try:
        return pa.array(values)
    except (pa.ArrowException, TypeError, ValueError, OverflowError):
        # mixed kinds in one column (e.g. rows of an older sweep that swept this path differently): text
        return pa.array([None if v is None else (v if isinstance(v, str) else json.dumps(v)) for v in values],
                        type=pa.string())


def to_table(rows: list[dict[str, Any]], params: Iterable[str]) -> pa.Table:
    """An Arrow table of ``rows`` with :func:`column_order` (absent cells are nulls)."""
    cols = column_order(rows, params)
    return pa.table({c: _array([r.get(c) for r in rows]) for c in cols})


def write_table(rows: list[dict[str, Any]], out: Path, params: Iterable[str]) -> None:
    """Write ``out/sweep.parquet`` and ``out/sweep.csv`` atomically."""
    table = to_table(rows, list(params))
    buf = io.BytesIO()
    pq.write_table(table, buf)
    atomic_write_bytes(Path(out) / PARQUET, buf.getvalue())
    buf = io.BytesIO()
    pa_csv.write_csv(table, buf)
    atomic_write_bytes(Path(out) / CSV, buf.getvalue())


class TableSink:
    """The table of a running sweep: the rows already there plus each new one (:meth:`add`), written at most
    every ``interval`` seconds while rows arrive and on :meth:`flush` (the end of the sweep, Ctrl-C)."""

    def __init__(self, out: Path, rows: list[dict[str, Any]], params: list[str], current: set[Key],
                 interval: float = 1.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.out = Path(out)
        self.params = list(params)
        self.current = current   # keys of this sweep's walks (their rows sort first)
        self.interval = interval
        self.clock = clock
        self._rows: dict[Key, dict[str, Any]] = {row_key(r): r for r in rows}
        self._last = -float("inf")
        self.dirty = False

    @property
    def rows(self) -> list[dict[str, Any]]:
        """The rows, this sweep's by walk index first, then the others in their previous order."""
        mine = sorted((r for k, r in self._rows.items() if k in self.current), key=lambda r: r["walk"])
        return mine + [r for k, r in self._rows.items() if k not in self.current]

    def add(self, row: dict[str, Any]) -> None:
        """Record ``row`` (replacing an older row of the same walk) and write the files if due."""
        self._rows[row_key(row)] = row
        self.dirty = True
        if self.clock() - self._last >= self.interval:
            self.flush()

    def flush(self) -> None:
        """Write the files now (when anything changed since the last write)."""
        if self.dirty:
            write_table(self.rows, self.out, self.params)
            self.dirty = False
        self._last = self.clock()
