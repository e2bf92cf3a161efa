"""Figures of a run (humanoid_sim.plots, scripts/plot.py): every file is written, every plotted line is the
results.npz data it claims to be, the saturation limits are the actuator model's, phases are shaded in the
thesis colours."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.patches import Rectangle
from PIL import Image

from humanoid_sim.model import HumanoidModel
from humanoid_sim.results import load_results

REPO = Path(__file__).resolve().parents[1]
SIM1 = REPO / "scripts" / "params" / "sim1.yaml"
RUN_UNTIL = 1.0  # s: LFFSSP, RFFDSP and the start of RFFSSP of Simulation 1 (three phases, both feet loaded)

#: the figure files of a run, thesis section 6.2 (written out here, not taken from the module under test)
EXPECTED_FILES = {
    "reference_iso.png", "reference_xy.png", "reference_xz.png",                          # Figs. 6.51-6.53
    "phases.png",
    "joints_theta3-6.png", "joints_theta7-10.png", "joints_theta11-14.png",               # Figs. 6.54-6.56
    "joints_theta15-17l.png", "joints_theta18-20.png", "joints_theta21-24.png",           # Figs. 6.57-6.59
    "joints_theta25-27.png",                                                              # Fig. 6.60
    "task_hip.png", "task_toe_R.png", "task_toe_L.png",                                   # Figs. 6.61-6.63
    "torques_T1-7.png", "torques_T9-15.png", "torques_T2-8.png", "torques_T10-16.png",    # Figs. 6.64-6.67
    "torques_T17-19.png", "torques_T20-23.png", "torques_T24-26.png",                     # Figs. 6.68-6.70
    "grf_force_R.png", "grf_force_L.png", "grf_moment_R.png", "grf_moment_L.png",         # Figs. 6.71-6.74
    "contact_world.png",
}
THESIS_PHASE_RGB = {"LFFSSP": to_rgb("red"), "RFFDSP": to_rgb("blue"), "RFFSSP": to_rgb("magenta"),
                    "LFFDSP": to_rgb("cyan")}  # thesis L4219-4221


@pytest.fixture(scope="module")
def run_npz(hm: HumanoidModel, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 1 s run of Simulation 1, saved as walk.py saves it."""
    from humanoid_sim.scenario import load_scenario
    from humanoid_sim.simulate import Simulator

    sim = Simulator(hm, load_scenario(SIM1))
    result = sim.run(t_end=RUN_UNTIL)
    out = tmp_path_factory.mktemp("run") / "results.npz"
    result.log.save(out, [p.name for p in sim.traj.phases])
    return out


@pytest.fixture(scope="module")
def figures(run_npz: Path):
    from humanoid_sim.plots import run_figures

    return run_figures(load_results(run_npz))


