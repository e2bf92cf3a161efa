"""The exception hierarchy: every error humanoid_sim raises on purpose is a :class:`HumanoidSimError`.

Three kinds matter to a caller, and the command-line tools map them to exit statuses (:data:`EXIT_STATUS`):

- :class:`InputError`: bad input (a scenario, a sweep or design file, a robot description, an option). The message
  names the field, the value and what was expected. Nothing has been written. Exit status 2.
- :class:`ControllerError`: a controller failed (raised, or returned torques of the wrong shape or non-finite ones).
  The run stops and keeps its log. Exit status 1.
- :class:`SimulationError`: the simulation itself failed (diverged, fell, a singular contact system). The run stops
  and keeps its log. Exit status 1.

Each subclass keeps the built-in base it had (``ValueError`` for bad input, ``RuntimeError`` for failures), so code
that catches those still works.
"""

from __future__ import annotations


class HumanoidSimError(Exception):
    """Base of every error humanoid_sim raises on purpose."""


class InputError(HumanoidSimError, ValueError):
    """Bad input: the message names the field, the value and what was expected (exit status 2)."""


class ControllerError(HumanoidSimError, RuntimeError):
    """A controller failed: it raised, or returned torques of the wrong shape or with non-finite values. The
    message names the controller (exit status 1; the run keeps its log)."""


class SimulationError(HumanoidSimError, RuntimeError):
    """The simulation failed: the state diverged or left the ground plane, the robot fell, a contact system was
    singular, a phase overran (exit status 1; the run keeps its log)."""


class FallError(SimulationError):
    """The robot fell: the hip dropped below the fall height, or (on real ground) a foot rolled over an edge, the
    trunk tilted past its limit, or a body other than a foot touched the ground."""


EXIT_STATUS: dict[type[HumanoidSimError], int] = {InputError: 2, ControllerError: 1, SimulationError: 1}
"""Exit status of the command-line tools per error kind (0 is a run that reached its end)."""


def exit_status(exc: BaseException) -> int:
    """The command-line exit status for ``exc``: 2 for bad input, else 1."""
    for kind, status in EXIT_STATUS.items():
        if isinstance(exc, kind):
            return status
    return 1


__all__ = ["ControllerError", "EXIT_STATUS", "FallError", "HumanoidSimError", "InputError", "SimulationError",
           "exit_status"]
