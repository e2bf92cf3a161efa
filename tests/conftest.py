"""Shared pytest fixtures, and the reasons a test is skipped, in plain words."""

from __future__ import annotations

import os
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


@pytest.fixture(scope="session", autouse=True)
def _variant_cache(tmp_path_factory: pytest.TempPathFactory):
    """Robot variants' generated URDFs go to a folder of this session, not the user's cache (set before any Dask
    worker starts, so the workers inherit it)."""
    old = os.environ.get("HUMANOID_SIM_CACHE")
    os.environ["HUMANOID_SIM_CACHE"] = str(tmp_path_factory.mktemp("cache"))
    yield
    if old is None:
        os.environ.pop("HUMANOID_SIM_CACHE", None)
    else:
        os.environ["HUMANOID_SIM_CACHE"] = old


VARIANT_DOC = {"length_scale": {"foot": 1.08, "shank": 1.1, "thigh": 0.93, "trunk": 1.05, "arms": 0.9, "head": 1.2},
               "mass_scale": {"all": 1.1, "trunk": 0.9, "right_thigh": 1.2},
               "sole": {"length_m": 0.25, "width_m": 0.11},
               "payload": {"mass_kg": 4.0, "body": "upper_trunk", "position_m": [0.06, 0.03, -0.1]}}
"""A robot variant that changes every kind of parameter (the ``robot:`` section of a scenario), left-right
asymmetric (one thigh heavier, the payload off the centre line)."""


@pytest.fixture(scope="session")
def variant_hm(_variant_cache) -> HumanoidModel:
    """The model of :data:`VARIANT_DOC` (generated into the session's cache)."""
    from humanoid_sim.robot.variant import variant_model
    from humanoid_sim.scenario.robot import parse_robot

    return variant_model(parse_robot("<test>", VARIANT_DOC).variant)


@pytest.fixture(scope="session")
def hm() -> HumanoidModel:
    """The thesis humanoid, loaded once per test session (tests must not mutate its model)."""
    return load_model()


@pytest.fixture(scope="session")
def sim1():
    """Simulation 1's scenario (scripts/params/sim1.yaml), loaded once per test session (tests must not change it)."""
    from humanoid_sim.scenario.schema import load_scenario

    return load_scenario(ROOT / "scripts" / "params" / "sim1.yaml")
