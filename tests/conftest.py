"""Shared pytest fixtures, and the reasons a test is skipped, in plain words."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from humanoid_sim.robot.model import HumanoidModel, load_model

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
"""The headless browser the rendering tests use, or None."""
_chromium_present = pytest.mark.skipif(
    CHROMIUM is None, reason="needs the Chromium web browser to render the 3-D view, and it is not installed "
                             "(Debian/Ubuntu: apt-get install chromium; .ci/run installs it)")


def needs_chromium(test):
    """Mark a test that renders the 3-D view in headless Chromium: slow (a browser start and a page render), and
    skipped with a reason when the browser is not installed."""
    return pytest.mark.slow(_chromium_present(test))


REFERENCE = ROOT.parent / "shared" / "reference"
"""The thesis's numbers, extracted independently of this project (the folder ``shared/reference`` next to the
project's folder in the development workspace; a fresh clone does not have it)."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Give the tests that compare the scenario files with the independent extraction a skip reason a newcomer
    understands when the extraction is not there (tests/scenario/test_scenarios_params.py reads
    ``REFERENCE/<sim>.yaml``)."""
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


@pytest.fixture(scope="session")
def sim1():
    """Simulation 1's scenario (scripts/params/sim1.yaml), loaded once per test session (tests must not change it)."""
    from humanoid_sim.scenario.schema import load_scenario

    return load_scenario(ROOT / "scripts" / "params" / "sim1.yaml")
