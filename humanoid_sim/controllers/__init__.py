"""Controllers: state, phase and references -> actuator torques (interface:
:class:`humanoid_sim.interfaces.controller.Controller`).

- :class:`.thesis.controller.ThesisController`: thesis sections 5.1 and 5.2 (the thesis gait's default);
- :class:`.balance.controller.BalanceController`: the QP whole-body controller (the zmp gait's default);
- a user's own, given as an object or by a dotted name ``package.module:ClassName`` (:func:`.loading.load_controller`;
  scenario key ``controller_class``).
"""

from humanoid_sim.interfaces.controller import (
                                           Command,
                                           ControlContext,
                                           Controller,
                                           ControllerError,
                                           Observation,
                                           as_command,
)

__all__ = ["Command", "ControlContext", "Controller", "ControllerError", "Observation", "as_command"]
