"""The ``robot:`` section of a scenario: the body itself as a design variable.

Without the section the walk runs on the thesis robot (``models/thesis_humanoid.urdf``), bit for bit.  With it, the
body table is changed as :mod:`humanoid_sim.robot.variant` describes and every part of the walk (Pinocchio, MuJoCo,
the gait plan, the controllers, the compiled kernels, the sizing card) runs on the generated model::

    robot:
      length_scale: {shank: 1.1, thigh: 1.0}   # segments: foot, shank, thigh, trunk, arms, head (-)
      mass_scale: {all: 1.0, trunk: 0.9}       # all, a segment, toe, lower_trunk, upper_trunk or a body name (-)
      sole: {length_m: 0.24, width_m: 0.10}    # m (the heel moves, the toe tip stays)
      payload: {mass_kg: 5, body: upper_trunk, position_m: [0.05, 0, -0.15]}   # kg; m, body frame from O_k
      hip_height: follow_legs                  # or: path
      actuators: {joints: {all: osl_knee}}     # the actuators: section (humanoid_sim.scenario.actuators)

``hip_height``: with ``follow_legs`` (the default) every hip waypoint of the path (``path.Phip``, the lower trunk's
CoM) moves up by what longer legs (shank, thigh) and a longer trunk add below that point
(:meth:`~humanoid_sim.robot.variant.RobotVariant.hip_height_change`), so the walk keeps the thesis robot's knee bend;
``path`` keeps the path's heights as written (shorter legs then bend more, longer legs straighten towards the
singular stretched knee, and legs 10 % shorter cannot reach sim 3's hip height at all).

A length factor lies in [0.5, 2] and a mass factor in [0.1, 10]: beyond them the thesis's shapes and its walk
(the hip height of the path) stop meaning anything.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from humanoid_sim.robot.variant import (
    MASS_GROUPS,
    PAYLOAD_BODIES,
    SEGMENTS,
    Payload,
    RobotVariant,
    VariantError,
    check_sole_length,
)
from humanoid_sim.scenario.fields import Num, ScenarioError, check_keys, mapping_of, number, show, vector

KEYS = ("length_scale", "mass_scale", "sole", "payload", "hip_height", "actuators")
"""The section's keys."""

HIP_HEIGHT = ("follow_legs", "path")
"""How the path's hip height follows the legs (module docstring)."""
LENGTH = Num("a length factor", 0.5, 2.0)
MASS = Num("a mass factor", 0.1, 10.0)
BODY_NAMES = ("right_toe", "left_toe", "right_foot", "left_foot", "right_shank", "left_shank", "right_thigh",
              "left_thigh", "lower_trunk", "upper_trunk", "right_arm", "left_arm", "head")
"""The real bodies of the body table (a mass-scale key)."""


def _factors(src: str, where: str, raw: Any, allowed: tuple[str, ...], rng: Num) -> tuple[tuple[str, float], ...]:
    d = mapping_of(src, where, raw)
    check_keys(src, where, d, allowed)
    return tuple(sorted((str(k), number(src, f"{where}.{k}", v, rng)) for k, v in d.items()))


class RobotSection(NamedTuple):
    """The parsed section.

    Attributes:
        variant: the body's parameters.
        actuators: the section's ``actuators`` entry as written (for
            :func:`humanoid_sim.scenario.actuators.parse_actuators`), or None.
        hip_rise_m: how much higher the path's hip waypoints are put, m (0 with ``hip_height: path``).
    """

    variant: RobotVariant
    actuators: Any
    hip_rise_m: float


def parse_mass_scale(src: str, where: str, raw: Any) -> tuple[tuple[str, float], ...]:
    """A ``mass_scale`` mapping (``all``, a segment or a body -> factor in [0.1, 10]), sorted by key."""
    return _factors(src, where, raw, ("all", *MASS_GROUPS, *BODY_NAMES), MASS)


def parse_payload(src: str, where: str, raw: Any) -> Payload:
    """A ``payload`` mapping (``mass_kg``, ``body``, ``position_m``) as a :class:`Payload`.

    Raises:
        ScenarioError: naming ``where`` and the field.
    """
    p = mapping_of(src, where, raw)
    check_keys(src, where, p, ("mass_kg", "body", "position_m"))
    if "mass_kg" not in p:
        raise ScenarioError(f"{src}: {where}.mass_kg: missing; expected a mass in kg >= 0")
    mass = number(src, f"{where}.mass_kg", p["mass_kg"], Num("a mass in kg", 0.0, 100.0))
    body = p.get("body", "upper_trunk")
    if body not in PAYLOAD_BODIES:
        raise ScenarioError(f"{src}: {where}.body = {show(body)}: expected one of {', '.join(PAYLOAD_BODIES)}")
    pos = p.get("position_m")
    position = None if pos is None else tuple(vector(src, f"{where}.position_m", pos, 3,
                                                     Num("a coordinate in m", -1.0, 1.0), "coordinates in m"))
    return Payload(mass, str(body), position)  # type: ignore[arg-type]


def parse_robot(src: str, raw: Any) -> RobotSection | None:
    """The ``robot`` section (module docstring), or None when absent.

    Raises:
        ScenarioError: the message names the field, the value and what was expected.
    """
    if raw is None:
        return None
    d = mapping_of(src, "robot", raw)
    check_keys(src, "robot", d, KEYS)
    lengths = _factors(src, "robot.length_scale", d.get("length_scale", {}), tuple(SEGMENTS), LENGTH)
    masses = parse_mass_scale(src, "robot.mass_scale", d.get("mass_scale", {}))
    sole = mapping_of(src, "robot.sole", d.get("sole", {}))
    check_keys(src, "robot.sole", sole, ("length_m", "width_m"))
    length = (None if sole.get("length_m") is None
              else number(src, "robot.sole.length_m", sole["length_m"], Num("a sole length in m", 0.1, 0.5)))
    width = (None if sole.get("width_m") is None
             else number(src, "robot.sole.width_m", sole["width_m"], Num("a sole width in m", 0.03, 0.3)))
    payload = None if d.get("payload") is None else parse_payload(src, "robot.payload", d["payload"])
    variant = RobotVariant(length_scale=lengths, mass_scale=masses, sole_length_m=length, sole_width_m=width,
                           payload=payload)
    if length is not None:
        foot = dict(lengths).get("foot", 1.0)
        try:   # checked against the body table now, not when the walk starts
            check_sole_length(length, foot)
        except VariantError as exc:
            raise ScenarioError(f"{src}: robot.sole.{exc}") from None
    hip = d.get("hip_height", "follow_legs")
    if hip not in HIP_HEIGHT:
        raise ScenarioError(f"{src}: robot.hip_height = {show(hip)}: expected one of {', '.join(HIP_HEIGHT)}")
    return RobotSection(variant, d.get("actuators"), variant.hip_height_change() if hip == "follow_legs" else 0.0)


__all__ = ["HIP_HEIGHT", "KEYS", "RobotSection", "parse_mass_scale", "parse_payload", "parse_robot"]
