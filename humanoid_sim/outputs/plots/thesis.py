"""PNG figures of a run (matplotlib, Agg backend): :data:`FIGURES`, the full list ``walk.py`` and ``plot.py`` draw
(``walk.py`` draws :data:`QUICK_FIGURES` unless asked for all; :data:`FIGURE_SETS`).

- ``reference_iso/xy/xz.png`` (Figs. 6.51-6.53, :func:`plot_reference`): hip CoM path coloured by phase, the toe
  points' paths in their foot's colour, waypoints marked.  World frame, metres.
- ``phases.png``: the phase timeline (phase index over time, which foot carries a weld; on real contact, which
  foot the phase plans as support).
- ``joints_*.png`` (Figs. 6.54-6.60): the 26 thesis joint angles in the thesis's seven groups, rad, each named by its
  joint (``right ankle roll theta9``: rotation about the body x axis, pitch y, yaw z; body axes x forward, y left).
- ``task_hip.png``, ``task_toe_R.png``, ``task_toe_L.png`` (Figs. 6.61-6.63): Body-17 CoM (and yaw) and
  the toe points P_tpR / P_tpL against their references, world frame.
- ``torques_<group>.png`` (Figs. 6.64-6.70, named by the joints they drive: ``torques_right_toe_ankle`` holds T1, T3,
  T5, T7): actuator torques T (after saturation) and the computed-torque
  command T_cmd, with the saturation limits +-T_max; components in the frame of the higher body (eq. 4.69).
- ``grf_force_R/L.png``, ``grf_moment_R/L.png`` (Figs. 6.71-6.74): ground force F_0,k and moment M_0,k
  (about the CoM of body k) on bodies 1, 3 (right foot) and 2, 4 (left foot), resolved in body frame k.
- ``contact_world.png``: per-foot vertical ground force (world), centre of pressure and ZMP against time, and a
  ground view: the outline of each supporting sole, the support polygon of each double support, the CoP of each
  foot and the whole-body ZMP, red where outside.
- ``contact_audit.png`` (:mod:`humanoid_sim.outputs.plots.audit`): the contact-feasibility audit.

Style (:mod:`humanoid_sim.outputs.colours`): phases shaded in the thesis colours; one colour per foot in every figure
(right
green, left purple); ZMP orange; references grey dashed; units in square brackets.  Each figure has its title on the
first line and its legends on the second, above the plots.  :func:`run_figures` returns the figures without saving;
each data line carries a ``gid`` ``"<signal>:<index>"`` naming the results.npz column it draws (``"theta:3"`` is
``r["theta"][:, 3]``, ``"body_force:1,2"`` is ``r["body_force"][:, 1, 2]``, ``"hip_yaw:"`` is ``r["hip_yaw"]``);
saturation limit lines carry ``"limit:<T name>"``; lines of the ground view and the audit ``"ground:..."`` /
``"audit:..."`` (see their builders).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from humanoid_sim.errors import HumanoidSimError
from humanoid_sim.outputs.colours import (
    FOOT_COLOURS,
    FOOT_NAMES,
    LIMIT_COLOUR,
    PHASE_COLOURS,
    REFERENCE_COLOUR,
    SIGNAL_COLOUR,
    WAYPOINT_COLOUR,
)
from humanoid_sim.outputs.plots.common import (  # noqa: F401
    HEADER_IN,
    REFERENCE_STYLE,
    _handle,
    _header,
    _line,
    _phase_runs,
    _phases_present,
    _save,
    _shade,
    engine_of,
    new_figure,
    real_contact,
    shade_phases,
)
from humanoid_sim.outputs.plots.ground import contact_world_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from humanoid_sim.analysis.audit import AuditReport
    from humanoid_sim.references.chapter3 import ReferenceTrajectory

DEFAULT_FRICTION = 0.8
"""Coulomb coefficient of the audit figure when the caller gives none (the scenarios' default)."""


# ============================================================================================ header and legends


# ============================================================================================ reference figures
def _sample_reference(traj: ReferenceTrajectory, dt: float) -> list[dict[str, np.ndarray | str]]:
    """Hip and toe positions per nominal phase, sampled every ``dt`` s (phase ends included)."""
    out = []
    for ph in traj.phases:
        n = max(2, int(np.ceil(ph.duration / dt)) + 1)
        ts = np.linspace(0.0, ph.duration, n)
        samples = [traj.sample(ph.index, t) for t in ts]
        out.append({
            "name": ph.name,
            "hip": np.array([s.hip_p for s in samples]),
            "R": np.array([s.toe_R_p for s in samples]),
            "L": np.array([s.toe_L_p for s in samples]),
        })
    return out


REFERENCE_STEMS = ("reference_iso", "reference_xy", "reference_xz")


def reference_figures(traj: ReferenceTrajectory, dt: float = 0.005) -> dict[str, Figure]:
    """The reference-trajectory figures (thesis Figs. 6.51-6.53) by stem: isometric 3-D view, X-Y plane (equal
    axes), X-Z plane.  ``dt``: sampling step of the nominal schedule, s.  Toe lines carry the gids
    ``"reference:toe_R"`` / ``"reference:toe_L"``, hip lines ``"reference:hip:<phase index>"``."""
    data = _sample_reference(traj, dt)
    wp = np.asarray(traj.params.Phip)
    toes = {f: np.concatenate([d[f] for d in data]) for f in ("R", "L")}
    phases = [n for n in PHASE_COLOURS if n in {d["name"] for d in data}]
    handles = ([_handle(f"hip CoM, {n}", color=PHASE_COLOURS[n], lw=2) for n in phases]
               + [_handle(f"{FOOT_NAMES[f]} toe point P_tp{f}", color=FOOT_COLOURS[f], lw=1) for f in ("R", "L")]
               + [_handle("waypoints P_k", color=WAYPOINT_COLOUR, marker="o", mfc="none", ls="none", ms=4)])

    def draw(ax, ix: int, iy: int, iz: int | None = None) -> None:
        for k, d in enumerate(data):
            hip = d["hip"]
            coords = [hip[:, ix], hip[:, iy]] + ([hip[:, iz]] if iz is not None else [])
            (line,) = ax.plot(*coords, color=PHASE_COLOURS[d["name"]], lw=2)
            line.set_gid(f"reference:hip:{k}")
        for f in ("R", "L"):
            c = toes[f]
            coords = [c[:, ix], c[:, iy]] + ([c[:, iz]] if iz is not None else [])
            (line,) = ax.plot(*coords, color=FOOT_COLOURS[f], lw=1)
            line.set_gid(f"reference:toe_{f}")
        coords = [wp[:, ix], wp[:, iy]] + ([wp[:, iz]] if iz is not None else [])
        ax.plot(*coords, "o", ms=4, mfc="none", color=WAYPOINT_COLOUR)

    figs: dict[str, Figure] = {}
    fig = new_figure(figsize=(8, 7.5))
    ax = fig.add_subplot(projection="3d")
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.02, top=1 - 1.1 / 7.5)
    draw(ax, 0, 1, 2)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    allpts = np.concatenate([toes["R"], toes["L"], wp] + [d["hip"] for d in data])
    ax.set_box_aspect(tuple(np.maximum(np.ptp(allpts, axis=0), 0.05)))  # true proportions
    ax.view_init(elev=25, azim=-60)
    _header(fig, "Reference trajectories, isometric view (world frame; thesis Fig. 6.51)", handles[:4], None)
    fig.legend(handles=handles[4:], loc="upper left", bbox_to_anchor=(0.02, 1 - 0.68 / 7.5), ncol=3, fontsize=7,
               frameon=False, borderaxespad=0.0)
    figs["reference_iso"] = fig

    for name, (ix, iy), labels, fig_no in (("xy", (0, 1), ("x [m]", "y [m]"), "6.52"),
                                           ("xz", (0, 2), ("x [m]", "z [m]"), "6.53")):
        fig = new_figure(figsize=(8, 7))
        ax = fig.add_subplot()
        fig.subplots_adjust(left=0.1, right=0.97, bottom=0.08, top=1 - 1.1 / 7)
        draw(ax, ix, iy)
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        if name == "xy":
            ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, lw=0.3)
        _header(fig, f"Reference trajectories on the {name.upper()[0]}-{name.upper()[1]} plane (world frame; thesis "
                     f"Fig. {fig_no})", handles[:4], None)
        fig.legend(handles=handles[4:], loc="upper left", bbox_to_anchor=(0.02, 1 - 0.68 / 7), ncol=3, fontsize=7,
                   frameon=False, borderaxespad=0.0)
        figs[f"reference_{name}"] = fig
    return figs


