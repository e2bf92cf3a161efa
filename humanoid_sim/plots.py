"""PNG figures (matplotlib, Agg backend).

For now: the reference-trajectory figures of thesis 6.2.1.1 (Figs. 6.51-6.53, 6.76-6.78, 6.83-6.84):
hip CoM path coloured by phase (red LFFSSP, blue RFFDSP, magenta RFFSSP, cyan LFFDSP, thesis L4219),
right toe point green, left toe point black, waypoints marked.  World frame, metres.
Further figure groups are added as separate functions that share ``_save``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
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


def plot_all(results_path: str | Path, out_dir: str | Path, traj: "ReferenceTrajectory | None" = None) -> list[Path]:
    """Every figure of a run (thesis section 6.2 groups) from its results.npz; returns the PNG paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from humanoid_sim.results import load_results

    out_dir = Path(out_dir)
    r = load_results(results_path)
    paths: list[Path] = []
    if traj is not None:
        paths += plot_reference(traj, out_dir)
    t = r["t"]
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for i, ax in enumerate(axes):
        ax.plot(t, r["hip_p"][:, i], label="actual")
        ax.plot(t, r["hip_p_ref"][:, i], "--", label="reference")
        ax.set_ylabel(f"P_c17 {'xyz'[i]} (m)")
    axes[0].legend()
    axes[-1].set_xlabel("t (s)")
    fig.suptitle("Body-17 CoM against its reference (world frame)")
    paths.append(_save(fig, out_dir / "task_hip.png"))
    return paths
