"""One walk, assembled: a scenario's references, an engine, a controller, the stepping loop.

:class:`Simulator` is the convenience front end ``walk.py`` and the tests use::

    sim = Simulator(hm, scenario)                       # weld engine + thesis controller (compiled when possible)
    sim = Simulator(hm, scenario, engine="thesis")      # the thesis oracle engine
    sim = Simulator(hm, scenario, controller=MyController())
    result = sim.run()                                  # humanoid_sim.sim.loop.SimResult

The pieces live in :mod:`humanoid_sim.sim.loop` (the one stepping loop), :mod:`humanoid_sim.engines` and
:mod:`humanoid_sim.controllers`.  The controller is the scenario's ``controller_class`` when it names one, else
for the zmp gait ``gait.controller`` (the balance QP by default), else the thesis's
(:class:`humanoid_sim.controllers.thesis.controller.ThesisController`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from humanoid_sim.controllers.thesis.controller import ThesisController
from humanoid_sim.engines import make_engine
from humanoid_sim.engines.weld import BASIC, unwrap_to, yaw_of
from humanoid_sim.interfaces.controller import ControlContext, Controller

# PhaseRecord and SimulationError are part of this module's interface (SimResult.phases, Simulator.run's failures)
from humanoid_sim.interfaces.selector import PhaseRecord, SimulationError
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.references.zmp.zmp_walk import initial_state, make_trajectory
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import Scenario
from humanoid_sim.sim.loop import SimResult, run


def _settings_for(controller: Controller, scenario: Scenario) -> object:
    """The scenario's section for ``controller``: the balance controller's or the thesis controller's settings, else a
    user controller's ``controller_settings``."""
    if isinstance(controller, ThesisController):
        return scenario.controller
    if type(controller).__name__ == "BalanceController":
        return scenario.balance
    return scenario.controller_settings


class Simulator:
    """One scenario on one engine with one controller.

    ``engine``: "pinocchio" (default) or "thesis" (:data:`humanoid_sim.engines.ENGINE_NAMES`).  ``controller``: an
    object of the controller interface, or None for the scenario's ``controller_class`` or else the thesis's.
    ``compiled``: for the weld engine and the thesis controller, use the compiled kernel (None = when numba is
    installed and the kernel agrees with the reference path, True = required, False = never; ``--no-kernel``).
    """

    def __init__(self, hm: HumanoidModel, scenario: Scenario, compiled: bool | None = None,
                 engine: str = "pinocchio", controller: Controller | None = None) -> None:
        self.hm = hm
        self.sc = scenario
        self.model = hm.model
        self.q0 = initial_state(hm, scenario)
        self.traj = make_trajectory(hm, scenario, self.q0)
        self.engine = make_engine(engine, hm, scenario, self.traj, compiled=compiled)
        if controller is None:
            if scenario.controller_class is not None:
                from humanoid_sim.controllers.loading import load_controller

                controller = load_controller(scenario.controller_class)
            elif scenario.gait.is_zmp and scenario.gait.controller == "balance":
                from humanoid_sim.controllers.balance.controller import BalanceController

                controller = BalanceController(scenario.balance, compiled=compiled is not False)  # --no-kernel
            else:
                controller = ThesisController(compiled=compiled if engine in ("pinocchio", "mujoco") else False)
        self.controller = controller
        controller.setup(ControlContext(hm, scenario, self.traj, self.q0, self.engine.name, self.engine.constraints,
                                        settings=_settings_for(controller, scenario)))

    # the thesis controller's and the weld engine's parts, for tests and tools
    @property
    def traj(self) -> ReferenceTrajectory:
        """The reference trajectory (shared by the loop, the engine and the controller)."""
        return self._traj

    @traj.setter
    def traj(self, value: ReferenceTrajectory) -> None:
        self._traj = value
        for part in (getattr(self, "engine", None), getattr(self, "controller", None)):
            if part is not None and hasattr(part, "traj"):
                part.traj = value
        if hasattr(getattr(self, "controller", None), "landing"):
            self.controller.landing()

    @property
    def kernel(self):
        """The thesis controller's compiled stage kernel, or None."""
        return getattr(self.controller, "kernel", None)

    @property
    def cmd(self):
        return self.controller.cmd

    @property
    def act(self):
        return self.controller.act

    @property
    def dyn(self):
        return self.engine.dyn

    @property
    def _w_tau(self):
        return self.controller._w_tau

    @property
    def _w_lam(self):
        return self.controller._w_lam

    def evaluate(self, k, phase, anchors, t, q, v) -> dict:
        """The thesis controller and the weld engine's motion at one state: a, lam, tau, T, T_cmd, sat, thdd_c."""
        cmd = self.controller.evaluate(k, phase, anchors, t, q, v)
        a, lam = self.engine._motion(phase, anchors, q, v, cmd)
        return {"a": a, "lam": lam, "tau": cmd.tau, "T": cmd.T, "T_cmd": cmd.T_cmd, "sat": cmd.saturated,
                "thdd_c": cmd.theta_ddot_cmd, "cmd": cmd, **(cmd.extra or {})}

    def check_kernel(self, tol: float = 1e-8) -> str | None:
        return self.controller.check_kernel(tol)

    def project_on_support(self, phase, anchors, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The weld engine's projection onto the support foot."""
        return self.engine.project_on_support(phase, anchors, q, v)

    def run(self, t_end: float | None = None, progress: Callable[[float, int], None] | None = None,
            hold: Phase | None = None) -> SimResult:
        """Simulate until every planned phase is done, ``t_end`` (s), the scenario's end time, or a failure
        (``hold``: stay in one contact phase instead, see :func:`humanoid_sim.sim.loop.run`)."""
        return run(self.engine, self.controller, self.traj, self.sc, self.q0, t_end=t_end, progress=progress,
                   hold=hold)


__all__ = ["BASIC", "PhaseRecord", "SimResult", "SimulationError", "Simulator", "unwrap_to", "yaw_of"]