def plot_reference(traj: ReferenceTrajectory, out_dir: str | Path, dt: float = 0.005,
                   prefix: str = "reference") -> list[Path]:
    """Write the reference-trajectory figures (:func:`reference_figures`) as ``<prefix>_iso/xy/xz.png``; their
    paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return [_save(fig, out_dir / f"{stem.replace('reference', prefix, 1)}.png")
            for stem, fig in reference_figures(traj, dt).items()]


# ============================================================================================ run figures
JOINT_LABELS: dict[str, str] = {
    "theta3": "right toe pitch", "theta4": "left toe pitch", "theta5": "right ankle pitch",
    "theta6": "left ankle pitch", "theta7": "right ankle yaw", "theta8": "left ankle yaw",
    "theta9": "right ankle roll", "theta10": "left ankle roll", "theta11": "right knee pitch",
    "theta12": "left knee pitch", "theta13": "right hip pitch", "theta14": "left hip pitch",
    "theta15": "right hip roll", "theta16": "left hip roll", "theta17r": "right hip yaw", "theta17l": "left hip yaw",
    "theta18": "waist pitch", "theta19": "waist yaw", "theta20": "waist roll", "theta21": "right shoulder roll",
    "theta22": "left shoulder roll", "theta23": "right shoulder pitch", "theta24": "left shoulder pitch",
    "theta25": "neck yaw", "theta26": "neck pitch", "theta27": "neck roll",
}
"""The joint each thesis angle turns, and about which body axis (URDF axes: x roll, y pitch, z yaw)."""
#: thesis Figs. 6.54-6.60: joint-angle groups (file stem, title, thesis angle names)
JOINT_GROUPS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("joints_toe_ankle_pitch", "toe and ankle pitch", ("theta3", "theta4", "theta5", "theta6")),
    ("joints_ankle_yaw_roll", "ankle yaw and roll", ("theta7", "theta8", "theta9", "theta10")),
    ("joints_knee_hip_pitch", "knee and hip pitch", ("theta11", "theta12", "theta13", "theta14")),
    ("joints_hip_roll_yaw", "hip roll and yaw", ("theta15", "theta16", "theta17r", "theta17l")),
    ("joints_waist", "waist", ("theta18", "theta19", "theta20")),
    ("joints_shoulders", "shoulders", ("theta21", "theta22", "theta23", "theta24")),
    ("joints_neck", "neck", ("theta25", "theta26", "theta27")),
)
LEGACY_STEMS = ("joints_theta3-6", "joints_theta7-10", "joints_theta11-14", "joints_theta15-17l",
                "joints_theta18-20", "joints_theta21-24", "joints_theta25-27",
                "torques_T1-7", "torques_T9-15", "torques_T2-8", "torques_T10-16", "torques_T17-19",
                "torques_T20-23", "torques_T24-26")
"""Figure names that earlier versions wrote and this one does not (``walk.py`` removes them from its output
folder so that they do not pass for a new run's)."""
#: thesis Figs. 6.64-6.70: actuator-torque groups (file stem, title, torque names)
TORQUE_GROUPS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("torques_right_toe_ankle", "right toe and ankle", ("T1", "T3", "T5", "T7")),
    ("torques_right_knee_hip", "right knee and hip", ("T9", "T11", "T13", "T15")),
    ("torques_left_toe_ankle", "left toe and ankle", ("T2", "T4", "T6", "T8")),
    ("torques_left_knee_hip", "left knee and hip", ("T10", "T12", "T14", "T16")),
    ("torques_waist", "waist", ("T17", "T18", "T19")),
    ("torques_shoulders", "shoulders", ("T20", "T21", "T22", "T23")),
    ("torques_neck", "neck", ("T24", "T25", "T26")),
)
#: thesis Figs. 6.71-6.74: (file stem, signal, title, foot, [(body, row of body_force/body_moment)])
GRF_GROUPS: tuple[tuple[str, str, str, str, tuple[tuple[int, int], ...]], ...] = (
    ("grf_force_R", "body_force", "Ground reaction forces on bodies 1 and 3 (right foot)", "R", ((1, 0), (3, 2))),
    ("grf_force_L", "body_force", "Ground reaction forces on bodies 2 and 4 (left foot)", "L", ((2, 1), (4, 3))),
    ("grf_moment_R", "body_moment", "Ground reaction moments on bodies 1 and 3 (right foot)", "R", ((1, 0), (3, 2))),
    ("grf_moment_L", "body_moment", "Ground reaction moments on bodies 2 and 4 (left foot)", "L", ((2, 1), (4, 3))),
)
REQUIRED_SIGNALS = ("t", "phase", "basic_phase", "phase_names", "theta", "T", "T_cmd", "hip_p", "hip_p_ref",
                    "hip_yaw", "hip_yaw_ref", "toe_R_p", "toe_R_p_ref", "toe_L_p", "toe_L_p_ref", "body_force",
                    "body_moment", "foot_wrench", "cop", "zmp", "in_contact", "q")
