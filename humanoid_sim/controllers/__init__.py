"""Controllers: state, phase and references -> actuator torques (interface: :class:`.base.Controller`).

- :class:`.thesis.ThesisController` (the default): thesis sections 5.1 and 5.2;
- a user's own, given as an object or by a dotted name ``package.module:ClassName`` (:func:`.loading.load_controller`;
  scenario key ``controller_class``).
"""

from humanoid_sim.controllers.base import (Command, ControlContext, Controller, ControllerError, Observation,
                                           as_command)

__all__ = ["Command", "ControlContext", "Controller", "ControllerError", "Observation", "as_command"]
