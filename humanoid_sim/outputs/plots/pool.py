"""Figure workers started ahead of the figures: processes that load matplotlib and the figure modules (and draw one
throw-away figure, which loads the fonts: :func:`humanoid_sim.outputs.plots.thesis.warm_up`) while their caller is
still simulating.

:func:`~humanoid_sim.outputs.plots.thesis.plot_all` draws a run's figures in worker processes.  Started at that
moment, each worker first spends ~0.5 s importing matplotlib and the figure modules (or the caller imports them
before the workers fork), after the walk, on its critical path.  ``walk.py`` calls :func:`start` before it
simulates instead: the workers warm up on the second core while the walk runs on the first, :func:`plot_all` hands
them the figures as soon as results.npz is written (:func:`running`), and the walk's own process never imports
matplotlib.  :func:`stop` ends them.  Where ``fork`` is not available (Windows), :func:`start` does nothing and
:func:`plot_all` starts its workers as before.

A worker ignores Ctrl-C (SIGINT), which the terminal sends to every process of the walk, and dies of SIGTERM: the
walk stops its workers itself (:func:`stop`), without a traceback from each.  After its warm-up a worker freezes
what it has loaded out of the garbage collector's full collections, which otherwise cost ~0.1 s in the middle of a
figure.
"""

from __future__ import annotations

import gc
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager

MAX_WORKERS = 4
"""Most figure worker processes (matplotlib spends ~0.2 s per figure; more workers than cores only contend)."""

_pool: ProcessPoolExecutor | None = None
_size = 0


def default_workers(n_figures: int) -> int:
    """Worker processes for ``n_figures`` figures: one per CPU, at most :data:`MAX_WORKERS` and one per figure."""
    return min(MAX_WORKERS, os.cpu_count() or 1, max(1, n_figures))


def _warm(warm_up: Callable[[], None]) -> None:
    """A worker's start: Ctrl-C left to the walk, ``warm_up()`` (best effort: whatever fails there fails again, with
    its own message, when the worker draws a real figure), then what the worker has loaded frozen out of the garbage
    collector's full collections (``gc.freeze``)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)   # (walk.py's handler turns SIGTERM into an interrupt: not here)
    try:
        warm_up()
    except Exception:  # (see the docstring)
        pass
    gc.freeze()   # the full collections while the figures draw skip what is loaded now (~0.1 s each)


def _ready() -> bool:
    return True


def start(n_figures: int, warm_up: Callable[[], None]) -> ProcessPoolExecutor | None:
    """Start the worker processes for ``n_figures`` figures now (:func:`default_workers` of them; none for one
    worker, which :func:`plot_all` replaces by drawing in its own process), each running ``warm_up()`` first
    (:func:`humanoid_sim.outputs.plots.thesis.warm_up`); the pool, or None."""
    global _pool, _size
    if _pool is not None:
        return _pool
    n = default_workers(n_figures)
    if n < 2 or "fork" not in multiprocessing.get_all_start_methods():
        return None
    _pool = ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("fork"), initializer=_warm,
                                initargs=(warm_up,))
    _size = n
    with _signals_ignored():   # the workers are born ignoring Ctrl-C and SIGTERM (see the module docstring)
        _pool.submit(_ready)   # forks every worker now (with fork, the first task launches them all)
    return _pool


@contextmanager
def _signals_ignored():
    """SIGINT ignored and SIGTERM at its default in this process (and so in a process forked meanwhile), then
    restored; nothing outside the main thread, where signal handlers cannot be set."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN), signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous[0])
        signal.signal(signal.SIGTERM, previous[1])


def running() -> tuple[ProcessPoolExecutor, int] | None:
    """The pool :func:`start` started and its worker count, or None."""
    return None if _pool is None else (_pool, _size)


def stop() -> None:
    """Stop the workers :func:`start` started (waiting for the ones still warming up; idempotent)."""
    global _pool, _size
    pool, _pool, _size = _pool, None, 0
    if pool is not None:
        pool.shutdown(wait=True, cancel_futures=True)
