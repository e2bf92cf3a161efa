"""scripts/compare_gaits.py's input checks (the figure itself:
tests/references/test_zmp_walk.py::test_cop_in_sole_*)."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))

import compare_gaits  # noqa: E402


def test_a_folder_that_is_not_a_run_exits_2_and_writes_nothing(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.npz").write_bytes(b"")
    out = tmp_path / "out"
    assert compare_gaits.main([str(run), "--out", str(out)]) == 2
    assert "expected a walk.py output folder with summary.json" in capsys.readouterr().err
    assert not out.exists()


def test_an_unreadable_results_file_exits_2_and_writes_nothing(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.npz").write_bytes(b"not an npz")
    (run / "summary.json").write_text('{"scenario": "x"}')
    out = tmp_path / "out"
    assert compare_gaits.main([str(run), "--out", str(out)]) == 2
    assert capsys.readouterr().err.startswith("compare_gaits.py: error:")
    assert not out.exists()
