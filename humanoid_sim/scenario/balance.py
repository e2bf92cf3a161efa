"""The ``balance:`` section of a scenario: settings of the balance controller (the zmp gait's QP controller).

Every key is optional; an absent key takes the default below. Gains are given as the natural frequency omega of a
critically damped PD (stiffness omega^2, damping 2 omega); weights are relative weights of the QP's cost terms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from humanoid_sim.errors import InputError
from humanoid_sim.scenario.fields import ScenarioError

FEEDBACKS = ("dcm", "pd")
"""The values of ``BalanceSettings.feedback``."""
BASE_VELOCITIES = ("filtered", "measured")
"""The values of ``BalanceSettings.base_velocity``."""
_CHOICES = ("feedback", "base_velocity")
_FLAGS = ("time_shift", "lazy_torque_limits", "step_adjustment", "step_timing", "external_force",
          "footholds", "flat_trail", "flat_lead_in")


@dataclass(frozen=True)
class BalanceSettings:
    """Gains, task weights and contact margins of the balance controller.

    Attributes:
        hip_omega: hip (Body-17 CoM) tracking gain, rad/s.
        trunk_omega: trunk orientation tracking gain, rad/s.
        swing_omega: swing-foot tracking gain, rad/s.
        posture_omega: joint posture regularisation gain, rad/s.
        w_hip: weight of the hip task (-).
        w_trunk: weight of the trunk orientation task (-).
        w_swing: weight of the swing-foot task (-).
        w_posture: weight of the leg posture task (-).
        w_upper: weight of the upper-body posture task (-).
        w_acc: weight of the joint accelerations (regularisation, -).
        w_force: weight of the contact wrenches (regularisation, -).
        w_torque: weight of the joint torques (regularisation, -).
        cop_margin_ssp_m: how far inside the sole edge the centre of pressure stays in single support, m.
        cop_margin_dsp_m: the same in double support, m.
        friction_safety: share of the scenario's friction coefficient the controller may use, in (0, 1].
        ff_dt_s: time step of the finite difference that gives the references' feed-forward acceleration, s.
        torque_margin: share of each actuator's saturation limit the controller may command, in (0, 1].
        landing_search_mps: downward speed of a late swing foot looking for the ground, m/s.
        landing_depth_m: how far below the ground the swing foot's reference may search, m.
        heel_lift_rad: heel lift (foot pitch about the toe joint) of the trailing foot at toe-off, rad.
        heel_lift_time_s: duration of the heel lift ramp, s.
        heel_return_time_s: duration of the ramp that lays the swing foot flat again, s.
        swing_ramp_s: duration of the swing task's weight ramp after lift-off, s.
        w_unload: weight that unloads the foot about to lift off in double support (-).
        time_shift: follow the plan on a clock delayed by the touchdowns' lateness (true) or on the nominal clock.
        lazy_torque_limits: add the actuator-limit rows to the QP only when its optimum without them breaks a limit
            (the same optimum, fewer rows).
        feedback: the horizontal balance feedback: ``dcm`` (capture-point feedback on the whole-body CoM, toward the
            plan's DCM, with step adjustment when ``step_adjustment``) or ``pd`` (the Body-17 CoM's PD to the hip
            plan, ``hip_omega``).  A trajectory without a whole-body CoM plan (chapter 3's) uses ``pd``.
        dcm_gain: the DCM error's decay rate k of the ``dcm`` feedback, 1/s.
        step_adjustment: with ``feedback: dcm``, move the swing foot's landing by the DCM error predicted at
            touchdown (humanoid_sim.controllers.balance.steps).
        step_deadband_m: the predicted DCM error at touchdown that leaves the foothold where planned, m.
        step_forward_m: the largest forward move of a foothold (heading frame), m.
        step_backward_m: the largest backward move of a foothold, m (on sim3_zmp's 0.16 m steps, 0.25 m lands
            the foot 0.09 m behind the stance foot; the feet are 0.32 m apart sideways, so the legs do not meet).
        step_outward_m: the largest move of a foothold away from the stance foot, m.
        step_min_width_m: the smallest lateral distance between the toe points of the landing and the stance foot
            (no crossing step), m.
        step_timing: with ``step_adjustment``, land the swing foot earlier when the foothold the DCM asks for lies
            beyond the reach (the swing's path on a faster clock; humanoid_sim.controllers.balance.steps).
        step_min_time_s: the shortest remaining swing time step timing may leave, s.
        step_timing_after: the share of the swing (0-1) after which step timing may shorten it, -.
        step_max_jump_s: how far the plan's clock may move on at an early touchdown step timing made, s: within
            it and the time gained, the move that brings the plan's lateral DCM nearest the measured one (the rest,
            the plan waits).
        step_max_rate: the fastest the swing's path may run, times the plan's speed (>= 1).
        step_return_m: how far each step takes back of the footholds' earlier moves (toward the planned footholds),
            m: a walk knocked off its path walks back onto it (0: the rest of the walk keeps the moves).
        base_velocity: the base twist the controller acts on, on real ground (an engine without a weld model; on
            welds the observation's, exact): ``filtered`` (the sensed twist through a first-order low-pass filter of
            cut-off ``base_velocity_filter_hz``: humanoid_sim.controllers.balance.estimate) or ``measured`` (as
            sensed).
        base_velocity_filter_hz: that filter's cut-off, Hz.
        external_force: with ``feedback: dcm``, on real ground, estimate the horizontal force the model does not
            know (a slope, a steady push) from the feet's force sensors and the CoM's momentum, and lean the CoM
            against it (humanoid_sim.controllers.balance.force).
        external_force_filter_hz: that estimate's cut-off, Hz.
        lean_max_m: the largest lean of the CoM against that force, m (also what tells a push from a slope: an
            estimate beyond lean_max_m m omega^2 is taken for a push, whose impulse the estimate drops).
        footholds: on real ground, find the part of a flat stance foot's sole the ground supports (from its turn and
            its sensed CoP) and keep the CoP there (humanoid_sim.controllers.balance.foothold).
        foothold_tilt_rad: the turn of a stance foot from its anchor, about a sole axis, that reveals a partial
            foothold, rad.
        foothold_cut_margin_m: how far inside a cut the CoP stays, m.
        foothold_min_width_m: the least width a cut leaves on either side of it, m.
        foothold_toe_bent_rad: the toe-joint angle at anchoring beyond which a foot's toe box carries no load, rad.
        foothold_settle_s: how long after a stance starts its turn from the anchor is not read for cuts (a landing
            foot settling flat onto the ground), s.
        flat_trail: on real ground, hold a trailing foot whose last stance stood on a partial foothold (its toe bent
            on something, or its sole cut) flat on its heel box through the double support (no toe-off), instead
            of by its toe.
        flat_lead_in: on real ground, hold the standing lead-in's trailing foot flat on its heel box until its
            toe-off (the last ``heel_lift_time_s``), instead of by its toe from the start (docs/controllers.md).
    """

    hip_omega: float = 12.0
    trunk_omega: float = 15.0
    swing_omega: float = 25.0
    posture_omega: float = 8.0
    w_hip: float = 100.0
    w_trunk: float = 30.0
    w_swing: float = 100.0
    w_posture: float = 0.05
    w_upper: float = 1.0
    w_acc: float = 1e-4
    w_force: float = 1e-6
    w_torque: float = 1e-5
    cop_margin_ssp_m: float = 0.015
    cop_margin_dsp_m: float = 0.010
    friction_safety: float = 0.3
    ff_dt_s: float = 1e-3
    torque_margin: float = 0.98
    landing_search_mps: float = 0.05
    landing_depth_m: float = 0.004
    heel_lift_rad: float = 0.12
    heel_lift_time_s: float = 0.3
    heel_return_time_s: float = 0.2
    swing_ramp_s: float = 0.05
    w_unload: float = 0.001
    time_shift: bool = True
    lazy_torque_limits: bool = True
    feedback: str = "dcm"
    dcm_gain: float = 20.0
    step_adjustment: bool = True
    step_deadband_m: float = 0.02
    step_forward_m: float = 0.2
    step_backward_m: float = 0.25
    step_outward_m: float = 0.15
    step_min_width_m: float = 0.12
    step_timing: bool = True
    step_min_time_s: float = 0.2
    step_timing_after: float = 0.0
    step_max_jump_s: float = 0.3
    step_max_rate: float = 2.5
    step_return_m: float = 0.05
    base_velocity: str = "filtered"
    base_velocity_filter_hz: float = 30.0
    external_force: bool = True
    external_force_filter_hz: float = 0.5
    lean_max_m: float = 0.08
    footholds: bool = True
    foothold_tilt_rad: float = 0.026
    foothold_cut_margin_m: float = 0.005
    foothold_min_width_m: float = 0.015
    foothold_toe_bent_rad: float = 0.05
    foothold_settle_s: float = 0.01
    flat_trail: bool = True
    flat_lead_in: bool = True

    def __post_init__(self) -> None:
        if self.feedback not in FEEDBACKS:
            raise InputError(f"BalanceSettings.feedback = {self.feedback!r}: expected one of {', '.join(FEEDBACKS)}")
        if self.base_velocity not in BASE_VELOCITIES:
            raise InputError(f"BalanceSettings.base_velocity = {self.base_velocity!r}: expected one of "
                             f"{', '.join(BASE_VELOCITIES)}")
        for f in fields(self):
            x = getattr(self, f.name)
            if f.name in _CHOICES:
                continue
            if f.name in _FLAGS:
                if not isinstance(x, bool):
                    raise InputError(f"BalanceSettings.{f.name} = {x!r}: expected true or false")
                continue
            ok = isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            nonneg = f.name.startswith(("w_", "cop_", "step_")) or f.name in ("landing_depth_m", "heel_lift_rad",
                                                                               "foothold_settle_s")
            lo_ok = x >= 0 if nonneg else x > 0
            if f.name == "step_max_rate" and ok and x < 1.0:
                raise InputError(f"BalanceSettings.step_max_rate = {x!r}: expected a finite number >= 1 (the "
                                 "swing's path never runs slower than the plan)")
            if not (ok and lo_ok) or (f.name in ("friction_safety", "torque_margin") and x > 1.0):
                raise InputError(f"BalanceSettings.{f.name} = {x!r}: expected a finite number "
                                 f"{'>= 0' if nonneg else '> 0'}"
                                 f"{' and <= 1' if f.name in ('friction_safety', 'torque_margin') else ''}")


def parse_balance(src: str, raw: object) -> BalanceSettings:
    """The ``balance`` section of a scenario file as :class:`BalanceSettings`.

    Args:
        src: the file's name, for messages.
        raw: the section as read from YAML (a mapping, or None for the defaults).

    Raises:
        ScenarioError: not a mapping, an unknown key (the closest valid name is suggested), or a value out of range.
    """
    import difflib

    if raw is None:
        return BalanceSettings()
    if not isinstance(raw, dict):
        raise ScenarioError(f"{src}: balance: expected a mapping of settings, got {type(raw).__name__}")
    names = [f.name for f in fields(BalanceSettings)]
    for k in raw:
        if k not in names:
            close = difflib.get_close_matches(str(k), names, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ScenarioError(f"{src}: balance.{k}: unknown setting{hint}; expected one of {', '.join(names)}")
    values: dict[str, Any] = {k: (float(v) if isinstance(v, int) and not isinstance(v, bool) and k not in _FLAGS
                                  else v) for k, v in raw.items()}
    try:
        return BalanceSettings(**values)
    except InputError as exc:
        raise ScenarioError(f"{src}: balance.{str(exc).removeprefix('BalanceSettings.')}") from None


__all__ = ["BASE_VELOCITIES", "FEEDBACKS", "BalanceSettings", "parse_balance"]
