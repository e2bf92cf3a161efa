"""A scenario's pushes and terrain on MuJoCo (:mod:`humanoid_sim.scenario.disturbances`).

Terrain: each piece is a static box geom of the world body (:func:`add_terrain`, called by
:func:`humanoid_sim.engines.mujoco.model.build_model`) with the ground plane's contact parameters (``solref``,
``solimp``, ``condim`` 3, ``conaffinity`` 1 so that the soles touch it and nothing else) and its own friction
coefficient.  Its ``priority`` 1 makes MuJoCo take the patch's friction for a sole on it (MuJoCo otherwise takes
the larger of the two geoms' coefficients, so a slippery patch would not be slippery).  The engine reads the
soles' contacts with terrain as it reads those with the floor.

Pushes (:class:`Pusher`): a force on a body through ``data.xfrc_applied`` (world frame, at the MuJoCo body's
centre of mass ``xipos``; a push at another point of the body adds the moment arm x force).  The engine calls
:meth:`Pusher.apply` once per control update, before the update's MuJoCo steps; the force is then held over the
control period as the torques are, scaled by the share of the period the push window covers.  So the impulse a
push gives is its force times its duration exactly, whatever the start and the duration against the control grid
(only the first and last periods carry a partial force).  A push in the ``heading`` frame is turned by the lower
trunk's yaw psi = atan2(R[1, 0], R[0, 0]) read from MuJoCo at the first update that the push acts in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from humanoid_sim.errors import InputError
from humanoid_sim.scenario.disturbances import Push, TerrainPiece, resolve_start

TERRAIN_PRIORITY = 1
"""Contact priority of a terrain geom (the soles' is 0): MuJoCo takes the friction of the higher-priority geom."""


@dataclass(frozen=True)
class TerrainBox:
    """A terrain piece as a MuJoCo box (world frame, SI units): ``centre`` (3,), ``half`` sizes (3,), rotation ``R``
    (3, 3: the box axes as columns), ``friction`` (None: the floor's), and its ``piece``."""

    centre: np.ndarray
    half: np.ndarray
    R: np.ndarray
    friction: float | None
    piece: TerrainPiece

    def describe(self) -> dict[str, Any]:
        """For summary.json and the playback: kind, centre (m), size (full lengths, m), rotation, friction."""
        p = self.piece
        out: dict[str, Any] = {"kind": p.kind, "centre_m": self.centre.tolist(), "size_m": (2 * self.half).tolist(),
                               "rotation": self.R.tolist(), "friction": self.friction}
        if p.kind == "slope":
            n = self.R[:, 2]
            out.update({"angle_deg": math.degrees(math.acos(min(1.0, float(n[2])))), "normal": n.tolist(),
                        "direction": p.direction})
        return out


def terrain_boxes(pieces: Sequence[TerrainPiece], heading: float) -> list[TerrainBox]:
    """The boxes of terrain ``pieces`` for a walk whose heading is ``heading`` (rad: the planned Body-17 yaw at
    t = 0, which orients slopes)."""
    out = []
    for p in pieces:
        centre, half, R = p.box(heading)
        out.append(TerrainBox(centre, half, R, p.friction, p))
    return out


def add_terrain(spec: mujoco.MjSpec, boxes: Sequence[TerrainBox], friction: float, solref: Sequence[float],
                solimp: Sequence[float]) -> list[str]:
    """Add ``boxes`` to the world body of ``spec`` as static geoms with the floor's contact parameters (``friction``
    for a box without its own, ``solref``, ``solimp``); returns their names (``terrain_<i>``)."""
    names = []
    for i, b in enumerate(boxes):
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(b.R).ravel())
        name = f"terrain_{i}"
        spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=b.centre.tolist(),
                                quat=quat.tolist(), size=b.half.tolist(), contype=0, conaffinity=1, condim=3,
                                friction=[friction if b.friction is None else b.friction, 0.0, 0.0],
                                solref=list(solref), solimp=list(solimp), priority=TERRAIN_PRIORITY)
        names.append(name)
    return names


@dataclass
class _Active:
    """A push resolved for the run: MuJoCo body id, application point in the body frame (m), window (s), force in
    its frame (N), and the world force once it has started."""

    push: Push
    body: int
    point: np.ndarray
    t0: float
    t1: float
    world: np.ndarray | None = None


def push_point(hm: Any, mj_model: mujoco.MjModel, push: Push) -> tuple[int, np.ndarray, str]:
    """Where ``push`` acts: (MuJoCo body id, the point in that body's frame (m), the point's name).

    Raises:
        InputError: the body is not a thesis body with a mass, a URDF link or a model frame.
    """
    import pinocchio as pin

    b = push.body
    frames = hm.model.frames
    names = [f.name for f in frames]
    if isinstance(b, str) and mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_BODY, b) >= 0:
        bid = mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_BODY, b)
        return bid, mj_model.body_ipos[bid].copy(), f"{b} (CoM)"
    if isinstance(b, int):
        frame = f"Pc_{b}"
        if frame not in names:
            massive = sorted(int(n[3:]) for n in names if n.startswith("Pc_") and n[3:].isdigit())
            raise InputError(f"{push.where}.body: expected a thesis body with a mass ({', '.join(map(str, massive))}),"
                             f" got {b}")
    elif b in names:
        frame = b
    else:
        raise InputError(f"{push.where}.body: {b!r} is neither a URDF link nor a frame of the model; expected a "
                         "thesis body number (17: the lower trunk), a link such as 'lower_trunk' or a frame such "
                         "as 'O_17'")
    f = frames[hm.frame_id(frame)]
    link = f
    # the link (MuJoCo body) that carries the frame: the BODY frame right below a joint (model.link_of_body's walk)
    while not (link.type == pin.FrameType.BODY and frames[link.parentFrame].type == pin.FrameType.JOINT) \
            and link.parentFrame != 0:
        link = frames[link.parentFrame]
    M = link.placement.actInv(f.placement)          # both placements are in their parent joint's frame
    link_name = link.name
    bid = mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_BODY, link_name)
    if bid < 0:
        raise InputError(f"{push.where}.body: the link {link_name!r} carrying {frame} is not a MuJoCo body")
    return bid, np.array(M.translation), frame


