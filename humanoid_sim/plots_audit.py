"""The contact-feasibility figure ``contact_audit.png`` (matplotlib, Agg backend).

Four panels against time, phases shaded (red LFFSSP, blue RFFDSP, magenta RFFSSP, cyan LFFDSP, thesis L4219):
normal force per foot (N, world z; below zero = the weld pulls), CoP margin per foot (mm, signed distance to the
edge of the touching sole, > 0 inside), friction ratio |f_t|/f_n per foot against mu, and the whole-body ZMP
margin to the support polygon (mm, > 0 inside).  Margins use a symmetric-log axis: touchdown transients reach
metres while the interesting band is millimetres.  See README.md, "Contact-feasibility audit".
"""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from humanoid_sim.audit import FEET, AuditReport  # noqa: E402
from humanoid_sim.results import atomic_write_bytes  # noqa: E402

PHASE_SHADES = {"LFFSSP": "red", "RFFDSP": "blue", "RFFSSP": "magenta", "LFFDSP": "cyan"}  # thesis L4219-4221
FOOT_STYLE = {"R": dict(color="green", label="right foot"), "L": dict(color="black", label="left foot")}
MARGIN_LINTHRESH_MM = 10.0  # linear band of the symlog margin axes: the sole is 90 mm wide


def _shade(ax: plt.Axes, t: np.ndarray, names: np.ndarray, h: float) -> None:
    if len(t) == 0:
        return
    start = 0
    for k in range(1, len(t) + 1):
        if k == len(t) or names[k] != names[start]:
            ax.axvspan(t[start], t[k - 1] + h, color=PHASE_SHADES.get(str(names[start]), "grey"), alpha=0.08, lw=0)
            start = k


def plot_contact_audit(report: AuditReport, path: str | Path, title: str = "") -> Path:
    """Write the audit figure to ``path`` (PNG, atomically) and return the path."""
    path = Path(path)
    t = report.t
    h = float(np.median(np.diff(t))) if len(t) > 1 else 0.01
    fig, axes = plt.subplots(4, 1, figsize=(10, 10), sharex=True)
    for i, foot in enumerate(FEET):
        st = FOOT_STYLE[foot]
        axes[0].plot(t, report.f_n[:, i], lw=1, marker=".", ms=2, **st)
        axes[1].plot(t, 1e3 * report.cop_margin[:, i], lw=1, marker=".", ms=2, **st)
        axes[2].plot(t, report.friction_ratio[:, i], lw=1, marker=".", ms=2, **st)
    axes[3].plot(t, 1e3 * report.zmp_margin, lw=1, color="tab:orange", label="whole-body ZMP")
    axes[0].axhline(0.0, color="k", lw=0.6)
    axes[0].set_ylabel("normal force f_z (N)")
    axes[0].set_title("normal force (< 0: the weld pulls on the ground)", fontsize=9)
    for ax, what in ((axes[1], "CoP margin to the sole edge"), (axes[3], "ZMP margin to the support polygon")):
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_yscale("symlog", linthresh=MARGIN_LINTHRESH_MM)
        ax.set_ylabel("margin (mm)")
        ax.set_title(f"{what} (> 0 inside)", fontsize=9)
    axes[2].axhline(report.mu, color="r", lw=0.8, ls="--", label=f"mu = {report.mu:g}")
    axes[2].set_yscale("log")
    axes[2].set_ylabel("|f_t| / f_n")
    axes[2].set_title("friction ratio (above mu: the foot would slip)", fontsize=9)
    for ax in axes:
        _shade(ax, t, report.phase_name, h)
        ax.grid(alpha=0.3, which="both", lw=0.4)
        handles, _ = ax.get_legend_handles_labels()
        if handles:
            ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("t (s)")
    s = report.summary()
    frac = s["infeasible_fraction"]
    fig.suptitle((title + ": " if title else "") + "contact feasibility of the welded feet -- "
                 + ("no contact steps" if frac is None else f"{100 * frac:.0f} % of contact steps infeasible")
                 + "\nshading: red LFFSSP, blue RFFDSP, magenta RFFSSP, cyan LFFDSP", fontsize=10)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
    return path
