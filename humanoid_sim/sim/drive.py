"""The scenario's motors between the controller and the engine (:mod:`humanoid_sim.scenario.actuators`).

Two effects, both absent without an ``actuators:`` section:

- **Rotor inertia.**  :func:`with_motors` gives the robot model whose ``armature`` holds each motored joint's
  reflected rotor inertia N^2 J_r.  The engines integrate with it (Pinocchio's CRBA, RNEA and ABA include
  ``model.armature``; the MuJoCo engine copies it into ``dof_armature``) and the controllers plan with it, so a
  controller knows the inertia its motors add.
- **The torque-speed envelope.**  :class:`Drive` clips each motored joint's torque to what its motor gives at the
  joint's current speed (:func:`humanoid_sim.robot.motors.torque_envelope`: current limit, back-EMF against the bus
  voltage, less the drive's friction) and records where it had to: which joint, when, by how much.  The drive gives
  at most the torque asked and never reverses it: beyond its no-load speed a motor could only brake
  (regeneration through the bridge, an overspeed the sizing card flags as a negative speed margin), and that
  braking torque, stiff in the speed, would make the held commands of a 2 ms control period explode; the drive then
  gives zero.

Friction is the motor's load, not the joint's: a torque-controlled drive supplies the commanded joint torque plus
its gearbox's friction, so friction shows in the motor's current, heat and envelope (the joint gets less than the
motor's stall torque), not in the joint's dynamics.  Why: an explicit Coulomb friction torque in the weld engine's
10 ms feedthrough steps is stiff on light joints (0.2 N m over 0.01 rad/s on the 1.3e-4 kg m^2 toe body).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from humanoid_sim.interfaces.controller import Command, Observation
from humanoid_sim.robot.actuators import Actuators
from humanoid_sim.robot.model import THETA_NAMES, HumanoidModel
from humanoid_sim.robot.motors import torque_envelope
from humanoid_sim.scenario.actuators import ActuatorChoice


def with_motors(hm: HumanoidModel, choice: ActuatorChoice) -> HumanoidModel:
    """A copy of the robot model whose ``armature`` holds the motors' reflected rotor inertias (kg m^2, v order)."""
    model = hm.model.copy()
    armature = np.array(model.armature, dtype=float)
    armature[np.asarray(hm.theta_v_idx)] += choice.armature()
    model.armature = armature
    return replace(hm, model=model, data=model.createData())


@dataclass
class Shortfall:
    """Where one joint's motor could not give the torque asked (times of the controller calls that were clipped)."""

    joint: str
    motor: str
    calls: int = 0
    first_s: float = float("nan")
    last_s: float = float("nan")
    worst_Nm: float = 0.0
    worst_s: float = float("nan")
    worst_asked_Nm: float = float("nan")
    worst_speed_rad_s: float = float("nan")

    def as_dict(self) -> dict[str, Any]:
        return {"joint": self.joint, "motor": self.motor, "clipped_calls": self.calls, "first_s": float(self.first_s),
                "last_s": float(self.last_s), "worst_shortfall_Nm": float(self.worst_Nm),
                "worst_at_s": float(self.worst_s), "torque_asked_Nm": float(self.worst_asked_Nm),
                "speed_rad_s": float(self.worst_speed_rad_s)}


@dataclass
class Drive:
    """The motors' envelopes applied to a controller's commands (module docstring).

    Args:
        hm: the robot model (with the motors' armature).
        choice: the scenario's motors.
    """

    hm: HumanoidModel
    choice: ActuatorChoice
    shortfalls: dict[str, Shortfall] = field(default_factory=dict)
    calls: int = 0

    def __post_init__(self) -> None:
        thetas = [th for th in THETA_NAMES if th in self.choice.motors]
        pos = [THETA_NAMES.index(th) for th in thetas]
        self._thetas = thetas
        self._v = np.asarray(self.hm.theta_v_idx)[pos]
        self._sign = np.asarray(self.hm.theta_sign, dtype=float)[pos]
        self._specs = [self.choice.motors[th] for th in thetas]
        groups: dict[str, list[int]] = {}   # joints sharing a motor: one vectorised envelope per motor
        for i, spec in enumerate(self._specs):
            groups.setdefault(spec.name, []).append(i)
        self._groups = [(self._specs[idx[0]], np.array(idx)) for idx in groups.values()]
        self._act = Actuators(self.hm)

    def __call__(self, cmd: Command, obs: Observation) -> Command:
        """The command with each motored joint's torque inside its envelope at the observed speed; the command itself
        when nothing was clipped (then it is unchanged, with its own motion and thesis torques)."""
        self.calls += 1
        tau = cmd.tau
        if tau is None:   # thesis torques only: the generalized torques they map to (as the engines do)
            tau = self._act.torque_map(obs.q) @ cmd.T
            tau[:6] = 0.0
        asked = self._sign * tau[self._v]
        omega = self._sign * np.asarray(obs.v)[self._v]
        got = asked.copy()
        for spec, idx in self._groups:   # at the reference winding resistance (no thermal state during the run)
            env = torque_envelope(spec, omega[idx])
            # never more than asked, never reversed: beyond the no-load speed the envelope is a braking torque only
            # (uncontrolled regeneration through the bridge); applying it at the control rate is stiff and explosive
            got[idx] = np.clip(asked[idx], np.minimum(env.tau_min, 0.0), np.maximum(env.tau_max, 0.0))
        clipped = got != asked
        if not clipped.any():
            return cmd
        for i in np.flatnonzero(clipped):
            th = self._thetas[i]
            s = self.shortfalls.setdefault(th, Shortfall(th, self._specs[i].name))
            gap = abs(asked[i] - got[i])
            s.calls += 1
            s.first_s = obs.t if s.calls == 1 else s.first_s
            s.last_s = obs.t
            if gap > s.worst_Nm:
                s.worst_Nm, s.worst_s, s.worst_asked_Nm, s.worst_speed_rad_s = gap, obs.t, asked[i], omega[i]
        new = np.array(tau, dtype=float)
        new[self._v] = self._sign * got
        # the controller's own motion and thesis torques no longer hold: the engine solves and derives them again
        return Command(tau=new, T_cmd=cmd.T_cmd if cmd.T_cmd is not None else cmd.T,
                       theta_ddot_cmd=cmd.theta_ddot_cmd)

    def report(self) -> dict[str, Any]:
        """For summary.json: the motors, and per joint where its motor fell short (empty when it never did)."""
        return {**self.choice.describe(), "controller_calls": self.calls,
                "envelope_shortfalls": [s.as_dict() for s in self.shortfalls.values()]}


__all__ = ["Drive", "Shortfall", "with_motors"]
