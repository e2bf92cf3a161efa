"""The controller interface: what the stepping loop gives a controller and what it must return.

A controller turns the state, the phase and the references into actuator torques.  The loop
(:mod:`humanoid_sim.sim.loop`) calls it whenever the engine needs torques: the shipped thesis and balance controllers
at every integration stage on the weld and oracle engines (a feedthrough function of the state, as the thesis's
Simulink model), a user's controller once per control period (1 ms) with its torques held
(:func:`humanoid_sim.sim.simulate.user_engine_options`); on MuJoCo every controller at its control period.

Units and frames (as everywhere in humanoid_sim): SI units; world frame = thesis frame 0 (x lateral, y forward,
z up, ground z = 0); ``q`` (nq = 33) and ``v`` (nv = 32) are Pinocchio's: ``q = [base position (m), base
quaternion (x, y, z, w), 26 joint angles (rad)]``, ``v = [base linear velocity (m/s), base angular velocity
(rad/s)`` -- both in the base (lower trunk, Body 17) frame -- ``, 26 joint rates (rad/s)]``.  The thesis's
angles theta follow from ``hm.theta_from_q(q)`` (eq. 4.1 order and signs).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from humanoid_sim.dynamics.contact.constraints import Anchors
from humanoid_sim.errors import ControllerError
from humanoid_sim.interfaces.selector import CoordinateNames
from humanoid_sim.robot.phases import Phase

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.references.chapter3 import ReferenceTrajectory
    from humanoid_sim.robot.model import HumanoidModel
    from humanoid_sim.scenario.schema import Scenario


@dataclass
class ControlContext:
    """What a controller is given once, before the run (:meth:`Controller.setup`).

    hm: the robot (Pinocchio model ``hm.model``, frame ids ``hm.frame_id(name)``, theta <-> q/v maps).
    scenario: the validated scenario.
    traj: the reference trajectory (chapter 3): ``traj.hip_reference(k, t)``, ``traj.toe_reference(k, t, foot)``,
        ``traj.sample_global(t)``, ``traj.phases[k]`` (nominal schedule).
    q0: the initial configuration (nq,), at rest, both feet on the ground.
    engine: the engine's name ("pinocchio", "thesis", ...).
    constraints: what the engine offers for a computed torque under the phase's contact constraints, or None when
        its contacts are not constraints (real contact): the weld engine's :class:`humanoid_sim.dynamics.welds.
        WeldModel`, the oracle engine's :class:`humanoid_sim.engines.oracle.OracleModel`.  Controllers that do not
        use it ignore it.
    settings: the controller's own settings from the scenario: a user controller's ``controller_settings`` mapping,
        the balance controller's :class:`humanoid_sim.scenario.BalanceSettings`, the thesis controller's
        :class:`humanoid_sim.scenario.ControllerParams`.
    """

    hm: HumanoidModel
    scenario: Scenario
    traj: ReferenceTrajectory
    q0: np.ndarray
    engine: str
    constraints: Any = None
    settings: Any = None


@dataclass
class Observation:
    """One call's input.

    t: time (s); k: index of the current phase in ``traj.phases``; phase: its contact phase; q, v: the state
    (Pinocchio conventions, see the module docstring); anchors: where the phase's held bodies are held (weld
    placements, toe-lock angles; ``humanoid_sim.dynamics.contact.Anchors``) on engines that hold them, else the feet's
    placements at touchdown; stage: the integration stage within the step (0 = the step's start); plan_delay: how
    much later than planned the latest touchdown so far came (s, >= 0; the phase selector's
    :attr:`~humanoid_sim.interfaces.selector.PhaseSelector.plan_delay`): the plan's clock is ``t - plan_delay``, the
    time at
    which a controller that waits for late touchdowns reads its references; foot_wrenches: on engines whose contacts
    are physical (MuJoCo), what the feet's force-torque sensors measured over the last control period (its mean):
    (2, 6), rows R and L, each the ground's force on the foot (N) and its moment about the world origin (N m), world
    frame; None on engines that impose their contacts (welds: the controller solves for the multipliers itself) and
    before the first period.
    """

    t: float
    k: int
    phase: Phase
    q: np.ndarray
    v: np.ndarray
    anchors: Anchors | None
    stage: int = 0
    plan_delay: float = 0.0
    foot_wrenches: np.ndarray | None = None

    def with_velocity(self, v: np.ndarray) -> Observation:
        """This observation with ``v`` in place of its velocity (a new record; ``dataclasses.replace`` does the
        same at four times the cost, on a path that runs at every control call)."""
        return Observation(self.t, self.k, self.phase, self.q, v, self.anchors, self.stage, self.plan_delay,
                           self.foot_wrenches)


@dataclass
class Command:
    """One call's output: the generalized forces to apply, and what a controller knows about them.

    tau: (nv,) generalized forces in Pinocchio's v order, N m on the 26 joints, zero on the six base rows (the base
        is not actuated).  May be None when T is given (the engine maps T to tau with the actuator map).
    T: (26,) the thesis's actuator torques (eq. 4.69 components, N m) that ``tau`` realises, after saturation, when
        the controller computes them (else the loop logs what the engine derives).
    T_cmd: (26,) the same before saturation; saturated: (26,) bool, which components were clipped.
    theta_ddot_cmd: (26,) the command accelerations (rad/s^2) behind the torques, if any.
    motion: (a (nv,), lam) the accelerations and constraint multipliers the controller solved for under an engine's
        constraint model ``motion_model`` (the same object the engine offered in ``ControlContext.constraints``);
        that engine may use them instead of solving its forward dynamics again (same result).
    extra: engine-specific by-products for the log (e.g. the compiled stage's log vector), keyed by name.
    """

    tau: np.ndarray | None
    T: np.ndarray | None = None
    T_cmd: np.ndarray | None = None
    saturated: np.ndarray | None = None
    theta_ddot_cmd: np.ndarray | None = None
    motion: tuple[np.ndarray, np.ndarray] | None = None
    motion_model: Any = None
    extra: dict | None = None


@runtime_checkable
class Controller(Protocol):
    """A controller: ``setup`` once, then called with an :class:`Observation`, it returns a :class:`Command` (or
    a plain array: (26,) joint torques in Pinocchio's joint order ``v[6:]``, or (nv,) generalized forces with zero
    base rows).  ``name`` appears in messages.

    An optional attribute ``control_period_s`` says how often the engine calls it: absent, every 1 ms with the
    torques held in between (:data:`humanoid_sim.sim.simulate.USER_CONTROL_PERIOD_S`, stable for ordinary joint PD
    gains); a number, that period in s; None, at every integration stage as a feedthrough of the state (the shipped
    thesis and balance controllers, as the thesis's Simulink model evaluates its controller).

    Optional hooks the stepping loop calls when present: ``landing()`` after a touchdown taught the trajectory the
    actual landing (drop cached references); ``plan_jump(k) -> float`` at the touchdown ending single support k:
    how far (s, >= 0) the plan's clock moves on toward the double support's start when the controller landed that
    swing early on purpose (step timing; :meth:`humanoid_sim.interfaces.selector.PhaseSelector.advance`);
    ``swing_landing(k) -> ndarray | None``: where (world toe point, m) the controller lands single support k's swing
    when it moved the foothold, so that a touchdown sensed there counts (the travel guard of 6.1.1.1 measures
    against it), or None for the plan's."""

    name: str

    def setup(self, ctx: ControlContext) -> None:
        """Prepare for a run (build models, read weights); called once before the first step."""
        ...

    def __call__(self, obs: Observation) -> Command | np.ndarray:
        """Torques at this state."""
        ...


def as_command(out: Any, nv: int, name: str, names: CoordinateNames | None = None) -> Command:
    """Check a controller's output and return it as a :class:`Command`.

    Args:
        out: what the controller returned.
        nv: the model's velocity dimension (32).
        name: the controller's name, for the messages.
        names: the state's component names, for the messages (None: entries by index).

    Raises:
        ControllerError: naming the controller, for anything else than a Command or an array of shape (26,) /
            (nv,), for non-finite values (naming their joints) and for forces on the (unactuated) base rows.
    """
    if type(out) is Command:    # the usual answer, checked first without the general path's set-up
        tau = out.tau
        if type(tau) is np.ndarray and tau.shape == (nv,) and tau.dtype == np.float64 and \
                np.isfinite(np.add.reduce(tau)) and not (tau[0] or tau[1] or tau[2] or tau[3] or tau[4] or tau[5]):
            return out

    def label(size: int, i: int) -> str:
        return f"entry {i}" if names is None else names.component(size, i)

    def order() -> str:  # the joints of a (nv - 6,) torque vector, in order
        return "" if names is None else f" ({', '.join(n.split(' (')[0] for n in names.v[6:])})"

    if isinstance(out, Command):
        tau = out.tau
        if tau is None and out.T is not None:  # thesis actuator torques only (an engine maps them)
            T = out.T
            if not (isinstance(T, np.ndarray) and T.shape == (26,) and np.isfinite(np.add.reduce(T))):
                bad = ""
                if isinstance(T, np.ndarray) and T.shape == (26,) and T.dtype.kind == "f":
                    i = int(np.flatnonzero(~np.isfinite(T))[0]) if not np.isfinite(T).all() else 0
                    bad = f" (component T{i + 1} is {T[i]})"
                raise ControllerError(f"controller {name!r} returned thesis torques T that are not 26 finite "
                                      f"numbers{bad}: {T!r}")
            return out
    else:
        out = Command(tau=out)
        tau = out.tau
    if not isinstance(tau, np.ndarray):
        try:
            tau = np.asarray(tau, dtype=float)
        except (TypeError, ValueError):
            raise ControllerError(f"controller {name!r} returned {type(tau).__name__}, expected an array of "
                                  f"{nv - 6} joint torques (or {nv} generalized forces) or a Command") from None
    if tau.shape == (nv - 6,):
        tau = np.concatenate([np.zeros(6), tau.astype(float)])
    elif tau.shape != (nv,):
        raise ControllerError(f"controller {name!r} returned torques of shape {tau.shape}, expected ({nv - 6},) "
                              f"joint torques in Pinocchio's joint order{order()} or ({nv},) generalized forces")
    if tau.dtype != np.float64:
        try:
            tau = tau.astype(float)
        except (TypeError, ValueError):
            raise ControllerError(f"controller {name!r} returned torques of type {tau.dtype}, expected numbers") \
                from None
    if not np.isfinite(np.add.reduce(tau)):
        nonfinite = np.flatnonzero(~np.isfinite(tau))
        which = ", ".join(f"{label(nv, i)} = {tau[i]}" for i in nonfinite[:6]) + (", ..." if nonfinite.size > 6 else "")
        raise ControllerError(f"controller {name!r} returned non-finite torques: {which} (entries {nonfinite.tolist()} "
                              f"of the v-ordered vector)")
    if tau[0] != 0.0 or tau[1] != 0.0 or tau[2] != 0.0 or tau[3] != 0.0 or tau[4] != 0.0 or tau[5] != 0.0:
        if np.max(np.abs(tau[:6])) > 1e-9:  # 1e-9 N: round-off of a controller that zeroes the rows itself
            rows = "" if names is None else " (" + ", ".join(names.v[:6]) + " rows)"
            raise ControllerError(f"controller {name!r} returned forces on the unactuated base rows "
                                  f"{tau[:6].tolist()}{rows}; the base (free flyer) has no actuator")
        tau = tau.copy()
        tau[:6] = 0.0
    out.tau = tau
    return out
