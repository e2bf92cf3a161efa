"""PNG figures of a run (matplotlib, Agg backend), one per figure group of thesis section 6.2.

- ``reference_iso/xy/xz.png`` (Figs. 6.51-6.53, :func:`plot_reference`): hip CoM path coloured by phase
  (red LFFSSP, blue RFFDSP, magenta RFFSSP, cyan LFFDSP, thesis L4219), right toe point green, left toe
  point black, waypoints marked.  World frame, metres.
- ``phases.png``: the phase timeline (phase index over time, which foot carries a constraint).
- ``joints_theta*.png`` (Figs. 6.54-6.60): the 26 thesis joint angles in the thesis's seven groups, rad.
- ``task_hip.png``, ``task_toe_R.png``, ``task_toe_L.png`` (Figs. 6.61-6.63): Body-17 CoM (and yaw) and
  the toe points P_tpR / P_tpL against their references, world frame.
- ``torques_*.png`` (Figs. 6.64-6.70): actuator torques T (after saturation) and the computed-torque
  command T_cmd, with the saturation limits +-T_max; components in the frame of the higher body (eq. 4.69).
- ``grf_force_R/L.png``, ``grf_moment_R/L.png`` (Figs. 6.71-6.74): ground force F_0,k and moment M_0,k
  (about the CoM of body k) on bodies 1, 3 (right foot) and 2, 4 (left foot), resolved in body frame k.
- ``contact_world.png``: per-foot vertical ground force (world), centre of pressure and ZMP.

Every time plot shades the phases in the thesis colours.  :func:`run_figures` returns the figures without
saving; each data line carries a ``gid`` ``"<signal>:<index>"`` naming the results.npz column it draws
(``"theta:3"`` is ``r["theta"][:, 3]``, ``"body_force:1,2"`` is ``r["body_force"][:, 1, 2]``, ``"hip_yaw:"``
is ``r["hip_yaw"]``), and saturation limit lines carry ``"limit:<T name>"``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Callable

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
import numpy as np  # noqa: E402

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.trajectory import ReferenceTrajectory

#: thesis L4219-4221 colour legend
PHASE_COLOURS = {"LFFSSP": "red", "RFFDSP": "blue", "RFFSSP": "magenta", "LFFDSP": "cyan"}
TOE_COLOURS = {"R": "green", "L": "black"}


def _save(fig: "plt.Figure", path: Path) -> Path:
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def _sample_reference(traj: "ReferenceTrajectory", dt: float) -> list[dict[str, np.ndarray | str]]:
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


def plot_reference(traj: "ReferenceTrajectory", out_dir: str | Path, dt: float = 0.005,
                   prefix: str = "reference") -> list[Path]:
    """Write the reference-trajectory figures and return their paths.

    Files: ``<prefix>_iso.png`` (isometric 3-D view), ``<prefix>_xy.png`` (X-Y plane, equal axes),
    ``<prefix>_xz.png`` (X-Z plane).  ``dt``: sampling step of the nominal schedule, s.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    data = _sample_reference(traj, dt)
    wp = np.asarray(traj.params.Phip)
    toes = {f: np.concatenate([d[f] for d in data]) for f in ("R", "L")}

    def draw(ax, ix: int, iy: int, iz: int | None = None) -> None:
        seen: set[str] = set()
        for d in data:
            hip = d["hip"]
            lab = None if d["name"] in seen else f"hip CoM, {d['name']}"
            seen.add(d["name"])
            coords = [hip[:, ix], hip[:, iy]] + ([hip[:, iz]] if iz is not None else [])
            ax.plot(*coords, color=PHASE_COLOURS[d["name"]], lw=2, label=lab)
        for f, name in (("R", "right toe P_tpR"), ("L", "left toe P_tpL")):
            c = toes[f]
            coords = [c[:, ix], c[:, iy]] + ([c[:, iz]] if iz is not None else [])
            ax.plot(*coords, color=TOE_COLOURS[f], lw=1, label=name)
        coords = [wp[:, ix], wp[:, iy]] + ([wp[:, iz]] if iz is not None else [])
        ax.plot(*coords, "o", ms=4, mfc="none", color="orange", label="waypoints P_k")

    paths = []
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    draw(ax, 0, 1, 2)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    allpts = np.concatenate([toes["R"], toes["L"], wp] + [d["hip"] for d in data])
    ax.set_box_aspect(tuple(np.maximum(np.ptp(allpts, axis=0), 0.05)))  # true proportions
    ax.view_init(elev=25, azim=-60)
    ax.set_title("Reference trajectories (isometric view)")
    ax.legend(fontsize=7, loc="upper left")
    paths.append(_save(fig, out_dir / f"{prefix}_iso.png"))

    for name, (ix, iy), labels in (("xy", (0, 1), ("x [m]", "y [m]")), ("xz", (0, 2), ("x [m]", "z [m]"))):
        fig, ax = plt.subplots(figsize=(8, 6))
        draw(ax, ix, iy)
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        if name == "xy":
            ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, lw=0.3)
        ax.set_title(f"Reference trajectories on the {name.upper()[0]}-{name.upper()[1]} plane")
        ax.legend(fontsize=7, loc="best")
        paths.append(_save(fig, out_dir / f"{prefix}_{name}.png"))
    return paths




