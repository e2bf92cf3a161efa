"""The optimiser's figure ``pareto.png``: every candidate in the plane of the first two objectives (one objective:
against the trial number), the feasible front, the baseline design and the designs written out."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from humanoid_sim.sweep.design_file import DesignStudy
from humanoid_sim.sweep.optimize import ACCEPTED, BASELINE, pareto_front


def _value(row: dict[str, Any], key: str) -> float:
    v = row.get(key)
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan


def _zoom(ax: Any, keep: list[dict[str, Any]], rows: list[dict[str, Any]], xk: str, yk: str) -> int:
    """Limit the axes to the feasible candidates and the baseline, padded by half their span (a fallen walk's
    objectives can lie far off and would squeeze the front into a line); returns how many candidates fall outside."""
    import numpy as np

    pts = np.array([[_value(r, xk), _value(r, yk)] for r in keep], dtype=float).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) < 2:
        return 0
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = np.maximum(0.5 * (hi - lo), 0.05 * np.maximum(np.abs(hi), 1e-9))
    lo, hi = lo - pad, hi + pad
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    allp = np.array([[_value(r, xk), _value(r, yk)] for r in rows], dtype=float).reshape(-1, 2)
    return int(np.sum(~((allp >= lo) & (allp <= hi)).all(axis=1)))


def plot_pareto(study: DesignStudy, rows: list[dict[str, Any]], best: list[int], path: Path) -> Path:
    """Draw the figure (module docstring) into ``path`` (PNG) and return it.

    Args:
        study: the design file.
        rows: the candidates' rows (the baseline's trial is -1).
        best: the trial numbers of the designs written out (labelled).
        path: the PNG to write.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [f"objective:{o.label}" for o in study.objectives]
    cand = [r for r in rows if r["trial"] != BASELINE]
    base = next((r for r in rows if r["trial"] == BASELINE), None)
    front = pareto_front(study, rows)
    fig, ax = plt.subplots(figsize=(7.5, 5.5), dpi=110)
    two = len(labels) >= 2
    xk, yk = (labels[0], labels[1]) if two else ("trial", labels[0])
    for feasible, style in ((False, dict(marker="x", color="0.6", label="infeasible (fell, or a motor fails)")),
                            (True, dict(marker="o", color="tab:blue", label="feasible"))):
        pts = [r for r in cand if bool(r[ACCEPTED]) == feasible]
        ax.scatter([_value(r, xk) for r in pts], [_value(r, yk) for r in pts], s=28, alpha=0.8, **style)
    if front:
        if two:
            ax.plot([_value(r, xk) for r in front], [_value(r, yk) for r in front], "-", color="tab:red", lw=1.5,
                    label="feasible front", zorder=1)
        else:
            ordered = sorted(cand, key=lambda r: r["trial"])
            best_so_far, xs, ys = math.inf, [], []
            sign = 1.0 if study.objectives[0].direction == "minimize" else -1.0
            for r in ordered:
                v = _value(r, yk)
                if r[ACCEPTED] and math.isfinite(v) and sign * v < sign * best_so_far:
                    best_so_far = v
                if math.isfinite(best_so_far):
                    xs.append(r["trial"])
                    ys.append(best_so_far)
            ax.step(xs, ys, where="post", color="tab:red", lw=1.5, label="best feasible so far")
    if base is not None:
        bx = _value(base, xk) if two else -1
        by = _value(base, yk)
        if math.isfinite(by):
            ax.scatter([bx], [by], marker="*", s=220, color="black", zorder=5,
                       label=f"baseline ({study.base.stem}{'' if base[ACCEPTED] else ', infeasible'})")
    for r in cand:
        if r["trial"] in best:
            ax.annotate(f"trial {r['trial']}", (_value(r, xk), _value(r, yk)), textcoords="offset points",
                        xytext=(6, 6), fontsize=8, color="tab:red")
    hidden = _zoom(ax, [r for r in cand if r[ACCEPTED]] + ([base] if base is not None else []), cand, xk, yk)
    ax.set_xlabel(xk.removeprefix("objective:") + (f" ({study.objectives[0].direction})" if two else ""))
    ax.set_ylabel(yk.removeprefix("objective:") + f" ({study.objectives[1 if two else 0].direction})")
    n_feas = sum(1 for r in cand if r[ACCEPTED])
    ax.set_title(f"{study.source.stem}: {len(cand)} candidates on {study.engine}, {n_feas} feasible"
                 + (f" ({hidden} far outside, not shown)" if hidden else ""), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    plt.close(fig)
    return path


__all__ = ["plot_pareto"]
