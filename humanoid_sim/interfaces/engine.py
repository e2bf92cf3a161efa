"""The engine interface: what advances the state under the phase's contacts.

An engine owns the simulated state and its integration.  The stepping loop (:mod:`humanoid_sim.sim.loop`) drives it
step by step; the engine calls the controller (already checked and counted by the loop) whenever it needs
torques, and reports the kinematics the phase selector reads.  Units and frames: SI, world = thesis frame 0 (x
lateral, y forward, z up, ground z = 0); Pinocchio's q / v conventions (:mod:`humanoid_sim.interfaces.controller`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple, Protocol, runtime_checkable

import numpy as np

from humanoid_sim.interfaces.controller import Command, Observation
from humanoid_sim.interfaces.log import SimLog
from humanoid_sim.interfaces.selector import PhaseSelector
from humanoid_sim.robot.phases import Phase


class StepRow(NamedTuple):
    """What the stepping loop keeps of one step, for the engine's :meth:`Engine.build_log` after the run.

    Attributes:
        t: the step's start time, s.
        k: the index of the current phase in the trajectory's schedule.
        phase: the current contact phase.
        reference: the nominal references at t (``ReferenceTrajectory.sample_global(t)``).
        hip_ctrl_ref: the hip CoM reference the controller tracks at t (clamped to the phase's window), world, m.
        record: the engine's own record of the step (a NamedTuple of the engine's, returned by :meth:`Engine.step`).
    """

    t: float
    k: int
    phase: Phase
    reference: Any
    hip_ctrl_ref: np.ndarray
    record: Any


@runtime_checkable
class Engine(Protocol):
    """An engine (implementations: :class:`humanoid_sim.engines.weld.WeldEngine`,
    :class:`humanoid_sim.engines.oracle.OracleEngine`, :class:`humanoid_sim.engines.mujoco.engine.MujocoEngine`).

    Attributes: ``name`` (as ``walk.py --engine`` spells it); ``model`` (the Pinocchio model); ``constraints``
    (what it offers a controller for a computed torque under the phase's contacts, or None); optionally ``errors``
    (its own exception types that end a run with a reason) and ``close()`` (called once the run is over).

    Optional hooks, for engines whose contacts are physical rather than imposed (the loop uses them when present,
    :class:`humanoid_sim.engines.mujoco.engine.MujocoEngine`):

    - ``touchdown_signal(foot) -> bool | None``: whether ``foot`` (the swing foot of a single support) has touched
      the ground at the current state; a bool replaces the geometric touchdown rule's height clause (its
      horizontal-travel clause stays as a guard), None defers to the geometric rule;
    - ``check(t) -> None``: called after every step, before the phase selector's checks; raises a
      :class:`humanoid_sim.interfaces.selector.SimulationError` (its message the one-line reason) to end the run, e.g.
      on a
      fall;
    - ``run_info() -> dict``: merged into ``SimResult.extra`` after the run (e.g. ground measures for summary.json).
    """

    name: str
    model: Any
    constraints: Any

    def start(self, q0: np.ndarray, phase: Phase) -> None:
        """Set the state to rest at configuration q0 (nq,) with ``phase``'s contacts where q0 puts them."""
        ...

    def step(self, t: float, h: float, k: int, control: Callable[[Observation], Command],
             checks: PhaseSelector) -> Any:
        """Advance the state from t to t + h (s) in phase index k, calling ``control`` for torques; call
        ``checks.check_stage`` on every intermediate state and ``checks.check_acceleration`` on every acceleration.
        Returns the step's record: a NamedTuple of the engine's own, consumed by :meth:`build_log`."""
        ...

    def state_vectors(self) -> tuple[np.ndarray, np.ndarray]:
        """The state's coordinates and rates (for the divergence checks)."""
        ...

    def hip_com(self) -> np.ndarray:
        """Body-17 CoM (3,), world, m, at the current state (NaN if the state is not finite)."""
        ...

    def toe_point(self, foot: str) -> np.ndarray:
        """Toe point P_tp (3,) of foot "R" / "L", world, m (after :meth:`hip_com`)."""
        ...

    def toe_rotation(self, foot: str) -> np.ndarray:
        """Orientation (3x3) of the toe body (O_1 / O_2) of ``foot`` (after :meth:`hip_com`)."""
        ...

    def touchdown(self, t: float, phase: Phase, foot: str, key: str) -> None:
        """The swing ``foot`` landed at the end of single support ``phase``; ``key`` names the scenario's reset
        weights (``reset.<key>``) for engines that apply the thesis's velocity reset."""
        ...

    def enter(self, phase: Phase) -> None:
        """The next phase starts now (contacts change)."""
        ...

    def build_log(self, rows: list[StepRow]) -> SimLog:
        """The run's log from the loop's rows (one :class:`StepRow` per step)."""
        ...
