"""What every figure shares: file writing, the header with its legend, phase shading.

The figure modules import matplotlib when they first build a figure (:func:`new_figure`), not when they are
imported: a walk's own process then loads it only if it draws a figure itself (``walk.py``'s figures are drawn by
worker processes, :mod:`humanoid_sim.outputs.plots.pool`)."""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from humanoid_sim.outputs.colours import PHASE_COLOURS, REFERENCE_COLOUR

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

REFERENCE_STYLE = dict(color=REFERENCE_COLOUR, ls="--", lw=1.0)

REAL_CONTACT_ENGINES = ("mujoco",)
"""Engines with real, unilateral ground contact; the others (``pinocchio``, ``thesis``) weld the supporting feet."""


def real_contact(engine: str | None) -> bool:
    """Whether a run's engine (summary.json's ``engine``, results.npz's ``engine``) has real, unilateral ground
    contact, so that its figures speak of contact forces and the planned support rather than of welds.  None (an
    unknown engine) reads as the default, welded one."""
    return engine in REAL_CONTACT_ENGINES


def engine_of(r: dict[str, np.ndarray], engine: str | None = None) -> str | None:
    """The engine of a run: ``engine`` when given, else the ``engine`` entry of its results.npz (None without)."""
    if engine is not None:
        return engine
    e = r.get("engine")
    return None if e is None else str(np.asarray(e))


@cache
def _figure_class() -> type[Figure]:
    """matplotlib's Figure class, imported on the first call, which also selects the Agg backend (once, as importing
    these modules did before they imported matplotlib lazily)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    return Figure


def new_figure(**kwargs: Any) -> Figure:
    """A bare :class:`matplotlib.figure.Figure` (not registered with pyplot) with ``kwargs``."""
    return _figure_class()(**kwargs)


def _save(fig: Figure, path: Path, dpi: int = 120) -> Path:
    fig.savefig(path, dpi=dpi)
    return path


HEADER_IN = 0.85
"""Height of the band above the plots (inches): the title on the first line, the legends on the second."""


def _header(fig: Figure, title: str, handles: list, phases: list[str] | None, left: float = 0.02) -> None:
    """Title at the top left; below it, the data legend (left) and the phase-shading legend (right), both outside
    the plotting area so that they cover neither the title nor a line."""
    from matplotlib.patches import Patch

    h_in = fig.get_figheight()
    fig.suptitle(title, x=left, y=1 - 0.08 / h_in, ha="left", va="top", fontsize=11)
    y = 1 - 0.42 / h_in
    if handles:
        fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(left, y), ncol=len(handles), fontsize=7,
                   frameon=False, borderaxespad=0.0, handlelength=2.2)
    if phases:
        patches = [Patch(visible=False, label="phase shading:")]
        patches += [Patch(color=PHASE_COLOURS[n], alpha=0.25, label=n) for n in phases]
        fig.legend(handles=patches, loc="upper right", bbox_to_anchor=(0.995, y), ncol=len(patches), fontsize=7,
                   frameon=False, borderaxespad=0.0, handlelength=1.5, columnspacing=1.0)


def _phases_present(r: dict[str, np.ndarray]) -> list[str]:
    names = {str(x) for x in np.asarray(r["phase_names"])[np.unique(r["phase"])]}
    return [n for n in PHASE_COLOURS if n in names]


def _handle(label: str, **style: Any) -> Line2D:
    from matplotlib.lines import Line2D

    return Line2D([], [], label=label, **style)


def _phase_runs(phase: np.ndarray) -> list[tuple[int, int]]:
    """[first, last] step of each run of equal phase index."""
    cuts = np.flatnonzero(np.diff(phase)) + 1
    starts = np.concatenate([[0], cuts])
    ends = np.concatenate([cuts - 1, [len(phase) - 1]])
    return list(zip(starts.tolist(), ends.tolist()))


def shade_phases(ax, t: np.ndarray, phase: np.ndarray, names: list[str], alpha: float = 0.12) -> None:
    """Shade each phase of a run in its thesis colour (span: its first step to the next phase's first step, s)."""
    h = float(np.median(np.diff(t))) if len(t) > 1 else 0.01
    for a, b in _phase_runs(phase):
        t1 = t[b + 1] if b + 1 < len(t) else t[b] + h
        ax.axvspan(t[a], t1, color=PHASE_COLOURS.get(names[phase[a]], "#808080"), alpha=alpha, lw=0)


def _shade(ax, r: dict[str, np.ndarray]) -> None:
    shade_phases(ax, r["t"], r["phase"], [str(x) for x in r["phase_names"]])


def _line(ax, r: dict[str, np.ndarray], signal: str, index: tuple[int, ...], **kw):
    """Plot ``r[signal][:, *index]`` against t, tagged with its gid."""
    y = r[signal][(slice(None),) + index]
    (line,) = ax.plot(r["t"], y, **kw)
    line.set_gid(f"{signal}:{','.join(str(i) for i in index)}")
    return line
