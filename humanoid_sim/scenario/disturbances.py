"""The ``disturbances:`` section of a scenario: a world that differs from the one the controller planned for.

Without the section every walk is what it was.  With it::

    disturbances:
      pushes:                          # external forces on a body, several per walk (MuJoCo only)
        - body: 17                     # thesis body number (its CoM), a URDF link (its CoM) or a model frame
          impulse_Ns: 11.0             # exactly one of impulse_Ns and force_N: a magnitude ...
          direction_deg: 90            # ... along an angle about z from the frame's x axis (or direction: [x, y, z])
          frame: heading               # world, or heading: x forward, y left, z up (the trunk's yaw at the start)
          start: {phase: 7, fraction: 0.5}   # or start: {time_s: 3.2}
          duration_s: 0.1
      terrain:                         # static boxes on the ground plane (MuJoCo only)
        - {kind: slope, centre: [0.0, 1.0], size: [0.6, 1.0], angle_deg: 3, direction: up}
        - {kind: bar, centre: [0.0, 1.9, 0.005], size: [1.0, 0.02, 0.01], yaw_deg: 0, friction: 0.6}
      sensing:                         # what the controller observes, and when its command lands (every engine)
        base_linear_velocity_mps: 0.02
        base_angular_velocity_radps: 0.02
        joint_position_rad: 0.0
        joint_velocity_radps: 0.0
        seed: 0
        delay_s: 0.02
      model:                           # the engine's robot and ground differ from the controller's model
        payload: {mass_kg: 20, body: upper_trunk}   # a mass the controller does not know of
        mass_scale: {all: 1.25}        # every mass (and inertia) 25 % above what the controller assumes
        friction: 0.5                  # the engine's ground (MuJoCo); the controller keeps contact's
      incline: {angle_deg: 3, direction: down}   # the whole ground inclined (every engine)

Pushes:

- ``body``: where the force acts, default ``17`` (the lower trunk, the pelvis): a thesis body number with a mass
  (the force acts at its centre of mass, frame ``Pc_<n>``), a URDF link name (at the link's centre of mass), or a
  frame of the model (``O_17``, ``P_tpR``: at that frame's origin, on the link that carries it; the engine adds the
  moment of the force about the link's centre of mass).  Names are checked against the robot when the walk is set
  up (the MuJoCo engine refuses an unknown one: :func:`humanoid_sim.engines.mujoco.disturb.push_point`, exit 2).
- ``force_N`` or ``impulse_Ns``: a vector [x, y, z] in ``frame`` (no direction then), or a magnitude > 0 with a
  direction.  An impulse J over ``duration_s`` d is the constant force J / d.
- ``direction``: a unit vector [x, y, z] in ``frame`` (norm within 1e-3 of 1, for values typed with a few digits;
  it is normalised), or ``direction_deg``: an angle in degrees about z from the frame's x axis (horizontal).
- ``frame``: ``world`` (thesis frame 0: x lateral right, y forward, z up) or ``heading`` (default): x forward,
  y left, z up, turned by the walk's yaw at the push's start: psi = atan2(R[1, 0], R[0, 0]) of the lower trunk's
  (Body 17's) rotation R, whose x axis points forward at the thesis's initial posture.
- ``start``: ``{time_s: t}``, or ``{phase: k, fraction: f}``: the k-th phase of the reference trajectory,
  numbered from 1 as summary.json's ``phase_log`` and the progress bar number them, at the fraction f in [0, 1] of
  its nominal window: t = t_start + f (t_end - t_start) on the nominal schedule (:func:`resolve_start`).  A walk
  whose phases run late meets the push at that nominal time all the same.
- ``duration_s``: > 0.

Terrain (MuJoCo only; a weld engine refuses it): static boxes in the world with the ground plane's contact
parameters (:func:`humanoid_sim.engines.mujoco.model.build_model`) and ``friction`` (default: the scenario's
``contact.friction_coefficient``), which overrides the sole's on that patch.

- ``box``, ``step``, ``bar``, ``tile``: ``centre`` [x, y, z] (m, world), ``size`` [lx, ly, lz] (full lengths, m,
  along the box's axes), ``yaw_deg`` (about z from world x, default 0).  A 10 mm bar lying on the ground:
  ``centre: [x, y, 0.005]``, ``size: [1.0, 0.02, 0.01]``.
- ``slope``: a tilted slab whose top face rises by ``angle_deg`` (in (0, 45]) along the walk heading (``direction:
  up``), against it (``down``) or toward the walk's left (``sideways``); or given by its top face's ``normal``
  [x, y, z] (world, z > 0) instead.  ``centre`` [x, y] is its footprint's centre on the ground, ``size`` [length
  along the heading, width across it] (m), and its lowest top corner touches z = 0, so a foot walks onto it from
  the ground (a down slope thus starts with a step up of length * tan(angle): put a ``step`` or an up ``slope``
  before it).  The walk heading of a slope is the planned Body-17 yaw at t = 0.  ``thickness_m`` (default 0.1)
  only hides the slab's underside below the ground.

Sensing (every engine: between the engine and the controller, :mod:`humanoid_sim.sim.disturbances`): white Gaussian
noise of the given standard deviations on the base twist ``v[:3]`` (m/s) and ``v[3:6]`` (rad/s, both in the base
frame, Pinocchio's convention), the joint angles ``q[7:]`` (rad) and rates ``v[6:]`` (rad/s) the controller's
``Observation`` carries, a fresh draw at every controller call from a generator seeded with ``seed``; and an
actuation delay ``delay_s``, rounded to a whole number of the engine's control periods.

Model (every engine; :class:`humanoid_sim.sim.simulate.Simulator`): the engine runs a robot variant
(:mod:`humanoid_sim.robot.variant`) whose masses are the scenario robot's times ``mass_scale`` and which carries
``payload`` (not with a ``robot.payload`` too), on ground of ``friction``; the controller, the plan and the contact
audit keep the scenario's robot and friction.  Masses only: the kinematics, and so the start posture, are shared.

Incline: the whole ground inclined by ``angle_deg`` (in (0, 15]) ``up``, ``down`` or ``sideways`` (rising toward
the walk's left) along the walk's heading (the yaw of the right toe body at the start, ``path.foot_R0``), the
robot standing on it from the start.  The engine's gravity is turned by the angle toward the downhill direction
(ground and gravity in the engine's frame: the same physics as an inclined ground, and the ground plane stays
z = 0 for the contact code and the audit); the controller's model keeps the vertical gravity, so it does not know.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from humanoid_sim.robot.variant import Payload
from humanoid_sim.scenario.fields import Num, ScenarioError, check_keys, mapping_of, number, show, type_hint, vector
from humanoid_sim.scenario.robot import parse_mass_scale, parse_payload

KEYS = ("pushes", "terrain", "sensing", "model", "incline")
INCLINE_DIRECTIONS = ("up", "down", "sideways")
MODEL_KEYS = ("payload", "mass_scale", "friction")
PUSH_KEYS = ("body", "force_N", "impulse_Ns", "direction", "direction_deg", "frame", "start", "duration_s")
FRAMES = ("heading", "world")
BOX_KINDS = ("box", "step", "bar", "tile")
TERRAIN_KINDS = (*BOX_KINDS, "slope")
BOX_KEYS = ("kind", "centre", "size", "yaw_deg", "friction")
SLOPE_KEYS = ("kind", "centre", "size", "angle_deg", "direction", "normal", "thickness_m", "friction")
SLOPE_DIRECTIONS = ("up", "down", "sideways")
SENSING_KEYS = ("base_linear_velocity_mps", "base_angular_velocity_radps", "joint_position_rad",
                "joint_velocity_radps", "foot_force_N", "foot_moment_Nm", "seed", "delay_s")
DEFAULT_BODY = 17
"""The pushed body by default: the lower trunk (the pelvis), the robot's root, pushed at its CoM ``Pc_17``."""