# ============================================================================================ run figures
#: thesis Figs. 6.54-6.60: joint-angle groups (file stem, thesis angle names)
JOINT_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("joints_theta3-6", ("theta3", "theta4", "theta5", "theta6")),
    ("joints_theta7-10", ("theta7", "theta8", "theta9", "theta10")),
    ("joints_theta11-14", ("theta11", "theta12", "theta13", "theta14")),
    ("joints_theta15-17l", ("theta15", "theta16", "theta17r", "theta17l")),
    ("joints_theta18-20", ("theta18", "theta19", "theta20")),
    ("joints_theta21-24", ("theta21", "theta22", "theta23", "theta24")),
    ("joints_theta25-27", ("theta25", "theta26", "theta27")),
)
#: thesis Figs. 6.64-6.70: actuator-torque groups (file stem, title, torque names)
TORQUE_GROUPS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("torques_T1-7", "right toe and ankle", ("T1", "T3", "T5", "T7")),
    ("torques_T9-15", "right knee and hip", ("T9", "T11", "T13", "T15")),
    ("torques_T2-8", "left toe and ankle", ("T2", "T4", "T6", "T8")),
    ("torques_T10-16", "left knee and hip", ("T10", "T12", "T14", "T16")),
    ("torques_T17-19", "waist", ("T17", "T18", "T19")),
    ("torques_T20-23", "shoulders", ("T20", "T21", "T22", "T23")),
    ("torques_T24-26", "neck", ("T24", "T25", "T26")),
)
#: thesis Figs. 6.71-6.74: (file stem, signal, title, [(body, row of body_force/body_moment)])
GRF_GROUPS: tuple[tuple[str, str, str, tuple[tuple[int, int], ...]], ...] = (
    ("grf_force_R", "body_force", "Ground reaction forces on bodies 1 and 3 (right foot)", ((1, 0), (3, 2))),
    ("grf_force_L", "body_force", "Ground reaction forces on bodies 2 and 4 (left foot)", ((2, 1), (4, 3))),
    ("grf_moment_R", "body_moment", "Ground reaction moments on bodies 1 and 3 (right foot)", ((1, 0), (3, 2))),
    ("grf_moment_L", "body_moment", "Ground reaction moments on bodies 2 and 4 (left foot)", ((2, 1), (4, 3))),
)
REQUIRED_SIGNALS = ("t", "phase", "basic_phase", "phase_names", "theta", "T", "T_cmd", "hip_p", "hip_p_ref",
                    "hip_yaw", "hip_yaw_ref", "toe_R_p", "toe_R_p_ref", "toe_L_p", "toe_L_p_ref", "body_force",
                    "body_moment", "foot_wrench", "cop", "zmp", "in_contact")


class PlotError(ValueError):
    """The results cannot be plotted (missing signal, empty log, bad shape); the message says which."""


