"""A scenario's ``disturbances`` between the engine and the controller: sensing noise, actuation delay, and which
engines take pushes and terrain (:mod:`humanoid_sim.scenario.disturbances`).

:class:`Sensed` wraps the controller as the loop calls it (:func:`humanoid_sim.sim.loop.run`): it changes only what
the controller sees and when its command lands, the same way on every engine.

- Noise: at every controller call a fresh draw of white Gaussian noise (one generator, seeded with ``seed``: a
  run is reproducible) is added to the observation's base linear velocity ``v[:3]`` (m/s), base angular velocity
  ``v[3:6]`` (rad/s; both in the base frame, Pinocchio's convention: the noise is isotropic, so the frame does not
  change its law), joint angles ``q[7:]`` (rad) and joint rates ``v[6:]`` (rad/s).  The engine keeps the true state.
- Delay: the command applied at t is the one the controller computed at t - d, with d = ``delay_s`` rounded to the
  nearest whole number of control periods (the engine's control period; the loop step ``h`` for a feedthrough
  controller, which the weld and oracle engines call at every integration stage: the stage at the same place of
  the step d earlier).  Until t reaches d the first command is applied: the robot starts at rest in the posture the
  controller holds, as if it had been running before t = 0.  A FIFO of (time, command).
- A command computed from a noisy or a past state no longer carries the motion or the by-products the controller
  solved with it (``Command.motion``, ``Command.extra``): the engine integrates its torques under its own dynamics.

Pushes and terrain need real ground: a weld engine holds a welded foot against any force and has no ground to
shape, so :func:`check_engine` refuses them there (an :class:`~humanoid_sim.errors.InputError`, exit 2 before
anything is written).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import pinocchio as pin

from humanoid_sim.errors import InputError
from humanoid_sim.interfaces.controller import Command, Observation
from humanoid_sim.scenario.disturbances import Sensing

REAL_GROUND_ENGINES = ("mujoco",)
"""Engines that take pushes and terrain."""


def check_engine(scenario: Any, engine: str) -> None:
    """Refuse a scenario's pushes and terrain on an engine without real ground.

    Raises:
        InputError: naming the section and the engines that take it.
    """
    dist = scenario.disturbances
    if dist is not None and dist.incline is not None and engine == "thesis":
        raise InputError("disturbances.incline: the thesis engine's equations (the NumPy oracle) take gravity from "
                         "the body table; expected --engine pinocchio or mujoco for an inclined ground")
    if dist is None or engine in REAL_GROUND_ENGINES:
        return
    for key, what in (("terrain", "terrain boxes"), ("pushes", "pushes")):
        if getattr(dist, key):
            raise InputError(f"disturbances.{key}: the {engine!r} engine welds the feet to the ground plane, so it "
                             f"has no {what} (a welded foot holds against any push, and there is no ground to "
                             f"shape); expected --engine {' or '.join(REAL_GROUND_ENGINES)} for this scenario, or "
                             f"no disturbances.{key}")


def control_period(engine: Any, h: float) -> float:
    """The period at which ``engine`` calls the controller, s: its control period (the weld engine's
    ``control_period_s``, the MuJoCo engine's ``settings.control_period_s``), else the loop step ``h``."""
    p = getattr(engine, "control_period_s", None)
    if p is None:
        p = getattr(getattr(engine, "settings", None), "control_period_s", None)
    return float(p) if p else float(h)


class Sensed:
    """The controller seen through noisy sensors, its commands landing late (module docstring).

    Args:
        inner: the controller as the loop calls it (checked).
        sensing: the noise and delay settings.
        period: the engine's control period, s (:func:`control_period`).
    """

    def __init__(self, inner: Callable[[Observation], Command], sensing: Sensing, period: float) -> None:
        self.inner = inner
        self.sensing = sensing
        self.period = period
        self.rng = np.random.default_rng(sensing.seed)
        self.periods = int(round(sensing.delay_s / period))
        self.delay = self.periods * period            # s, the delay applied
        self.eps = 1e-9 * max(1.0, self.delay)        # s: times t + i h accumulate round-off far below this
        self.queue: deque[tuple[float, Command]] = deque()
        self.calls = 0
        s = sensing
        self._std = [(v, i, sd) for v, i, sd in ((True, slice(0, 3), s.base_linear_velocity_mps),
                                                  (True, slice(3, 6), s.base_angular_velocity_radps),
                                                  (False, slice(7, None), s.joint_position_rad),
                                                  (True, slice(6, None), s.joint_velocity_radps)) if sd > 0.0]
        # the feet's force-torque sensors (Observation.foot_wrenches): each force and moment component
        self._wrench_std = [(c, sd) for c, sd in ((slice(0, 3), s.foot_force_N), (slice(3, 6), s.foot_moment_Nm))
                            if sd > 0.0]

    def observe(self, obs: Observation) -> Observation:
        """``obs`` with the sensing noise added (new arrays; the engine's state is untouched)."""
        if not self._std and not self._wrench_std:
            return obs
        q, v = obs.q.copy(), obs.v.copy()
        for is_v, rows, sd in self._std:
            x = v if is_v else q
            x[rows] += self.rng.normal(0.0, sd, x[rows].shape)
        w = obs.foot_wrenches
        if w is not None and self._wrench_std:
            w = w.copy()
            for cols, sd in self._wrench_std:
                w[:, cols] += self.rng.normal(0.0, sd, w[:, cols].shape)
        return replace(obs, q=q, v=v, foot_wrenches=w)

    def __call__(self, obs: Observation) -> Command:
        self.calls += 1
        cmd = self.inner(self.observe(obs))
        cmd = replace(cmd, motion=None, motion_model=None, extra=None)
        if self.periods == 0:
            return cmd
        queue = self.queue
        queue.append((obs.t, cmd))
        due = obs.t - self.delay + self.eps
        while len(queue) > 1 and queue[1][0] <= due:
            queue.popleft()
        return replace(queue[0][1])   # a copy: an engine fills a command's tau in place

    def report(self) -> dict[str, Any]:
        """For summary.json: the settings, the delay applied (s, and in control periods) and the controller calls
        that saw the noise."""
        s = self.sensing
        return {"base_linear_velocity_mps": s.base_linear_velocity_mps,
                "base_angular_velocity_radps": s.base_angular_velocity_radps,
                "joint_position_rad": s.joint_position_rad, "joint_velocity_radps": s.joint_velocity_radps,
                "foot_force_N": s.foot_force_N, "foot_moment_Nm": s.foot_moment_Nm,
                "seed": s.seed, "delay_s": s.delay_s, "delay_applied_s": self.delay, "delay_periods": self.periods,
                "control_period_s": self.period, "controller_calls": self.calls}


class Unsolved:
    """The controller's commands without the motion it solved on its own model: an engine whose robot differs
    (``disturbances.model``) integrates the torques under its own dynamics."""

    def __init__(self, inner: Callable[[Observation], Command]) -> None:
        self.inner = inner

    def __call__(self, obs: Observation) -> Command:
        return replace(self.inner(obs), motion=None, motion_model=None, extra=None)


def sensed(scenario: Any, control: Callable[[Observation], Command], engine: Any,
           h: float) -> Callable[[Observation], Command]:
    """``control`` seen through the scenario's sensing (:class:`Sensed`; :class:`Unsolved` when only the engine's
    model differs), or ``control`` itself without either."""
    dist = scenario.disturbances
    if dist is None or (dist.sensing is None and dist.model is None and dist.incline is None):
        return control
    if dist.sensing is None:
        return Unsolved(control)
    return Sensed(control, dist.sensing, control_period(engine, h))


def engine_world(hm: Any, scenario: Any) -> tuple[Any, Any]:
    """The robot model and the scenario the engine runs: ``(hm, scenario)`` themselves, or with
    ``disturbances.model`` the scenario robot's variant with its masses scaled and the payload added (the motors'
    rotor inertia as in ``hm``) and the scenario with the engine's ground friction.

    Raises:
        InputError: a payload both in ``robot`` and in ``disturbances.model``.
    """
    dist = scenario.disturbances
    if dist is None or (dist.model is None and dist.incline is None):
        return hm, scenario
    if dist.model is None:
        return _inclined(hm, scenario), scenario
    from humanoid_sim.robot.variant import RobotVariant, variant_model
    from humanoid_sim.sim.drive import with_motors

    model = dist.model
    body = scenario.robot if scenario.robot is not None else RobotVariant()
    if model.payload is not None and body.payload is not None and body.payload.mass_kg > 0.0:
        raise InputError("disturbances.model.payload: the scenario's robot already carries a payload "
                         "(robot.payload); expected the engine's extra mass in one of them")
    scales = dict(body.mass_scale)
    for key, f in model.mass_scale:
        scales[key] = scales.get(key, 1.0) * f
    variant = replace(body, mass_scale=tuple(sorted(scales.items())),
                      payload=model.payload if model.payload is not None else body.payload)
    hm_engine = variant_model(variant)
    if scenario.actuators is not None:
        hm_engine = with_motors(hm_engine, scenario.actuators)
    sc = scenario
    if model.friction is not None:
        sc = replace(scenario, contact=replace(scenario.contact, friction_coefficient=model.friction))
    return _inclined(hm_engine, scenario), sc


def _inclined(hm: Any, scenario: Any) -> Any:
    """``hm``, or with ``disturbances.incline`` a copy whose gravity is turned toward the downhill direction."""
    incline = scenario.disturbances.incline
    if incline is None:
        return hm
    R = np.asarray(scenario.path.foot_R0, dtype=float)
    heading = math.atan2(R[1, 0], R[0, 0])   # the right toe body's x axis points forward at the start
    model = hm.model.copy()
    model.gravity = pin.Motion(np.concatenate([incline.gravity(float(hm.spec.gravity), heading), np.zeros(3)]))
    return replace(hm, model=model, data=model.createData())


def summary_entry(extra: dict[str, Any], control: Any, scenario: Any = None, engine: Any = None) -> dict[str, Any]:
    """summary.json's ``disturbances`` entry: the engine's ``pushes`` and ``terrain`` (taken out of ``extra``, its
    ``run_info``; [] when it applied none), the sensing report (None without sensing), and with
    ``disturbances.model`` the engine's model (its robot's mass in kg, Pinocchio's sum, and the friction)."""
    out = {"pushes": extra.pop("pushes", []), "terrain": extra.pop("terrain", []),
           "sensing": control.report() if isinstance(control, Sensed) else None}
    dist = None if scenario is None else scenario.disturbances
    model = None if dist is None else dist.model
    if dist is not None and dist.incline is not None:
        hm = getattr(engine, "hm", None)
        out["incline"] = {"angle_deg": dist.incline.angle_deg, "direction": dist.incline.direction,
                          "gravity_mps2": None if hm is None else hm.model.gravity.linear.tolist()}
    if model is not None:
        hm = getattr(engine, "hm", None)
        out["model"] = {**model.describe(),
                        "engine_mass_kg": None if hm is None else float(sum(i.mass for i in hm.model.inertias))}
    return out


__all__ = ["REAL_GROUND_ENGINES", "Sensed", "Unsolved", "check_engine", "control_period", "engine_world", "sensed",
           "summary_entry"]
