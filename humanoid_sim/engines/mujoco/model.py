"""The MuJoCo model of the thesis humanoid, built at run time from the generated URDF with ``mujoco.MjSpec``.

What is added to the URDF (which has inertias and visual boxes only, design.md section 9):

- a free joint on the lower trunk ``lower_trunk`` (body 17, Pinocchio's root; without it MuJoCo welds the root
  to the world).  ``compiler.alignfree`` stays off, so the free joint's frame is the URDF link frame O_17, as
  Pinocchio's ``q[:7]``;
- a ground plane z = 0 (world frame = thesis frame 0, z up) and gravity (0, 0, -9.81) m/s^2 from the model YAML;
- per foot two collision boxes, the toe body (1 / 2) and the foot main body (3 / 4), equal to the URDF's sole
  visual boxes (checked against :class:`humanoid_sim.robot.sole.SoleGeometry`: bottom face z = 0 at the zero posture,
  heel -0.0384 m to toe tip 0.1876 m from the ankle, split at the toe joint, 0.09 m wide; 0.226 m long in all);
- no other collisions: the soles collide with the ground only (``contype`` 1 / ``conaffinity`` 0 on the soles,
  0 / 1 on the plane), so a foot never collides with the other foot or its own toe;
- 26 motor actuators (gear 1, one per revolute joint, named after the joint, in MuJoCo's dof order) with no
  control or force range: the controller and the project's actuator model clip torques, not MuJoCo.  The URDF's
  +-pi joint limits and 150 N m effort are dropped (Pinocchio ignores them too);
- the 14 virtual (massless) bodies get MuJoCo's lower bound on mass and inertia (``boundmass`` /
  ``boundinertia`` 1e-13; the compiled masses are 2e-13 kg): MuJoCo refuses massless moving bodies;
  no joint damping, armature or friction loss (the thesis model has none: the rigid-body dynamics are the
  thesis's, and tests compare the mass matrix and bias forces with Pinocchio's).

The numerical settings are :class:`MujocoSettings`; its docstring gives each choice with the measurement behind
it.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from humanoid_sim.engines.mujoco.disturb import TerrainBox, add_terrain
from humanoid_sim.errors import InputError
from humanoid_sim.robot.model import FOOT_BODY, TOE_BODY, HumanoidModel
from humanoid_sim.robot.sole import SoleGeometry

FEET = ("R", "L")
BASE_BODY = "lower_trunk"
VIRTUAL_BOUND = 1e-13  # kg and kg m^2: MuJoCo's lower bound on the virtual bodies' mass and inertia
CONES = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}
INTEGRATORS = {"euler": mujoco.mjtIntegrator.mjINT_EULER, "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
               "rk4": mujoco.mjtIntegrator.mjINT_RK4}


class MujocoModelError(InputError):
    """Bad MuJoCo settings or a URDF whose sole boxes do not match the model's sole geometry."""