TIME_STEMS: tuple[str, ...] = (("phases",) + tuple(g[0] for g in JOINT_GROUPS)
                               + ("task_hip", "task_toe_R", "task_toe_L")
                               + tuple(g[0] for g in TORQUE_GROUPS) + tuple(g[0] for g in GRF_GROUPS)
                               + ("contact_world",))
"""The time-series figures of :func:`run_figures`, in thesis section 6.2 order."""
FIGURES: tuple[str, ...] = REFERENCE_STEMS + TIME_STEMS + ("contact_audit",)
"""Every figure of a run (file stem; the file is ``<stem>.png``): the thesis's full set, what ``walk.py --figures all``
writes and ``plot.py`` redraws.  The reference figures need the scenario's trajectory."""
QUICK_FIGURES: tuple[str, ...] = ("phases", "torques_right_toe_ankle", "torques_right_knee_hip", "contact_world",
                                  "contact_audit")
"""The figures a user looks at first (``walk.py``'s default, drawn in about a second): the phase timeline, the
right leg's actuator torques, the ground reactions with their CoP and ZMP, and the contact audit."""
FIGURE_SETS: dict[str, tuple[str, ...]] = {"quick": QUICK_FIGURES, "all": FIGURES, "none": ()}
"""The named figure sets of ``walk.py --figures`` and ``plot.py --figures``."""


