"""The contact-feasibility figure ``contact_audit.png`` (matplotlib, Agg backend), one of ``plots.FIGURES``.

Four panels against time, phases shaded in the thesis colours: normal force per foot (N, world z; on the welded
engines below zero = the weld pulls, on real contact never below zero), CoP margin per foot (mm, signed distance to
the edge of the touching sole, > 0 inside), friction ratio |f_t|/f_n per foot against mu, and the whole-body ZMP
margin to the support polygon (mm, > 0 inside).  The title and the normal-force panel name the engine's kind of
contact (``engine`` argument: welded feet, or real unilateral contact).  Margins use a
symmetric-log axis: touchdown transients reach metres while the interesting band is millimetres.  Colours and the
title/legend band are those of every figure (:mod:`humanoid_sim.outputs.plots.thesis`,
:mod:`humanoid_sim.outputs.colours`).  Lines carry
the gids ``"audit:<quantity>:<foot>"`` (quantity f_n, cop_margin, friction_ratio) and ``"audit:zmp_margin:"``.
See docs/outputs.md, "The contact-feasibility audit".
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from humanoid_sim.analysis.audit import FEET, AuditReport
from humanoid_sim.interfaces.log import atomic_write_bytes
from humanoid_sim.outputs.colours import (
    FOOT_COLOURS,
    FOOT_NAMES,
    LIMIT_COLOUR,
    PHASE_COLOURS,
    REFERENCE_COLOUR,
    ZMP_COLOUR,
)
from humanoid_sim.outputs.plots.common import HEADER_IN, _handle, _header, new_figure, real_contact, shade_phases

PHASE_SHADES = PHASE_COLOURS
"""Former name of :data:`humanoid_sim.outputs.colours.PHASE_COLOURS`."""
MARGIN_LINTHRESH_MM = 10.0  # linear band of the symlog margin axes: the sole is 90 mm wide


def contact_audit_figure(report: AuditReport, title: str = "", engine: str | None = None):
    """The audit figure as a bare :class:`matplotlib.figure.Figure`.  ``engine``: the run's engine; on real contact
    (:func:`.common.real_contact`) the figure speaks of the engine's contact forces, otherwise of the welded feet."""
    real = real_contact(engine)
    t = report.t
    names = [str(n) for n in report.phase_name]
    order = list(dict.fromkeys(names))
    phase = np.array([order.index(n) for n in names], dtype=int)
    # a run's consecutive phases of the same basic name form one shaded span, as the basic phase is all this knows
    h_in = HEADER_IN + 0.5 + 4 * 2.0 + 0.6
    fig = new_figure(figsize=(10, h_in))
    axes = fig.subplots(4, 1, sharex=True)
    fig.subplots_adjust(left=0.09, right=0.98, top=1 - (HEADER_IN + 0.2) / h_in, bottom=0.5 / h_in, hspace=0.3)
    for i, foot in enumerate(FEET):
        st = dict(color=FOOT_COLOURS[foot], lw=1, marker=".", ms=2)
        for ax, q, y in ((axes[0], "f_n", report.f_n[:, i]), (axes[1], "cop_margin", 1e3 * report.cop_margin[:, i]),
                         (axes[2], "friction_ratio", report.friction_ratio[:, i])):
            (line,) = ax.plot(t, y, **st)
            line.set_gid(f"audit:{q}:{foot}")
    (line,) = axes[3].plot(t, 1e3 * report.zmp_margin, lw=1, color=ZMP_COLOUR)
    line.set_gid("audit:zmp_margin:")
    axes[0].axhline(0.0, color=REFERENCE_COLOUR, lw=0.6)
    axes[0].set_ylabel("normal force f_z [N]")
    axes[0].set_title(f"normal force of real unilateral contact ({engine}; pushes only: >= 0)" if real else
                      "normal force (< 0: the weld pulls on the ground)", fontsize=9)
    for ax, what in ((axes[1], "CoP margin to the sole edge"), (axes[3], "ZMP margin to the support polygon")):
        ax.axhline(0.0, color=REFERENCE_COLOUR, lw=0.6)
        ax.set_yscale("symlog", linthresh=MARGIN_LINTHRESH_MM)
        ax.set_ylabel("margin [mm]")
        ax.set_title(f"{what} (> 0 inside)", fontsize=9)
    axes[2].axhline(report.mu, color=LIMIT_COLOUR, lw=0.8, ls="--")
    axes[2].set_yscale("log")
    axes[2].set_ylabel("|f_t| / f_n [-]")
    axes[2].set_title("friction ratio (above mu: the foot would slip)", fontsize=9)
    for ax in axes:
        if len(t):
            shade_phases(ax, t, phase, order, alpha=0.08)
        ax.grid(alpha=0.3, which="both", lw=0.4)
    axes[-1].set_xlabel("t [s]")
    s = report.summary()
    frac = s["infeasible_fraction"]
    if real:
        head = ((title + ": " if title else "") + f"contact forces of real unilateral contact ({engine}) -- "
                + ("no contact steps" if frac is None else f"{100 * frac:.0f} % of contact steps fail a check"))
    else:
        head = ((title + ": " if title else "") + "contact feasibility of the welded feet -- "
                + ("no contact steps" if frac is None else f"{100 * frac:.0f} % of contact steps infeasible"))
    handles = ([_handle(FOOT_NAMES[f], color=FOOT_COLOURS[f], marker=".", ms=4) for f in FEET]
               + [_handle("whole-body ZMP", color=ZMP_COLOUR), _handle(f"mu = {report.mu:g}", color=LIMIT_COLOUR,
                                                                       lw=0.8, ls="--")])
    _header(fig, head, handles, [n for n in PHASE_COLOURS if n in order])
    return fig


def plot_contact_audit(report: AuditReport, path: str | Path, title: str = "", dpi: int = 100,
                       engine: str | None = None) -> Path:
    """Write the audit figure to ``path`` (PNG, atomically) and return the path."""
    path = Path(path)
    fig = contact_audit_figure(report, title, engine)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    atomic_write_bytes(path, buf.getvalue())
    return path
