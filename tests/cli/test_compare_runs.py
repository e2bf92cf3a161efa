"""scripts/compare_runs.py: two writes of one walk are the same; one changed bit or number is a difference."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np

import humanoid_sim as hs

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "compare_runs.py"


def _module():
    spec = importlib.util.spec_from_file_location("compare_runs", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_a_changed_bit_or_number_is_found_and_new_keys_are_not_differences(tmp_path: Path) -> None:
    cmp = _module()
    run = hs.run_walk("sim1", until=0.05)
    run.write(tmp_path / "a" / "w", figures=False, playback=False)
    run.write(tmp_path / "b" / "w", figures=False, playback=False)
    assert cmp.main([str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    summary = json.loads((tmp_path / "b" / "w" / "summary.json").read_text())
    summary["new_key"] = 1.0
    summary["wall_time_s"] = 99.0                    # when and how fast: not a difference
    (tmp_path / "b" / "w" / "summary.json").write_text(json.dumps(summary))
    assert cmp.main([str(tmp_path / "a" / "w"), str(tmp_path / "b" / "w")]) == 0
    with np.load(tmp_path / "b" / "w" / "results.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["T"][3, 2] = np.nextafter(arrays["T"][3, 2], np.inf)   # one ulp
    np.savez_compressed(tmp_path / "b" / "w" / "results.npz", **arrays)
    diffs, new = cmp.compare_walk(tmp_path / "a" / "w", tmp_path / "b" / "w")
    assert diffs == ["results.npz: T differs"] and new == ["summary.new_key"]
    summary["steps"] += 1
    (tmp_path / "b" / "w" / "summary.json").write_text(json.dumps(summary))
    assert "summary.steps: 5 != 6" in cmp.compare_walk(tmp_path / "a" / "w", tmp_path / "b" / "w")[0]