FORCE = Num("a force in N", -1e5, 1e5)
FORCE_MAG = Num("a force magnitude in N", 0.0, 1e5, lo_open=True)
IMPULSE = Num("an impulse in N s", -1e4, 1e4)
IMPULSE_MAG = Num("an impulse magnitude in N s", 0.0, 1e4, lo_open=True)
UNIT = Num("a direction component", -1.0, 1.0)
UNIT_TOL = 1e-3   # a unit vector typed with three or four digits (0.707) is off by up to ~1e-3
ANGLE = Num("an angle in deg", -360.0, 360.0)
DURATION = Num("a duration in s", 0.0, lo_open=True)
TIME = Num("a time in s", 0.0, 1e4)
FRACTION = Num("a fraction of the phase's nominal duration", 0.0, 1.0)
COORD = Num("a coordinate in m", -1e4, 1e4)
LENGTH = Num("a length in m", 0.0, 100.0, lo_open=True)
SLOPE_ANGLE = Num("a slope angle in deg", 0.0, 45.0, lo_open=True)
FRICTION = Num("a friction coefficient", 0.0, 5.0, lo_open=True)
STD = {"base_linear_velocity_mps": Num("a standard deviation in m/s", 0.0, 10.0),
       "base_angular_velocity_radps": Num("a standard deviation in rad/s", 0.0, 10.0),
       "joint_position_rad": Num("a standard deviation in rad", 0.0, 1.0),
       "joint_velocity_radps": Num("a standard deviation in rad/s", 0.0, 10.0),
       "foot_force_N": Num("a standard deviation in N", 0.0, 1e4),
       "foot_moment_Nm": Num("a standard deviation in N m", 0.0, 1e4)}