def _plot_script():
    spec = importlib.util.spec_from_file_location("plot_script", REPO / "scripts" / "plot.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_plot_script_writes_every_figure(run_npz: Path, tmp_path: Path) -> None:
    out = tmp_path / "figs"
    assert _plot_script().main([str(run_npz), "--out", str(out), "--scenario", str(SIM1)]) == 0
    written = {p.name for p in out.glob("*.png")}
    assert written == EXPECTED_FILES
    for name in written:
        with Image.open(out / name) as im:
            im.verify()  # a complete, decodable PNG
        with Image.open(out / name) as im:
            assert im.format == "PNG" and im.width > 400 and im.height > 300, (name, im.size)
            assert np.asarray(im.convert("L")).std() > 5, f"{name} is blank"


def test_plot_script_rejects_bad_input(tmp_path: Path) -> None:
    mod = _plot_script()
    assert mod.main([str(tmp_path / "missing.npz")]) == 2
    bad = tmp_path / "results.npz"
    np.savez(bad, t=np.arange(3.0))  # a results file without the other signals
    assert mod.main([str(bad), "--out", str(tmp_path / "o")]) == 2


def _data_lines(fig):
    for ax in fig.axes:
        for line in ax.get_lines():
            gid = line.get_gid()
            if gid and not gid.startswith("limit:"):
                yield ax, line, gid


def test_plotted_lines_are_the_logged_data(figures, run_npz: Path) -> None:
    r = load_results(run_npz)
    plotted: dict[str, set[tuple[int, ...]]] = {}
    for stem, fig in figures.items():
        lines = list(_data_lines(fig))
        assert lines, f"{stem}: no data line"
        for _, line, gid in lines:
            signal, idx = gid.split(":")
            index = tuple(int(i) for i in idx.split(",")) if idx else ()
            np.testing.assert_array_equal(line.get_xdata(), r["t"], err_msg=f"{stem} {gid}: time axis")
            # exact: a figure must show the logged numbers, not a resampled or smoothed copy
            np.testing.assert_array_equal(line.get_ydata(), r[signal][(slice(None),) + index],
                                          err_msg=f"{stem} {gid}")
            plotted.setdefault(signal, set()).add(index)
    # every joint angle and every actuator torque (applied and commanded) appears
    for signal in ("theta", "T", "T_cmd"):
        assert plotted[signal] == {(i,) for i in range(26)}, signal
    for signal in ("body_force", "body_moment"):
        assert plotted[signal] == {(b, c) for b in range(4) for c in range(3)}, signal
    for signal in ("hip_p", "hip_p_ref", "toe_R_p", "toe_R_p_ref", "toe_L_p", "toe_L_p_ref"):
        assert plotted[signal] == {(0,), (1,), (2,)}, signal
    assert plotted["hip_yaw"] == {()} and plotted["hip_yaw_ref"] == {()} and plotted["phase"] == {()}


def test_saturation_limits_are_the_actuator_limits(figures, hm: HumanoidModel) -> None:
    from humanoid_sim.actuators import T_NAMES, Actuators

    limits = dict(zip(T_NAMES, Actuators(hm).limits))  # the limits the simulator saturates with
    seen = set()
    for stem, fig in figures.items():
        for ax in fig.axes:
            for line in ax.get_lines():
                gid = line.get_gid() or ""
                if gid.startswith("limit:"):
                    name = gid.split(":")[1]
                    seen.add(name)
                    assert abs(line.get_ydata()[0]) == limits[name], (stem, name)
                    assert ax.get_ylim()[1] >= limits[name], f"{stem}: limit {name} outside the axes"
    assert seen == set(T_NAMES)


def test_axes_carry_units_and_phase_shading(figures, run_npz: Path) -> None:
    r = load_results(run_npz)
    names = [str(n) for n in r["phase_names"]]
    # the phase runs of the log, computed here from the raw phase signal
    change = np.flatnonzero(np.diff(r["phase"])) + 1
    starts = np.concatenate([[0], change])
    expected = [(float(r["t"][s]), THESIS_PHASE_RGB[names[r["phase"][s]]]) for s in starts]
    assert len(expected) == 3, "the 1 s run should cross LFFSSP -> RFFDSP -> RFFSSP"
    for stem, fig in figures.items():
        for ax in fig.axes:
            ylabel = ax.get_ylabel()
            assert ylabel.endswith("]") and "[" in ylabel, f"{stem}: y label {ylabel!r} has no unit"
            spans = sorted(((p.get_x() if isinstance(p, Rectangle) else p.get_xy()[0][0]), p.get_facecolor())
                           for p in ax.patches)
            assert len(spans) == len(expected), f"{stem}: {len(spans)} phase spans, expected {len(expected)}"
            for (x0, colour), (t0, rgb) in zip(spans, expected):
                assert x0 == t0
                assert tuple(colour[:3]) == rgb, f"{stem}: phase at t = {t0} shaded {colour[:3]}, want {rgb}"
        assert fig.axes[-1].get_xlabel() == "t [s]", stem


def test_parallel_drawing_writes_the_same_files(run_npz: Path, tmp_path: Path) -> None:
    """plot_all's worker processes produce byte-identical PNGs to drawing them all in this process."""
    from humanoid_sim.plots import plot_all

    serial = plot_all(run_npz, tmp_path / "serial", workers=1)
    parallel = plot_all(run_npz, tmp_path / "parallel", workers=2)
    assert [p.name for p in serial] == [p.name for p in parallel] and len(serial) >= 20
    for a, b in zip(serial, parallel):
        assert a.read_bytes() == b.read_bytes(), a.name
