"""Figures of a sweep: actuator sizing (``sizing.png``) and the completion/feasibility map (``feasibility.png``).

- :func:`plot_sizing`: per actuator (the 26 thesis torques T1..T26, eq. 4.69 order), the distribution over the
  completed walks of the peak applied |T| and of the peak commanded |T_cmd| (what the controller asked for before
  saturation), both as a fraction of the actuator's saturation limit
  (:attr:`humanoid_sim.robot.actuators.Actuators.limits`);
  below, the share of completed walks in which the actuator saturated at least once.  A sweep with a text axis
  (a choice of gait) draws one box per choice instead (:func:`sizing_group`).
- :func:`plot_feasibility` (:func:`feasibility_figure`): one row of panels per value of the sweep's text axis (a
  gait; never pooled), and in each row, over the first two other swept parameters, the share of walks that
  completed, the fraction of steps with a saturated actuator and the contact audit's infeasible fraction of steps
  (both means over the completed walks).  Grid parameters give a table of cells (further parameters pooled in each
  cell); a cell in which every walk failed is hatched and reads "failed" on every panel.  When a random parameter
  is among the two, one marker per walk, a failed walk an "x".  Axes are labelled in physical units
  (:mod:`humanoid_sim.sweep.labels`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from humanoid_sim.sweep.spec import Axis

FAILED_COLOUR = "#c0392b"


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _num(x: Any) -> float:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) and x is not None else math.nan


def actuator_labels() -> list[str]:
    """Axis labels of the 26 actuators (T-bar order): name, joint and moment axis in the higher body's frame
    (x forward = roll, y left = pitch, z up = yaw at the zero posture)."""
    from humanoid_sim.robot.actuators import GROUPS

    out = []
    for g in GROUPS:
        side, _, joint = g.name.partition("_") if g.name.startswith(("right_", "left_")) else ("", "", g.name)
        joint = {"shoulder": "shldr"}.get(joint, joint)   # fits the tick spacing
        for t, c in zip(g.T, g.comps):
            out.append(f"{t}\n{side[:1].upper() + ' ' if side else ''}{joint}\n{('roll', 'pitch', 'yaw')[c]}")
    return out


GROUP_COLOURS = ("#2e86c1", "#27ae60", "#8e44ad", "#d35400")
"""Box colours of the groups of :func:`plot_sizing` (e.g. the two gaits), in the order the groups first appear."""


def plot_sizing(rows: Sequence[dict[str, Any]], names: Sequence[str], limits: Sequence[float], path: Path,
                title: str = "", labels: Sequence[str] | None = None, group: str | None = None,
                joints: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Write the actuator-sizing figure of the completed ``rows`` to ``path`` (PNG).  ``names``: actuator names
    (``T1`` ...), ``limits``: their saturation limits, N m; ``labels``: tick labels (default: the names).

    ``group``: a row column that splits the walks (e.g. ``gait.hip_reference``: the two gaits ask very different
    torques of the ankle, and pooled boxes would hide which gait needs what).  Without it, each actuator has a box
    of the peak applied |T| and one of the peak commanded |T_cmd|; with it, one box of the peak applied |T| per
    group value (side by side, one colour each) and a marker at the largest commanded |T_cmd| of that group, and
    the saturation bars per group.

    ``joints``: per actuator the thesis joint variable whose axis it drives at the reference posture
    (:func:`humanoid_sim.analysis.design.joint_limits`); with it, two more panels show per joint the walks' peak speed
    (rad/s) and peak mechanical power (W) from the rows' design columns, in the same column as the torque.

    Returns what the boxes show: per set (its legend label; "" without ``group``), the (walks, actuators) array
    of peak applied |T| / limit."""
    plt = _plt()
    done = [r for r in rows if r.get("completed")]
    lim = np.asarray(limits, dtype=float)

    def peaks(rs: list[dict[str, Any]], key: str) -> list[np.ndarray]:
        return [np.array([_num(r.get(f"{key}_{n}")) for r in rs]) / lim[i] for i, n in enumerate(names)]

    def saturating(rs: list[dict[str, Any]]) -> np.ndarray:
        return np.array([np.mean([_num(r.get(f"saturated_fraction_per_actuator_{n}")) > 0 for r in rs]) if rs
                         else 0.0 for n in names], dtype=float)

    values: list[Any] = []
    if group is not None:
        for r in done:
            if r.get(group) not in values:
                values.append(r.get(group))
    sets = [(f"{group} = {_label(v)}", [r for r in done if r.get(group) == v]) for v in values] if values else \
        [("", done)]
    applied = {label: peaks(rs, "torque_peak_Nm") for label, rs in sets}   # what the boxes show, per set
    if joints is None:
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(14, 8), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
        extra = []
    else:
        fig, (ax, ax3, ax4, ax2) = plt.subplots(4, 1, figsize=(14, 12), sharex=True,
                                                gridspec_kw={"height_ratios": [3, 1.5, 1.5, 1]})
        extra = [(ax3, "speed_peak_rad_s", "peak speed\n[rad/s]"), (ax4, "power_peak_W", "peak power\n[W]")]
    x = np.arange(len(names))

    def box(data: list[np.ndarray], dx: float, width: float, colour: str, label: str) -> None:
        clean = [d[np.isfinite(d)] for d in data]
        bp = ax.boxplot(clean, positions=x + dx, widths=width, patch_artist=True, showfliers=True,
                        flierprops={"markersize": 3, "markeredgecolor": colour},
                        medianprops={"color": "black"}, whis=(0, 100), manage_ticks=False)
        for b in bp["boxes"]:
            b.set_facecolor(colour)
            b.set_alpha(0.75)
        ax.plot([], [], "s", color=colour, label=label)

    n_sets = len(sets)
    width = 0.8 / n_sets          # per group's box (the grouped figure)
    if not done:
        ax.text(0.5, 0.5, "no completed walk", transform=ax.transAxes, ha="center", va="center", fontsize=14)
    elif group is None:
        box(applied[""], -0.2, 0.32, GROUP_COLOURS[0], "peak applied |T| (after saturation)")
        box(peaks(done, "torque_cmd_peak_Nm"), 0.2, 0.32, "#aab7b8", "peak commanded |T_cmd| (before saturation)")
    else:
        for j, (label, rs) in enumerate(sets):
            colour = GROUP_COLOURS[j % len(GROUP_COLOURS)]
            dx = (j - (n_sets - 1) / 2) * width
            box(applied[label], dx, width * 0.8, colour,
                f"{label}: peak applied |T| ({len(rs)} walks)")
            cmd = np.array([np.nanmax(c) if np.isfinite(c).any() else np.nan
                            for c in peaks(rs, "torque_cmd_peak_Nm")])
            ax.plot(x + dx, cmd, "v", color=colour, markersize=4, markeredgecolor="black", markeredgewidth=0.4,
                    label=f"{label}: largest commanded |T_cmd| (before saturation)")
    ax.axhline(1.0, color=FAILED_COLOUR, ls=":", lw=1.5, label="saturation limit")
    ax.set_ylabel("peak torque / limit")
    ax.set_ylim(bottom=0.0)
    ax.set_xlim(-0.6, len(names) - 0.4)
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    ax.set_title(title or f"Actuator sizing over {len(done)} completed walks (of {len(rows)})")
    if group is None:
        ax2.bar(x, 100 * saturating(done), color="#e67e22")
    else:
        for j, (label, rs) in enumerate(sets):
            ax2.bar(x + (j - (n_sets - 1) / 2) * width, 100 * saturating(rs), width=width * 0.8,
                    color=GROUP_COLOURS[j % len(GROUP_COLOURS)], label=label)
    for axe, key, ylabel in extra:   # per joint axis: the walks' peak speed and power, one box per set
        assert joints is not None
        for j, (_, rs) in enumerate(sets):
            colour = GROUP_COLOURS[j % len(GROUP_COLOURS)]
            data = [np.array([_num(r.get(f"design_joints_{th}_{key}")) for r in rs]) for th in joints]
            clean = [d[np.isfinite(d)] for d in data]
            dx = (j - (n_sets - 1) / 2) * width
            if any(len(c) for c in clean):
                bp = axe.boxplot(clean, positions=x + dx, widths=width * 0.8, patch_artist=True, whis=(0, 100),
                                 medianprops={"color": "black"}, manage_ticks=False, showfliers=False)
                for b in bp["boxes"]:
                    b.set_facecolor(colour)
                    b.set_alpha(0.75)
        axe.set_ylabel(ylabel)
        axe.set_ylim(bottom=0.0)
        axe.grid(axis="y", alpha=0.3)
    ax2.set_ylabel("walks\nsaturating, %")
    ax2.set_ylim(0, 105)
    ax2.grid(axis="y", alpha=0.3)
    ax2.set_xticks(x)
    ax2.set_xticklabels([f"{lb}\n{v:g}" for lb, v in zip(labels or names, lim)], fontsize=7)
    ax2.set_xlabel("actuator (thesis eq. 4.69 order), joint, axis, and its limit in N m")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return {label: np.array(a).T for label, a in applied.items()}