class PlotError(HumanoidSimError, ValueError):
    """The results cannot be plotted (missing signal, empty log, bad shape); the message says which."""


def torque_limits() -> dict[str, float]:
    """Saturation limit of every actuator torque, N m (models/thesis_humanoid.yaml, errata section 7)."""
    return dict(_spec_torque_limits())


@cache
def _spec_torque_limits() -> tuple[tuple[str, float], ...]:
    """:func:`torque_limits`, read from the robot's YAML once per process (parsing it takes ~0.15 s, as long as
    drawing a figure; a figure worker reads it while it warms up, :mod:`humanoid_sim.outputs.plots.pool`)."""
    from humanoid_sim.robot.actuators import GROUPS
    from humanoid_sim.robot.model import DEFAULT_SPEC
    from urdf_gen.spec import load_spec

    spec = load_spec(DEFAULT_SPEC)
    return tuple((name, float(spec.actuators[g.name]["limit"])) for g in GROUPS for name in g.T)


def warm_up() -> None:
    """Load what drawing the figures needs before the first one (a figure worker's start,
    :mod:`humanoid_sim.outputs.plots.pool`): matplotlib's Agg canvas, the audit figure's module, the torque limits
    (the robot's YAML), and what one small throw-away figure loads: the fonts, and the parser of the mathtext that
    log and symlog axes label their ticks with ($10^{2}$)."""
    import io

    import matplotlib.backends.backend_agg  # noqa: F401

    import humanoid_sim.outputs.plots.audit  # noqa: F401

    torque_limits()
    fig = new_figure(figsize=(2.0, 2.0))
    ax, log = fig.subplots(2, 1, sharex=True)
    ax.plot([0.0, 1.0], [0.0, 1.0], label="warm-up", marker=".", ms=2)
    ax.axvspan(0.2, 0.4, alpha=0.25, lw=0)
    log.plot([0.0, 1.0], [0.1, 100.0])
    log.set_yscale("log")
    log.set_xlabel("t [s]")
    fig.legend(fontsize=7)
    fig.suptitle("warm-up", fontsize=11)
    fig.savefig(io.BytesIO(), format="png", dpi=50)


