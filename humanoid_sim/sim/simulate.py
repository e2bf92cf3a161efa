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
from humanoid_sim.dynamics.contact import ContactDynamics
from humanoid_sim.dynamics.welds import WeldModel
from humanoid_sim.engines import make_engine
from humanoid_sim.engines.weld import BASIC, unwrap_to, yaw_of
from humanoid_sim.errors import InputError
from humanoid_sim.interfaces.controller import ControlContext, Controller

# PhaseRecord and SimulationError are part of this module's interface (SimResult.phases, Simulator.run's failures)
from humanoid_sim.interfaces.selector import PhaseRecord, SimulationError
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.references.zmp.zmp_walk import initial_state, make_trajectory
from humanoid_sim.robot.model import HumanoidModel
from humanoid_sim.robot.phases import Phase
from humanoid_sim.scenario.schema import Scenario
from humanoid_sim.sim.disturbances import check_engine, engine_world
from humanoid_sim.sim.drive import Drive, with_motors
from humanoid_sim.sim.loop import SimResult, run

USER_CONTROL_PERIOD_S = 0.001
"""Control period of a user's controller, s (1 kHz, a torque-controlled humanoid's servo rate): its torques are
held over the period on every engine that holds torques (welds, MuJoCo).  A PD held for a period T is stable while
kd T / I < 2 for the lightest joint motion of effective inertia I; on the welds in double support that is the head's
yaw, I = 0.0144 kg m^2, so 1 ms holds kd up to 28 N m s/rad (10 ms: 2.8)."""

USER_ARMATURE_KG_M2 = 0.02
"""Rotor inertia reflected on each joint for a user's controller on MuJoCo, kg m^2 (a geared motor's: a 2e-6 kg m^2
rotor behind a 100:1 gear).  On real ground a foot's toe body is free and light (0.13 kg, 1.3e-4 kg m^2 about its
joint): a held PD with kd = 20 N m s/rad would need a period below 13 us.  With the armature every joint has I >=
0.02 kg m^2, which holds kd up to 40 N m s/rad at 1 ms."""


def user_engine_options(engine: str, controller: Controller) -> dict:
    """The engine settings a controller runs with.

    A controller's ``control_period_s`` attribute says how it runs: None for a feedthrough of the state evaluated at
    every integration stage (the shipped thesis and balance controllers), a period in s for a controller whose
    torques are held over that period, :data:`USER_CONTROL_PERIOD_S` when the attribute is absent (a user's
    controller). A held controller gets that period on the weld engine and on MuJoCo, and on MuJoCo the joints'
    armature :data:`USER_ARMATURE_KG_M2`; the thesis oracle calls every controller at each ode3 stage.

    Returns:
        The engine options (``control_period_s``, ``armature_kg_m2``), empty for a feedthrough controller.
    """
    period = getattr(controller, "control_period_s", USER_CONTROL_PERIOD_S)
    if period is None or engine not in ("pinocchio", "mujoco"):
        return {}
    if engine == "mujoco":
        return {"control_period_s": float(period), "armature_kg_m2": USER_ARMATURE_KG_M2}
    return {"control_period_s": float(period)}


def _settings_for(controller: Controller, scenario: Scenario) -> object:
    """The scenario's section for ``controller``: the balance controller's or the thesis controller's settings, else a
    user controller's ``controller_settings``."""
    from humanoid_sim.controllers.balance.controller import BalanceController

    if isinstance(controller, ThesisController):
        return scenario.controller
    if isinstance(controller, BalanceController):
        return scenario.balance
    return scenario.controller_settings


class Simulator:
    """One scenario on one engine with one controller.

    ``engine``: "pinocchio" (default), "thesis" or "mujoco" (:data:`humanoid_sim.engines.ENGINE_NAMES`).
    ``controller``: an object of the controller interface, or None for the scenario's ``controller_class`` or else
    the thesis's.  A user's controller runs at a control period with its torques held, on MuJoCo with the joints'
    armature (:func:`user_engine_options`); the shipped controllers run at their engines' own rates.
    ``compiled``: for the weld engine and the thesis controller, use the compiled kernel (None = when numba is
    installed and the kernel agrees with the reference path, True = required, False = never; ``--no-kernel``).
    """

    def __init__(self, hm: HumanoidModel, scenario: Scenario, compiled: bool | None = None,
                 engine: str = "pinocchio", controller: Controller | None = None,
                 planner: Callable[[HumanoidModel, Scenario, np.ndarray], ReferenceTrajectory] | None = None) -> None:
        self.drive: Drive | None = None
        check_engine(scenario, engine)   # pushes and terrain need real ground (sim/disturbances.py)
        if scenario.actuators is not None:   # the motors' rotor inertia in every model, their envelopes on commands
            if engine == "thesis":
                raise InputError("actuators: the thesis engine's equations (the NumPy oracle) have no rotor inertia; "
                                 "expected --engine pinocchio or mujoco for a scenario with motors")
            hm = with_motors(hm, scenario.actuators)
            self.drive = Drive(hm, scenario.actuators)
        self.hm = hm
        self.sc = scenario
        self.model = hm.model
        self.q0 = initial_state(hm, scenario)
        # ``planner``: another source of the same plan (a cache of it), called as make_trajectory is
        self.traj = (make_trajectory if planner is None else planner)(hm, scenario, self.q0)
        if controller is None:
            if scenario.controller_class is not None:
                from humanoid_sim.controllers.loading import load_controller

                controller = load_controller(scenario.controller_class)
            elif scenario.gait.is_zmp and scenario.gait.controller == "balance":
                from humanoid_sim.controllers.balance.controller import BalanceController

                controller = BalanceController(scenario.balance, compiled=compiled is not False)  # --no-kernel
            else:
                controller = ThesisController(compiled=compiled if engine in ("pinocchio", "mujoco") else False)
        hm_engine, sc_engine = engine_world(hm, scenario)   # the engine's own robot and ground (disturbances.model)
        self.engine = make_engine(engine, hm_engine, sc_engine, self.traj, compiled=compiled,
                                  **user_engine_options(engine, controller))
        self.controller = controller
        constraints = self.engine.constraints
        if hm_engine is not hm and isinstance(constraints, WeldModel):   # the controller solves on its own model
            constraints = WeldModel(ContactDynamics(hm.model))
        controller.setup(ControlContext(hm, scenario, self.traj, self.q0, self.engine.name, constraints,
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
                   hold=hold, drive=self.drive)


__all__ = ["BASIC", "USER_ARMATURE_KG_M2", "USER_CONTROL_PERIOD_S", "PhaseRecord", "SimResult", "SimulationError",
           "Simulator", "unwrap_to", "user_engine_options", "yaw_of"]
