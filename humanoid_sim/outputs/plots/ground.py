"""The ground figure: the ground reaction per foot over time, and the ground view (soles, support polygons, centres
of pressure and ZMP, outside points marked)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from humanoid_sim.outputs.colours import FOOT_COLOURS, FOOT_NAMES, OUTSIDE_COLOUR, REFERENCE_COLOUR, ZMP_COLOUR
from humanoid_sim.outputs.plots.common import (
    HEADER_IN,
    REFERENCE_STYLE,
    _handle,
    _header,
    _line,
    _phase_runs,
    _phases_present,
    _shade,
    new_figure,
)

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from humanoid_sim.analysis.audit import AuditReport

WINDOW_M = 2.0
"""m: the ground view of a walk whose soles span more than this shows a square window of this size (a 60 s walk
spans ~12 m, where a 5 cm sole margin would be a few pixels)."""


def ground_window(report: AuditReport) -> tuple[tuple[float, float], tuple[float, float], float] | None:
    """The ground view's window: ((x0, x1), (y0, y1), t) in m and s, centred on the ZMP (or the soles) at the step
    with the smallest ZMP margin, or None when every sole of the walk fits in :data:`WINDOW_M`."""
    corners = [P for row in report.polygons for P in row if P is not None and np.all(np.isfinite(P))]
    if not corners:
        return None
    pts = np.concatenate(corners)
    if float(np.max(np.ptp(pts, axis=0))) <= WINDOW_M:
        return None
    margin = np.where(np.isfinite(report.zmp_margin), report.zmp_margin, np.inf)
    k = int(np.argmin(margin)) if np.isfinite(margin).any() else len(margin) - 1
    centre = report.zmp[k] if np.all(np.isfinite(report.zmp[k])) else None
    if centre is None:   # no ZMP at that step: the middle of its soles
        soles = [P for P in report.polygons[k] if P is not None and np.all(np.isfinite(P))]
        centre = np.mean(np.concatenate(soles), axis=0) if soles else np.mean(pts, axis=0)
    half = WINDOW_M / 2.0
    cx, cy = float(centre[0]), float(centre[1])
    return (cx - half, cx + half), (cy - half, cy + half), float(report.t[k])


def _support_outlines(r: dict[str, np.ndarray], report: AuditReport) -> list[tuple[int, str, np.ndarray]]:
    """(phase run start step, foot or "support", closed outline (k + 1, 2)) of every phase run: each supporting
    sole's polygon at the run's first step (the feet are welded during a phase, so it holds for the whole run) and, in
    double support, the support polygon (convex hull of both)."""
    from humanoid_sim.analysis.audit import convex_hull

    out = []
    for a, _ in _phase_runs(r["phase"]):
        polys = report.polygons[a]
        present = [p for p in polys if p is not None and np.all(np.isfinite(p))]
        for f, foot in enumerate(("R", "L")):
            P = polys[f]
            if P is not None and np.all(np.isfinite(P)):
                out.append((a, foot, np.vstack([P, P[:1]])))
        if len(present) == 2:
            H = convex_hull(np.concatenate(present))
            out.append((a, "support", np.vstack([H, H[:1]])))
    return out


def contact_world_figure(r: dict[str, np.ndarray], report: AuditReport) -> Figure:
    """The ground reaction per foot over time (vertical force, CoP and ZMP coordinates) beside the ground view.

    On a walk whose soles span more than :data:`WINDOW_M`, the ground view shows a square window of that size around
    the moment of the smallest ZMP margin (the title says which), so that soles and points stay readable.

    Args:
        r: the run's results arrays (``results.npz``).
        report: the run's contact audit.
    """
    from matplotlib.gridspec import GridSpec

    h_in = HEADER_IN + 0.75 + 3 * 2.0
    fig = new_figure(figsize=(13, h_in))
    gs = GridSpec(3, 2, figure=fig, width_ratios=(1.55, 1.0), left=0.07, right=0.985, top=1 - (HEADER_IN + 0.25) / h_in,
                  bottom=0.5 / h_in, hspace=0.12, wspace=0.18)
    axes = [fig.add_subplot(gs[0, 0])]
    axes += [fig.add_subplot(gs[i, 0], sharex=axes[0]) for i in (1, 2)]
    for ax in axes:
        _shade(ax, r)
        ax.grid(True, lw=0.3)
    for ax in axes[:2]:
        ax.tick_params(labelbottom=False)
    axes[2].set_xlabel("t [s]")
    for f, foot in enumerate(("R", "L")):
        _line(axes[0], r, "foot_wrench", (f, 2), color=FOOT_COLOURS[foot])
    axes[0].set_ylabel("vertical force F_z [N]")
    for i, ax in zip((0, 1), axes[1:]):
        for f, foot in enumerate(("R", "L")):
            _line(ax, r, "cop", (f, i), color=FOOT_COLOURS[foot])
        _line(ax, r, "zmp", (i,), color=ZMP_COLOUR, lw=1)
        ax.set_ylabel(f"CoP and ZMP {'xy'[i]} [m]")

    # ground view: supporting soles, support polygons, CoP and ZMP, red where outside
    g = fig.add_subplot(gs[:, 1])
    g.set_label("ground view")
    for a, who, P in _support_outlines(r, report):
        if who == "support":
            (line,) = g.plot(P[:, 0], P[:, 1], color=REFERENCE_COLOUR, lw=0.8, ls="--")
        else:
            (line,) = g.plot(P[:, 0], P[:, 1], color=FOOT_COLOURS[who], lw=0.9)
        line.set_gid(f"ground:sole_{who}:{a}" if who != "support" else f"ground:support:{a}")
    for f, foot in enumerate(("R", "L")):
        c = report.cop[:, f]
        ok = np.isfinite(c[:, 0])
        out = report.cop_outside[:, f] & ok
        (line,) = g.plot(c[ok & ~out, 0], c[ok & ~out, 1], ".", ms=2.5, color=FOOT_COLOURS[foot])
        line.set_gid(f"ground:cop_{foot}")
        (line,) = g.plot(c[out, 0], c[out, 1], "x", ms=3, mew=0.8, color=OUTSIDE_COLOUR)
        line.set_gid(f"ground:cop_{foot}_outside")
    z = report.zmp
    ok = np.isfinite(z[:, 0])
    out = report.zmp_outside & ok
    (line,) = g.plot(z[ok & ~out, 0], z[ok & ~out, 1], "o", ms=2.5, mfc="none", mew=0.7, color=ZMP_COLOUR)
    line.set_gid("ground:zmp")
    (line,) = g.plot(z[out, 0], z[out, 1], "+", ms=4, mew=0.8, color=OUTSIDE_COLOUR)
    line.set_gid("ground:zmp_outside")
    g.grid(True, lw=0.3)
    g.set_xlabel("x [m]")
    g.set_ylabel("y [m]")
    window = ground_window(report)
    if window is None:
        g.set_aspect("equal", adjustable="datalim")
        g.set_title("ground view: soles, support polygons, CoP and ZMP", fontsize=9)
    else:
        (x0, x1), (y0, y1), t = window
        g.set_xlim(x0, x1)
        g.set_ylim(y0, y1)
        g.set_aspect("equal", adjustable="box")
        g.set_title(f"ground view, a {WINDOW_M:g} m window at t = {t:.2f} s (smallest ZMP margin):\nsoles, support "
                    "polygons, CoP and ZMP", fontsize=9)
    handles = ([_handle(f"{FOOT_NAMES[f]}: F_z, CoP, sole", color=FOOT_COLOURS[f], marker=".", ms=5)
                for f in ("R", "L")]
               + [_handle("whole-body ZMP", color=ZMP_COLOUR, marker="o", mfc="none", ms=4),
                  _handle("support polygon (double support)", **REFERENCE_STYLE),
                  _handle("outside its sole / support polygon", color=OUTSIDE_COLOUR, marker="x", ls="none")])
    _header(fig, "Ground reaction per foot (world frame), centre of pressure and ZMP", handles, _phases_present(r),
            left=0.01)
    return fig


__all__ = ["WINDOW_M", "contact_world_figure", "ground_window"]
