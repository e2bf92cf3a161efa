"""Figures of a run (humanoid_sim.outputs.plots.thesis, scripts/plot.py): every file is written, every plotted line is
the results.npz data it claims to be, the saturation limits are the actuator model's, phases are shaded in the
thesis colours."""

from __future__ import annotations

import importlib.util
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from matplotlib.colors import to_rgb
from matplotlib.patches import Rectangle
from PIL import Image

from humanoid_sim.interfaces.log import load_results
from humanoid_sim.robot.model import HumanoidModel

REPO = Path(__file__).resolve().parents[2]
SIM1 = REPO / "scripts" / "params" / "sim1.yaml"
RUN_UNTIL = 1.0  # s: LFFSSP, RFFDSP and the start of RFFSSP of Simulation 1 (three phases, both feet loaded)

#: the figure files of a run, thesis section 6.2 (written out here, not taken from the module under test)
EXPECTED_FILES = {
    "reference_iso.png", "reference_xy.png", "reference_xz.png",                          # Figs. 6.51-6.53
    "phases.png",
    "joints_toe_ankle_pitch.png", "joints_ankle_yaw_roll.png", "joints_knee_hip_pitch.png",  # Figs. 6.54-6.56
    "joints_hip_roll_yaw.png", "joints_waist.png", "joints_shoulders.png",                # Figs. 6.57-6.59
    "joints_neck.png",                                                                    # Fig. 6.60
    "task_hip.png", "task_toe_R.png", "task_toe_L.png",                                   # Figs. 6.61-6.63
    "torques_right_toe_ankle.png", "torques_right_knee_hip.png",                          # Figs. 6.64-6.65
    "torques_left_toe_ankle.png", "torques_left_knee_hip.png",                            # Figs. 6.66-6.67
    "torques_waist.png", "torques_shoulders.png", "torques_neck.png",                     # Figs. 6.68-6.70
    "grf_force_R.png", "grf_force_L.png", "grf_moment_R.png", "grf_moment_L.png",         # Figs. 6.71-6.74
    "contact_world.png", "contact_audit.png",
}
THESIS_PHASE_RGB = {"LFFSSP": to_rgb("red"), "RFFDSP": to_rgb("blue"), "RFFSSP": to_rgb("magenta"),
                    "LFFDSP": to_rgb("cyan")}  # thesis L4219-4221