DELAY = Num("a delay in s", 0.0, 1.0)


@dataclass(frozen=True)
class PushStart:
    """When a push starts: at ``time_s``, or at ``fraction`` of the nominal window of phase number ``phase``
    (1-based, ``traj.phases[phase - 1]``)."""

    time_s: float | None = None
    phase: int | None = None
    fraction: float = 0.0


@dataclass(frozen=True)
class Push:
    """One push: a constant force on a body over a window of time.

    Attributes:
        body: thesis body number (its CoM), or a URDF link or model frame name.
        force: the force (3,) in ``frame``, N (an impulse given in the scenario divided by ``duration_s``).
        frame: ``world`` or ``heading`` (module docstring).
        start: when it starts.
        duration_s: how long it acts, s.
        given: ``force_N`` or ``impulse_Ns``: how the scenario gave it (for the summary).
        where: the field path, for messages (``disturbances.pushes[0]``).
    """

    body: int | str
    force: tuple[float, float, float]
    frame: str
    start: PushStart
    duration_s: float
    given: str = "force_N"
    where: str = "disturbances.pushes[0]"

    @property
    def impulse(self) -> tuple[float, float, float]:
        """The impulse (3,) in ``frame``, N s."""
        return (self.force[0] * self.duration_s, self.force[1] * self.duration_s, self.force[2] * self.duration_s)


