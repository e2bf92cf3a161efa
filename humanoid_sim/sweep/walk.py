"""One walk of a sweep: a scenario document -> its summary -> one table row.  Runs in a Dask worker process.

Per process, the model (URDF parse, :func:`humanoid_sim.robot.model.load_model`) is built once and cached
(:func:`model`); the compiled kernel (numba, loaded from its disk cache) is loaded by the first simulator the
process constructs and reused by every later one (numba's dispatchers live in the module).  :class:`WalkSetup`
(a Dask ``WorkerPlugin``) does both when a worker joins, before its first task.  :data:`STATS` counts model loads
and walks per process (``Client.run(worker_stats)`` reads it: a test checks one model load per worker).

:func:`run_walk` is the only function here that knows how a walk is run (the simulator, the summary, the
contact audit); everything else goes through it.
"""

from __future__ import annotations

import asyncio
import os
import socket
import threading
import time
from typing import Any

import numpy as np

from humanoid_sim.engines import ENGINE_NAMES  # the one list of engines (humanoid-sweep --engine)

STATS: dict[str, int] = {"model_loads": 0, "walks": 0, "warm_ups": 0}
"""Per-process counters: model loads, walks run (:func:`walk_row` calls), worker warm-ups."""

_CACHE: dict[str, Any] = {}
_LOCK = threading.Lock()   # the warm-up thread and the first task may ask for the model at once



def model() -> Any:
    """The humanoid model of this process (built on the first call, then reused: :func:`humanoid_sim.api.robot`)."""
    from humanoid_sim import api

    with _LOCK:
        if "hm" not in _CACHE:
            _CACHE["hm"] = api.robot()
            STATS["model_loads"] += 1
        return _CACHE["hm"]


def torque_rms(T: np.ndarray) -> np.ndarray:
    """Root mean square over the steps of each actuator torque, N m: ``T`` (N, 26) -> (26,); NaN when N = 0.  The
    step is fixed, so this is the RMS over time (what sizes a motor's continuous rating)."""
    T = np.asarray(T, dtype=float)
    if T.shape[0] == 0:
        return np.full(T.shape[1], np.nan)
    return np.sqrt(np.mean(T * T, axis=0))


def run_walk(doc: dict, engine: str, source: str = "<sweep walk>", planner: Any = None) -> dict[str, Any]:
    """Simulate the scenario document ``doc`` on ``engine`` and return its summary (``summary.json``'s content,
    :func:`humanoid_sim.api.run_walk`) plus ``torque_rms_Nm`` (actuator name -> RMS |T|, N m).  ``planner``: as
    :func:`humanoid_sim.api.prepare`'s (a cache of the walk's plan).

    Raises:
        InputError: a bad scenario or engine. A walk that fails in the simulator returns normally with
            ``completed = false`` and its reason.
    """
    from humanoid_sim import api
    from humanoid_sim.robot.actuators import T_NAMES
    from humanoid_sim.scenario.schema import parse_scenario

    if engine not in ENGINE_NAMES:
        raise ValueError(f"engine: {engine!r} is not one of {', '.join(ENGINE_NAMES)}")
    model()   # counted once per process
    run = api.run_walk(parse_scenario(doc, source), engine, verbose=False, planner=planner)
    summary = run.summary
    trace = run.result.trace   # every integration step (the log where that is every step)
    rms = torque_rms(trace.columns["T"]) if trace is not None and len(trace) else np.full(len(T_NAMES), np.nan)
    out: dict[str, Any] = {}
    for k, v in summary.items():   # torque_rms_Nm next to torque_peak_Nm
        out[k] = v
        if k == "torque_peak_Nm":
            out["torque_rms_Nm"] = {name: float(x) if np.isfinite(x) else None for name, x in zip(T_NAMES, rms)}
    return out


# --------------------------------------------------------------------------------------------- rows
_NOT_COLUMNS = ("scenario", "engine", "completed", "status", "reason", "phase_log", "provenance")


