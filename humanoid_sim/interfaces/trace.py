"""The full-rate trace: the signals a designer's peaks come from, at every step of the engine.

The log (:mod:`humanoid_sim.interfaces.log`) holds one row per loop step (``simulation.step_s``, 10 ms for the
thesis's walks): the state at the step's start and the torques of its first control update.  An engine that
integrates in smaller steps (MuJoCo: 1 ms timesteps under 2 ms control updates) keeps a trace with one row per
integration step, so that peaks, RMS values, work and fractions are taken over every state the engine computed,
not over one in ten.  The trace has the log's signal names and meanings (:data:`TRACE_SIGNALS`, a subset of
:data:`humanoid_sim.interfaces.log.SIGNALS`) and the engine's step as its period.  On an engine whose integration
step is the loop step (the weld engine with the shipped feedthrough controllers) the trace is the log itself.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

TRACE_SIGNALS: tuple[str, ...] = ("t", "phase", "basic_phase", "q", "v", "a", "tau", "T", "T_cmd", "saturated",
                                  "body_force", "body_moment", "foot_wrench", "cop", "zmp", "in_contact")
"""The log signals a trace holds (same units and meanings as the log's)."""


class Trace(NamedTuple):
    """Signals at every integration step of a run.

    Attributes:
        columns: signal name -> array whose first axis is the row (one per integration step, the state at the
            step's start), for every name of :data:`TRACE_SIGNALS`.
        period_s: the time between rows, s (the engine's integration step).
        source: how the rows were taken: ``"log"`` (the trace is the log: every integration step is logged) or
            ``"engine"`` (recorded by the engine at each of its steps).
    """

    columns: dict[str, np.ndarray]
    period_s: float
    source: str

    def __len__(self) -> int:
        return len(self.columns["t"])


def trace_of_log(arrays: dict[str, np.ndarray], period_s: float) -> Trace:
    """The trace of a run whose log holds every integration step (the columns are shared, not copied)."""
    return Trace({k: arrays[k] for k in TRACE_SIGNALS}, float(period_s), "log")


class RowBuffer:
    """Fixed-width float rows appended one at a time into preallocated blocks (an engine's per-step record).

    Args:
        width: floats per row.
        block: rows per block (a block is allocated when the last one is full).
    """

    def __init__(self, width: int, block: int = 4096) -> None:
        self.width = width
        self.block = block
        self._blocks: list[np.ndarray] = []
        self._n = 0

    def next_row(self) -> np.ndarray:
        """A view of the next row (to be filled by the caller)."""
        block, i = self.next_slot()
        return block[i]

    def next_slot(self) -> tuple[np.ndarray, int]:
        """The block holding the next row and the row's index in it (to be filled by the caller; no view made)."""
        i = self._n % self.block
        if i == 0:
            self._blocks.append(np.empty((self.block, self.width)))
        self._n += 1
        return self._blocks[-1], i

    def __len__(self) -> int:
        return self._n

    def array(self) -> np.ndarray:
        """The rows appended so far, (n, width)."""
        if not self._blocks:
            return np.empty((0, self.width))
        return np.concatenate(self._blocks)[:self._n]


__all__ = ["TRACE_SIGNALS", "RowBuffer", "Trace", "trace_of_log"]
