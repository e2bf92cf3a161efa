"""Sweep files (humanoid_sim/sweep/spec.py): expansion semantics against hand-computed documents, the scenario hash,
every validation error (exit 2 with nothing run and nothing written), and the shipped speed_step.yaml.

No Dask here: these tests run no walk (the cluster tests are in tests/sweep/test_runner.py).
"""

from __future__ import annotations

import copy
import itertools
from pathlib import Path

import numpy as np
import pytest
import yaml

from humanoid_sim.cli import sweep as cli
from humanoid_sim.scenario.schema import ScenarioError, parse_scenario
from humanoid_sim.sweep import runner
from humanoid_sim.sweep.spec import DottedPath, SweepError, load_sweep, scenario_hash

ROOT = Path(__file__).resolve().parents[2]
SIM3 = ROOT / "scripts" / "params" / "sim3.yaml"
SPEED_STEP = ROOT / "scripts" / "sweeps" / "speed_step.yaml"
BASE = yaml.safe_load(SIM3.read_text())


def sweep_file(tmp_path: Path, body: dict | str, name: str = "s.yaml") -> Path:
    p = tmp_path / name
    p.write_text(body if isinstance(body, str) else yaml.safe_dump(body, sort_keys=False))
    return p


def spec_of(tmp_path: Path, **body) -> list:
    return load_sweep(sweep_file(tmp_path, {"base": str(SIM3), **body})).expand()


# --------------------------------------------------------------------------------------------- expansion
def test_grid_is_the_product_in_file_order_with_scale_and_scalar_fill(tmp_path):
    walks = spec_of(tmp_path, grid={"path.Vhip": {"scale": [0.8, 1.2]}, "path.SW": [0.28, 0.3, 0.32]})
    assert len(walks) == 6
    combos = list(itertools.product([0.8, 1.2], [0.28, 0.3, 0.32]))   # first key varies slowest
    for w, (s, sw) in zip(walks, combos):
        assert w.params == {"path.Vhip:scale": s, "path.SW": sw}
        expected = copy.deepcopy(BASE)
        expected["path"]["Vhip"] = [v * s for v in BASE["path"]["Vhip"]]
        expected["path"]["SW"] = [sw] * len(BASE["path"]["SW"])      # a scalar sets every element
        assert w.doc == expected
        assert w.scenario_hash == scenario_hash(expected)
    assert [w.index for w in walks] == list(range(6))


def test_indices_wildcards_and_linked_paths(tmp_path):
    walks = spec_of(tmp_path, grid={"path.Phip[*][1], path.dtheta_PLN": {"scale": [1.5]},
                                    "path.SH[0]": [0.07], "controller.Wp_fa_LFFSSP[2]": [1.0e5]})
    (w,) = walks
    P = BASE["path"]["Phip"]
    assert w.doc["path"]["Phip"] == [[p[0], p[1] * 1.5, p[2]] for p in P]   # only every waypoint's y
    assert w.doc["path"]["dtheta_PLN"] == [x * 1.5 for x in BASE["path"]["dtheta_PLN"]]
    assert w.doc["path"]["SH"] == [0.07] + BASE["path"]["SH"][1:]
    assert w.doc["controller"]["Wp_fa_LFFSSP"] == BASE["controller"]["Wp_fa_LFFSSP"][:2] + [1.0e5]
    assert set(w.params) == {"path.Phip[*][1],path.dtheta_PLN:scale", "path.SH[0]", "controller.Wp_fa_LFFSSP[2]"}


def test_a_missing_key_is_created_and_left_to_the_scenario_schema(tmp_path):
    assert "t_end_s" not in BASE["simulation"]
    (w,) = spec_of(tmp_path, grid={"simulation.t_end_s": [1.5]})
    assert w.doc["simulation"]["t_end_s"] == 1.5
    assert parse_scenario(w.doc).simulation.t_end_s == 1.5
    # a new section is created too (sim 3 has no 'gait' section); the schema decides what it may hold
    (w,) = spec_of(tmp_path, grid={"gait.hip_reference": ["zmp_preview"]})
    assert w.doc["gait"] == {"hip_reference": "zmp_preview"}
    with pytest.raises(SweepError, match=r"walk 0 \(gait\.preview_s=1\.6\): gait\.preview_s: unknown key"):
        spec_of(tmp_path, grid={"gait.preview_s": [1.6]})