def flatten_summary(summary: dict[str, Any]) -> dict[str, Any]:
    """The summary's numbers as flat columns: a scalar ``k`` -> ``k``; a mapping of scalars ``k: {a: x}`` ->
    ``k_a`` (per actuator ``torque_peak_Nm_T1`` ..., per foot ``..._R``); the contact audit's totals with the
    prefix ``contact_`` (its per-phase breakdown is left to the walk's summary file); every scalar leaf of the
    design numbers, names joined by ``_`` (``design_walk_work_positive_J``, per joint
    ``design_joints_theta11_speed_peak_rad_s``).
    Skipped: the scenario name, engine, completion and reason (columns of their own) and the phase log.  The
    summary's ``completed`` (every planned phase done) becomes ``all_phases_completed``."""
    out: dict[str, Any] = {"all_phases_completed": bool(summary["completed"])}

    def put(name: str, v: Any) -> None:
        if isinstance(v, dict):
            for sub, x in v.items():
                if not isinstance(x, (dict, list)):
                    out[f"{name}_{sub}"] = x
        elif not isinstance(v, list):
            out[name] = v

    for k, v in summary.items():
        if k in _NOT_COLUMNS:
            continue
        if k == "design" and isinstance(v, dict):   # every scalar leaf: design_walk_*, design_joints_<theta>_*
            stack = [("design", v)]
            while stack:
                prefix, d = stack.pop()
                for sub, x in d.items():
                    if isinstance(x, dict):
                        stack.append((f"{prefix}_{sub}", x))
                    elif not isinstance(x, list):
                        out[f"{prefix}_{sub}"] = x
            continue
        if k == "contact" and isinstance(v, dict):
            if "error" in v:
                out["contact_error"] = v["error"]
                continue
            for ck, cv in v.items():
                if ck != "per_phase":
                    put(f"contact_{ck}", cv)
            continue
        put(k, v)
    return out


def walk_row(doc: dict, engine: str, source: str = "<sweep walk>", planner: Any = None) -> dict[str, Any]:
    """The Dask task of one walk: ``{"row": columns, "summary": summary or None}``, or ``{"interrupted": True}``
    when the walk was stopped by a KeyboardInterrupt (not a result: the runner does not record it).

    Row columns: ``completed`` (the walk reached its end, every planned phase or the scenario's
    ``simulation.t_end_s``, without failing), ``failure_kind`` (None, "simulation" = the simulator stopped the
    walk: divergence, fall, overtime, singular system; "exception" = the walk raised), ``reason`` (the
    simulator's one-line reason, or the exception), ``failure_time_s`` (simulated time of the failure, s),
    :func:`flatten_summary`'s columns, ``task_wall_time_s`` (the whole task: scenario, simulator construction,
    run, summary, audit; s) and ``worker`` (host:pid)."""
    t0 = time.perf_counter()
    STATS["walks"] += 1
    worker = f"{socket.gethostname()}:{os.getpid()}"
    try:
        summary = run_walk(doc, engine, source, planner)
    except Exception as exc:  # noqa: BLE001 - any failure of one walk is that walk's row, never the sweep's end
        row = {"completed": False, "status": "failed", "failure_kind": "exception",
               "reason": f"{type(exc).__name__}: {exc}",
               "failure_time_s": None, "task_wall_time_s": time.perf_counter() - t0, "worker": worker}
        return {"row": row, "summary": None}
    reason = str(summary["reason"])
    if summary["status"] == "interrupted":
        return {"interrupted": True}
    completed = summary["status"] in ("completed", "stopped")
    row = {"completed": completed, "status": summary["status"], "failure_kind": None if completed else "simulation",
           "reason": reason,
           "failure_time_s": None if completed else summary["sim_time_s"], **flatten_summary(summary),
           "task_wall_time_s": time.perf_counter() - t0, "worker": worker}
    return {"row": row, "summary": summary}


# --------------------------------------------------------------------------------------------- worker setup
def warm_up(engine: str, doc: dict | None) -> None:
    """Load the model and, for the compiled engine, the kernel (one simulator built on ``doc``, not run).
    Errors are swallowed: a walk that then fails reports them in its row."""
    STATS["warm_ups"] += 1
    try:
        model()
        if doc is not None and engine == "pinocchio":
            from humanoid_sim import api
            from humanoid_sim.scenario.schema import parse_scenario

            api.prepare(parse_scenario(doc, "<warm-up>"), engine)
    except Exception:  # noqa: BLE001
        pass


def worker_stats() -> dict[str, int]:
    """This process's :data:`STATS` and pid (for ``Client.run``)."""
    return {**STATS, "pid": os.getpid()}


try:  # the plugin base class is only needed where dask is installed (the runner imports this module anyway)
    from distributed.diagnostics.plugin import WorkerPlugin
except ImportError:  # pragma: no cover
    WorkerPlugin = object  # type: ignore[assignment,misc]


class WalkSetup(WorkerPlugin):  # type: ignore[misc,valid-type]
    """Dask worker plugin: :func:`warm_up` when a worker joins (also a worker restarted after a crash), in a
    thread so that the worker's event loop keeps answering the scheduler meanwhile."""

    name = "humanoid-sweep-setup"

    def __init__(self, engine: str, doc: dict | None) -> None:
        self.engine = engine
        self.doc = doc

    async def setup(self, worker: Any) -> None:
        await asyncio.to_thread(warm_up, self.engine, self.doc)