@dataclass(frozen=True)
class MujocoSettings:
    """Numerical settings of the MuJoCo engine (SI units).  Defaults, and the measurements behind them
    (``python -m humanoid_sim.engines.mujoco.experiments`` repeats them; standing = sim 1's initial posture held by
    :class:`humanoid_sim.engines.mujoco.standing.StandingController`):

    - ``solref`` (0.005 s, 1) and ``solimp`` (0.95, 0.99, 0.001 m, 0.5, 2) on the sole and floor geoms: a
      stiffer, harder contact than MuJoCo's default (0.02 s; 0.9, 0.95), critically damped so a touchdown does
      not bounce (the thesis's touchdown is inelastic).  Standing 2 s, the soles sink 0.29 mm and the hip
      drifts 0.9 mm; with solref 10 ms 0.71 mm and 2.7 mm; with MuJoCo's defaults 1.8 mm and 4.6 mm (the
      softer ground lets the body lean).
    - ``cone`` elliptic, ``impratio`` 10.  MuJoCo's soft friction lets a loaded sole creep.  With a 20 N
      horizontal push on the trunk for 1.5 s while standing (friction use 0.04, far inside mu = 0.8), the soles
      crept 0.49 mm with a pyramidal cone, 0.29 mm elliptic with impratio 1, 0.028 mm with impratio 10 and
      0.004 mm with 100 (MuJoCo's defaults: 2.5 mm).  Impratio 10 already makes creep negligible next to the
      1 mm (standing) and 5 mm (per stance) slip bounds; 100 measured the same step cost and is a one-field
      change if a walk shows creep.
    - ``timestep`` 1 ms: 5 steps per contact time constant (MuJoCo needs >= 2).  Against 0.2 ms, the hip
      (Body-17 CoM) path over 1 s differs by 0.15 mm standing and 0.11 mm after a 5 mm drop onto both feet
      (0.31 and 0.24 mm at 2 ms, 0.06 and 0.04 mm at 0.5 ms: first order).
    - ``friction`` 0.8: the scenario's ``contact.friction_coefficient`` (sliding only, condim 3; four corner
      contacts per box give the sole its resistance to twisting).
    - ``integrator`` ``euler`` (MuJoCo's semi-implicit Euler): with no joint damping there is nothing for the
      implicit integrators to stabilise, and it is the cheapest.
    - Newton solver, ``iterations`` 100, ``tolerance`` 1e-10: the contact forces feed Newton checks of the
      ground reaction, so the solver converges far below the test tolerances (1 iteration per step when
      warm-started while standing).
    """

    timestep: float = 1e-3
    friction: float = 0.8
    cone: str = "elliptic"
    impratio: float = 10.0
    solref: tuple[float, float] = (0.005, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    integrator: str = "euler"
    iterations: int = 100
    tolerance: float = 1e-10

    def __post_init__(self) -> None:
        def bad(name: str, expected: str) -> MujocoModelError:
            return MujocoModelError(f"MujocoSettings.{name} = {getattr(self, name)!r}: expected {expected}")

        if not (_finite(self.timestep) and 0 < self.timestep <= 0.01):
            raise bad("timestep", "a step in (0, 0.01] s")
        if not (_finite(self.friction) and 0 < self.friction <= 5):
            raise bad("friction", "a friction coefficient in (0, 5]")
        if self.cone not in CONES:
            raise bad("cone", f"one of {tuple(CONES)}")
        if not (_finite(self.impratio) and self.impratio >= 1):
            raise bad("impratio", "a number >= 1")
        if not (len(self.solref) == 2 and all(_finite(x) and x > 0 for x in self.solref)):
            raise bad("solref", "(time constant s > 0, damping ratio > 0)")
        if self.solref[0] < 2 * self.timestep:
            raise bad("solref", f"a time constant >= 2 timesteps ({2 * self.timestep:g} s); a shorter one is not "
                                "resolved by the integrator")
        s = self.solimp
        if not (len(s) == 5 and all(_finite(x) for x in s) and 0 < s[0] <= s[1] < 1 and s[2] > 0
                and 0 < s[3] < 1 and s[4] >= 1):
            raise bad("solimp", "(dmin, dmax, width m, midpoint, power) with 0 < dmin <= dmax < 1, width > 0, "
                                "0 < midpoint < 1, power >= 1")
        if self.integrator not in INTEGRATORS:
            raise bad("integrator", f"one of {tuple(INTEGRATORS)}")
        if not (isinstance(self.iterations, int) and self.iterations >= 1):
            raise bad("iterations", "an integer >= 1")
        if not (_finite(self.tolerance) and self.tolerance >= 0):
            raise bad("tolerance", "a number >= 0")

    @classmethod
    def from_scenario(cls, scenario: Any, **overrides: Any) -> MujocoSettings:
        """Defaults with the scenario's ``contact.friction_coefficient``; ``overrides`` replace named fields."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise MujocoModelError(f"MujocoSettings: unknown field(s) {unknown}; expected some of {sorted(names)}")
        kw = {"friction": float(scenario.contact.friction_coefficient)}
        kw.update(overrides)
        return cls(**kw)


def _finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@dataclass
class MujocoModel:
    """The compiled model and the ids the engine needs.

    ``sole_geoms[foot]`` = (toe geom id, main-body geom id); ``foot_bodies[foot]`` = (toe body id, main body id);
    ``sole_geometry`` the sole rectangle the boxes were built from; ``base_body`` the lower-trunk body id;
    ``terrain_geoms`` the ids of a scenario's terrain boxes (:mod:`.disturb`), ground as the floor is.
    """

    model: mujoco.MjModel
    settings: MujocoSettings
    sole_geoms: dict[str, tuple[int, int]]
    foot_bodies: dict[str, tuple[int, int]]
    floor_geom: int
    base_body: int
    sole_geometry: SoleGeometry
    total_mass: float = field(default=0.0)
    terrain_geoms: tuple[int, ...] = ()

    def geom_foot(self) -> dict[int, str]:
        """Sole geom id -> foot ('R' / 'L')."""
        return {g: foot for foot, pair in self.sole_geoms.items() for g in pair}


def link_of_body(hm: HumanoidModel, body: int) -> tuple[str, pin.SE3]:
    """URDF link (= MuJoCo body) that carries thesis body frame O_<body>, and the placement of O_<body> in it."""
    frames = hm.model.frames
    frame = frames[hm.frame_id(f"O_{body}")]
    link = frame
    # O_k is a fixed frame under its link: walk up to the BODY frame whose parent is the joint frame.
    while not (link.type == pin.FrameType.BODY and frames[link.parentFrame].type == pin.FrameType.JOINT):
        if link.parentFrame == 0:
            raise MujocoModelError(f"{hm.urdf_path}: no link found above frame O_{body}")
        link = frames[link.parentFrame]
    return link.name, link.placement.actInv(frame.placement)


def _urdf_boxes(urdf_path: Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Visual boxes of the URDF: link name -> (centre (3,), rpy (3,), size (3,)) in the link frame, m / rad."""
    root = ET.parse(urdf_path).getroot()
    out = {}
    for link in root.iter("link"):
        for vis in link.iter("visual"):
            box = vis.find("geometry/box")
            if box is None:
                continue
            origin = vis.find("origin")
            attrs = origin.attrib if origin is not None else {}
            xyz = np.array([float(x) for x in attrs.get("xyz", "0 0 0").split()])
            rpy = np.array([float(x) for x in attrs.get("rpy", "0 0 0").split()])
            out[link.get("name")] = (xyz, rpy, np.array([float(x) for x in box.get("size").split()]))
    return out


def _sole_box(hm: HumanoidModel, boxes: dict, body: int, corners: np.ndarray) -> tuple[str, np.ndarray, np.ndarray]:
    """The URDF visual box of thesis body ``body``, checked to have ``corners`` (sole rectangle in O_body) as its
    bottom face; returns (link name, centre in the link frame, half sizes)."""
    link, M = link_of_body(hm, body)
    if link not in boxes:
        raise MujocoModelError(f"{hm.urdf_path}: link {link!r} (body {body}) has no visual box; expected the sole box")
    centre, rpy, size = boxes[link]
    if np.any(np.abs(rpy) > 1e-12):
        raise MujocoModelError(f"{hm.urdf_path}: sole box of link {link!r} is rotated (rpy {rpy.tolist()}); "
                               "expected an axis-aligned box")
    # The sole rectangle is given in O_body; the leg links sit at their thesis frames (model YAML ``joint_at``).
    if not M.isIdentity(1e-12):
        raise MujocoModelError(f"{hm.urdf_path}: frame O_{body} is not at the origin of link {link!r}; expected "
                               "the foot links at their thesis frames")
    c = corners
    lo, hi = centre - size / 2, centre + size / 2
    bottom = np.array([[lo[0], lo[1], lo[2]], [hi[0], lo[1], lo[2]], [hi[0], hi[1], lo[2]], [lo[0], hi[1], lo[2]]])
    # 1e-9 m: both come from the same YAML numbers through float printing in the URDF (~1e-12).
    if not np.allclose(bottom, c, atol=1e-9):
        raise MujocoModelError(f"{hm.urdf_path}: bottom face of the sole box of link {link!r} is "
                               f"{bottom.tolist()}, expected the model's foot_sole rectangle {c.tolist()}")
    return link, centre, size / 2


def build_model(hm: HumanoidModel, settings: MujocoSettings | None = None,
                terrain: Sequence[TerrainBox] = ()) -> MujocoModel:
    """Compile the MuJoCo model of ``hm`` (its URDF and sole geometry) with ``settings``, and a scenario's
    ``terrain`` boxes (:func:`humanoid_sim.engines.mujoco.disturb.add_terrain`: static, the floor's contact
    parameters)."""
    settings = MujocoSettings() if settings is None else settings
    if not isinstance(settings, MujocoSettings):
        raise MujocoModelError(f"settings: expected a MujocoSettings, got {type(settings).__name__}")
    spec = mujoco.MjSpec.from_file(str(hm.urdf_path))
    spec.compiler.boundmass = VIRTUAL_BOUND
    spec.compiler.boundinertia = VIRTUAL_BOUND
    spec.compiler.alignfree = False
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.compiler.autolimits = True

    opt = spec.option
    opt.timestep = settings.timestep
    opt.gravity = [float(x) for x in hm.model.gravity.linear]   # (0, 0, -g), or turned for an incline
    opt.cone = CONES[settings.cone]
    opt.impratio = settings.impratio
    opt.integrator = INTEGRATORS[settings.integrator]
    opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
    opt.iterations = settings.iterations
    opt.tolerance = settings.tolerance

    base = spec.body(BASE_BODY)
    if base is None:
        raise MujocoModelError(f"{hm.urdf_path}: no link {BASE_BODY!r} (body 17) to put the free joint on")
    base.add_freejoint()

    for j in spec.joints:
        if j.type == mujoco.mjtJoint.mjJNT_HINGE:
            j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
            j.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
            for attr in ("damping", "stiffness"):  # scalars before MuJoCo 4, (3,) polynomials since
                setattr(j, attr, np.zeros_like(getattr(j, attr)) if np.ndim(getattr(j, attr)) else 0.0)
            j.armature = 0.0
            j.frictionloss = 0.0

    floor = spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 1.0],
                                    contype=0, conaffinity=1, condim=3, friction=[settings.friction, 0.0, 0.0],
                                    solref=list(settings.solref), solimp=list(settings.solimp))
    terrain_names = add_terrain(spec, terrain, settings.friction, settings.solref, settings.solimp)
    sole = SoleGeometry.from_model(hm)
    boxes = _urdf_boxes(hm.urdf_path)
    # The main body's part of the sole: heel to the toe joint (the toe body carries the rest, to the toe tip).
    heel_part = sole.flat_corners()
    heel_part[1:3, 0] = sole.toe_joint[0]
    names = {}
    for foot in FEET:
        for body, corners in ((TOE_BODY[foot], sole.toe_corners()), (FOOT_BODY[foot], heel_part)):
            link, centre, half = _sole_box(hm, boxes, body, corners)
            name = f"sole_{foot}{body}"
            spec.body(link).add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=centre.tolist(),
                                     size=half.tolist(), contype=1, conaffinity=0, condim=3,
                                     friction=[settings.friction, 0.0, 0.0], solref=list(settings.solref),
                                     solimp=list(settings.solimp), mass=0.0)
            names[(foot, body)] = (name, link)

    for j in spec.joints:
        if j.type == mujoco.mjtJoint.mjJNT_HINGE:
            act = spec.add_actuator(name=j.name, target=j.name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_motor()
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
    floor.name = "floor"
    model = spec.compile()

    def gid(name: str) -> int:
        return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)

    def bid(name: str) -> int:
        return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)

    sole_geoms = {f: (gid(names[(f, TOE_BODY[f])][0]), gid(names[(f, FOOT_BODY[f])][0])) for f in FEET}
    foot_bodies = {f: (bid(names[(f, TOE_BODY[f])][1]), bid(names[(f, FOOT_BODY[f])][1])) for f in FEET}
    return MujocoModel(model=model, settings=settings, sole_geoms=sole_geoms, foot_bodies=foot_bodies,
                       floor_geom=gid("floor"), base_body=bid(BASE_BODY), sole_geometry=sole,
                       total_mass=float(np.sum(model.body_mass)),
                       terrain_geoms=tuple(gid(n) for n in terrain_names))