def test_random_samples_are_seeded_uniform_and_crossed_with_the_grid(tmp_path):
    body = {"grid": {"path.SW": [0.28, 0.32]},
            "random": {"n": 50, "seed": 3, "path.SH": {"low": 0.05, "high": 0.09},
                       "path.t_SSP": {"scale": {"low": 0.9, "high": 1.1}}}}
    walks = spec_of(tmp_path, **body)
    assert len(walks) == 100
    sh = np.array([w.params["path.SH"] for w in walks[:50]])
    k = np.array([w.params["path.t_SSP:scale"] for w in walks[:50]])
    assert np.all((sh >= 0.05) & (sh < 0.09)) and np.all((k >= 0.9) & (k < 1.1))
    assert len(set(sh)) == 50   # 50 distinct draws
    # the same samples for every grid point (common random numbers across the grid)
    assert [w.params["path.SH"] for w in walks[50:]] == list(sh)
    for w in walks[:3]:
        assert w.doc["path"]["SH"] == [w.params["path.SH"]] * 8
        assert w.doc["path"]["t_SSP"] == [0.7 * w.params["path.t_SSP:scale"]] * 8
    again = spec_of(tmp_path, **body)
    assert [w.scenario_hash for w in again] == [w.scenario_hash for w in walks]   # reproducible
    body["random"]["seed"] = 4
    other = spec_of(tmp_path, **body)
    assert other[0].params["path.SH"] != walks[0].params["path.SH"]


def test_scenario_hash_is_canonical():
    doc = copy.deepcopy(BASE)
    h = scenario_hash(doc)
    reordered = {k: doc[k] for k in reversed(list(doc))}
    assert scenario_hash(reordered) == h                      # key order does not matter
    ints = copy.deepcopy(doc)
    ints["path"]["T_dir"] = [1.0] * 8                         # YAML 1 and 1.0: the same number to the parser
    assert scenario_hash(ints) == h
    changed = copy.deepcopy(doc)
    changed["path"]["SH"][3] = np.nextafter(0.08, 1.0)        # one ulp anywhere changes it
    assert scenario_hash(changed) != h
    assert len(h) == 16 and int(h, 16) >= 0


def test_dotted_path_overlap():
    a = DottedPath.parse("path.Phip[*][1]", "x")
    assert a.overlaps(DottedPath.parse("path.Phip[2]", "x"))
    assert a.overlaps(DottedPath.parse("path", "x"))
    assert not a.overlaps(DottedPath.parse("path.Phip[*][2]", "x"))
    assert not a.overlaps(DottedPath.parse("path.SW", "x"))


