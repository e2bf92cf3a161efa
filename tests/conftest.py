"""Shared pytest fixtures."""

from __future__ import annotations

import pytest

from humanoid_sim.model import HumanoidModel, load_model


@pytest.fixture(scope="session")
def hm() -> HumanoidModel:
    """The thesis humanoid, loaded once per test session (tests must not mutate its model)."""
    return load_model()