def torque_limits() -> dict[str, float]:
    """Saturation limit of every actuator torque, N m (models/thesis_humanoid.yaml, errata section 7)."""
    from humanoid_sim.actuators import GROUPS
    from humanoid_sim.model import DEFAULT_SPEC
    from urdf_gen.spec import load_spec

    spec = load_spec(DEFAULT_SPEC)
    return {name: float(spec.actuators[g.name]["limit"]) for g in GROUPS for name in g.T}


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


def _phase_runs(phase: np.ndarray) -> list[tuple[int, int]]:
    """[first, last] step of each run of equal phase index."""
    cuts = np.flatnonzero(np.diff(phase)) + 1
    starts = np.concatenate([[0], cuts])
    ends = np.concatenate([cuts - 1, [len(phase) - 1]])
    return list(zip(starts.tolist(), ends.tolist()))


def _shade(ax, r: dict[str, np.ndarray]) -> None:
    """Shade each phase of the run in its thesis colour (span: its first step to the next phase's first)."""
    t = r["t"]
    names = [str(x) for x in r["phase_names"]]
    h = float(np.median(np.diff(t))) if len(t) > 1 else 0.01
    for a, b in _phase_runs(r["phase"]):
        t1 = t[b + 1] if b + 1 < len(t) else t[b] + h
        ax.axvspan(t[a], t1, color=PHASE_COLOURS.get(names[r["phase"][a]], "grey"), alpha=0.12, lw=0)


def _phase_legend(fig, r: dict[str, np.ndarray]) -> None:
    from matplotlib.patches import Patch

    present = [n for n in PHASE_COLOURS if n in {str(x) for x in r["phase_names"][np.unique(r["phase"])]}]
    handles = [Patch(color=PHASE_COLOURS[n], alpha=0.25, label=n) for n in present]
    fig.legend(handles=handles, loc="upper right", ncol=len(handles), fontsize=7, title="phase shading",
               title_fontsize=7)


def _line(ax, r: dict[str, np.ndarray], signal: str, index: tuple[int, ...], **kw):
    """Plot ``r[signal][:, *index]`` against t, tagged with its gid."""
    y = r[signal][(slice(None),) + index]
    (line,) = ax.plot(r["t"], y, **kw)
    line.set_gid(f"{signal}:{','.join(str(i) for i in index)}")
    return line