# --------------------------------------------------------------------------------------------- validation
BAD = [
    ("unknown top key", {"base": "BASE", "gird": {"path.SW": [0.3]}}, "gird: unknown key; did you mean 'grid'?"),
    ("no base", {"grid": {"path.SW": [0.3]}}, "base: missing"),
    ("base not found", {"base": "nowhere.yaml", "grid": {"path.SW": [0.3]}}, "base: no scenario file 'nowhere.yaml'"),
    ("nothing to sweep", {"base": "BASE"}, "nothing to sweep"),
    ("grid not a mapping", {"base": "BASE", "grid": [1]}, "grid: expected a mapping of dotted paths"),
    ("scalar grid value", {"base": "BASE", "grid": {"path.SW": 0.3}},
     "grid.path.SW: expected a non-empty list of values, or {scale: [factors]}"),
    ("empty list", {"base": "BASE", "grid": {"path.SW": []}}, "grid.path.SW: expected a non-empty list"),
    ("scale of text", {"base": "BASE", "grid": {"path.Vhip": {"scale": ["x"]}}},
     "grid.path.Vhip.scale[0]: expected a finite number (a factor), got 'x'"),
    ("unknown in value", {"base": "BASE", "grid": {"path.Vhip": {"scal": [1.0]}}}, "unknown key 'scal'"),
    ("duplicate value", {"base": "BASE", "grid": {"path.SW": [0.3, 0.3]}},
     "grid.path.SW: the value 0.3 appears twice (entries 0 and 1)"),
    ("bad path", {"base": "BASE", "grid": {"path..SW": [0.3]}}, "'path..SW' is not a dotted path"),
    ("key into a list", {"base": "BASE", "grid": {"path.SW.x": [0.3]}},
     "path.SW.x: path.SW is a list in the base scenario, not a mapping"),
    ("index into a mapping", {"base": "BASE", "grid": {"path[0]": [0.3]}},
     "path[0]: path is a mapping in the base scenario, not a list"),
    ("index out of range", {"base": "BASE", "grid": {"path.SW[8]": [0.3]}},
     "path.SW[8]: index out of range, path.SW has 8 entries"),
    ("scale of a missing value", {"base": "BASE", "grid": {"simulation.t_end_s": {"scale": [2.0]}}},
     "simulation.t_end_s: scale needs a value to multiply"),
    ("scale of text in the base", {"base": "BASE", "grid": {"simulation.method": {"scale": [2.0]}}},
     "simulation.method: scale needs a number or a list of numbers in the base scenario, found 'ode3'"),
    ("random without n", {"base": "BASE", "random": {"seed": 1, "path.SH": {"low": 0.05, "high": 0.09}}},
     "random.n: missing"),
    ("random n zero", {"base": "BASE", "random": {"n": 0, "seed": 1, "path.SH": {"low": 0.05, "high": 0.09}}},
     "random.n: expected an integer >= 1, got 0"),
    ("random bool seed", {"base": "BASE", "random": {"n": 2, "seed": True, "path.SH": {"low": 0.05, "high": 0.09}}},
     "random.seed: expected an integer >= 0, got True"),
    ("random low >= high", {"base": "BASE", "random": {"n": 2, "seed": 1, "path.SH": {"low": 0.09, "high": 0.05}}},
     "random.path.SH: expected low < high, got low = 0.09, high = 0.05"),
    ("random list", {"base": "BASE", "random": {"n": 2, "seed": 1, "path.SH": [0.05, 0.09]}},
     "random.path.SH: expected {low: number, high: number}"),
    ("random no parameter", {"base": "BASE", "random": {"n": 2, "seed": 1}}, "random: no parameter to sample"),
    ("overlap", {"base": "BASE", "grid": {"path.SW": [0.3], "path.SW[1]": [0.28]}},
     "grid.path.SW[1]: path.SW[1] and path.SW (grid.path.SW) address the same value"),
    ("invalid generated scenario", {"base": "BASE", "grid": {"path.Vhip": {"scale": [1.0]}, "path.SW": [0.3, -0.1]}},
     "walk 1 (path.Vhip:scale=1, path.SW=-0.1): path.SW[0]: expected a step width in m in (0, 1], got -0.1"),
    ("overlap through an index", {"base": "BASE", "grid": {"path.k_SH": [0.5, 0.4], "path.k_SH[0]": [0.5]}},
     "address the same value"),
    ("equal documents", {"base": "BASE", "grid": {"path.T_dir": [1, [1, 1, 1, 1, 1, 1, 1, 1.0]]}},
     "walk 1 (path.T_dir=[1, 1, 1, 1, 1, 1, 1, 1.0]) generates the same scenario as walk 0"),
]


@pytest.mark.parametrize("case,body,needle", BAD, ids=[b[0] for b in BAD])
def test_bad_sweep_file_names_the_field(tmp_path, case, body, needle):
    body = {k: (str(SIM3) if v == "BASE" else v) for k, v in body.items()}
    p = sweep_file(tmp_path, body)
    with pytest.raises(SweepError) as exc:
        load_sweep(p).expand()
    assert needle in str(exc.value)
    assert str(exc.value).startswith(str(p))


def test_bad_yaml_empty_file_and_invalid_base(tmp_path):
    with pytest.raises(SweepError, match="not valid YAML at line 3, column 1"):
        load_sweep(sweep_file(tmp_path, "base: x\ngrid: [\n"))
    with pytest.raises(SweepError, match="the file is empty"):
        load_sweep(sweep_file(tmp_path, ""))
    with pytest.raises(SweepError, match="duplicate key 'grid'"):
        load_sweep(sweep_file(tmp_path, "base: x\ngrid: {}\ngrid: {}\n"))
    bad_base = copy.deepcopy(BASE)
    bad_base["path"]["SW"][2] = "wide"
    b = tmp_path / "bad_base.yaml"
    b.write_text(yaml.safe_dump(bad_base))
    with pytest.raises(SweepError, match=r"base: the base scenario is invalid: .*path\.SW\[2\]: expected a step width"):
        load_sweep(sweep_file(tmp_path, {"base": "bad_base.yaml", "grid": {"path.SH": [0.07]}}))


def test_base_is_resolved_against_the_sweep_folder_then_the_cwd(tmp_path, monkeypatch):
    sub = tmp_path / "sweeps"
    sub.mkdir()
    (tmp_path / "params").mkdir()
    (tmp_path / "params" / "b.yaml").write_text(SIM3.read_text())
    s = sweep_file(sub, {"base": "../params/b.yaml", "grid": {"path.SH": [0.07]}})
    assert load_sweep(s).base_path.resolve() == (tmp_path / "params" / "b.yaml").resolve()
    monkeypatch.chdir(tmp_path)
    s2 = sweep_file(sub, {"base": "params/b.yaml", "grid": {"path.SH": [0.07]}}, "s2.yaml")   # not next to s2
    assert load_sweep(s2).base_path.resolve() == (tmp_path / "params" / "b.yaml").resolve()


