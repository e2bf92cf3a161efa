"""The exception hierarchy and its exit statuses (humanoid_sim.errors)."""

from __future__ import annotations

import pytest

from humanoid_sim.errors import ControllerError, HumanoidSimError, InputError, SimulationError, exit_status


@pytest.mark.parametrize("kind, builtin, status", [(InputError, ValueError, 2), (ControllerError, RuntimeError, 1),
                                                   (SimulationError, RuntimeError, 1)])
def test_each_kind_keeps_its_builtin_base_and_exit_status(kind, builtin, status) -> None:
    exc = kind("x")
    assert isinstance(exc, HumanoidSimError) and isinstance(exc, builtin)
    assert exit_status(exc) == status


def test_anything_else_exits_with_one() -> None:
    assert exit_status(KeyError("k")) == 1
    assert exit_status(HumanoidSimError("base")) == 1


def test_the_selector_and_the_controller_interface_raise_these_very_classes() -> None:
    from humanoid_sim.interfaces import controller, selector

    assert selector.SimulationError is SimulationError
    assert controller.ControllerError is ControllerError
