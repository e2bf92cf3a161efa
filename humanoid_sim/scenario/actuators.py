"""The ``actuators:`` section of a scenario: a motor and gearbox per joint, from a catalogue.

Without the section every joint is the thesis's torque source, clipped at its saturation limit (and every walk is
what it was).  With it, each joint named gets a :class:`humanoid_sim.robot.motors.MotorSpec` from the catalogue
(default: the shipped ``models/actuators.yaml``, every number with its source)::

    actuators:
      catalogue: my_motors.yaml      # optional, relative to the scenario file
      joints:
        all: osl_knee                # every joint ...
        ankle: osl_knee              # ... both ankles (a joint group without its side) ...
        right_knee: osl_knee         # ... one joint group (humanoid_sim.robot.actuators.GROUPS) ...
        theta11: mini_cheetah_knee   # ... one thesis joint variable; the most specific key wins
        neck: null                   # no motor: the thesis's torque source
      gear_ratio: {hip: 80, theta3: 12}   # optional: another gearbox for these joints' motors (same keys)
      rotor_inertia: true            # optional: false leaves the rotors' inertia out of the dynamics (a what-if)

What a motor changes (:mod:`humanoid_sim.sim.drive`): its reflected rotor inertia N^2 J_r joins the joint's inertia
in every engine and in the controllers' models; the joint torque it can give at the joint's speed (its torque-speed
envelope: current limit and back-EMF against the bus voltage, less its friction) bounds what the controller asks,
and the run reports where it did not suffice; the sizing card gives its current, electrical power and winding
temperature over the walk.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from humanoid_sim.robot.actuators import GROUPS
from humanoid_sim.robot.model import THETA_NAMES
from humanoid_sim.robot.motors import CATALOGUE, MotorSpec, load_catalogue
from humanoid_sim.scenario.fields import ScenarioError

KEYS = ("catalogue", "joints", "gear_ratio", "rotor_inertia")
"""The section's keys."""


def _sideless() -> dict[str, list[str]]:
    """Joint group names without their side (``knee`` -> right_knee, left_knee) -> the groups."""
    out: dict[str, list[str]] = {}
    for g in GROUPS:
        for side in ("right_", "left_"):
            if g.name.startswith(side):
                out.setdefault(g.name.removeprefix(side), []).append(g.name)
    return out


@dataclass(frozen=True)
class ActuatorChoice:
    """The motor of each thesis joint variable that has one.

    Attributes:
        motors: thesis joint variable (``theta11``) -> its motor (catalogue name in ``MotorSpec.name``).
        catalogue: the catalogue file the motors come from.
        rotor_inertia: whether the rotors' reflected inertia joins the dynamics (False: the same motors' envelopes
            and electrical model on the rigid bodies alone, to see what the rotors change).
        gear_ratios: the joints whose gearbox the section changed -> their gear ratio N (already in ``motors``).
    """

    motors: dict[str, MotorSpec]
    catalogue: str
    rotor_inertia: bool = True
    gear_ratios: dict[str, float] = field(default_factory=dict)

    def armature(self) -> np.ndarray:
        """Reflected rotor inertia N^2 J_r per thesis joint variable (26,, eq. 4.1 order), kg m^2; 0 without motor
        (all 0 when :attr:`rotor_inertia` is False)."""
        return np.array([self.motors[th].reflected_inertia if th in self.motors and self.rotor_inertia else 0.0
                         for th in THETA_NAMES])

    def describe(self) -> dict[str, Any]:
        """For summary.json: the catalogue, each joint's motor name, and whether the rotors' inertia is in."""
        out = {"catalogue": self.catalogue, "rotor_inertia": self.rotor_inertia,
               "joints": {th: spec.name for th, spec in self.motors.items()}}
        if self.gear_ratios:
            out["gear_ratio"] = dict(self.gear_ratios)
        return out