# --------------------------------------------------------------------------------------------- the command
@pytest.fixture
def no_cluster(monkeypatch):
    """Fail the test if the command tries to start or reach a cluster (nothing may run)."""
    def refuse(*a, **k):
        raise AssertionError("a cluster was started")
    monkeypatch.setattr(runner, "dask_client", refuse)


CLI_BAD = [
    (["--workers", "0"], "--workers: expected a number of worker processes >= 1, got 0"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"], "--workers: applies to the local cluster only"),
    (["--scheduler", "http//x"], "--scheduler: expected a scheduler address PROTOCOL://HOST:PORT"),
]


@pytest.mark.parametrize("extra,needle", CLI_BAD, ids=["workers0", "workers+scheduler", "address"])
def test_bad_options_exit_2(tmp_path, capsys, no_cluster, extra, needle):
    out = tmp_path / "out"
    assert cli.main([str(SPEED_STEP), "--out", str(out), *extra]) == 2
    assert needle in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("body,needle", [
    ({"base": str(SIM3), "grid": {"path.SW": [0.3, 0.31, 0.32, -0.1]}}, "walk 3 (path.SW=-0.1): path.SW[0]"),
    ({"base": str(SIM3), "grid": {"path.SW": 0.3}}, "grid.path.SW: expected a non-empty list"),
], ids=["one bad walk among many", "bad field"])
def test_bad_sweep_exits_2_with_nothing_run_and_nothing_written(tmp_path, capsys, no_cluster, body, needle):
    p = sweep_file(tmp_path, body)
    out = tmp_path / "out"
    assert cli.main([str(p), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("humanoid-sweep: error: ") and needle in err and "Traceback" not in err
    assert not out.exists()


def test_an_unreadable_table_exits_2_and_stays_untouched(tmp_path, capsys, no_cluster):
    out = tmp_path / "out"
    out.mkdir()
    (out / "sweep.parquet").write_bytes(b"not parquet")
    assert cli.main([str(SPEED_STEP), "--out", str(out)]) == 2
    assert "sweep.parquet: cannot read the existing sweep table" in capsys.readouterr().err
    assert (out / "sweep.parquet").read_bytes() == b"not parquet" and sorted(out.iterdir()) == [out / "sweep.parquet"]


# --------------------------------------------------------------------------------------------- speed_step.yaml
def test_speed_step_is_4_step_times_by_4_step_lengths_by_2_gaits_of_sim3():
    spec = load_sweep(SPEED_STEP)
    assert spec.base_path.resolve() == SIM3.resolve()
    walks = spec.expand()
    assert len(walks) == 32
    assert [len(a.values) for a in spec.grid] == [4, 4, 2]
    base = next(w for w in walks if all(v in (1.0, "thesis") for v in w.params.values()))
    doc = copy.deepcopy(base.doc)
    assert doc.pop("gait") == {"hip_reference": "thesis"}    # the default, written out
    assert scenario_hash(doc) == scenario_hash(BASE)         # factor 1 x 1 with the thesis gait is sim 3 itself
    assert [a.column for a in spec.grid][0] == "path.t_SSP:scale"
    t_ssp = sorted({tuple(w.doc["path"]["t_SSP"]) for w in walks})
    assert [t[0] for t in t_ssp] == pytest.approx([0.56, 0.63, 0.7, 0.84], abs=1e-12)
    assert all(w.doc["path"]["PTR"] == BASE["path"]["PTR"] for w in walks)   # the double support scales alike
    assert all(w.doc["path"]["Vhip"] == BASE["path"]["Vhip"] for w in walks)


def test_every_walk_of_speed_step_is_a_different_walk():
    """No two walks of the shipped sweep have equal parsed scenarios or planned references (chapter 3's, and for
    the zmp gait everything the ZMP plan takes), and no axis is reported as changing nothing."""
    from humanoid_sim.sweep.checks import noop_axes, same_walk_pairs, walk_print

    spec = load_sweep(SPEED_STEP)
    walks = spec.expand()
    prints = [walk_print(w.doc) for w in walks]
    assert same_walk_pairs(walks, prints) == []
    assert noop_axes(spec, walks, prints) == []
    # pairwise, the planned references differ by far more than the tolerance (at least 1 cm or 10 ms somewhere)
    gap = min(float(np.max(np.abs(a.samples - b.samples))) for i, a in enumerate(prints) for b in prints[i + 1:]
              if a.samples.shape == b.samples.shape)
    assert gap > 0.01


def test_an_axis_that_changes_no_zmp_walk_is_reported(tmp_path, capsys, no_cluster):
    """The hip speed Vhip moves only chapter 3's hip, which the zmp plan replaces: swept with both gaits, it changes
    every thesis walk and no zmp walk.  The check names the axis and the zmp groups, and humanoid-sweep prints it
    before any walk runs."""
    from humanoid_sim.sweep.checks import noop_axes, same_walk_pairs

    body = {"base": str(SIM3), "grid": {"path.Vhip": {"scale": [0.8, 1.2]}, "path.SW": [0.3, 0.32],
                                        "gait.hip_reference": ["thesis", "zmp_preview"]}}
    path = sweep_file(tmp_path, body)
    spec = load_sweep(path)
    walks = spec.expand()
    msgs = noop_axes(spec, walks)
    assert len(msgs) == 1
    assert msgs[0].startswith("path.Vhip:scale changes no walk of 2 groups")
    assert "[path.SW=0.3, gait.hip_reference=zmp_preview]" in msgs[0]
    assert "[path.SW=0.32, gait.hip_reference=zmp_preview]" in msgs[0]
    assert "thesis" not in msgs[0].split(":", 2)[2].replace("gait.hip_reference=zmp_preview", "")
    pairs = same_walk_pairs(walks)
    by_index = {w.index: w.params for w in walks}
    assert pairs and all(by_index[i]["gait.hip_reference"] == by_index[j]["gait.hip_reference"] == "zmp_preview"
                         and by_index[i]["path.SW"] == by_index[j]["path.SW"] for i, j in pairs)
    # the command warns before it reaches for a cluster (refused here: nothing runs)
    assert cli.main([str(path), "--out", str(tmp_path / "out"), "--quiet", "--scheduler", "tcp://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert "humanoid-sweep: warning: path.Vhip:scale changes no walk of 2 groups" in err


def _gait_axis_values() -> set:
    spec = load_sweep(SPEED_STEP)
    axis = [a for a in spec.grid if any(p.text == "gait.hip_reference" for p in a.paths)]
    return set(axis[0].values) if axis else set()


def test_speed_step_lists_every_gait_the_schema_accepts():
    """speed_step.yaml's gait axis lists exactly the hip references the scenario schema accepts."""
    accepted = set()
    for gait in ("thesis", "zmp_preview"):
        doc = copy.deepcopy(BASE)
        doc.setdefault("gait", {})["hip_reference"] = gait
        try:
            parse_scenario(doc)
        except ScenarioError:
            continue
        accepted.add(gait)
    assert _gait_axis_values() == accepted


def test_an_unreachable_scheduler_exits_2_with_nothing_written(tmp_path, capsys, monkeypatch):
    import socket

    with socket.socket() as sock:   # a port nothing listens on (bound, closed)
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    monkeypatch.setattr(runner, "CONNECT_TIMEOUT_S", 1.0)   # Dask retries connecting until its timeout
    out = tmp_path / "out"
    assert cli.main([str(SPEED_STEP), "--out", str(out), "--scheduler", f"tcp://127.0.0.1:{port}", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"humanoid-sweep: error: cannot reach the scheduler at tcp://127.0.0.1:{port}: " in err
    assert not out.exists()


def test_the_sweep_builds_each_kernel_part_set_its_walks_need_once(monkeypatch):
    """The shipped speed/step sweep crosses both gaits: before the local workers start, the CLI builds the thesis
    controller's parts for one thesis-gait walk and the balance controller's for one zmp walk, and nothing when
    numba's cache already holds them."""
    from humanoid_sim.sim import builds as build

    walks = load_sweep(ROOT / "scripts" / "sweeps" / "speed_step.yaml").expand()
    calls = []
    monkeypatch.setattr(build, "cache_ready", lambda parts=build.PARTS: False)
    monkeypatch.setattr(build, "build", lambda path, parts: calls.append(
        (parts, parse_scenario(yaml.safe_load(Path(path).read_text()), "x").gait.hip_reference)))
    cli._build_kernel(walks)
    assert sorted(calls) == sorted([(build.PARTS, "thesis"), (build.BALANCE_PARTS, "zmp_preview")])
    calls.clear()
    monkeypatch.setattr(build, "cache_ready", lambda parts=build.PARTS: True)
    cli._build_kernel(walks)
    assert calls == []