def _check(r: dict[str, np.ndarray]) -> None:
    missing = [k for k in REQUIRED_SIGNALS if k not in r]
    if missing:
        raise PlotError(f"results lack the signals {missing}")
    n = len(r["t"])
    if n == 0:
        raise PlotError("the log is empty (0 steps)")
    for k in REQUIRED_SIGNALS:
        if k != "phase_names" and len(r[k]) != n:
            raise PlotError(f"signal {k!r} has {len(r[k])} rows, t has {n}")
    if r["theta"].shape[1:] != (26,) or r["T"].shape[1:] != (26,):
        raise PlotError(f"theta / T must have 26 columns, got {r['theta'].shape} / {r['T'].shape}")


def _time_figure(r, n_rows: int, n_cols: int = 1, height: float = 2.0, width: float | None = None):
    """A bare Figure (not pyplot: no global registry, so many figures can be alive at once) of time plots with the
    header band of :func:`_header`; fixed margins (inches) instead of a layout engine, which triples the drawing
    time."""
    h_in = HEADER_IN + 0.5 + height * n_rows
    fig = new_figure(figsize=(width or (9 if n_cols == 1 else 11), h_in))
    axes = fig.subplots(n_rows, n_cols, sharex=True, squeeze=False)
    fig.subplots_adjust(left=0.12 if n_cols == 1 else 0.08, right=0.98, top=1 - HEADER_IN / h_in, bottom=0.5 / h_in,
                        hspace=0.12, wspace=0.25)
    for ax in axes.flat:
        _shade(ax, r)
        ax.grid(True, lw=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    return fig, axes


def _fig_phases(r, engine: str | None = None):
    real = real_contact(engine)
    names = [str(x) for x in r["phase_names"]]
    fig, axes = _time_figure(r, 2, height=1.8)
    ax = axes[0, 0]
    _line(ax, r, "phase", (), drawstyle="steps-post", color=SIGNAL_COLOUR)
    used = np.unique(r["phase"])
    ax.set_yticks(used)
    ax.set_yticklabels([f"{k + 1} {names[k]}" for k in used], fontsize=7)
    ax.set_ylabel("phase [-]")
    ax = axes[1, 0]
    for f, foot in enumerate(("R", "L")):
        _line(ax, r, "in_contact", (f,), drawstyle="steps-post", color=FOOT_COLOURS[foot])
    ax.set_yticks([0, 1])
    ax.set_yticklabels(["swing", "support"] if real else ["free", "held"])
    ax.set_ylim(-0.15, 1.15)
    ax.set_ylabel("planned support [-]" if real else "foot constraint [-]")
    title = ("Phase timeline, and the planned support foot (the phase's contact set; the ground acts through real "
             f"unilateral contact, {engine})" if real else "Phase timeline, and which foot is held on the ground")
    _header(fig, title,
            [_handle("phase index", color=SIGNAL_COLOUR)]
            + [_handle(FOOT_NAMES[f], color=FOOT_COLOURS[f]) for f in ("R", "L")], _phases_present(r))
    return fig


def _fig_joints(r, title: str, names: tuple[str, ...], fig_no: str):
    from humanoid_sim.robot.model import THETA_NAMES

    fig, axes = _time_figure(r, len(names))
    for ax, name in zip(axes[:, 0], names):
        _line(ax, r, "theta", (THETA_NAMES.index(name),), color=SIGNAL_COLOUR)
        ax.set_ylabel(f"{JOINT_LABELS[name]}\n{name} [rad]", fontsize=8)
    _header(fig, f"Joint angles: {title} (thesis Fig. {fig_no})", [_handle("simulation", color=SIGNAL_COLOUR)],
            _phases_present(r))
    return fig


def _fig_task(r, key: str, title: str, label: str):
    rows = 4 if key == "hip" else 3
    fig, axes = _time_figure(r, rows)
    sig = "hip_p" if key == "hip" else f"toe_{key}_p"
    colour = SIGNAL_COLOUR if key == "hip" else FOOT_COLOURS[key]
    for i, ax in enumerate(axes[:3, 0]):
        _line(ax, r, sig, (i,), color=colour)
        _line(ax, r, f"{sig}_ref", (i,), **REFERENCE_STYLE)
        ax.set_ylabel(f"{label} {'xyz'[i]} [m]")
    if key == "hip":
        ax = axes[3, 0]
        _line(ax, r, "hip_yaw", (), color=colour)
        _line(ax, r, "hip_yaw_ref", (), **REFERENCE_STYLE)
        ax.set_ylabel("Body-17 yaw [rad]")
    _header(fig, title, [_handle("simulation", color=colour), _handle("reference", **REFERENCE_STYLE)],
            _phases_present(r))
    return fig


def _fig_torques(r, names: tuple[str, ...], title: str, limits: dict[str, float]):
    from humanoid_sim.robot.actuators import T_NAMES

    fig, axes = _time_figure(r, len(names))
    for ax, name in zip(axes[:, 0], names):
        i = T_NAMES.index(name)
        _line(ax, r, "T_cmd", (i,), color=REFERENCE_COLOUR, lw=0.8, ls="--")
        _line(ax, r, "T", (i,), color=SIGNAL_COLOUR)
        lim = limits[name]
        for sign in (1.0, -1.0):
            line = ax.axhline(sign * lim, color=LIMIT_COLOUR, lw=0.8, ls=":")
            line.set_gid(f"limit:{name}")
        peak = float(np.nanmax(np.abs(r["T_cmd"][:, i]))) if len(r["t"]) else 0.0
        ax.set_ylim(-1.1 * max(lim, peak), 1.1 * max(lim, peak))
        ax.set_ylabel(f"{name} [N m]")
    _header(fig, f"Actuator torques {names[0]} to {names[-1]}: {title} (components in the higher body's frame)",
            [_handle("applied T", color=SIGNAL_COLOUR),
             _handle("command T_cmd", color=REFERENCE_COLOUR, lw=0.8, ls="--"),
             _handle("saturation +-T_max", color=LIMIT_COLOUR, lw=0.8, ls=":")], _phases_present(r))
    return fig


def _fig_grf(r, signal: str, title: str, foot: str, bodies: tuple[tuple[int, int], ...]):
    unit, sym = ("N", "F") if signal == "body_force" else ("N m", "M")
    fig, axes = _time_figure(r, 3, n_cols=len(bodies), height=1.8)
    for c, (body, row) in enumerate(bodies):
        for i in range(3):
            ax = axes[i, c]
            _line(ax, r, signal, (row, i), color=FOOT_COLOURS[foot])
            ax.set_ylabel(f"{sym}_0,{body} {'xyz'[i]} [{unit}]")
        axes[0, c].set_title(f"body {body} (components in frame {body})", fontsize=9)
    fig.subplots_adjust(top=1 - (HEADER_IN + 0.25) / fig.get_figheight())  # room for the column titles
    _header(fig, title, [_handle(FOOT_NAMES[foot], color=FOOT_COLOURS[foot])], _phases_present(r))
    return fig


# ---------------------------------------------------------------------------------------- contact_world
# ---------------------------------------------------------------------------------------- the list
def _builders(r: dict[str, np.ndarray], limits: dict[str, float], report: Callable[[], AuditReport],
              title: str = "", engine: str | None = None) -> dict[str, Callable[[], Figure]]:
    """Every figure of :data:`TIME_STEMS` and ``contact_audit`` as a zero-argument builder, by file stem; ``engine``
    words the phase timeline and the audit for welded feet or real contact (:func:`.common.real_contact`)."""
    builders: dict[str, Callable[[], Figure]] = {"phases": lambda: _fig_phases(r, engine)}
    for i, (stem, title_, names) in enumerate(JOINT_GROUPS):
        builders[stem] = lambda title_=title_, names=names, i=i: _fig_joints(r, title_, names, f"6.{54 + i}")
    builders["task_hip"] = lambda: _fig_task(r, "hip", "Position of the mass centre of body 17 with its reference "
                                             "(world frame; thesis Fig. 6.61)", "P_c17")
    builders["task_toe_R"] = lambda: _fig_task(r, "R", "Toe point on the right foot (body 1) with its reference "
                                               "(world frame; thesis Fig. 6.62)", "P_tpR")
    builders["task_toe_L"] = lambda: _fig_task(r, "L", "Toe point on the left foot (body 2) with its reference "
                                               "(world frame; thesis Fig. 6.63)", "P_tpL")
    for stem, title_, names in TORQUE_GROUPS:
        builders[stem] = lambda title_=title_, names=names: _fig_torques(r, names, title_, limits)
    for stem, signal, title_, foot, bodies in GRF_GROUPS:
        builders[stem] = (lambda signal=signal, title_=title_, foot=foot, bodies=bodies:
                          _fig_grf(r, signal, title_, foot, bodies))
    builders["contact_world"] = lambda: contact_world_figure(r, report())
    builders["contact_audit"] = lambda: _audit_figure(report(), title, engine)
    return builders


def _audit_figure(report: AuditReport, title: str, engine: str | None = None) -> Figure:
    from humanoid_sim.outputs.plots.audit import contact_audit_figure

    return contact_audit_figure(report, title=title, engine=engine)


def audit_of(r: dict[str, np.ndarray], mu: float = DEFAULT_FRICTION, hm: Any = None) -> AuditReport:
    """The contact-feasibility audit of a run (:func:`humanoid_sim.analysis.audit.audit_results`) for its figures."""
    from humanoid_sim.analysis.audit import AuditError, audit_results

    if hm is None:
        from humanoid_sim.robot.model import load_model

        hm = load_model()
    try:
        return audit_results(r, hm, mu)
    except AuditError as exc:
        raise PlotError(f"contact audit: {exc}") from None


def run_figures(r: dict[str, np.ndarray], limits: dict[str, float] | None = None,
                only: list[str] | None = None, *, report: AuditReport | None = None,
                mu: float = DEFAULT_FRICTION, title: str = "", engine: str | None = None) -> dict[str, Figure]:
    """Every figure of a run except the reference ones (a :func:`humanoid_sim.interfaces.log.load_results` dict), by
    file
    stem, in :data:`FIGURES` order: :data:`TIME_STEMS` and ``contact_audit``.

    The figures are bare :class:`matplotlib.figure.Figure` objects (not registered with pyplot).  ``limits``: saturation
    limit per torque name (N m), default :func:`torque_limits`.  ``only``: build just these stems.  ``report``: the
    run's contact audit (computed here with friction coefficient ``mu`` when a figure needs it and none is given).
    ``title``: the scenario name, for the audit figure.  ``engine``: the run's engine (default: results.npz's
    ``engine`` entry; None reads as welded feet), which words the phase timeline and the audit."""
    _check(r)
    engine = engine_of(r, engine)
    limits = torque_limits() if limits is None else limits
    cache: dict[str, Any] = {"report": report}

    def get_report() -> AuditReport:
        if cache["report"] is None:
            cache["report"] = audit_of(r, mu)
        return cache["report"]

    builders = _builders(r, limits, get_report, title, engine)
    stems = list(builders) if only is None else [s for s in builders if s in set(only)]
    return {stem: builders[stem]() for stem in stems}


def figure_stems(r: dict[str, np.ndarray] | None = None) -> list[str]:
    """File stems of :func:`run_figures`, in order (the same for every run)."""
    return list(TIME_STEMS) + ["contact_audit"]


def _render(results_path: str, out_dir: str, stems: list[str], dpi: int, report: AuditReport | None,
            mu: float, title: str, engine: str | None = None) -> list[str]:
    """Build and save the figures ``stems`` of a run (a worker's share of :func:`plot_all`)."""
    import io

    from humanoid_sim.interfaces.log import atomic_write_bytes, load_results

    out = []
    figs = run_figures(load_results(results_path), only=stems, report=report, mu=mu, title=title, engine=engine)
    for stem, fig in figs.items():
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        atomic_write_bytes(Path(out_dir) / f"{stem}.png", buf.getvalue())
        out.append(str(Path(out_dir) / f"{stem}.png"))
    return out


def plot_all(results_path: str | Path, out_dir: str | Path, traj: ReferenceTrajectory | None = None,
             *, dpi: int = 100, workers: int | None = None, mu: float = DEFAULT_FRICTION,
             report: AuditReport | None = None, title: str = "", hm: Any = None,
             stems: tuple[str, ...] | list[str] | None = None, engine: str | None = None,
             meanwhile: Callable[[], Any] | None = None) -> list[Path]:
    """Write the figures of :data:`FIGURES` of a run from its results.npz into ``out_dir``; returns the PNG paths in
    :data:`FIGURES` order.

    ``stems``: draw only these figures (e.g. :data:`QUICK_FIGURES`; default every one of :data:`FIGURES`).
    ``engine``: the run's engine, which words the phase timeline and the audit (default: results.npz's ``engine``).
    ``meanwhile``: other work of the caller (the playback, say), run in this process while the workers draw.

    ``traj`` (the run's :class:`ReferenceTrajectory`): the reference-trajectory figures, skipped without it.  ``mu``:
    the friction coefficient of the contact audit, or ``report``: the audit itself (``hm``: the model to compute it
    with).  ``title``: the scenario name.  The figures are drawn by ``workers`` processes (default: one per CPU, at
    most 4; 1 draws them here): matplotlib spends ~0.2 s per figure, far more than the simulation per figure's worth
    of data.  Without ``workers``, the workers :mod:`~humanoid_sim.outputs.plots.pool` started ahead draw them when
    they run (``walk.py`` starts them before it simulates).  Every file is written atomically.
    """
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    from humanoid_sim.interfaces.log import load_results
    from humanoid_sim.outputs.plots import pool

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    r = load_results(results_path)
    _check(r)
    wanted = set(FIGURES if stems is None else stems)
    unknown = wanted - set(FIGURES)
    if unknown:
        raise PlotError(f"unknown figures {sorted(unknown)}; the figures are {', '.join(FIGURES)}")
    engine = engine_of(r, engine)
    if report is None and wanted & {"contact_world", "contact_audit"}:
        report = audit_of(r, mu, hm)
    stems = [s for s in figure_stems(r) if s in wanted]
    # contact_world and contact_audit are the slowest two: first and second, so that different workers draw them
    stems = sorted(stems, key=lambda s: {"contact_world": -2, "contact_audit": -1}.get(s, 0))
    ahead = pool.running() if workers is None else None
    if ahead is not None:
        workers = ahead[1]
    else:
        workers = pool.default_workers(len(stems)) if workers is None else max(1, int(workers))
    shares = [stems[i::workers] for i in range(workers)]
    done: dict[str, Path] = {}

    def reference() -> None:
        if traj is not None and wanted & set(REFERENCE_STEMS):
            import io

            from humanoid_sim.interfaces.log import atomic_write_bytes

            for stem, fig in reference_figures(traj).items():
                if stem not in wanted:
                    continue
                buf = io.BytesIO()
                fig.savefig(buf, format="png", dpi=120)
                atomic_write_bytes(out_dir / f"{stem}.png", buf.getvalue())
                done[stem] = out_dir / f"{stem}.png"

    if workers == 1:
        reference()
        done.update({Path(p).stem: Path(p) for p in _render(str(results_path), str(out_dir), stems, dpi, report,
                                                             float(mu), title, engine)})
        if meanwhile is not None:
            meanwhile()
    else:
        def submit(executor: ProcessPoolExecutor) -> list:
            return [executor.submit(_render, str(results_path), str(out_dir), share, dpi, report, float(mu), title,
                                    engine) for share in shares if share]

        futures: list = []
        if ahead is not None:
            try:
                futures = submit(ahead[0])
            except BrokenProcessPool:   # a worker started ahead died (killed while it warmed up): draw without them
                futures = []
        own = None
        if not futures:
            # what every worker needs, loaded before they fork from this process (each would load it anew otherwise)
            import matplotlib.backends.backend_agg  # noqa: F401

            import humanoid_sim.outputs.plots.audit  # noqa: F401

            own = ProcessPoolExecutor(max_workers=workers)
        try:
            if own is not None:
                futures = submit(own)
            reference()  # meanwhile, in this process
            if meanwhile is not None:
                meanwhile()
            done.update({Path(p).stem: Path(p) for f in futures for p in f.result()})
        finally:
            if own is not None:
                own.shutdown()
    return [done[s] for s in FIGURES if s in done]