def _per_joint(src: str, where: str, mapping: dict) -> dict[str, Any]:
    """Resolve a mapping of joint keys (``all``, a joint group with or without its side, a thesis joint variable) to
    values per thesis joint variable; the most specific key wins."""
    sideless, groups = _sideless(), {g.name: g for g in GROUPS}
    rank: dict[str, tuple[int, Any]] = {}   # theta -> (specificity, value)
    for key, value in mapping.items():
        if key == "all":
            level, thetas = 0, list(THETA_NAMES)
        elif key in sideless:
            level, thetas = 1, [th for g in sideless[key] for th in groups[g].thetas]
        elif key in groups:
            level, thetas = 2, list(groups[key].thetas)
        elif key in THETA_NAMES:
            level, thetas = 3, [key]
        else:
            names = ["all", *sideless, *groups, *THETA_NAMES]
            close = difflib.get_close_matches(str(key), names, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ScenarioError(f"{src}: {where}.{key}: not a joint{hint}; expected all, "
                                f"{', '.join(sideless)}, a joint group ({', '.join(groups)}) or a thesis joint "
                                "variable (theta3 ... theta27)")
        for th in thetas:
            if th not in rank or rank[th][0] <= level:
                rank[th] = (level, value)
    return {th: rank[th][1] for th in THETA_NAMES if th in rank}


def parse_actuators(src: str, raw: object, folder: Path | None = None) -> ActuatorChoice | None:
    """The ``actuators`` section (module docstring) as an :class:`ActuatorChoice`, or None when absent.

    Args:
        src: the file's name, for messages.
        raw: the section as read from YAML.
        folder: the scenario file's folder (a relative ``catalogue`` is read from there).

    Raises:
        ScenarioError: the message names the field, the value and what was expected.
    """
    if raw is None:
        return None
    if not isinstance(raw, dict):
        raise ScenarioError(f"{src}: actuators: expected a mapping with joints (and optionally catalogue, "
                            f"rotor_inertia), got {raw!r}")
    for k in raw:
        if k not in KEYS:
            close = difflib.get_close_matches(str(k), KEYS, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ScenarioError(f"{src}: actuators.{k}: unknown key{hint}; expected {' or '.join(KEYS)}")
    path = CATALOGUE
    if raw.get("catalogue") is not None:
        if not isinstance(raw["catalogue"], str):
            raise ScenarioError(f"{src}: actuators.catalogue = {raw['catalogue']!r}: expected the path of a YAML file")
        path = Path(raw["catalogue"])
        if not path.is_absolute() and folder is not None:
            path = folder / path
    try:
        catalogue = load_catalogue(path)
    except Exception as exc:  # the catalogue's own message names the field; prefix where it was asked for
        raise ScenarioError(f"{src}: actuators.catalogue: {exc}") from exc
    joints = raw.get("joints")
    if not isinstance(joints, dict) or not joints:
        raise ScenarioError(f"{src}: actuators.joints = {joints!r}: expected a mapping of joints (all, a joint group "
                            "with or without its side, or a thesis joint variable) to catalogue names or null")
    for key, name in joints.items():
        if name is not None and (not isinstance(name, str) or name not in catalogue):
            close = difflib.get_close_matches(str(name), list(catalogue), n=1)
            raise ScenarioError(f"{src}: actuators.joints.{key} = {name!r}: not in the catalogue {str(path)!r}"
                                f"{f' (did you mean {close[0]!r}?)' if close else ''}; expected one of "
                                f"{', '.join(catalogue)} or null")
    chosen = _per_joint(src, "actuators.joints", joints)
    motors = {th: catalogue[name] for th, name in chosen.items() if name is not None}
    ratios, changed = raw.get("gear_ratio"), {}
    if ratios is not None:
        if not isinstance(ratios, dict) or not ratios:
            raise ScenarioError(f"{src}: actuators.gear_ratio = {ratios!r}: expected a mapping of joints (as in "
                                "actuators.joints) to gear ratios")
        for key, n in ratios.items():
            if isinstance(n, bool) or not isinstance(n, (int, float)) or not 1.0 <= n <= 1000.0:
                raise ScenarioError(f"{src}: actuators.gear_ratio.{key} = {n!r}: expected a gear ratio N in "
                                    "[1, 1000] (motor speed / joint speed)")
        for th, n in _per_joint(src, "actuators.gear_ratio", ratios).items():
            if th not in motors:
                raise ScenarioError(f"{src}: actuators.gear_ratio: {th} has no motor (actuators.joints); expected "
                                    "gear ratios for joints with a motor only")
            motors[th] = replace(motors[th], gear_ratio=float(n))
            changed[th] = float(n)
    rotor = raw.get("rotor_inertia", True)
    if not isinstance(rotor, bool):
        raise ScenarioError(f"{src}: actuators.rotor_inertia = {rotor!r}: expected true or false")
    return ActuatorChoice({th: motors[th] for th in THETA_NAMES if th in motors}, str(path), rotor, changed)


__all__ = ["ActuatorChoice", "KEYS", "parse_actuators"]
