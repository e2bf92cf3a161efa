"""The sizing card's files: the design table, fatigue cycles, load cases, the full-rate trace and the sizing figures.

- ``design.csv``: one row per joint (thesis joint variable, its joint, the thesis torque limit of its axis) with the
  numbers of :mod:`humanoid_sim.analysis.design` (units in the column names);
- ``fatigue.csv``: rainflow cycles per km of each joint's torque and bending moment, per range bin;
- ``load_cases.json``: per joint the worst instant of each of axial force, shear, torsion and bending: time, value,
  the whole 6-axis wrench in the joint frame, the configuration q (Pinocchio's order);
- ``trace.npz`` (on request): the full-rate trace's signals, with ``period_s`` and ``source``;
- ``sizing_legs.png`` / ``sizing_upper.png``: per joint axis the torque-speed operating points at every step over
  the torque limit (dashed; for a joint with a motor, the motor's torque-speed envelope), the peak (red ring) and
  the RMS torque (dotted); beside each, the power over time.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from humanoid_sim.analysis.design import DesignCard
from humanoid_sim.interfaces.log import atomic_write_bytes, atomic_write_text
from humanoid_sim.interfaces.trace import Trace
from humanoid_sim.robot.motors import MotorSpec

SIZING_FIGURES: dict[str, tuple[str, ...]] = {
    "sizing_legs": ("toe", "ankle", "knee", "hip"),
    "sizing_upper": ("waist", "shoulder", "neck"),
}
"""The sizing figures and the joint groups (by the words in their actuator names) each one draws."""


def _csv(rows: list[dict], path: Path) -> Path:
    buf = io.StringIO()
    if rows:
        w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    atomic_write_text(path, buf.getvalue())
    return path


def write_design(card: DesignCard, out: Path, *, trace: Trace | None = None, figures: Sequence[str] = (),
                 title: str = "", engine: str = "", motors: dict[str, MotorSpec] | None = None) -> list[Path]:
    """Write the sizing card's files into ``out`` (module docstring).

    Args:
        card: the run's design numbers.
        out: the output folder (exists).
        trace: the full-rate trace to save as ``trace.npz``, or None.
        figures: the sizing figures to draw (names of :data:`SIZING_FIGURES`).
        title: the scenario's name, for the figures' titles.
        engine: the engine's name, for the figures' titles.
        motors: the scenario's motors by thesis joint variable (their envelopes in the figures), or None.

    Returns:
        The paths written.
    """
    out = Path(out)
    written = [_csv(card.joints, out / "design.csv"), _csv(card.fatigue, out / "fatigue.csv")]
    atomic_write_text(out / "load_cases.json", json.dumps(card.load_cases, indent=1) + "\n")
    written.append(out / "load_cases.json")
    if trace is not None:
        buf = io.BytesIO()
        np.savez_compressed(buf, **trace.columns, period_s=np.array(trace.period_s), source=np.array(trace.source))
        atomic_write_bytes(out / "trace.npz", buf.getvalue())
        written.append(out / "trace.npz")
    for name in figures:
        written.append(plot_sizing(card, out / f"{name}.png", SIZING_FIGURES[name], f"{title} on {engine}", motors))
    return written


def plot_sizing(card: DesignCard, path: Path, groups: Sequence[str], title: str,
                motors: dict[str, MotorSpec] | None = None) -> Path:
    """One sizing figure: a row per joint axis of the ``groups`` (by word in the actuator's name) with its
    torque-speed operating points and its power over time (module docstring); a joint with a motor (``motors``, by
    thesis joint variable) shows the motor's torque-speed envelope instead of the thesis's limit."""
    motors = motors or {}
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [(j, r) for j, r in enumerate(card.joints) if any(g in r["label"] for g in groups)]
    s = card.series
    n = len(rows)
    ncol = 2
    fig, axes = plt.subplots((n + 1) // 2, 2 * ncol, figsize=(15, 2.1 * ((n + 1) // 2) + 0.8), squeeze=False,
                             gridspec_kw={"width_ratios": [1.0, 1.3] * ncol})
    for k, (j, r) in enumerate(rows):
        ax_op, ax_p = axes[k // ncol, 2 * (k % ncol)], axes[k // ncol, 2 * (k % ncol) + 1]
        tq, sp, pw = s["torque"][:, j], s["speed"][:, j], s["power"][:, j]
        ax_op.plot(sp, tq, ",", color="tab:blue", alpha=0.5, rasterized=True)
        lim = r["limit_Nm"]
        spec = motors.get(r["joint"])
        if spec is not None:   # the motor's torque-speed envelope over the walk's speeds
            from humanoid_sim.robot.motors import torque_envelope

            lo, hi = float(np.min(sp)), float(np.max(sp))
            w = np.linspace(lo - 0.2 * (hi - lo + 1e-9), hi + 0.2 * (hi - lo + 1e-9), 200)
            env = torque_envelope(spec, w)
            ax_op.plot(w, env.tau_max, "k--", lw=0.8)
            ax_op.plot(w, env.tau_min, "k--", lw=0.8)
            lim = spec.stall_torque
        elif lim:
            for sign in (1, -1):
                ax_op.axhline(sign * lim, color="k", ls="--", lw=0.8)
        i = int(np.argmax(np.abs(tq)))
        ax_op.plot(sp[i], tq[i], "o", mfc="none", mec="tab:red", ms=7)
        for sign in (1, -1):
            ax_op.axhline(sign * (r["torque_rms_Nm"] or 0.0), color="tab:green", ls=":", lw=1.0)
        what = f"motor {spec.name}, stall" if spec is not None else "limit"
        ax_op.set_title(f"{r['label']}: peak {r['torque_peak_Nm']:.1f} N m ({what} {lim or float('nan'):.0f}), "
                        f"rms {r['torque_rms_Nm']:.1f}", fontsize=7.5)
        ax_op.set_xlabel("speed [rad/s]", fontsize=7)
        ax_op.set_ylabel("torque [N m]", fontsize=7)
        ax_p.plot(s["t"], pw, lw=0.5, color="tab:purple", rasterized=True)
        ax_p.axhline(0.0, color="k", lw=0.5)
        ax_p.set_title(f"power: peak {r['power_peak_W']:.1f} W, work +{r['work_positive_J']:.1f} / "
                       f"{r['work_negative_J']:.1f} J; speed peak {r['speed_peak_rad_s']:.2f} rad/s", fontsize=7.5)
        ax_p.set_xlabel("t [s]", fontsize=7)
        ax_p.set_ylabel("power [W]", fontsize=7)
        for ax in (ax_op, ax_p):
            ax.tick_params(labelsize=6.5)
            ax.grid(alpha=0.3)
    for k in range(n, axes.shape[0] * ncol):
        axes[k // ncol, 2 * (k % ncol)].axis("off")
        axes[k // ncol, 2 * (k % ncol) + 1].axis("off")
    w = card.walk
    cot = w["mechanical_cost_of_transport"]
    fig.suptitle(f"sizing card, {title}: operating points at every step ({card.rates['trace_period_s'] * 1000:g} ms); "
                 f"dashed: torque limit, dotted: RMS, red: peak.  Walk: {w['distance_m']:.2f} m, positive work "
                 f"{w['work_positive_J']:.0f} J, mechanical cost of transport "
                 f"{'n/a' if cot is None else f'{cot:.2f}'}", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    buf = io.BytesIO()
    fig.savefig(buf, dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
    return path


__all__ = ["SIZING_FIGURES", "plot_sizing", "write_design"]
