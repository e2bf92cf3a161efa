"""Shared pytest fixtures, and the reasons a test is skipped, in plain words."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from humanoid_sim.model import HumanoidModel, load_model

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
"""The headless browser the rendering tests use, or None."""
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="needs the Chromium web browser to render the 3-D view, and it is not installed "
                             "(Debian/Ubuntu: apt-get install chromium; .ci/run installs it)")
REFERENCE = ROOT.parent / "shared" / "reference"
"""The thesis's numbers, extracted independently of this project (the folder ``shared/reference`` next to the
project's folder in the development workspace; a fresh clone does not have it)."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Give the tests that compare the scenario files with the independent extraction a skip reason a newcomer
    understands when the extraction is not there (tests/test_scenarios_params.py reads ``REFERENCE/<sim>.yaml``)."""
    for item in items:
        if item.module.__name__.endswith("test_scenarios_params") and item.name.startswith(
                "test_values_match_the_reference_extraction"):
            name = item.callspec.params.get("name") if hasattr(item, "callspec") else None
            if name and not (REFERENCE / f"{name}.yaml").exists():
                item.add_marker(pytest.mark.skip(
                    reason=f"needs the thesis's numbers extracted independently of this project "
                           f"({REFERENCE / name}.yaml, next to the project folder in the development workspace); "
                           "a fresh clone does not have them"))


@pytest.fixture(scope="session")
def hm() -> HumanoidModel:
    """The thesis humanoid, loaded once per test session (tests must not mutate its model)."""
    return load_model()