class Pusher:
    """The pushes of one run on a MuJoCo model (module docstring).

    Args:
        hm: the robot (frames of the pushed points).
        model, data: MuJoCo's.
        pushes: the scenario's pushes.
        phases: the reference trajectory's phases (nominal windows of a phase-fraction start).
        total_mass: the robot's mass, kg (for the summary's delta-v).
        base_body: the lower trunk's MuJoCo body id (its yaw is the heading).
    """

    def __init__(self, hm: Any, model: mujoco.MjModel, data: mujoco.MjData, pushes: Sequence[Push], phases: Any,
                 total_mass: float, base_body: int) -> None:
        self.data = data
        self.base_body = base_body
        self.total_mass = float(total_mass)
        self.active: list[_Active] = []
        for p in pushes:
            body, point, _ = push_point(hm, model, p)
            t0 = resolve_start(p, phases)
            self.active.append(_Active(p, body, point, t0, t0 + p.duration_s))
        self._bodies = sorted({a.body for a in self.active})

    def reset(self) -> None:
        """A new run: no push has started, no external force."""
        for a in self.active:
            a.world = None
        self.data.xfrc_applied[:] = 0.0

    def apply(self, t: float, period: float) -> None:
        """Set ``xfrc_applied`` for the control period [t, t + period): each push's force times the share of the
        period its window covers, at its point."""
        d = self.data
        for b in self._bodies:
            d.xfrc_applied[b] = 0.0
        for a in self.active:
            share = (min(t + period, a.t1) - max(t, a.t0)) / period
            if share <= 0.0:
                continue
            if a.world is None:
                a.world = self._world_force(a)
            F = share * a.world
            arm = d.xmat[a.body].reshape(3, 3) @ a.point + d.xpos[a.body] - d.xipos[a.body]
            d.xfrc_applied[a.body, :3] += F
            d.xfrc_applied[a.body, 3:] += np.cross(arm, F)

    def _world_force(self, a: _Active) -> np.ndarray:
        """The push's force in the world frame, N, at its start (the heading frame turned by the trunk's yaw)."""
        F = np.array(a.push.force, dtype=float)
        if a.push.frame == "world":
            return F
        R = self.data.xmat[self.base_body].reshape(3, 3)
        psi = math.atan2(R[1, 0], R[0, 0])
        c, s = math.cos(psi), math.sin(psi)
        return np.array([c * F[0] - s * F[1], s * F[0] + c * F[1], F[2]])

    def report(self) -> list[dict[str, Any]]:
        """Per push for summary.json: body, start (s), duration (s), the world force (N) and impulse (N s), and the
        whole robot's delta-v (impulse / total mass, m/s); ``applied`` False (world force None) for a push the run
        did not reach."""
        out = []
        for a in self.active:
            p = a.push
            row: dict[str, Any] = {"body": p.body, "frame": p.frame, "given": p.given, "start_s": a.t0,
                                   "duration_s": p.duration_s, "applied": a.world is not None}
            if a.world is not None:
                J = a.world * p.duration_s
                row.update({"force_world_N": a.world.tolist(), "impulse_world_Ns": J.tolist(),
                            "impulse_Ns": float(np.linalg.norm(J)),
                            "delta_v_mps": float(np.linalg.norm(J)) / self.total_mass})
            else:
                J = np.array(p.impulse)
                row.update({"force_world_N": None, "impulse_world_Ns": None,
                            "impulse_Ns": float(np.linalg.norm(J)),
                            "delta_v_mps": float(np.linalg.norm(J)) / self.total_mass})
            out.append(row)
        return out


def scenario_terrain(hm: Any, scenario: Any, traj: Any) -> list[TerrainBox]:
    """The terrain boxes of ``scenario`` ([] without a ``disturbances`` section or terrain); a slope is oriented by
    the walk's heading, the planned Body-17 yaw at t = 0 (``traj``; the model's initial posture without one)."""
    dist = scenario.disturbances
    if dist is None or not dist.terrain:
        return []
    R = traj.sample_global(0.0).hip_R if traj is not None else hm.spec.C0
    return terrain_boxes(dist.terrain, math.atan2(R[1, 0], R[0, 0]))


def scenario_pusher(hm: Any, scenario: Any, traj: Any, mm: Any, data: mujoco.MjData) -> Pusher | None:
    """The :class:`Pusher` of ``scenario``'s pushes on the MuJoCo model ``mm`` (None without pushes: the engine
    then does no work for them)."""
    dist = scenario.disturbances
    if dist is None or not dist.pushes:
        return None
    return Pusher(hm, mm.model, data, dist.pushes, [] if traj is None else traj.phases, mm.total_mass,
                  mm.base_body)


def disturbance_info(terrain: Sequence[TerrainBox], pusher: Pusher | None) -> dict[str, Any]:
    """The engine's ``run_info`` entries of what it applied: ``pushes`` and ``terrain`` (nothing without them)."""
    out: dict[str, Any] = {}
    if pusher is not None:
        out["pushes"] = pusher.report()
    if terrain:
        out["terrain"] = [b.describe() for b in terrain]
    return out


__all__ = ["Pusher", "TERRAIN_PRIORITY", "TerrainBox", "add_terrain", "disturbance_info", "push_point",
           "scenario_pusher", "scenario_terrain", "terrain_boxes"]
