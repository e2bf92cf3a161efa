"""Two gaits side by side: centre-of-pressure traces inside the sole outlines, and actuator torques.

``cop_in_sole(r, report, hm)`` expresses each loaded foot's centre of pressure in that foot's sole frame: the
main-body frame O_3 / O_4 for a flat foot (x forward from the ankle, y to the foot's left, m), the toe body's frame
shifted to the toe joint's place for a foot held by its toe, so that every CoP of a walk can be drawn on one sole
outline.  ``gait_comparison_figure`` draws, per run and per foot, the sole outline (heel to toe tip, with the toe
joint line and the 10 mm single-support margin dashed), the single-support CoPs in the foot's
colour and the double-support ones lighter, outside points in red.  ``torque_table`` gives peak and RMS |T| per
actuator component of each run, as Markdown.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from humanoid_sim.analysis.audit import FLAT, NONE, AuditReport, SoleGeometry
from humanoid_sim.outputs.colours import FOOT_COLOURS, FOOT_NAMES, OUTSIDE_COLOUR
from humanoid_sim.robot.phases import FOOT_SPECS

FEET = ("R", "L")
MARGIN_SSP_M = 0.010
"""The single-support CoP margin (m), drawn dashed inside the sole."""


def cop_in_sole(r: dict[str, np.ndarray], report: AuditReport, hm: Any) -> dict[str, dict[str, np.ndarray]]:
    """Per foot: ``xy`` (n, 2) CoPs in the sole frame (m, see the module docstring), ``single`` (n,) bool (the
    other foot not in contact), ``outside`` (n,) bool (the audit's verdict), ``t`` (n,) s."""
    model = hm.model
    data = model.createData()
    sole = SoleGeometry.from_model(hm)
    toe_offset = np.array(sole.toe_joint[:2])
    fid = {f: (model.getFrameId(FOOT_SPECS[f].main_frame), model.getFrameId(FOOT_SPECS[f].toe_frame)) for f in FEET}
    out: dict[str, dict[str, list]] = {f: {"xy": [], "single": [], "outside": [], "t": []} for f in FEET}
    loaded = report.loaded
    for k in np.flatnonzero(loaded.any(axis=1)):
        pin.framesForwardKinematics(model, data, r["q"][k])
        for i, f in enumerate(FEET):
            if not loaded[k, i]:
                continue
            flat = report.kind[k, i] == FLAT
            M = data.oMf[fid[f][0] if flat else fid[f][1]]
            p = np.array([report.cop[k, i, 0], report.cop[k, i, 1], 0.0])
            local = M.rotation.T @ (p - M.translation)
            xy = local[:2] + (0.0 if flat else toe_offset)
            out[f]["xy"].append(xy)
            out[f]["single"].append(bool(report.kind[k, 1 - i] == NONE))
            out[f]["outside"].append(bool(report.cop_outside[k, i]))
            out[f]["t"].append(float(report.t[k]))
    return {f: {key: np.array(v, dtype=float if key in ("xy", "t") else bool).reshape((-1, 2) if key == "xy" else (-1,))
                for key, v in d.items()} for f, d in out.items()}


def gait_comparison_figure(runs: Sequence[tuple[str, dict[str, np.ndarray], AuditReport]], hm: Any):
    """One row per run (label, results arrays, audit report), one column per foot (see the module docstring)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sole = SoleGeometry.from_model(hm)
    w = sole.width / 2.0
    x0, x1, xj = sole.heel_back_x, sole.toe_front_x, sole.toe_joint[0]
    fig, axes = plt.subplots(len(runs), 2, figsize=(9.0, 3.2 * len(runs)), squeeze=False)
    for row, (label, r, report) in enumerate(runs):
        cops = cop_in_sole(r, report, hm)
        for col, f in enumerate(FEET):
            ax = axes[row, col]
            c = cops[f]
            ax.plot([x0, x1, x1, x0, x0], [-w, -w, w, w, -w], color=FOOT_COLOURS[f], lw=1.5)
            ax.plot([xj, xj], [-w, w], color=FOOT_COLOURS[f], lw=0.8, ls=":")
            m = MARGIN_SSP_M
            ax.plot([x0 + m, x1 - m, x1 - m, x0 + m, x0 + m], [-w + m, -w + m, w - m, w - m, -w + m],
                    color=FOOT_COLOURS[f], lw=0.8, ls="--")
            for single, alpha, kind in ((False, 0.25, "double support"), (True, 0.9, "single support")):
                sel = (c["single"] == single) & ~c["outside"]
                ax.plot(c["xy"][sel, 0], c["xy"][sel, 1], ".", ms=2.5, color=FOOT_COLOURS[f], alpha=alpha,
                        label=f"{kind} ({sel.sum()})")
            bad = c["outside"]
            if bad.any():
                ax.plot(c["xy"][bad, 0], c["xy"][bad, 1], ".", ms=2.5, color=OUTSIDE_COLOUR,
                        label=f"outside the sole ({bad.sum()})")
            n = len(c["outside"])
            frac = 100.0 * bad.sum() / n if n else 0.0
            ax.set_title(f"{label}: {FOOT_NAMES[f]}, CoP outside {frac:.0f} % of {n} steps", fontsize=9)
            ax.set_xlabel("x forward (m)")
            ax.set_ylabel("y left (m)")
            lim_y = max(w + 0.02, float(np.nanmax(np.abs(c["xy"][:, 1]))) + 0.01 if n else w + 0.02)
            ax.set_ylim(-min(lim_y, 0.25), min(lim_y, 0.25))
            ax.set_xlim(x0 - 0.03, x1 + 0.03)
            ax.set_aspect("equal", adjustable="datalim")
            ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
            ax.grid(alpha=0.3)
    fig.suptitle("Centre of pressure in each foot's sole frame (sole outline solid, 10 mm margin dashed, "
                 "toe joint dotted; points beyond 0.25 m not shown)", fontsize=9)
    fig.tight_layout()
    return fig


def torque_table(runs: Sequence[tuple[str, dict[str, np.ndarray]]], names: Sequence[str]) -> str:
    """Markdown: peak and RMS |T| (N m) per actuator component for each (label, results arrays)."""
    head = "| actuator | " + " | ".join(f"{lab} peak | {lab} RMS" for lab, _ in runs) + " |"
    sep = "|---|" + "---|---|" * len(runs)
    rows = []
    for i, name in enumerate(names):
        cells = []
        for _, r in runs:
            T = np.abs(np.asarray(r["T"])[:, i])
            cells += [f"{T.max():.1f}", f"{np.sqrt(np.mean(T ** 2)):.1f}"]
        rows.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join([head, sep, *rows])