@pytest.fixture(scope="module")
def run_npz(hm: HumanoidModel, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 1 s run of Simulation 1, saved as walk.py saves it."""
    from humanoid_sim.scenario.schema import load_scenario
    from humanoid_sim.sim.simulate import Simulator

    sim = Simulator(hm, load_scenario(SIM1))
    result = sim.run(t_end=RUN_UNTIL)
    out = tmp_path_factory.mktemp("run") / "results.npz"
    result.log.save(out, [p.name for p in sim.traj.phases])
    return out


@pytest.fixture(scope="module")
def figures(run_npz: Path):
    from humanoid_sim.outputs.plots.thesis import run_figures

    return run_figures(load_results(run_npz))


def _plot_script():
    spec = importlib.util.spec_from_file_location("plot_script", REPO / "scripts" / "plot.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.slow
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
    """Lines that draw a results.npz column against t (gid "<signal>:<index>")."""
    for ax in fig.axes:
        for line in ax.get_lines():
            gid = line.get_gid()
            if gid and not gid.startswith(("limit:", "ground:", "audit:", "reference:")):
                yield ax, line, gid


def test_plotted_lines_are_the_logged_data(figures, run_npz: Path) -> None:
    r = load_results(run_npz)
    plotted: dict[str, set[tuple[int, ...]]] = {}
    for stem, fig in figures.items():
        lines = list(_data_lines(fig))
        if stem == "contact_audit":  # audit quantities, not results columns (tests/analysis/test_audit.py checks them)
            continue
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
    from humanoid_sim.robot.actuators import T_NAMES, Actuators

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
            for label in (ax.get_xlabel(), ax.get_ylabel()):
                # one unit style: "quantity [unit]", never "(unit)"
                assert not label or (label.endswith("]") and "[" in label), f"{stem}: label {label!r}"
            assert ax.get_ylabel(), f"{stem}: an axes without a y label"
            if ax.get_label() == "ground view":  # the x-y view of contact_world, not a time plot
                continue
            spans = sorted(((p.get_x() if isinstance(p, Rectangle) else p.get_xy()[0][0]), p.get_facecolor())
                           for p in ax.patches)
            assert len(spans) == len(expected), f"{stem}: {len(spans)} phase spans, expected {len(expected)}"
            for (x0, colour), (t0, rgb) in zip(spans, expected):
                assert x0 == t0
                assert tuple(colour[:3]) == rgb, f"{stem}: phase at t = {t0} shaded {colour[:3]}, want {rgb}"
        assert "t [s]" in {ax.get_xlabel() for ax in fig.axes}, stem


@pytest.mark.slow
def test_parallel_drawing_writes_the_same_files(run_npz: Path, tmp_path: Path) -> None:
    """plot_all's worker processes produce byte-identical PNGs to drawing them all in this process."""
    from humanoid_sim.outputs.plots.thesis import plot_all

    serial = plot_all(run_npz, tmp_path / "serial", workers=1)
    parallel = plot_all(run_npz, tmp_path / "parallel", workers=2)
    assert [p.name for p in serial] == [p.name for p in parallel] and len(serial) >= 20
    for a, b in zip(serial, parallel):
        assert a.read_bytes() == b.read_bytes(), a.name


# --------------------------------------------------------------------------------------------- style
def _foot_of(gid: str) -> str | None:
    """The foot a line belongs to, read from its gid (the results column it draws), or "outside" for the
    outside-the-polygon markers; None for lines of no foot.  Written out here from the results.npz layout."""
    sig, _, idx = gid.partition(":")
    if sig in ("toe_R_p", "toe_L_p"):
        return sig[4]
    if sig in ("foot_wrench", "cop", "in_contact"):
        return "RL"[int(idx.split(",")[0])]
    if sig in ("body_force", "body_moment"):  # rows: bodies 1, 2, 3, 4 = right toe, left toe, right, left foot
        return "RLRL"[int(idx.split(",")[0])]
    if sig == "reference":
        return idx[-1] if idx.startswith("toe_") else None
    if sig == "audit":
        return idx.split(":")[1] or None
    if sig == "ground":
        if idx.endswith("_outside"):
            return "outside"
        m = re.match(r"(?:sole|cop)_([RL])", idx)
        return m.group(1) if m else None
    return None


def test_one_colour_per_foot_in_every_figure(figures, hm: HumanoidModel) -> None:
    """Every line of a foot (toe paths, ground reactions, CoP, sole outlines, contact flags, audit) has that foot's
    colour, in every figure including the reference and audit figures; the two feet differ; no other line uses
    either colour; the outside markers have a colour of their own."""
    from matplotlib.colors import to_hex

    from humanoid_sim.outputs.plots.thesis import reference_figures
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.scenario.schema import load_scenario

    every = {**figures, **reference_figures(ReferenceTrajectory(load_scenario(SIM1).path), dt=0.05)}
    seen: dict[str, set[str]] = {}
    where: dict[str, set[str]] = {}
    others: list[tuple[str, str, str]] = []
    for stem, fig in every.items():
        for ax in fig.axes:
            for line in ax.get_lines():
                gid = line.get_gid()
                if not gid or gid.startswith("limit:"):
                    continue
                foot = _foot_of(gid)
                colour = to_hex(line.get_color())
                if foot is None:
                    others.append((stem, gid, colour))
                else:
                    seen.setdefault(foot, set()).add(colour)
                    where.setdefault(foot, set()).add(stem)
    common = {"phases", "contact_world", "contact_audit", "reference_iso", "reference_xy", "reference_xz"}
    for foot in "RL":  # the figures that show one foot, and the ones that show both
        assert common | {f"task_toe_{foot}", f"grf_force_{foot}", f"grf_moment_{foot}"} <= where[foot], where[foot]
    assert len(seen["R"]) == 1 and len(seen["L"]) == 1, seen
    assert seen["R"] != seen["L"] and seen["outside"].isdisjoint(seen["R"] | seen["L"])
    feet = seen["R"] | seen["L"]
    assert not [o for o in others if o[2] in feet], [o for o in others if o[2] in feet][:5]


def _render_extents(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


@pytest.mark.slow
def test_legends_cover_neither_titles_nor_plots(figures) -> None:
    """Every legend lies inside its figure and overlaps no plotting area, no axes title and no figure title (the
    "(world frame)" of task_hip and the ZMP of contact_world were hidden under legends)."""
    for stem, fig in figures.items():
        renderer = _render_extents(fig)
        W, H = fig.bbox.width, fig.bbox.height
        legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
        assert legends, stem
        blocked = [ax.get_window_extent(renderer) for ax in fig.axes]
        blocked += [ax.title.get_window_extent(renderer) for ax in fig.axes if ax.get_title()]
        if fig._suptitle is not None:
            blocked.append(fig._suptitle.get_window_extent(renderer))
        for leg in legends:
            box = leg.get_window_extent(renderer)
            assert box.x0 >= 0 and box.y0 >= 0 and box.x1 <= W + 0.5 and box.y1 <= H + 0.5, (stem, box)
            for other in blocked:
                assert not box.overlaps(other), f"{stem}: a legend covers {other}"
        if fig._suptitle is not None:  # the title itself is whole
            box = fig._suptitle.get_window_extent(renderer)
            assert box.x0 >= 0 and box.x1 <= W and box.y1 <= H + 0.5, (stem, box)


def test_joint_figures_name_their_joints(figures) -> None:
    """Each joint axis is labelled with the joint it turns (the actuator groups of actuators.py name the joints;
    the URDF's axis gives roll x / pitch y / yaw z) and its thesis angle; no title or file is named by angle range."""
    from humanoid_sim.robot.actuators import GROUPS

    root = ET.parse(REPO / "models" / "thesis_humanoid.urdf").getroot()
    axis = {j.get("name"): {"1 0 0": "roll", "0 1 0": "pitch", "0 0 1": "yaw"}[j.find("axis").get("xyz")]
            for j in root.findall("./joint[@type='revolute']")}
    joint = {th: g.name.replace("_", " ") for g in GROUPS for th in g.thetas}
    stems = [s for s in figures if s.startswith("joints_")]
    assert len(stems) == 7
    named = set()
    for stem in stems:
        assert "theta" not in stem
        fig = figures[stem]
        assert not re.search(r"theta\d+\w* to theta", fig._suptitle.get_text()), fig._suptitle.get_text()
        for ax in fig.axes:
            th = re.search(r"(theta\d+[rl]?) \[rad\]", ax.get_ylabel()).group(1)
            assert f"{joint[th]} {axis[th]}" in ax.get_ylabel(), (stem, ax.get_ylabel())
            named.add(th)
    assert named == set(joint)


def test_contact_world_draws_the_sole_outlines(figures, run_npz: Path, hm: HumanoidModel) -> None:
    """The ground view of contact_world draws, for each single-support phase, the supporting sole: the model's sole
    rectangle (models/thesis_humanoid.yaml) carried by the foot body (O_3 right, O_4 left) at the phase's first
    step; in double support a support polygon enclosing both soles."""
    import yaml

    r = load_results(run_npz)
    sole = {k: v["value"] for k, v in yaml.safe_load((REPO / "models" / "thesis_humanoid.yaml").read_text())
            ["foot_sole"].items()}
    corners = np.array([[x, y, sole["sole_z"]] for x in (sole["heel_back_x"], sole["toe_front_x"])
                        for y in (-sole["width"] / 2, sole["width"] / 2)])
    ground = next(ax for ax in figures["contact_world"].axes if ax.get_label() == "ground view")
    lines = {line.get_gid(): np.column_stack([line.get_xdata(), line.get_ydata()]) for line in ground.get_lines()}
    data = hm.model.createData()
    names = [str(n) for n in r["phase_names"]]
    checked = 0
    for k in np.unique(r["phase"]):
        first = int(np.flatnonzero(r["phase"] == k)[0])
        if names[k] in ("LFFSSP", "RFFSSP"):
            foot = "L" if names[k] == "LFFSSP" else "R"
            pin.framesForwardKinematics(hm.model, data, r["q"][first])
            M = data.oMf[hm.frame_id("O_4" if foot == "L" else "O_3")]
            world = (corners @ M.rotation.T + M.translation)[:, :2]
            drawn = lines[f"ground:sole_{foot}:{first}"]
            np.testing.assert_allclose(drawn[0], drawn[-1])  # a closed outline
            # 1e-9 m: the same rigid transform of the same corners
            assert all(np.min(np.linalg.norm(drawn - c, axis=1)) < 1e-9 for c in world)
            checked += 1
        else:
            hull = lines[f"ground:support:{first}"]
            soles = np.concatenate([v for g, v in lines.items() if g.startswith("ground:sole_")
                                    and g.endswith(f":{first}")])
            from matplotlib.path import Path as MplPath

            # every sole corner inside or on the support polygon (radius 1e-9 m: points on its edges)
            assert MplPath(hull).contains_points(soles, radius=1e-9).all() or \
                MplPath(hull[::-1]).contains_points(soles, radius=1e-9).all()
    assert checked >= 2  # LFFSSP and RFFSSP in the 1 s run


@pytest.mark.slow
def test_plot_script_redraws_every_figure_walk_draws(tmp_path: Path) -> None:
    """walk.py --figures all and plot.py draw one list of figures: plot.py on walk.py's results writes the same
    file names, except the sizing figures (drawn from the run's full-rate numbers, which results.npz does not hold);
    walk.py's default and plot.py --figures quick, the same few."""
    from humanoid_sim.cli.walk import main
    from humanoid_sim.outputs.design import SIZING_FIGURES

    walked, redrawn, quick = tmp_path / "walk", tmp_path / "plot", tmp_path / "quick"
    assert main([str(SIM1), "--out", str(walked), "--until", "1.0", "--no-html", "--quiet", "--figures", "all"]) == 0
    assert _plot_script().main([str(walked / "results.npz"), "--out", str(redrawn)]) == 0
    by_walk = {p.name for p in walked.glob("*.png")}
    sizing = {f"{stem}.png" for stem in SIZING_FIGURES}
    assert by_walk == EXPECTED_FILES | sizing
    assert {p.name for p in redrawn.glob("*.png")} == by_walk - sizing
    assert main([str(SIM1), "--out", str(quick), "--until", "1.0", "--no-html", "--quiet"]) == 0
    by_default = {p.name for p in quick.glob("*.png")}
    assert _plot_script().main([str(quick / "results.npz"), "--out", str(redrawn / "q"), "--figures", "quick"]) == 0
    assert {p.name for p in (redrawn / "q").glob("*.png")} == by_default < EXPECTED_FILES


# ---------------------------------------------------------------------------------------------- what they say
def _texts(fig) -> str:
    """Every piece of text a figure shows: titles, axis labels, tick labels, legend entries."""
    from matplotlib.text import Text

    return "\n".join(t.get_text() for t in fig.findobj(Text))


def test_figure_text_names_the_engines_kind_of_contact(run_npz: Path) -> None:
    """On welds the phase timeline and the audit speak of held / welded feet; for a MuJoCo run, of the planned
    support and real unilateral contact, and never of welds."""
    from humanoid_sim.outputs.plots.thesis import run_figures

    r = load_results(run_npz)
    only = ["phases", "contact_audit", "contact_world"]
    weld = run_figures(r, only=only, engine="pinocchio")
    assert "which foot is held" in _texts(weld["phases"]) and "welded feet" in _texts(weld["contact_audit"])
    assert "the weld pulls" in _texts(weld["contact_audit"])
    mj = run_figures(r, only=only, engine="mujoco")
    for stem, fig in mj.items():
        text = _texts(fig)
        assert "weld" not in text.lower() and "held" not in text, (stem, text)
    assert "planned support" in _texts(mj["phases"])
    assert "real unilateral contact (mujoco)" in _texts(mj["contact_audit"])


def test_the_engine_comes_from_results_npz(run_npz: Path) -> None:
    from humanoid_sim.outputs.plots.thesis import run_figures

    r = {**load_results(run_npz), "engine": np.array("mujoco")}
    assert "planned support" in _texts(run_figures(r, only=["phases"])["phases"])


def test_torque_figures_are_named_by_the_joints_they_drive() -> None:
    """Each torque figure's name says the side and joints whose actuators it holds (not a T-number range that
    hides the odd/even split of eq. 4.69)."""
    from humanoid_sim.outputs.plots.thesis import TORQUE_GROUPS

    for stem, title, names in TORQUE_GROUPS:
        assert stem == "torques_" + title.replace(" and ", "_").replace(" ", "_"), stem
        assert not re.search(r"T\d", stem)
        side = {"right": 1, "left": 0}.get(title.split()[0])
        if side is not None and int(names[0][1:]) <= 16:   # legs: right odd, left even (eq. 4.69)
            assert all(int(n[1:]) % 2 == side for n in names), (stem, names)


def test_every_figure_is_listed_in_the_docs() -> None:
    from humanoid_sim.outputs.plots.thesis import FIGURES, QUICK_FIGURES

    doc = (REPO / "docs" / "outputs.md").read_text()
    for stem in FIGURES:
        assert f"`{stem}.png`" in doc, stem
    assert set(QUICK_FIGURES) <= set(FIGURES)


def test_plot_all_draws_only_the_figures_asked_for(run_npz: Path, tmp_path: Path) -> None:
    from humanoid_sim.outputs.plots.thesis import QUICK_FIGURES, PlotError, plot_all

    paths = plot_all(run_npz, tmp_path, stems=QUICK_FIGURES, workers=1)
    assert [p.stem for p in paths] == [s for s in QUICK_FIGURES]
    assert {p.name for p in tmp_path.glob("*.png")} == {f"{s}.png" for s in QUICK_FIGURES}
    with pytest.raises(PlotError, match="unknown figures"):
        plot_all(run_npz, tmp_path, stems=["torques_T1-7"])


def test_a_run_without_steps_writes_no_figures(hm: HumanoidModel, tmp_path: Path) -> None:
    """Run.write of a walk that ended before its first step: results.npz and summary.json, no figure, no
    playback, even when asked for all."""
    import humanoid_sim as hs

    run = hs.run_walk("sim1", until=0.2, verbose=False)
    run.result.log = type(run.result.log).from_columns({k: v[:0] for k, v in run.result.log.arrays().items()})
    written = run.write(tmp_path / "out", figures="all", playback=True)
    assert [p.name for p in written] == ["results.npz", "summary.json"]
    assert not list((tmp_path / "out").glob("*.png"))


def test_the_ground_view_of_a_long_walk_is_a_window_at_its_smallest_zmp_margin() -> None:
    from types import SimpleNamespace

    from humanoid_sim.outputs.plots.ground import WINDOW_M, ground_window

    def walk(length: float) -> SimpleNamespace:
        n = 50
        y = np.linspace(0.0, length, n)
        sole = np.array([[-0.05, -0.1], [0.05, -0.1], [0.05, 0.1], [-0.05, 0.1]])
        polygons = [[sole + [0.1, yk], sole + [-0.1, yk]] for yk in y]
        margin = np.full(n, 0.03)
        margin[37] = 0.004                                     # the step a designer should look at
        return SimpleNamespace(polygons=polygons, zmp=np.stack([np.zeros(n), y], axis=1), zmp_margin=margin,
                               t=np.arange(n) * 0.1)

    assert ground_window(walk(0.5 * WINDOW_M)) is None
    (x0, x1), (y0, y1), t = ground_window(walk(12.0))
    y37 = np.linspace(0.0, 12.0, 50)[37]
    assert (x1 - x0, y1 - y0) == (WINDOW_M, WINDOW_M) and t == pytest.approx(3.7)
    assert (x0 + x1) / 2 == pytest.approx(0.0) and (y0 + y1) / 2 == pytest.approx(y37)
