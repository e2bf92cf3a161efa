"""The push-recovery benchmark's outputs: the table (``push.parquet``, ``push.csv``), the side-by-side text table
(``push.md``) and the polar figure (``push.png``) of :mod:`humanoid_sim.sweep.push`'s results.

Delta-v is the whole robot's: impulse / mass, m/s.  Directions are in the heading frame (0 deg forward, 90 deg left);
the figure draws them so, forward up and left on the left.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from humanoid_sim.sweep.push import TARGETS_MPS, Benchmark, Outcome, direction_label, side_of, swing_foot, target_mps


def table_rows(bench: Benchmark, outcome: Outcome) -> list[dict[str, Any]]:
    """One row per cell (the scenario as given first, then the compared controller), in the order of the cells.

    Columns: ``scenario``, ``controller``, ``phase``, ``phase_name``, ``swing_foot``, ``instant``, ``fraction``,
    ``direction_deg`` (heading frame), ``direction_label``, ``side`` (swing / stance / empty), ``survived_Ns`` (the
    largest impulse survived), ``survived_dv_mps`` (its delta-v), ``failed_Ns`` and ``failed_dv_mps`` (the smallest
    failed; None when every probe up to the maximum survived), ``failure_reason`` (of that probe), ``probes``,
    ``target_dv_mps`` and ``meets_target`` (pushes straight forward, backward or sideways), ``mass_kg``,
    ``unpushed_completed`` (whether the controller's walk without a push completed: the bisection assumes it).
    """
    rows = []
    for cell in bench.cells:
        b = outcome.bisections[cell]
        m = outcome.mass_kg.get(cell.controller)
        target = target_mps(cell.direction_deg, cell.phase_name)
        survived_dv = _per_kg(b.survived, m)
        rows.append({
            "scenario": bench.name, "controller": cell.controller, "phase": cell.phase,
            "phase_name": cell.phase_name, "swing_foot": swing_foot(cell.phase_name), "instant": cell.instant,
            "fraction": cell.fraction, "direction_deg": cell.direction_deg,
            "direction_label": direction_label(cell.direction_deg, cell.phase_name),
            "side": side_of(cell.direction_deg, cell.phase_name), "survived_Ns": b.survived,
            "survived_dv_mps": survived_dv, "failed_Ns": b.failed, "failed_dv_mps": _per_kg(b.failed, m),
            "failure_reason": b.failed_reason, "probes": len(b.probes), "target_dv_mps": target,
            "meets_target": None if target is None or survived_dv is None else bool(survived_dv >= target),
            "mass_kg": m, "unpushed_completed": (outcome.nominal.get(cell.controller) or {}).get("completed")})
    return rows


def _per_kg(impulse: float | None, mass: float | None) -> float | None:
    """Delta-v, m/s, of an impulse (N s) on a mass (kg); None when either is unknown."""
    return None if impulse is None or not mass else impulse / mass


def write_table(rows: list[dict[str, Any]], out: Path) -> None:
    """``push.parquet`` and ``push.csv`` in ``out``, each written atomically."""
    import io

    import pyarrow as pa
    import pyarrow.csv as pa_csv
    import pyarrow.parquet as pq

    from humanoid_sim.interfaces.log import atomic_write_bytes

    table = pa.Table.from_pylist(rows)
    buf = io.BytesIO()
    pq.write_table(table, buf)
    atomic_write_bytes(Path(out) / "push.parquet", buf.getvalue())
    buf = io.BytesIO()
    pa_csv.write_csv(table, buf)
    atomic_write_bytes(Path(out) / "push.csv", buf.getvalue())


def _fmt(impulse: float | None, dv: float | None) -> str:
    if impulse is None:
        return "-"
    return f"{impulse:.2f} N s ({dv:.2f} m/s)" if dv is not None else f"{impulse:.2f} N s"


def side_by_side(rows: list[dict[str, Any]]) -> str:
    """A Markdown table, one line per phase, instant and direction, one column per controller: the largest
    impulse survived and its delta-v, ``>=`` when the maximum itself was survived, and the target."""
    controllers = list(dict.fromkeys(r["controller"] for r in rows))
    cells: dict[tuple, dict[str, dict]] = {}
    for r in rows:
        key = (r["phase"], r["phase_name"], r["instant"], r["fraction"], r["direction_deg"], r["direction_label"],
               r["target_dv_mps"])
        cells.setdefault(key, {})[r["controller"]] = r
    head = ["phase", "instant", "direction (heading frame)", *[f"survived: {c}" for c in controllers],
            "target"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for (k, name, instant, frac, d, label, target), by in cells.items():
        vals = []
        for c in controllers:
            hit = by.get(c)
            if hit is None:
                vals.append("")
                continue
            text = _fmt(hit["survived_Ns"], hit["survived_dv_mps"])
            vals.append((">= " if hit["failed_Ns"] is None else "") + text)
        lines.append(f"| {k} {name} | {instant} ({frac:g}) | {d:g} deg {label} | " + " | ".join(vals)
                     + f" | {'' if target is None else f'{target:g} m/s'} |")
    return "\n".join(lines) + "\n"


def plot_polar(rows: list[dict[str, Any]], path: Path, title: str = "") -> None:
    """``push.png``: one polar panel per pushed phase and instant (rows: phases, columns: instants), radius the
    largest delta-v survived (m/s), angle the push direction (heading frame, forward up, left on the left), one
    closed line per controller (an open triangle where the maximum impulse itself was survived); the targets
    (:data:`humanoid_sim.sweep.push.TARGETS_MPS`) as stars."""
    import math

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phases = list(dict.fromkeys((r["phase"], r["phase_name"]) for r in rows))
    instants = list(dict.fromkeys((r["instant"], r["fraction"]) for r in rows))
    controllers = list(dict.fromkeys(r["controller"] for r in rows))
    fig, axes = plt.subplots(len(phases), len(instants), subplot_kw={"projection": "polar"}, squeeze=False,
                             figsize=(max(4.2 * len(instants), 7.0), 4.4 * len(phases) + 1.2))
    rmax = max([r["survived_dv_mps"] or 0.0 for r in rows] + list(TARGETS_MPS.values())) * 1.15
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (k, name) in enumerate(phases):
        for j, (instant, frac) in enumerate(instants):
            ax = axes[i][j]
            ax.set_theta_zero_location("N")   # forward up; angles counter-clockwise: left on the left
            for n, c in enumerate(controllers):
                sel = sorted((r for r in rows if r["controller"] == c and r["phase"] == k
                              and r["instant"] == instant), key=lambda r: r["direction_deg"])
                if not sel:
                    continue
                th = [math.radians(r["direction_deg"]) for r in sel]
                rr = [r["survived_dv_mps"] or 0.0 for r in sel]
                colour = colours[n % len(colours)]
                ax.plot(th + th[:1], rr + rr[:1], "o-", color=colour, ms=4, label=c)
                capped = [(t, x) for t, x, r in zip(th, rr, sel) if r["failed_Ns"] is None]
                if capped:
                    ax.plot(*zip(*capped), "^", color=colour, mfc="none", ms=9)
            marks = [(0.0, TARGETS_MPS["forward"]), (180.0, TARGETS_MPS["backward"])]
            swing_left = swing_foot(name) == "L"
            marks += [(90.0 if swing_left else 270.0, TARGETS_MPS["toward the swing foot"]),
                      (270.0 if swing_left else 90.0, TARGETS_MPS["toward the stance foot"])]
            ax.plot([math.radians(a) for a, _ in marks], [v for _, v in marks], "*", color="crimson", ms=11,
                    label="target (mid single support)")
            ax.set_rlim(0.0, rmax)
            ax.set_rlabel_position(67.5)   # between forward-left and left, clear of the compass labels
            ax.set_xticks([math.radians(a) for a in range(0, 360, 45)])
            ax.set_xticklabels([_tick(a, name) for a in range(0, 360, 45)], fontsize=7)
            ax.set_title(f"phase {k} {name} (swing {swing_foot(name)}), {instant} ({frac:g})", fontsize=9)
            ax.tick_params(axis="y", labelsize=7)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 3), fontsize=8, frameon=False)
    fig.suptitle(title or "largest push survived: whole-body delta-v, m/s", fontsize=10)
    fig.tight_layout(rect=(0, 0.08, 1, 0.94))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _tick(angle: int, phase_name: str) -> str:
    """The compass name of a direction, with (swing) / (stance) for the sideways ones."""
    side = side_of(angle, phase_name)
    return direction_label(angle, phase_name).split(",")[0] + (f"\n({side})" if side and angle % 90 == 0 else "")
