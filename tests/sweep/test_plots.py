"""The sweep's figures (humanoid_sim/sweep/plots.py, labels.py) as matplotlib objects: one row of panels per gait,
failed cells hatched (never coloured as a value), axes labelled in physical units; and the table read by pandas.
Rows are built by hand: no walk runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from humanoid_sim.sweep.labels import axis_units
from humanoid_sim.sweep.plots import FAILED_HATCH, feasibility_figure, map_layout
from humanoid_sim.sweep.spec import load_sweep

ROOT = Path(__file__).resolve().parents[2]
SIM3 = ROOT / "scripts" / "params" / "sim3.yaml"
SPEED_STEP = ROOT / "scripts" / "sweeps" / "speed_step.yaml"
UNIT = r"\((s|m|m/s|rad|N m|no unit)[,)]"


def _rows(spec, failed=lambda w: False):
    """One row per walk of ``spec``: completed unless ``failed(walk)``, metrics from the walk index."""
    rows = []
    for w in spec.expand():
        ok = not failed(w)
        rows.append({"walk": w.index, "scenario_hash": w.scenario_hash, "engine": "pinocchio", **w.params,
                     "completed": ok, "saturated_fraction": (w.index % 7) / 10 if ok else None,
                     "contact_infeasible_fraction": 0.0 if ok else None})
    return rows


def _maps(fig):
    """The map panels (not the colour bars): every axes with a title."""
    return [a for a in fig.axes if a.get_title()]


def _hatched_cells(panel):
    return [p for p in panel.patches if p.get_hatch() == FAILED_HATCH]


def test_the_shipped_sweep_draws_one_row_of_panels_per_gait():
    spec = load_sweep(SPEED_STEP)
    group, (ax_x, ax_y) = map_layout(spec.axes)
    assert group == "gait.hip_reference"
    assert (ax_x.column, ax_y.column) == ("path.t_SSP:scale", "path.Phip[*][1],path.dtheta_PLN,path.dtheta_ADJ:scale")
    fig = feasibility_figure(_rows(spec), spec.axes, base_doc=spec.base_doc)
    panels = _maps(fig)
    assert len(panels) == 2 * 3                      # 2 gaits x (completion, saturation, contact feasibility)
    for gait in ("thesis", "zmp_preview"):
        mine = [p for p in panels if p.get_title().startswith(f"gait.hip_reference = {gait}: ")]
        assert len(mine) == 3, gait
        # each panel holds that gait's walks only: 16 cells, each "1/1" on the completion panel
        texts = [t.get_text() for t in mine[0].texts]
        assert texts.count("1/1") == 16
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_a_cell_where_every_walk_failed_is_hatched_on_every_panel():
    """Every zmp walk at the shortest step time fails, and one thesis walk: those cells are hatched and read
    "failed" on all three panels of their gait; no other cell is hatched; none shows a number."""
    spec = load_sweep(SPEED_STEP)
    t_col = "path.t_SSP:scale"
    failed = lambda w: ((w.params["gait.hip_reference"] == "zmp_preview" and w.params[t_col] == 0.8)  # noqa: E731
                        or w.index == 0)
    fig = feasibility_figure(_rows(spec, failed), spec.axes, base_doc=spec.base_doc)
    panels = _maps(fig)
    zmp = [p for p in panels if "zmp_preview" in p.get_title()]
    thesis = [p for p in panels if "= thesis" in p.get_title()]
    for p in zmp:
        cells = _hatched_cells(p)
        assert len(cells) == 4                                  # the 4 step lengths at factor 0.8
        assert sorted(c.get_x() + 0.5 for c in cells) == [0.0] * 4   # x column 0
        assert sum("failed" in t.get_text() for t in p.texts) == 4
    for p in thesis:
        assert len(_hatched_cells(p)) == 1
    # the failed cells carry no value: the masked image is empty there
    img = zmp[1].images[0].get_array()
    assert np.all(np.ma.getmaskarray(img)[:, 0]) and not np.any(np.ma.getmaskarray(img)[:, 1:])
    assert all(t.get_text() != "0.00" for p in zmp for t in p.texts if "failed" in t.get_text())
    legend = fig.legends[0]
    assert [t.get_text() for t in legend.get_texts()] == ["every walk of the cell failed"]
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_random_axes_mark_failed_walks(tmp_path):
    body = {"base": str(SIM3), "grid": {"gait.hip_reference": ["thesis", "zmp_preview"]},
            "random": {"n": 3, "seed": 1, "path.SW": {"low": 0.28, "high": 0.32}}}
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(body))
    spec = load_sweep(tmp_path / "r.yaml")
    fig = feasibility_figure(_rows(spec, lambda w: w.index == 4), spec.axes, base_doc=spec.base_doc)
    panels = _maps(fig)
    assert len(panels) == 6
    failed = [c for p in panels for c in p.collections if c.get_gid() == "failed-walks"]
    assert sum(len(c.get_offsets()) for c in failed) == 3      # walk 4 (zmp), once per panel of its row
    assert "step width SW (m)" in panels[0].get_xlabel()
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_axis_labels_carry_units():
    spec = load_sweep(SPEED_STEP)
    t_ssp, length, gait = (axis_units(a, spec.base_doc) for a in spec.grid)
    assert t_ssp.label == "single-support time t_SSP (s)"
    assert [t_ssp.tick(v) for v in t_ssp.axis.values] == ["0.56\nx0.8", "0.63\nx0.9", "0.7\nx1", "0.84\nx1.2"]
    assert length.label == "step length (waypoint spacing along y) Phip[*][1] (m)\ndtheta_PLN, dtheta_ADJ scaled alike"
    assert length.value(1.0) == pytest.approx(0.15708, abs=1e-5)     # sim 3's 0.15708 m per step
    assert gait.label == "gait.hip_reference"
    fig = feasibility_figure(_rows(spec), spec.axes, base_doc=spec.base_doc)
    import re

    for p in _maps(fig):
        assert re.search(UNIT, p.get_xlabel()) and re.search(UNIT, p.get_ylabel()), p.get_title()
    import matplotlib.pyplot as plt

    plt.close(fig)


@pytest.mark.parametrize("grid,label,value", [
    ({"path.Vhip": {"scale": [0.8, 1.2]}}, "hip speed Vhip (m/s, most entries)", 0.3),   # sim 3's cruise speed
    ({"path.SW": [0.3, 0.32]}, "step width SW (m)", None),
    ({"gait.horizon_s": [1.2, 1.6]}, "gait.horizon_s (s)", None),
    ({"simulation.fall_height_m": {"scale": [0.9, 1.1]}}, "simulation.fall_height_m (x base, m)", None),
    ({"controller.Wp_fa_LFFSSP[2]": {"scale": [0.5, 2.0]}}, "controller.Wp_fa_LFFSSP[2] (no unit)", 300000.0),
])
def test_the_label_rule(tmp_path, grid, label, value):
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({"base": str(SIM3), "grid": grid}))
    spec = load_sweep(tmp_path / "s.yaml")
    u = axis_units(spec.grid[0], spec.base_doc)
    assert u.label == label
    if value is not None:
        assert u.value(1.0) == pytest.approx(value)


def test_pandas_reads_a_sweep_table(tmp_path):
    import pandas as pd

    from humanoid_sim.sweep.table import PARQUET, write_table

    spec = load_sweep(SPEED_STEP)
    rows = _rows(spec, lambda w: w.index == 3)
    write_table(rows, tmp_path, [a.column for a in spec.axes])
    df = pd.read_parquet(tmp_path / PARQUET)
    assert len(df) == 32 and df["completed"].sum() == 31
    assert list(df.columns[:6]) == ["walk", "scenario_hash", "engine", *(a.column for a in spec.axes)]
    assert df.groupby("gait.hip_reference").size().to_dict() == {"thesis": 16, "zmp_preview": 16}
