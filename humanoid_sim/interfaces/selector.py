"""The phase selector of thesis section 6.1.1, shared by every engine (used by the stepping loop,
``humanoid_sim.sim.loop``).

It holds the current phase, the record of every phase as it actually happened, the phase-end targets, and the
checks made at every step boundary: a non-finite or diverging state, a fall, a phase lasting far beyond its
nominal duration (all :class:`SimulationError`), then the switching rules (``phases.ssp_should_end`` /
``dsp_should_end``).  The engines supply the kinematics (hip CoM, swing toe point) and carry out the
touchdown (velocity reset, landing data) themselves.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from humanoid_sim.errors import FallError, SimulationError
from humanoid_sim.references.chapter3 import ReferenceTrajectory
from humanoid_sim.robot.phases import Phase, SwitchThresholds, dsp_should_end, ssp_should_end
from humanoid_sim.scenario.schema import SimulationSettings

if TYPE_CHECKING:  # pragma: no cover
    from humanoid_sim.robot.model import HumanoidModel

DIVERGED_RATE = 100.0  # rad/s or m/s: no joint or base rate of a walking 55 kg humanoid comes near this

BASE_Q_NAMES = ("base position x", "base position y", "base position z", "base quaternion x", "base quaternion y",
                "base quaternion z", "base quaternion w")
BASE_V_NAMES = ("base linear velocity x", "base linear velocity y", "base linear velocity z",
                "base angular velocity x", "base angular velocity y", "base angular velocity z")


def all_finite(x: np.ndarray) -> bool:
    """True when every entry of x is finite: one reduction (a NaN or an infinity makes the sum non-finite; so would
    an overflow of the sum, i.e. magnitudes near 1e308, which are a divergence too)."""
    return math.isfinite(np.add.reduce(x))


@dataclass(frozen=True)
class CoordinateNames:
    """Names of the state's components for messages: a joint as its thesis angle and body, e.g. "theta11 (right
    thigh, body 11)" (theta_k is the angle of thesis body k, Table 2.6), a base component as "base linear velocity
    x".

    Attributes:
        q: the nq configuration components (Pinocchio's order).
        v: the nv velocity components (Pinocchio's order; ``v[6:]`` are the joints of a controller's torques).
        theta: the 26 joint angles in the thesis's eq. 4.1 order.
    """

    q: tuple[str, ...]
    v: tuple[str, ...]
    theta: tuple[str, ...]

    @classmethod
    def of(cls, hm: HumanoidModel) -> CoordinateNames:
        """The names of ``hm``'s coordinates (thesis angles from ``THETA_NAMES``, bodies from the model YAML)."""
        from humanoid_sim.robot.model import THETA_NAMES

        theta = tuple(joint_label(hm, name) for name in THETA_NAMES)
        q = [f"q component {i}" for i in range(hm.model.nq)]
        v = [f"v component {i}" for i in range(hm.model.nv)]
        q[:7], v[:6] = BASE_Q_NAMES, BASE_V_NAMES
        for label, iq, iv in zip(theta, hm.theta_q_idx, hm.theta_v_idx):
            q[iq], v[iv] = label, label
        return cls(tuple(q), tuple(v), theta)

    def component(self, size: int, i: int) -> str:
        """The name of entry ``i`` of a vector of ``size`` entries: a configuration (nq), a velocity, acceleration or
        generalized force (nv), or thesis angles, rates or accelerations (26, eq. 4.1 order: the oracle engine's
        state)."""
        for names in (self.q, self.v, self.theta):
            if size == len(names):
                return names[i]
        return str(i)


def joint_label(hm: HumanoidModel, theta: str) -> str:
    """``theta`` with its thesis body, e.g. "theta9 (right shank, body 9)" (theta_k moves body k; theta17r and
    theta17l are the two hips' angles of body 17)."""
    k = int(re.sub(r"\D", "", theta))
    body = hm.spec.bodies.get(k)
    return f"{theta} (body {k})" if body is None else f"{theta} ({body.name.replace('_', ' ')}, body {k})"


def _first_bad(x: np.ndarray) -> int:
    """Index of the first non-finite entry of x (0 when all are finite, e.g. when only their sum overflows)."""
    bad = np.flatnonzero(~np.isfinite(np.asarray(x, dtype=float)))
    return int(bad[0]) if bad.size else 0

@dataclass
class PhaseRecord:
    """One phase as it actually happened."""

    index: int
    name: str
    t_start: float
    t_end: float | None = None
    nominal_start: float = 0.0
    nominal_end: float = 0.0
    touchdown_error_m: float | None = None  # |actual landing toe point - planned end toe point|, horizontal
    landing_tilt_rad: float | None = None   # angle between the landed toe body's z-axis and the world z-axis


class PhaseSelector:
    """Current phase, phase records and the step-boundary decisions of thesis 6.1.1."""

    def __init__(self, traj: ReferenceTrajectory, thresholds: SwitchThresholds, settings: SimulationSettings,
                 toe_start: np.ndarray | None, names: CoordinateNames | None = None) -> None:
        """``toe_start``: the swing toe point at t = 0 (P_i of the first SSP), world, m.  ``names``: the state's
        component names for the messages (None: components by index)."""
        self.names = names
        self.traj = traj
        self.thresholds = thresholds
        self.settings = settings
        self.k = 0
        self.phase = Phase(traj.phases[0].name)
        first = traj.phases[0]
        self.records = [PhaseRecord(0, self.phase.value, 0.0, nominal_start=first.t_start, nominal_end=first.t_end)]
        self.targets = traj.phase_targets(0)
        self.toe_start = toe_start
        self.hold = False
        self.dsp_on_schedule = bool(getattr(traj, "dsp_on_schedule", False))
        """True: a double support lasts its planned duration and ends no earlier than its planned end on the plan's
        clock (the trajectory asks for it), else section 6.1.1's hip-distance / overtime rule."""
        self.plan_delay = 0.0
        """How much later than planned the latest touchdown so far came, s: the plan's clock is t - plan_delay (it
        waits for a late touchdown; it moves on after a swing the controller shortened on purpose, see
        :meth:`advance`, and plan_delay may then be < 0).  Only touchdowns count: a double support ends on the
        step grid, up to half a step after its planned end, and counting that would ratchet the delay up by a few
        ms at every step (measured: 63 ms over the 60 s walk)."""

    def hold_in(self, phase: Phase) -> None:
        """Stay in ``phase`` for the whole run (a standing test): no phase switch and no overtime check."""
        self.hold = True
        self.phase = phase
        self.records[0].name = phase.value

    @property
    def info(self):
        """The nominal schedule entry (``trajectory.PhaseInfo``) of the current phase."""
        return self.traj.phases[self.k]

    @property
    def is_last(self) -> bool:
        return self.k + 1 >= self.traj.n_phases

    def where(self) -> str:
        return f"phase {self.k + 1} ({self.phase.value})"

    def name(self, x: np.ndarray, i: int) -> str:
        """The name of entry ``i`` of the state vector ``x`` (:class:`CoordinateNames`), or its index."""
        return str(i) if self.names is None else self.names.component(len(x), i)

    def _non_finite(self, state: np.ndarray, rates: np.ndarray) -> str:
        """Which entry of the state is not finite, with its value: "velocity component theta9 (right shank, body 9)
        is nan"."""
        if not all_finite(state):
            i = _first_bad(state)
            return f"position component {self.name(state, i)} is {state[i]:.3g}"
        i = _first_bad(rates)
        return f"velocity component {self.name(rates, i)} is {rates[i]:.3g}"

    def check_stage(self, t: float, state: np.ndarray, rates: np.ndarray, stage: int) -> None:
        """Raise :class:`SimulationError` if an integration stage's state is not finite."""
        if not (all_finite(state) and all_finite(rates)):
            raise SimulationError(f"non-finite state at t = {t:.3f} s (integration stage {stage}) in "
                                  f"{self.where()}: {self._non_finite(state, rates)}; the motion diverged")

    def check_acceleration(self, t: float, acc: np.ndarray) -> None:
        """Raise :class:`SimulationError` if the dynamics returned a non-finite acceleration."""
        if not all_finite(acc):
            i = _first_bad(acc)
            raise SimulationError(f"non-finite acceleration at t = {t:.3f} s in {self.where()}: "
                                  f"acceleration component {self.name(acc, i)} is {acc[i]:.3g}; the motion diverged")

    def check_state(self, t: float, state: np.ndarray, rates: np.ndarray, hip_p: np.ndarray) -> None:
        """Raise :class:`SimulationError` on a non-finite state, rates above :data:`DIVERGED_RATE`, the hip CoM
        below the fall height or a phase lasting more than ``max_phase_overtime`` x its nominal duration."""
        if not (all_finite(state) and all_finite(rates)):
            raise SimulationError(f"non-finite state at t = {t:.3f} s in {self.where()}: "
                                  f"{self._non_finite(state, rates)}")
        if np.max(np.abs(rates)) > DIVERGED_RATE:
            i = int(np.argmax(np.abs(rates)))
            raise SimulationError(f"diverged at t = {t:.3f} s in {self.where()}: velocity component "
                                  f"{self.name(rates, i)} is "
                                  f"{rates[i]:.3g} (limit {DIVERGED_RATE:g} rad/s or m/s)")
        if hip_p[2] < self.settings.fall_height_m:
            raise FallError(f"fall: hip CoM height {hip_p[2]:.3f} m below {self.settings.fall_height_m} m "
                                  f"at t = {t:.3f} s")
        if self.hold:
            return
        info = self.info
        elapsed = t - self.records[-1].t_start
        nominal = info.duration
        if self.dsp_on_schedule and info.swing_foot is None:
            # a double support started by an early touchdown lasts until its planned end on the plan's clock
            nominal = max(nominal, info.t_end + self.plan_delay - self.records[-1].t_start)
        if elapsed > self.settings.max_phase_overtime * nominal:
            raise SimulationError(
                f"{self.where()} has lasted {elapsed:.2f} s, more than {self.settings.max_phase_overtime:g} x its "
                f"nominal {nominal:.3f} s (the swing foot never touched down)" if info.swing_foot else
                f"{self.where()} has lasted {elapsed:.2f} s, more than {self.settings.max_phase_overtime:g} x its "
                f"nominal {nominal:.3f} s")

    def should_switch(self, t: float, hip_p: np.ndarray, swing_toe_p: np.ndarray | None) -> bool:
        """Section 6.1.1: touchdown ends an SSP (``swing_toe_p`` needed), the hip-distance or overtime rule a DSP."""
        if self.hold:
            return False
        info = self.info
        if info.swing_foot is not None:
            end = self.targets.swing_toe_end
            assert swing_toe_p is not None and self.toe_start is not None and end is not None, "an SSP has a swing toe"
            return ssp_should_end(swing_toe_p, self.toe_start, end, self.thresholds)
        elapsed = t - self.records[-1].t_start
        if self.dsp_on_schedule:
            # the zmp gait: the ZMP moves across during the whole planned double support.  A touchdown sensed early
            # starts the double support early; it still ends at its planned end (plan clock), so the weight has
            # moved onto the new stance foot before the old one lifts (ending it after its duration from an early
            # touchdown lifted a foot still carrying ~250 N: on MuJoCo the new stance foot rocked and spun 20 deg)
            half = 0.5 * self.settings.step_s
            return elapsed >= info.duration - half and t - self.plan_delay >= info.t_end - half
        return dsp_should_end(hip_p, self.targets.hip_p_end, elapsed, info.duration, self.thresholds)

    def record_touchdown(self, toe_p: np.ndarray, R_toe: np.ndarray) -> str:
        """Log the landing of the swing foot (horizontal error to the planned toe point, tilt of the toe body) and
        return the scenario key of the velocity-reset weights of this transition."""
        rec = self.records[-1]
        end = self.targets.swing_toe_end
        assert end is not None, "a touchdown ends an SSP, which has a planned swing toe end"
        rec.touchdown_error_m = float(np.hypot(*(toe_p[:2] - end[:2])))
        rec.landing_tilt_rad = float(np.arccos(np.clip(R_toe[2, 2], -1.0, 1.0)))
        return f"Wadj_qdot_{self.phase.value}_to_{self.phase.next.value}"

    def end_phase(self, t: float) -> None:
        self.records[-1].t_end = t

    def advance(self, t: float, toe_start: np.ndarray | None, jump: float = 0.0) -> None:
        """Start the next phase at time t; ``toe_start``: its swing toe point (SSP) or None.  ``jump`` (s, >= 0):
        the controller shortened the swing that just touched down (step timing) and asks the plan's clock to move
        on by up to that much toward the double support's start, so that the walk runs ahead of its schedule
        instead of waiting for it."""
        self.k += 1
        self.phase = self.phase.next
        nxt = self.traj.phases[self.k]
        if self.phase.is_double_support:   # started by a sensed touchdown (a double support ends on schedule)
            self.plan_delay = max(self.plan_delay - max(jump, 0.0), t - nxt.t_start)
        self.records.append(PhaseRecord(self.k, self.phase.value, t, nominal_start=nxt.t_start,
                                        nominal_end=nxt.t_end))
        self.targets = self.traj.phase_targets(self.k)
        self.toe_start = toe_start

    def close(self, t: float) -> None:
        """At the end of a run: the current phase ends at t."""
        if self.records and self.records[-1].t_end is None:
            self.records[-1].t_end = t
