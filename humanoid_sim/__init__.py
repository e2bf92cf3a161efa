"""humanoid_sim: a Python simulator of humanoid biped walking in 3-D, on Pinocchio and MuJoCo.

A re-implementation, and extension, of G. Akalin's thesis *Simulation of Biped Locomotion of Humanoid Robots in 3D
Space* (METU 2010). The public API::

    import humanoid_sim as hs

    run = hs.run_walk("sim1_zmp", engine="mujoco")
    df = run.log.to_pandas()

The names below load on first use, so ``import humanoid_sim`` stays light.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from humanoid_sim.errors import ControllerError, FallError, HumanoidSimError, InputError, SimulationError
from humanoid_sim.paths import MODELS_DIR, PACKAGE_DIR, SCENARIOS_DIR, scenario_names

__version__ = "0.2.0"

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.api import Run, RunLog, run_walk
    from humanoid_sim.interfaces.controller import Command, ControlContext, Controller, Observation
    from humanoid_sim.robot.model import HumanoidModel, load_model
    from humanoid_sim.scenario import Scenario, load_scenario
    from humanoid_sim.sim.simulate import Simulator
    from humanoid_sim.sim.status import RunStatus

_LAZY = {
    "run_walk": "humanoid_sim.api", "Run": "humanoid_sim.api", "RunLog": "humanoid_sim.api",
    "Scenario": "humanoid_sim.scenario", "load_scenario": "humanoid_sim.scenario",
    "RunStatus": "humanoid_sim.sim.status", "Simulator": "humanoid_sim.sim.simulate",
    "HumanoidModel": "humanoid_sim.robot.model", "load_model": "humanoid_sim.robot.model",
    "Controller": "humanoid_sim.interfaces.controller", "ControlContext": "humanoid_sim.interfaces.controller",
    "Observation": "humanoid_sim.interfaces.controller", "Command": "humanoid_sim.interfaces.controller",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'humanoid_sim' has no attribute {name!r}")


__all__ = [
    "Command", "ControlContext", "Controller", "ControllerError", "FallError", "HumanoidModel", "HumanoidSimError",
    "InputError", "MODELS_DIR", "Observation", "PACKAGE_DIR", "Run", "RunLog", "RunStatus", "SCENARIOS_DIR",
    "Scenario", "SimulationError", "Simulator", "__version__", "load_model", "load_scenario", "run_walk",
    "scenario_names",
]
