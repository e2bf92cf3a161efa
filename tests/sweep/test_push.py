"""The push-recovery benchmark (humanoid_sim.sweep.push, humanoid-push): the bisection against survival functions
whose threshold is known, the swing / stance labels against the phase names, the command's bad input (exit 2,
nothing written), and one small real benchmark on MuJoCo checked against walks run directly."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from humanoid_sim.cli import push as cli
from humanoid_sim.sweep import push
from humanoid_sim.sweep.push import Bisection, PushError, bisect, direction_label, side_of, swing_foot, target_mps


# --------------------------------------------------------------------------------------------- bisection
@pytest.mark.parametrize("max_impulse, resolution", [(60.0, 1.0), (64.0, 1.0), (40.0, 10.0), (50.0, 0.3)])
@pytest.mark.parametrize("share", [0.01, 0.137, 0.5, 0.61, 0.74])   # below the top bracket (test below)
@pytest.mark.parametrize("inclusive", [False, True])
def test_bisection_brackets_a_known_threshold_in_ceil_log2_probes(max_impulse, resolution, share, inclusive):
    threshold = share * max_impulse
    survives = (lambda j: j <= threshold) if inclusive else (lambda j: j < threshold)
    b = bisect(survives, max_impulse, resolution)
    steps = math.ceil(math.log2(max_impulse / resolution))
    assert b.steps == steps
    assert len(b.probes) == steps
    assert b.failed is not None
    assert b.failed - b.survived <= resolution
    if inclusive:
        assert b.survived <= threshold < b.failed
    else:
        assert b.survived < threshold <= b.failed
    # every probe agrees with the survival function, and the bracket's ends are probes (or 0, the unpushed walk)
    assert all(ok == survives(j) for j, ok in b.probes)
    assert b.failed in [j for j, _ in b.probes]
    assert b.survived == 0.0 or b.survived in [j for j, _ in b.probes]


def test_bisection_that_never_fails_probes_the_maximum_itself():
    b = bisect(lambda j: True, 60.0, 1.0)
    assert len(b.probes) == b.steps + 1 == 7
    assert b.probes[-1] == (60.0, True)
    assert b.survived == 60.0 and b.failed is None


def test_bisection_with_a_threshold_in_the_top_bracket_finds_the_maximum_fails():
    b = bisect(lambda j: j < 59.9, 60.0, 1.0)   # every halving survives; the maximum decides
    assert b.probes[-1] == (60.0, False)
    assert b.failed == 60.0 and 59.0 < b.survived < 59.9


def test_bisection_that_always_fails_ends_below_the_resolution():
    b = bisect(lambda j: False, 60.0, 1.0)
    assert len(b.probes) == 6
    assert b.survived == 0.0 and 0.0 < b.failed <= 1.0


def test_bisection_keeps_the_reason_of_the_smallest_failure():
    b = Bisection(60.0, 1.0)
    b.record(30.0, False, "fall at 5 s")
    b.record(15.0, False, "fall at 4 s")
    b.record(7.5, True)
    assert (b.survived, b.failed, b.failed_reason) == (7.5, 15.0, "fall at 4 s")
    with pytest.raises(PushError, match="resolution"):
        Bisection(10.0, 20.0)


# --------------------------------------------------------------------------------------------- labels
@pytest.mark.parametrize("phase, swing, toward_swing, toward_stance", [("LFFSSP", "R", 270.0, 90.0),
                                                                       ("RFFSSP", "L", 90.0, 270.0)])
def test_direction_labels_follow_the_swing_foot_of_the_phase_name(phase, swing, toward_swing, toward_stance):
    # LFFSSP: the Left Foot is Fixed (stance), the right swings; heading frame: 90 deg is the robot's left
    assert swing_foot(phase) == swing
    assert side_of(toward_swing, phase) == "swing"
    assert side_of(toward_stance, phase) == "stance"
    assert side_of(0.0, phase) == side_of(180.0, phase) == side_of(360.0, phase) == ""
    assert side_of(toward_swing - 45.0, phase) == side_of(toward_swing + 45.0, phase) == "swing"
    assert direction_label(toward_swing, phase).endswith(", toward the swing foot")
    assert direction_label(toward_stance, phase).endswith(", toward the stance foot")
    assert direction_label(0.0, phase) == "forward" and direction_label(180.0, phase) == "backward"
    assert target_mps(toward_swing, phase) == 0.5 and target_mps(toward_stance, phase) == 0.3
    assert target_mps(0.0, phase) == 0.5 and target_mps(180.0, phase) == 0.7 and target_mps(45.0, phase) is None


def test_direction_label_names_the_compass_point():
    assert direction_label(135.0, "LFFSSP") == "backward-left, toward the stance foot"
    assert direction_label(315.0, "LFFSSP") == "forward-right, toward the swing foot"
    assert direction_label(30.0, "RFFSSP") == "30 deg, toward the swing foot"


def test_swing_foot_refuses_a_double_support():
    with pytest.raises(PushError, match="LFFDSP"):
        swing_foot("LFFDSP")


# --------------------------------------------------------------------------------------------- the benchmark's input
def test_default_phase_is_the_first_single_support_two_seconds_into_the_walk():
    b = push.make_benchmark("sim3_zmp")
    # sim3_zmp: a 1 s lead-in, 0.7 s single supports; phase 8 (RFFSSP) starts at 3.45 s, phase 6 at 2.63 s
    assert {c.phase for c in b.cells} == {8} and {c.phase_name for c in b.cells} == {"RFFSSP"}
    assert len(b.cells) == 24
    assert sorted({c.direction_deg for c in b.cells}) == [45.0 * i for i in range(8)]
    assert sorted({c.fraction for c in b.cells}) == [0.2, 0.5, 0.8]


def test_probe_document_replaces_the_pushes_and_keeps_the_other_disturbances():
    doc = {"name": "x", "disturbances": {"pushes": [{"impulse_Ns": 5.0}], "sensing": {"delay_s": 0.01}}}
    cell = push.Cell("scenario", 8, "RFFSSP", "mid", 0.5, 90.0)
    probe = push.probe_document(doc, cell, 12.5)
    assert probe["disturbances"]["sensing"] == {"delay_s": 0.01}
    assert probe["disturbances"]["pushes"] == [{"body": 17, "impulse_Ns": 12.5, "direction_deg": 90.0,
                                                "frame": "heading", "start": {"phase": 8, "fraction": 0.5},
                                                "duration_s": 0.1}]
    assert "pushes" not in push.probe_document(doc, cell, 0.0)["disturbances"]
    assert "disturbances" not in push.probe_document({"name": "x"}, cell, 0.0)
    assert doc["disturbances"]["pushes"] == [{"impulse_Ns": 5.0}]   # the scenario's document is left alone


def test_compare_overrides_are_applied_and_labelled():
    b = push.make_benchmark("sim3_zmp", instants=["mid"], directions=4, compare=["balance.hip_omega=10"])
    assert list(b.docs) == ["scenario", "balance.hip_omega=10"]
    assert b.docs["balance.hip_omega=10"]["balance"]["hip_omega"] == 10
    assert len(b.cells) == 8


@pytest.mark.parametrize("argv, field", [
    (["no_such_scenario"], "scenario"),
    (["sim3"], "gait.hip_reference"),                           # the thesis gait
    (["sim3_zmp", "--compare", "balance.no_such_gain=3"], "balance.no_such_gain"),
    (["sim3_zmp", "--compare", "hip_omega"], "--compare"),
    (["sim3_zmp", "--phase", "3"], "--phase"),                  # a double support
    (["sim3_zmp", "--resolution", "100"], "--resolution"),
    (["sim3_zmp", "--directions", "0"], "--directions"),
])
def test_bad_input_exits_2_naming_the_field_and_writes_nothing(argv, field, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main([*argv, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("humanoid-push: error: ") and field in err
    assert not out.exists()


# --------------------------------------------------------------------------------------------- a real benchmark
@pytest.mark.slow
def test_small_benchmark_on_mujoco_agrees_with_walks_run_directly(tmp_path, capsys):
    """Forward and backward at mid single support, bisection in [0, 40] N s to 10 N s: 2 probes a cell (3 when
    the maximum is probed too), and the unpushed walk.  The impulse a cell survived walks to completion when run
    directly (no plan cache), the one it failed does not, with the same numbers; a second run walks nothing (every
    probe recorded)."""
    out = tmp_path / "push"
    argv = ["sim3_zmp", "--out", str(out), "--workers", "2", "--directions", "2", "--instants", "mid",
            "--max-impulse", "40", "--resolution", "10", "--quiet"]
    assert cli.main(argv) == 0
    printed = capsys.readouterr().out
    rows = pq.read_table(out / "push.parquet").to_pylist()
    assert [r["direction_deg"] for r in rows] == [0.0, 180.0]
    assert (out / "push.csv").is_file() and (out / "push.png").stat().st_size > 0 and (out / "push.md").is_file()
    walks = 1 + sum(r["probes"] for r in rows)
    assert f"{walks} walks" in printed, printed
    probes = [json.loads(p.read_text()) for p in sorted((out / "probes").glob("*.json"))]
    assert len(probes) == walks
    nominal = [p for p in probes if p["impulse_Ns"] == 0.0]
    assert len(nominal) == 1 and nominal[0]["completed"]
    for r in rows:
        assert r["unpushed_completed"]
        if r["failed_Ns"] is None:   # every halving survived, and then the maximum itself
            assert r["probes"] == 3 and r["survived_Ns"] == 40.0
        else:   # two halvings, or a third at the maximum when both survived
            assert r["probes"] == (3 if r["failed_Ns"] == 40.0 else 2)
            assert r["failed_Ns"] - r["survived_Ns"] <= 10.0
            assert r["failure_reason"]
        assert r["mass_kg"] == pytest.approx(55.0, abs=1.0)   # the robot's mass, kg (a sum of link masses)
        assert r["survived_dv_mps"] == pytest.approx(r["survived_Ns"] / r["mass_kg"])
    base = push.load_document("sim3_zmp")[0]
    for r in rows[1:]:   # each end of the backward bracket, walked directly without the plan cache: the same walk
        cell = push.Cell("scenario", r["phase"], r["phase_name"], "mid", 0.5, r["direction_deg"])
        for impulse, survives in ((r["survived_Ns"], True), (r["failed_Ns"], False)):
            if impulse is None or impulse == 0.0:
                continue
            doc = push.probe_document(base, cell, impulse)
            direct = push.probe_task(doc, "direct walk", cache=False)
            assert direct["completed"] is survives
            recorded = json.loads(push.probe_file(out, doc).read_text())
            for k in ("status", "reason", "sim_time_s", "hip_com_error_max_m", "push_delta_v_mps"):
                assert recorded[k] == direct[k], k
            if not survives:
                assert r["failure_reason"] == direct["reason"]
    # resume: every probe is on file, nothing is walked, the same table
    assert cli.main(argv) == 0
    assert "0 walks" in capsys.readouterr().out
    assert pq.read_table(out / "push.parquet").to_pylist() == rows


def test_probe_files_are_named_by_the_probe_document(tmp_path: Path):
    cell = push.Cell("scenario", 8, "RFFSSP", "mid", 0.5, 90.0)
    a = push.probe_file(tmp_path, push.probe_document({"name": "x"}, cell, 10.0))
    b = push.probe_file(tmp_path, push.probe_document({"name": "x"}, cell, 10.0))
    c = push.probe_file(tmp_path, push.probe_document({"name": "x"}, cell, 11.0))
    assert a == b != c and a.parent == tmp_path / "probes"