def _time_figure(r, n_rows: int, title: str, n_cols: int = 1, height: float = 2.0):
    # a bare Figure (not pyplot): no global registry, so many figures can be alive at once
    h_in = 1.0 + height * n_rows
    fig = Figure(figsize=(9 if n_cols == 1 else 11, h_in))
    axes = fig.subplots(n_rows, n_cols, sharex=True, squeeze=False)
    # fixed margins (inches) instead of a layout engine, which triples the drawing time
    fig.subplots_adjust(left=0.09 if n_cols == 1 else 0.08, right=0.98, top=1 - (0.55 if n_cols == 1 else 0.8) / h_in,
                        bottom=0.5 / h_in, hspace=0.12, wspace=0.25)
    for ax in axes.flat:
        _shade(ax, r)
        ax.grid(True, lw=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    fig.suptitle(title, x=0.02, ha="left")
    _phase_legend(fig, r)
    return fig, axes


def _fig_phases(r):
    names = [str(x) for x in r["phase_names"]]
    fig, axes = _time_figure(r, 2, "Phase timeline", height=1.8)
    ax = axes[0, 0]
    _line(ax, r, "phase", (), drawstyle="steps-post", color="k")
    used = np.unique(r["phase"])
    ax.set_yticks(used)
    ax.set_yticklabels([f"{k + 1} {names[k]}" for k in used], fontsize=7)
    ax.set_ylabel("phase [-]")
    ax = axes[1, 0]
    for f, (foot, colour) in enumerate((("right", "tab:red"), ("left", "tab:blue"))):
        _line(ax, r, "in_contact", (f,), drawstyle="steps-post", color=colour, label=f"{foot} foot")
    ax.set_yticks([0, 1])
    ax.set_yticklabels(["free", "held"])
    ax.set_ylabel("foot constraint [-]")
    ax.legend(fontsize=7, loc="center right")
    return fig


def _fig_joints(r, names: tuple[str, ...]):
    from humanoid_sim.model import THETA_NAMES

    fig, axes = _time_figure(r, len(names), f"Joint space positions {names[0]} to {names[-1]}")
    for ax, name in zip(axes[:, 0], names):
        _line(ax, r, "theta", (THETA_NAMES.index(name),), color="tab:blue")
        ax.set_ylabel(f"{name} [rad]")
    return fig


def _fig_task(r, key: str, title: str, label: str):
    rows = 4 if key == "hip" else 3
    fig, axes = _time_figure(r, rows, title)
    sig = "hip_p" if key == "hip" else f"toe_{key}_p"
    for i, ax in enumerate(axes[:3, 0]):
        _line(ax, r, sig, (i,), color="tab:blue", label="simulation")
        _line(ax, r, f"{sig}_ref", (i,), color="k", ls="--", lw=1, label="reference")
        ax.set_ylabel(f"{label} {'xyz'[i]} [m]")
    if key == "hip":
        ax = axes[3, 0]
        _line(ax, r, "hip_yaw", (), color="tab:blue", label="simulation")
        _line(ax, r, "hip_yaw_ref", (), color="k", ls="--", lw=1, label="reference")
        ax.set_ylabel("Body-17 yaw [rad]")
    axes[0, 0].legend(fontsize=7, loc="best")
    return fig


def _fig_torques(r, names: tuple[str, ...], title: str, limits: dict[str, float]):
    from humanoid_sim.actuators import T_NAMES

    fig, axes = _time_figure(r, len(names), f"Actuator torques {names[0]} to {names[-1]} ({title})")
    for ax, name in zip(axes[:, 0], names):
        i = T_NAMES.index(name)
        _line(ax, r, "T_cmd", (i,), color="0.55", lw=0.8, ls="--", label="command T_cmd")
        _line(ax, r, "T", (i,), color="tab:blue", label="applied T")
        lim = limits[name]
        for sign in (1.0, -1.0):
            line = ax.axhline(sign * lim, color="red", lw=0.8, ls=":", label="saturation +-T_max" if sign > 0
                              else None)
            line.set_gid(f"limit:{name}")
        peak = float(np.nanmax(np.abs(r["T_cmd"][:, i]))) if len(r["t"]) else 0.0
        ax.set_ylim(-1.1 * max(lim, peak), 1.1 * max(lim, peak))
        ax.set_ylabel(f"{name} [N m]")
    axes[0, 0].legend(fontsize=7, loc="lower left", ncol=3)
    return fig


def _fig_grf(r, signal: str, title: str, bodies: tuple[tuple[int, int], ...]):
    unit, sym = ("N", "F") if signal == "body_force" else ("N m", "M")
    fig, axes = _time_figure(r, 3, title, n_cols=len(bodies), height=1.8)
    for c, (body, row) in enumerate(bodies):
        for i in range(3):
            ax = axes[i, c]
            _line(ax, r, signal, (row, i), color="tab:blue")
            ax.set_ylabel(f"{sym}_0,{body} {'xyz'[i]} [{unit}]")
        axes[0, c].set_title(f"body {body} (components in frame {body})", fontsize=9)
    return fig


def _fig_contact_world(r):
    fig, axes = _time_figure(r, 3, "Ground reaction per foot (world frame), centre of pressure and ZMP")
    ax = axes[0, 0]
    for f, (foot, colour) in enumerate((("right", "tab:red"), ("left", "tab:blue"))):
        _line(ax, r, "foot_wrench", (f, 2), color=colour, label=f"{foot} foot")
    ax.set_ylabel("vertical force F_z [N]")
    ax.legend(fontsize=7, loc="best")
    for i, ax in zip((0, 1), axes[1:, 0]):
        for f, (foot, colour) in enumerate((("right", "tab:red"), ("left", "tab:blue"))):
            _line(ax, r, "cop", (f, i), color=colour, label=f"CoP {foot}")
        _line(ax, r, "zmp", (i,), color="k", ls="--", lw=1, label="ZMP")
        ax.set_ylabel(f"{'xy'[i]} [m]")
    axes[1, 0].legend(fontsize=7, loc="best")
    return fig


def _builders(r: dict[str, np.ndarray], limits: dict[str, float]) -> dict[str, Callable[[], Figure]]:
    """Every time-series figure of a run as a zero-argument builder, by file stem (thesis section 6.2 order)."""
    builders: dict[str, Callable[[], Figure]] = {"phases": lambda: _fig_phases(r)}
    for stem, names in JOINT_GROUPS:
        builders[stem] = lambda names=names: _fig_joints(r, names)
    builders["task_hip"] = lambda: _fig_task(r, "hip", "Position of the mass centre of body 17 with its reference "
                                             "(world frame)", "P_c17")
    builders["task_toe_R"] = lambda: _fig_task(r, "R", "Toe point on the right foot (body 1) with its reference "
                                               "(world frame)", "P_tpR")
    builders["task_toe_L"] = lambda: _fig_task(r, "L", "Toe point on the left foot (body 2) with its reference "
                                               "(world frame)", "P_tpL")
    for stem, title, names in TORQUE_GROUPS:
        builders[stem] = lambda title=title, names=names: _fig_torques(r, names, title, limits)
    for stem, signal, title, bodies in GRF_GROUPS:
        builders[stem] = lambda signal=signal, title=title, bodies=bodies: _fig_grf(r, signal, title, bodies)
    builders["contact_world"] = lambda: _fig_contact_world(r)
    return builders


def run_figures(r: dict[str, np.ndarray], limits: dict[str, float] | None = None,
                only: list[str] | None = None) -> dict[str, Figure]:
    """Every time-series figure of a run (a :func:`humanoid_sim.results.load_results` dict), by file stem.

    The figures are bare :class:`matplotlib.figure.Figure` objects (not registered with pyplot).  ``limits``: saturation
    limit per torque name (N m), default :func:`torque_limits`.  ``only``: build just these stems.
    """
    _check(r)
    limits = torque_limits() if limits is None else limits
    builders = _builders(r, limits)
    stems = list(builders) if only is None else [s for s in builders if s in set(only)]
    return {stem: builders[stem]() for stem in stems}


def figure_stems(r: dict[str, np.ndarray]) -> list[str]:
    """File stems of :func:`run_figures`, in order."""
    return list(_builders(r, {}))


def _render(results_path: str, out_dir: str, stems: list[str], dpi: int) -> list[str]:
    """Build and save the figures ``stems`` of a run (a worker's share of :func:`plot_all`)."""
    from humanoid_sim.results import load_results

    out = []
    for stem, fig in run_figures(load_results(results_path), only=stems).items():
        fig.savefig(Path(out_dir) / f"{stem}.png", dpi=dpi)
        out.append(str(Path(out_dir) / f"{stem}.png"))
    return out


def plot_all(results_path: str | Path, out_dir: str | Path, traj: "ReferenceTrajectory | None" = None,
             *, dpi: int = 100, workers: int | None = None) -> list[Path]:
    """Write every figure of a run from its results.npz into ``out_dir``; returns the PNG paths.

    With ``traj`` (the run's :class:`ReferenceTrajectory`) the reference-trajectory figures come first.  The
    time-series figures are drawn by ``workers`` processes (default: one per CPU, at most 4; 1 draws them here):
    matplotlib spends ~0.3 s per figure, far more than the simulation per figure's worth of data.
    """
    import os
    from concurrent.futures import ProcessPoolExecutor

    from humanoid_sim.results import load_results

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    r = load_results(results_path)
    stems = figure_stems(r)
    workers = min(4, os.cpu_count() or 1) if workers is None else max(1, int(workers))
    shares = [stems[i::workers] for i in range(workers)]
    paths: list[Path] = []
    if workers == 1:
        if traj is not None:
            paths += plot_reference(traj, out_dir)
        return paths + [Path(p) for p in _render(str(results_path), str(out_dir), stems, dpi)]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(_render, str(results_path), str(out_dir), share, dpi) for share in shares]
        if traj is not None:
            paths += plot_reference(traj, out_dir)  # meanwhile, in this process
        done = {Path(p).stem: Path(p) for f in futures for p in f.result()}
    return paths + [done[s] for s in stems]