@dataclass(frozen=True)
class TerrainPiece:
    """One terrain piece as the scenario gives it (SI units, degrees where the key says so).

    Boxes: ``centre`` (3,), ``size`` (3,) full lengths, ``yaw_deg``.  Slopes: ``centre`` (2,) footprint centre,
    ``size`` (2,) length along the walk heading and width, ``angle_deg`` with ``direction``, or ``normal`` (3,),
    ``thickness_m``.  ``friction``: None for the scenario's coefficient."""

    kind: str
    centre: tuple[float, ...]
    size: tuple[float, ...]
    yaw_deg: float = 0.0
    angle_deg: float | None = None
    direction: str | None = None
    normal: tuple[float, float, float] | None = None
    thickness_m: float = 0.1
    friction: float | None = None
    where: str = "disturbances.terrain[0]"

    def box(self, heading: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The MuJoCo box: (centre (3,), half sizes (3,), rotation (3, 3): box axes in world columns), world frame,
        m.  ``heading``: the walk's heading (rad, the planned Body-17 yaw at t = 0), which orients a slope."""
        if self.kind != "slope":
            c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
            R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            return np.array(self.centre, dtype=float), np.array(self.size, dtype=float) / 2, R
        fwd = np.array([math.cos(heading), math.sin(heading), 0.0])
        left = np.array([-fwd[1], fwd[0], 0.0])
        n = slope_normal(self, heading)
        e1 = fwd - fwd.dot(n) * n                 # the heading's forward direction, in the top face
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        # half lengths of the top face whose ground footprint spans the asked length and width
        h1 = self.size[0] / 2 / abs(e1.dot(fwd))
        h2 = self.size[1] / 2 / abs(e2.dot(left))
        top_z = abs(e1[2]) * h1 + abs(e2[2]) * h2    # the lowest top corner on z = 0
        top = np.array([self.centre[0], self.centre[1], top_z])
        t = self.thickness_m
        return top - n * t / 2, np.array([h1, h2, t / 2]), np.column_stack([e1, e2, n])


def slope_normal(piece: TerrainPiece, heading: float) -> np.ndarray:
    """The unit normal (3,) of a slope's top face, world frame: ``normal`` as given, or tilted by ``angle_deg``
    toward the downhill side of ``direction`` relative to ``heading`` (rad)."""
    if piece.normal is not None:
        n = np.array(piece.normal, dtype=float)
        return n / np.linalg.norm(n)
    fwd = np.array([math.cos(heading), math.sin(heading), 0.0])
    uphill = {"up": fwd, "down": -fwd, "sideways": np.array([-fwd[1], fwd[0], 0.0])}[str(piece.direction)]
    a = math.radians(float(piece.angle_deg or 0.0))
    return math.cos(a) * np.array([0.0, 0.0, 1.0]) - math.sin(a) * uphill


@dataclass(frozen=True)
class Sensing:
    """Noise on what the controller observes (standard deviations, SI units) and the actuation delay, s."""

    base_linear_velocity_mps: float = 0.0
    base_angular_velocity_radps: float = 0.0
    joint_position_rad: float = 0.0
    joint_velocity_radps: float = 0.0
    foot_force_N: float = 0.0
    foot_moment_Nm: float = 0.0
    seed: int = 0
    delay_s: float = 0.0

    @property
    def noisy(self) -> bool:
        """Whether any signal gets noise."""
        return any(getattr(self, k) > 0.0 for k in STD)


@dataclass(frozen=True)
class EngineModel:
    """How the engine's world differs from the model the controller is given (``disturbances.model``).

    Attributes:
        payload: a point mass on the engine's robot the controller does not know of, or None.
        mass_scale: mass factors of the engine's robot (``all``, a segment or a body), on top of the scenario's.
        friction: the ground's friction coefficient in the engine (MuJoCo), or None for ``contact``'s.
    """

    payload: Payload | None = None
    mass_scale: tuple[tuple[str, float], ...] = ()
    friction: float | None = None

    def describe(self) -> dict[str, Any]:
        """For summary.json."""
        p = self.payload
        return {"payload": None if p is None else {"mass_kg": p.mass_kg, "body": p.body,
                                                   "position_m": None if p.position_m is None
                                                   else list(p.position_m)},
                "mass_scale": dict(self.mass_scale), "friction": self.friction}


@dataclass(frozen=True)
class Incline:
    """The whole ground inclined by ``angle_deg`` (deg) ``direction`` (``up``, ``down`` or ``sideways``: rising
    toward the walk's left) relative to the walk's heading."""

    angle_deg: float
    direction: str

    def gravity(self, g: float, heading: float) -> np.ndarray:
        """Gravity (3,) in the world frame whose ground plane z = 0 then stands for the incline, m/s^2: g turned by
        the angle toward the downhill direction (the walk's heading ``heading`` in rad: ``down`` = forward)."""
        fwd = np.array([math.cos(heading), math.sin(heading), 0.0])
        left = np.array([-fwd[1], fwd[0], 0.0])
        downhill = {"down": fwd, "up": -fwd, "sideways": -left}[self.direction]
        a = math.radians(self.angle_deg)
        return g * (math.sin(a) * downhill - math.cos(a) * np.array([0.0, 0.0, 1.0]))


@dataclass(frozen=True)
class Disturbances:
    """The validated ``disturbances`` section (module docstring)."""

    pushes: tuple[Push, ...] = ()
    terrain: tuple[TerrainPiece, ...] = ()
    sensing: Sensing | None = None
    source: str = field(default="<dict>", compare=False)
    model: EngineModel | None = None
    incline: Incline | None = None

    def describe_sensing(self) -> dict[str, Any] | None:
        """The sensing settings for summary.json, or None."""
        s = self.sensing
        return None if s is None else {k: getattr(s, k) for k in SENSING_KEYS}


def resolve_start(push: Push, phases: Any) -> float:
    """The push's start time, s: ``start.time_s``, or the nominal window of phase number ``start.phase`` (1-based)
    of ``phases`` (the reference trajectory's ``traj.phases``: each with ``t_start`` and ``t_end``) at
    ``start.fraction``.

    Raises:
        ScenarioError: a phase number beyond the trajectory's phases.
    """
    st = push.start
    if st.time_s is not None:
        return st.time_s
    assert st.phase is not None
    if st.phase > len(phases):
        raise ScenarioError(f"{push.where}.start.phase: expected a phase number in [1, {len(phases)}] (the walk "
                            f"has {len(phases)} phases), got {st.phase}")
    ph = phases[st.phase - 1]
    return float(ph.t_start + st.fraction * (ph.t_end - ph.t_start))


# --------------------------------------------------------------------------------------------- parsing
def _direction(src: str, where: str, d: dict) -> np.ndarray | None:
    """The push's unit direction (3,) from ``direction`` or ``direction_deg``, or None when neither is given."""
    if "direction" in d and "direction_deg" in d:
        raise ScenarioError(f"{src}: {where}: both direction and direction_deg given; expected one of them")
    if "direction_deg" in d:
        a = math.radians(number(src, f"{where}.direction_deg", d["direction_deg"], ANGLE))
        return np.array([math.cos(a), math.sin(a), 0.0])
    if "direction" in d:
        u = np.array(vector(src, f"{where}.direction", d["direction"], 3, UNIT, "components of a unit vector"))
        norm = float(np.linalg.norm(u))
        if abs(norm - 1.0) > UNIT_TOL:
            raise ScenarioError(f"{src}: {where}.direction: expected a unit vector [x, y, z] (norm 1 within "
                                f"{UNIT_TOL:g}), got {show(d['direction'])} (norm {norm:.4g})")
        return u / norm
    return None


def _push(src: str, where: str, raw: Any) -> Push:
    d = mapping_of(src, where, raw)
    check_keys(src, where, d, PUSH_KEYS)
    body: int | str = d.get("body", DEFAULT_BODY)
    if isinstance(body, bool) or not isinstance(body, (int, str)) or (isinstance(body, int) and not 1 <= body <= 99) \
            or (isinstance(body, str) and not body.strip()):
        raise ScenarioError(f"{src}: {where}.body: expected a thesis body number (17: the lower trunk), a URDF link "
                            f"or a model frame name, got {show(body)}{type_hint(body)}")
    given = [k for k in ("force_N", "impulse_Ns") if k in d]
    if len(given) != 1:
        raise ScenarioError(f"{src}: {where}: expected exactly one of force_N and impulse_Ns, got "
                            f"{' and '.join(given) if given else 'neither'}")
    key = given[0]
    if "duration_s" not in d:
        raise ScenarioError(f"{src}: {where}.duration_s: missing (expected a duration in s > 0)")
    duration = number(src, f"{where}.duration_s", d["duration_s"], DURATION)
    u = _direction(src, where, d)
    value = d[key]
    if isinstance(value, list):
        if u is not None:
            raise ScenarioError(f"{src}: {where}: {key} is a vector, which has its own direction; give a magnitude "
                                "with direction / direction_deg, or the vector alone")
        vec = np.array(vector(src, f"{where}.{key}", value, 3, FORCE if key == "force_N" else IMPULSE,
                              "components in the push's frame"))
        if not np.any(vec):
            raise ScenarioError(f"{src}: {where}.{key}: expected a non-zero vector, got {show(value)}")
    else:
        mag = number(src, f"{where}.{key}", value, FORCE_MAG if key == "force_N" else IMPULSE_MAG)
        if u is None:
            raise ScenarioError(f"{src}: {where}.direction: missing; {key} = {show(value)} is a magnitude and "
                                "needs a direction (a unit vector [x, y, z]) or direction_deg (an angle in deg)")
        vec = mag * u
    force = vec if key == "force_N" else vec / duration
    frame = d.get("frame", "heading")
    if frame not in FRAMES:
        raise ScenarioError(f"{src}: {where}.frame: expected one of {', '.join(FRAMES)}, got {show(frame)}")
    if "start" not in d:
        raise ScenarioError(f"{src}: {where}.start: missing (expected {{time_s: t}} or {{phase: k, fraction: f}})")
    return Push(body, (float(force[0]), float(force[1]), float(force[2])), frame, _start(src, f"{where}.start",
                                                                                          d["start"]),
                duration, key, where)


def _start(src: str, where: str, raw: Any) -> PushStart:
    if not isinstance(raw, dict):
        raise ScenarioError(f"{src}: {where}: expected {{time_s: t}} or {{phase: k, fraction: f}}, got "
                            f"{show(raw)}{type_hint(raw)}")
    check_keys(src, where, raw, ("time_s", "phase", "fraction"))
    if "time_s" in raw:
        if len(raw) > 1:
            raise ScenarioError(f"{src}: {where}: time_s given with {', '.join(k for k in raw if k != 'time_s')}; "
                                "expected either time_s or phase with fraction")
        return PushStart(time_s=number(src, f"{where}.time_s", raw["time_s"], TIME))
    if "phase" not in raw:
        raise ScenarioError(f"{src}: {where}: expected time_s, or phase (a number from 1) with fraction, got "
                            f"{show(raw)}")
    k = raw["phase"]
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ScenarioError(f"{src}: {where}.phase: expected a phase number >= 1 (as summary.json's phase_log "
                            f"numbers them), got {show(k)}{type_hint(k)}")
    return PushStart(phase=k, fraction=number(src, f"{where}.fraction", raw.get("fraction", 0.0), FRACTION))


def _terrain(src: str, where: str, raw: Any) -> TerrainPiece:
    d = mapping_of(src, where, raw)
    kind = d.get("kind")
    if kind not in TERRAIN_KINDS:
        raise ScenarioError(f"{src}: {where}.kind: expected one of {', '.join(TERRAIN_KINDS)}, got {show(kind)}")
    friction = None if d.get("friction") is None else number(src, f"{where}.friction", d["friction"], FRICTION)
    for k in ("centre", "size"):
        if k not in d:
            raise ScenarioError(f"{src}: {where}.{k}: missing")
    if kind in BOX_KINDS:
        check_keys(src, where, d, BOX_KEYS)
        centre = vector(src, f"{where}.centre", d["centre"], 3, COORD, "coordinates [x, y, z] in m (world)")
        size = vector(src, f"{where}.size", d["size"], 3, LENGTH, "full lengths [lx, ly, lz] in m")
        yaw = number(src, f"{where}.yaw_deg", d.get("yaw_deg", 0.0), ANGLE)
        return TerrainPiece(str(kind), tuple(centre), tuple(size), yaw_deg=yaw, friction=friction, where=where)
    check_keys(src, where, d, SLOPE_KEYS)
    centre = vector(src, f"{where}.centre", d["centre"], 2, COORD, "the footprint's centre [x, y] in m (world)")
    size = vector(src, f"{where}.size", d["size"], 2, LENGTH, "[length along the walk heading, width] in m")
    thick = number(src, f"{where}.thickness_m", d.get("thickness_m", 0.1), LENGTH)
    if "normal" in d:
        if "angle_deg" in d or "direction" in d:
            raise ScenarioError(f"{src}: {where}: normal given with angle_deg / direction; expected either a normal "
                                "or an angle with a direction")
        n = np.array(vector(src, f"{where}.normal", d["normal"], 3, Num("a normal component", -1e3, 1e3),
                            "components of the top face's normal (world)"))
        norm = float(np.linalg.norm(n))
        if not norm > 0 or n[2] / norm < math.cos(math.radians(45.0)) - 1e-12:
            raise ScenarioError(f"{src}: {where}.normal: expected an upward normal at most 45 deg from z, got "
                                f"{show(d['normal'])}")
        n = n / norm
        return TerrainPiece("slope", tuple(centre), tuple(size), normal=(float(n[0]), float(n[1]), float(n[2])),
                            thickness_m=thick, friction=friction, where=where)
    if "angle_deg" not in d:
        raise ScenarioError(f"{src}: {where}.angle_deg: missing (a slope needs angle_deg with direction, or normal)")
    angle = number(src, f"{where}.angle_deg", d["angle_deg"], SLOPE_ANGLE)
    direction = d.get("direction")
    if direction not in SLOPE_DIRECTIONS:
        raise ScenarioError(f"{src}: {where}.direction: expected one of {', '.join(SLOPE_DIRECTIONS)} (relative to "
                            f"the walk heading), got {show(direction)}")
    return TerrainPiece("slope", tuple(centre), tuple(size), angle_deg=angle, direction=str(direction),
                        thickness_m=thick, friction=friction, where=where)


def _sensing(src: str, raw: Any) -> Sensing:
    where = "disturbances.sensing"
    d = mapping_of(src, where, raw)
    check_keys(src, where, d, SENSING_KEYS)
    kw: dict[str, Any] = {k: number(src, f"{where}.{k}", d[k], rng) for k, rng in STD.items() if k in d}
    if "seed" in d:
        seed = d["seed"]
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 63:
            raise ScenarioError(f"{src}: {where}.seed: expected an integer >= 0, got {show(seed)}{type_hint(seed)}")
        kw["seed"] = seed
    if "delay_s" in d:
        kw["delay_s"] = number(src, f"{where}.delay_s", d["delay_s"], DELAY)
    return Sensing(**kw)


def _list(src: str, where: str, raw: Any) -> list:
    if raw is None:
        return []
    if not isinstance(raw, list):
        raise ScenarioError(f"{src}: {where}: expected a list, got {show(raw)}{type_hint(raw)}")
    return raw


def parse_disturbances(src: str, raw: Any) -> Disturbances | None:
    """The ``disturbances`` section (module docstring) as :class:`Disturbances`, or None when absent.

    Args:
        src: the file's name, for messages.
        raw: the section as read from YAML.

    Raises:
        ScenarioError: the message names the field, the value and what was expected.
    """
    if raw is None:
        return None
    d = mapping_of(src, "disturbances", raw)
    check_keys(src, "disturbances", d, KEYS)
    pushes = tuple(_push(src, f"disturbances.pushes[{i}]", p)
                   for i, p in enumerate(_list(src, "disturbances.pushes", d.get("pushes"))))
    terrain = tuple(_terrain(src, f"disturbances.terrain[{i}]", p)
                    for i, p in enumerate(_list(src, "disturbances.terrain", d.get("terrain"))))
    sensing = None if d.get("sensing") is None else _sensing(src, d["sensing"])
    model = None if d.get("model") is None else _model(src, d["model"])
    incline = None if d.get("incline") is None else _incline(src, d["incline"])
    return Disturbances(pushes, terrain, sensing, src, model, incline)


def _incline(src: str, raw: Any) -> Incline:
    where = "disturbances.incline"
    d = mapping_of(src, where, raw)
    check_keys(src, where, d, ("angle_deg", "direction"))
    if "angle_deg" not in d:
        raise ScenarioError(f"{src}: {where}.angle_deg: missing; expected an angle in deg in (0, 15]")
    angle = number(src, f"{where}.angle_deg", d["angle_deg"], Num("an angle in deg", 0.0, 15.0, lo_open=True))
    direction = d.get("direction", "down")
    if direction not in INCLINE_DIRECTIONS:
        raise ScenarioError(f"{src}: {where}.direction = {show(direction)}: expected one of "
                            f"{', '.join(INCLINE_DIRECTIONS)}")
    return Incline(angle, str(direction))


def _model(src: str, raw: Any) -> EngineModel:
    where = "disturbances.model"
    d = mapping_of(src, where, raw)
    check_keys(src, where, d, MODEL_KEYS)
    payload = None if d.get("payload") is None else parse_payload(src, f"{where}.payload", d["payload"])
    masses = parse_mass_scale(src, f"{where}.mass_scale", d.get("mass_scale", {}))
    friction = (None if d.get("friction") is None else
                number(src, f"{where}.friction", d["friction"], Num("a friction coefficient", 0.0, 5.0, lo_open=True)))
    return EngineModel(payload, masses, friction)


__all__ = ["DEFAULT_BODY", "Disturbances", "EngineModel", "Incline", "KEYS", "Push", "PushStart", "Sensing",
           "TerrainPiece", "parse_disturbances", "resolve_start", "slope_normal"]
