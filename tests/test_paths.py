"""Where the package finds its data (humanoid_sim.paths): shipped scenarios by name or path."""

from __future__ import annotations

from pathlib import Path

import pytest

from humanoid_sim.errors import InputError
from humanoid_sim.paths import MODELS_DIR, scenario_names, scenario_path

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_scenarios_are_the_repository_params() -> None:
    # in the repository the package data are the top-level scripts/params/ files a developer edits
    assert scenario_names() == sorted(p.stem for p in (ROOT / "scripts" / "params").glob("*.yaml"))
    assert {"sim1", "sim2", "sim3"} <= set(scenario_names())
    assert scenario_path("sim1").read_bytes() == (ROOT / "scripts" / "params" / "sim1.yaml").read_bytes()
    assert (MODELS_DIR / "thesis_humanoid.yaml").read_bytes() == (ROOT / "models" / "thesis_humanoid.yaml").read_bytes()


def test_a_path_is_taken_as_given(tmp_path) -> None:
    p = tmp_path / "mine.yaml"  # need not exist yet: the loader names a missing file itself
    assert scenario_path(p) == p
    assert scenario_path(str(p)) == p


def test_an_unknown_name_lists_the_shipped_ones() -> None:
    with pytest.raises(InputError, match=r"'no_such_walk' is neither a YAML file nor a shipped scenario.*sim1"):
        scenario_path("no_such_walk")