def sizing_group(axes: Sequence[Axis]) -> str | None:
    """The column :func:`plot_sizing` splits the walks by: the first grid axis whose values are all text (e.g.
    ``gait.hip_reference``, a choice of gait), or None."""
    for a in axes:
        if a.values and len(a.values) > 1 and all(isinstance(v, str) for v in a.values):
            return a.column
    return None


def _label(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    s = v if isinstance(v, str) else json.dumps(v)
    return s if len(s) <= 18 else s[:15] + "..."


METRICS = (("saturated_fraction", "steps with an actuator saturated, fraction"),
           ("contact_infeasible_fraction", "contact-infeasible steps, fraction (audit)"))
"""Row columns the feasibility map shows next to completion (mean over the completed walks), with their titles."""


def feasibility_cells(rows: Sequence[dict[str, Any]], ax_x: Axis, ax_y: Axis | None
                      ) -> tuple[list, list, np.ndarray, np.ndarray, list[np.ndarray]]:
    """The cells of the map over two grid axes: x values, y values ([None] without ``ax_y``), walks per cell
    ``n`` and completed walks ``ok`` (arrays [y, x]), and per :data:`METRICS` column its mean over the completed
    walks of the cell that have it (NaN where none).  Rows whose values are not on the axes are left out."""
    xs = [ax_x.cell(v) for v in ax_x.values]
    ys = [ax_y.cell(v) for v in ax_y.values] if ax_y is not None else [None]
    n = np.zeros((len(ys), len(xs)))
    ok = np.zeros_like(n)
    sums = [np.zeros_like(n) for _ in METRICS]
    counts = [np.zeros_like(n) for _ in METRICS]
    for r in rows:
        try:
            i = xs.index(r.get(ax_x.column))
            j = ys.index(r.get(ax_y.column)) if ax_y is not None else 0
        except ValueError:
            continue
        n[j, i] += 1
        if not r.get("completed"):
            continue
        ok[j, i] += 1
        for m, (col, _) in enumerate(METRICS):
            v = _num(r.get(col))
            if np.isfinite(v):
                sums[m][j, i] += v
                counts[m][j, i] += 1
    means = [np.where(c > 0, sm / np.maximum(c, 1), np.nan) for sm, c in zip(sums, counts)]
    return xs, ys, n, ok, means


FAILED_HATCH = "xxx"
"""Hatch of a map cell in which every walk failed (on every panel: a failed cell has no value to colour)."""
NO_WALK = "#f2f2f2"


def map_layout(axes: Sequence[Axis]) -> tuple[str | None, list[Axis]]:
    """The feasibility map's panel split and map axes: the text axis (:func:`sizing_group`: one row of panels per
    value), and the first two other axes (x, then y)."""
    group = sizing_group(axes)
    return group, [a for a in axes if a.column != group][:2]


def _group_values(rows: Sequence[dict[str, Any]], axes: Sequence[Axis], group: str | None) -> list[Any]:
    if group is None:
        return [None]
    axis = next(a for a in axes if a.column == group)
    return list(axis.values) + [v for v in dict.fromkeys(r.get(group) for r in rows) if v not in axis.values]


def feasibility_figure(rows: Sequence[dict[str, Any]], axes: Sequence[Axis], title: str = "",
                       base_doc: dict | None = None) -> Any:
    """The completion/feasibility map of ``rows`` (a matplotlib Figure).

    One row of panels per value of the sweep's text axis (:func:`map_layout`: e.g. one per gait; never pooled), and
    per row the share of walks that completed, then each of :data:`METRICS` averaged over the completed walks.  The
    map's axes are the first two other axes, labelled in physical units (:mod:`humanoid_sim.sweep.labels`, from the
    base scenario ``base_doc``).  A cell in which every walk failed is hatched (:data:`FAILED_HATCH`) and reads
    "failed" on every panel; a cell with no walk is blank.  Random axes among the two: one marker per walk, a
    failed walk an "x"."""
    from matplotlib.patches import Patch, Rectangle

    from humanoid_sim.sweep.labels import axis_units

    plt = _plt()
    group, map_axes = map_layout(axes)
    ax_x = map_axes[0] if map_axes else None
    ax_y = map_axes[1] if len(map_axes) > 1 else None
    ux = axis_units(ax_x, base_doc) if ax_x is not None else None
    uy = axis_units(ax_y, base_doc) if ax_y is not None else None
    ug = axis_units(next(a for a in axes if a.column == group), base_doc) if group is not None else None
    values = _group_values(rows, axes, group)
    ncol = 1 + len(METRICS)
    fig, panels = plt.subplots(len(values), ncol, figsize=(6 * ncol, 4.6 * len(values)), squeeze=False)
    titles = ["walks completed"] + [label + ",\nmean over completed walks" for _, label in METRICS]
    grid = ax_x is not None and ax_x.values != () and (ax_y is None or ax_y.values != ())
    for g, gv in enumerate(values):
        rows_g = [r for r in rows if group is None or r.get(group) == gv]
        prefix = f"{ug.label} = {gv}: " if ug is not None else ""
        for k in range(ncol):
            panel = panels[g, k]
            panel.set_title(prefix + titles[k], fontsize=10)
            panel.set_xlabel(ux.label if ux is not None else "", fontsize=8)
            panel.set_ylabel(uy.label if uy is not None else "", fontsize=8)
        if ax_x is None:
            continue
        if grid:
            xs, ys, n, ok, means = feasibility_cells(rows_g, ax_x, ax_y)
            failed = (n > 0) & (ok == 0)
            share = np.where((n > 0) & ~failed, ok / np.maximum(n, 1), np.nan)
            data = [(share, "RdYlGn")] + [(np.where(failed, np.nan, m), "RdYlGn_r") for m in means]
            for k, (d, cmap) in enumerate(data):
                panel = panels[g, k]
                panel.set_facecolor(NO_WALK)
                im = panel.imshow(np.ma.masked_invalid(d), origin="lower", cmap=cmap, vmin=0.0, vmax=1.0,
                                  aspect="auto")
                fig.colorbar(im, ax=panel, fraction=0.046)
                for j in range(len(ys)):
                    for i in range(len(xs)):
                        if n[j, i] == 0:
                            text = "no walk"
                        elif failed[j, i]:
                            panel.add_patch(Rectangle((i - 0.5, j - 0.5), 1.0, 1.0, facecolor="#d9d9d9",
                                                      edgecolor=FAILED_COLOUR, hatch=FAILED_HATCH, lw=0.0,
                                                      gid="failed-cell"))
                            text = f"failed\n0/{int(n[j, i])}" if k == 0 else "failed"
                        elif k == 0:
                            text = f"{int(ok[j, i])}/{int(n[j, i])}"
                        else:
                            v = d[j, i]
                            text = ("-" if not np.isfinite(v) else f"{v:.2f}") + \
                                (f"\n({int(ok[j, i])}/{int(n[j, i])} done)" if ok[j, i] < n[j, i] else "")
                        panel.text(i, j, text, ha="center", va="center", fontsize=8,
                                   fontweight="bold" if failed[j, i] else "normal")
                panel.set_xticks(range(len(xs)))
                panel.set_xticklabels([ux.tick(v) for v in xs], fontsize=8)
                panel.set_yticks(range(len(ys)))
                panel.set_yticklabels([uy.tick(v) for v in ys] if uy is not None else [""], fontsize=8)
        else:   # a random parameter among the two: one marker per walk
            completed = np.array([bool(r.get("completed")) for r in rows_g], dtype=bool)

            def coords(u: Any, rs: list[dict[str, Any]]) -> tuple[np.ndarray, list[str] | None]:
                if u is None:
                    return np.zeros(len(rs)), None
                vals = [u.value(r.get(u.axis.column)) for r in rs]
                if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
                    return np.array(vals, dtype=float), None
                cats = list(dict.fromkeys(_label(v) for v in vals))
                return np.array([cats.index(_label(v)) for v in vals], dtype=float), cats

            x, xcats = coords(ux, rows_g)
            y, ycats = coords(uy, rows_g)
            for k in range(ncol):
                panel = panels[g, k]
                if k == 0:
                    panel.scatter(x[completed], y[completed], c="#27ae60", marker="o", s=30, label="completed")
                else:
                    m = np.array([_num(r.get(METRICS[k - 1][0])) for r in rows_g])
                    sc = panel.scatter(x[completed], y[completed], c=m[completed], cmap="RdYlGn_r", vmin=0.0,
                                       vmax=1.0, marker="o", s=30)
                    fig.colorbar(sc, ax=panel, fraction=0.046)
                panel.scatter(x[~completed], y[~completed], c=FAILED_COLOUR, marker="x", s=40, label="failed",
                              gid="failed-walks")
                if xcats:
                    panel.set_xticks(range(len(xcats)))
                    panel.set_xticklabels(xcats, fontsize=8)
                if ycats:
                    panel.set_yticks(range(len(ycats)))
                    panel.set_yticklabels(ycats, fontsize=8)
                panel.grid(alpha=0.3)
            panels[g, 0].legend(fontsize=8)
    fig.legend(handles=[Patch(facecolor="#d9d9d9", edgecolor=FAILED_COLOUR, hatch=FAILED_HATCH,
                              label="every walk of the cell failed")], loc="lower right", fontsize=8)
    fig.suptitle(title or f"Completion and feasibility over {len(rows)} walks")
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    return fig


def plot_feasibility(rows: Sequence[dict[str, Any]], axes: Sequence[Axis], path: Path, title: str = "",
                     base_doc: dict | None = None) -> None:
    """Write :func:`feasibility_figure` to ``path`` (PNG)."""
    plt = _plt()
    fig = feasibility_figure(rows, axes, title, base_doc)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
