"""Scenarios: the YAML schema, its validation and the typed :class:`Scenario` a walk runs.

One module per concern: :mod:`.schema` (the scenario and its sections), :mod:`.thesis_controller` (the thesis
controller's weights), :mod:`.balance` (the balance controller's settings), :mod:`.fields` (value ranges and checks),
:mod:`.yamlio` (strict YAML reading).
"""

from humanoid_sim.scenario.balance import BalanceSettings
from humanoid_sim.scenario.fields import ScenarioError
from humanoid_sim.scenario.schema import Scenario, load_scenario, parse_scenario, read_scenario_doc
from humanoid_sim.scenario.thesis_controller import ControllerParams

__all__ = ["BalanceSettings", "ControllerParams", "Scenario", "ScenarioError", "load_scenario", "parse_scenario",
           "read_scenario_doc"]
