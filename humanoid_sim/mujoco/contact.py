"""Ground reactions of the feet from MuJoCo's contact forces, and slip / tilt / penetration measures.

Every active contact of a sole geom (toe body 1 / 2, main body 3 / 4) with the floor is read with
``mujoco.mj_contactForce``, which returns the force (and, for condim > 3, the torque) in the contact frame
``contact.frame`` (rows: normal, first tangent, second tangent; the normal points from geom1 to geom2).  That force
acts on geom2's body, its negative on geom1's; here it is turned into the force on the foot, in the world frame
(thesis frame 0, z up), applied at ``contact.pos``.

Per foot, :class:`FootContact` gives the resultant force (N), its moment about the world origin (N m), the centre
of pressure on the ground plane z = 0 (m), the normal force of each sole geom (N), the contact points and their
normal forces, and the deepest penetration (m).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from humanoid_sim.mujoco.model import FEET, MujocoModel

_EMPTY3 = np.zeros((0, 3))


@dataclass
class FootContact:
    """Ground reaction on one foot (world frame, SI units).

    ``force`` (3,) N and ``moment`` (3,) N m about the world origin: the resultant wrench the ground applies to
    the foot (toe and main body together).  ``cop`` (3,): centre of pressure on the plane z = 0 (NaN when the
    normal force is zero).  ``normal_toe`` / ``normal_main``: normal force (N) on the toe box and the main-body
    box.  ``points`` (k, 3) contact points, ``point_normal`` (k,) their normal forces (N), ``point_force`` (k, 3)
    their forces on the foot (world frame, N), ``point_geom`` (k,) which geom (0 toe, 1 main body).  ``penetration`` (m, >= 0): deepest penetration of a sole box.
    """

    foot: str
    force: np.ndarray = field(default_factory=lambda: np.zeros(3))
    moment: np.ndarray = field(default_factory=lambda: np.zeros(3))
    normal_toe: float = 0.0
    normal_main: float = 0.0
    points: np.ndarray = field(default_factory=lambda: _EMPTY3.copy())
    point_normal: np.ndarray = field(default_factory=lambda: np.zeros(0))
    point_force: np.ndarray = field(default_factory=lambda: _EMPTY3.copy())
    point_geom: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    penetration: float = 0.0

    @property
    def normal(self) -> float:
        """Total normal force on the sole, N."""
        return self.normal_toe + self.normal_main

    @property
    def cop(self) -> np.ndarray:
        """Centre of pressure on z = 0: the point where the moment's horizontal part vanishes, m."""
        fz = self.force[2]
        if not fz > 0:
            return np.full(3, np.nan)
        return np.array([-self.moment[1] / fz, self.moment[0] / fz, 0.0])

    @property
    def wrench(self) -> np.ndarray:
        """(6,) [force; moment about the world origin]."""
        return np.concatenate([self.force, self.moment])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (k, 3) arrays (np.cross costs ~40 us on arrays this small)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def _geom_tables(mm: MujocoModel) -> tuple[np.ndarray, np.ndarray]:
    """Per geom id: the foot index (0 'R', 1 'L', -1 not a sole) and the box (0 toe, 1 main body); cached on mm."""
    tables = getattr(mm, "_geom_tables", None)
    if tables is None:
        foot = np.full(mm.model.ngeom, -1, dtype=int)
        box = np.zeros(mm.model.ngeom, dtype=int)
        for i, f in enumerate(FEET):
            for j, g in enumerate(mm.sole_geoms[f]):
                foot[g], box[g] = i, j
        tables = (foot, box)
        mm._geom_tables = tables
    return tables


def foot_contacts(mm: MujocoModel, data: mujoco.MjData) -> dict[str, FootContact]:
    """Ground reaction of each foot at the current ``data`` (after ``mj_forward`` or ``mj_step``)."""
    out = {foot: FootContact(foot) for foot in FEET}
    ncon = data.ncon
    if ncon == 0:
        return out
    foot_of, box_of = _geom_tables(mm)
    contacts = data.contact
    geoms = np.asarray(contacts.geom[:ncon])
    g1, g2 = geoms[:, 0], geoms[:, 1]
    on2 = (foot_of[g2] >= 0) & (g1 == mm.floor_geom)   # the force acts on geom2's body: the foot
    on1 = (foot_of[g1] >= 0) & (g2 == mm.floor_geom)   # the force acts on geom1's body: minus it on the foot
    keep = np.flatnonzero(on1 | on2)  # others are not sole-floor contacts (the model has none, by contype)
    if keep.size == 0:
        return out
    geom = np.where(on2, g2, g1)[keep]
    sign = np.where(on2, 1.0, -1.0)[keep]
    f6 = np.zeros((keep.size, 6))
    for j, i in enumerate(keep):
        mujoco.mj_contactForce(mm.model, data, int(i), f6[j])
    frames = np.asarray(contacts.frame[:ncon]).reshape(ncon, 3, 3)[keep]
    # contact frame rows: normal, tangents; world vector = frame^T @ local
    F = sign[:, None] * np.einsum("kji,kj->ki", frames, f6[:, :3])    # forces on the foot, world frame
    T = sign[:, None] * np.einsum("kji,kj->ki", frames, f6[:, 3:])    # contact torques (zero for condim 3)
    P = np.asarray(contacts.pos[:ncon])[keep]
    pen = -np.asarray(contacts.dist[:ncon])[keep]
    moments = _cross(P, F) + T
    feet, boxes = foot_of[geom], box_of[geom]
    for i, foot in enumerate(FEET):
        sel = feet == i
        if not sel.any():
            continue
        c = out[foot]
        c.force = F[sel].sum(axis=0)
        c.moment = moments[sel].sum(axis=0)
        c.points = P[sel]
        c.point_normal = f6[sel, 0]
        c.point_force = F[sel]
        c.point_geom = boxes[sel]
        c.normal_toe = float(c.point_normal[c.point_geom == 0].sum())
        c.normal_main = float(c.point_normal[c.point_geom == 1].sum())
        c.penetration = max(0.0, float(pen[sel].max()))
    return out


# ---------------------------------------------------------------------------------------- sole measures
def sole_corners(mm: MujocoModel, data: mujoco.MjData, foot: str, box: int = 1) -> np.ndarray:
    """(4, 3) world positions of the bottom corners of one of the foot's sole boxes, m (after kinematics):
    ``box`` 1 the main body's (default), 0 the toe body's."""
    g = mm.sole_geoms[foot][box]
    half = mm.model.geom_size[g]
    local = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1]], dtype=float) * half
    R = data.geom_xmat[g].reshape(3, 3)
    return data.geom_xpos[g] + local @ R.T


def sole_tilt(mm: MujocoModel, data: mujoco.MjData, foot: str) -> float:
    """Angle (rad) between the foot main body's sole normal (its z axis) and the world z axis."""
    R = data.xmat[mm.foot_bodies[foot][1]].reshape(3, 3)
    return float(np.arctan2(np.hypot(R[0, 2], R[1, 2]), R[2, 2]))  # well conditioned near 0, unlike arccos


class SlipMeter:
    """Horizontal travel of each sole while it supports.

    ``update(foot, supporting, corners)`` with the main-body sole corners (:func:`sole_corners`): when a foot
    starts supporting, its corners are recorded; while it supports, its slip is the largest horizontal distance
    of a corner from its recorded position (m), so a rotation about the vertical counts as well as a slide.
    ``max_slip[foot]`` is the largest slip over all its supports; ``current[foot]`` that of the present support.
    """

    def __init__(self) -> None:
        self._anchor: dict[str, np.ndarray | None] = {foot: None for foot in FEET}
        self.current = {foot: 0.0 for foot in FEET}
        self.max_slip = {foot: 0.0 for foot in FEET}

    def update(self, foot: str, supporting: bool, corners: np.ndarray) -> float:
        if not supporting:
            self._anchor[foot] = None
            self.current[foot] = 0.0
            return 0.0
        anchor = self._anchor[foot]
        if anchor is None:
            self._anchor[foot] = np.array(corners[:, :2], dtype=float)
            return 0.0
        s = float(np.max(np.linalg.norm(corners[:, :2] - anchor, axis=1)))
        self.current[foot] = s
        self.max_slip[foot] = max(self.max_slip[foot], s)
        return s


EDGES = ("toe", "heel", "outer", "inner")


@dataclass
class SoleCop:
    """Where a foot's CoP lies on its sole.

    ``xy`` (2,): CoP in the foot main-body frame (x forward from the ankle, y to the foot's left), m, projected
    along the body's z axis; ``margin``: signed distance from the CoP to the sole rectangle's boundary (m,
    positive inside); ``edges``: the sole edges ("toe", "heel", "outer", "inner") within ``edge_tol`` of the CoP
    (empty when the CoP is well inside).  The sole is the flat rectangle heel to toe tip (the toe box counted
    flat: its joint bends little while the foot supports).
    """

    xy: np.ndarray
    margin: float
    edges: tuple[str, ...]


def sole_cop(mm: MujocoModel, data: mujoco.MjData, contact: FootContact, edge_tol: float = 2e-3) -> SoleCop | None:
    """The foot's CoP in its sole (None when the foot carries no normal force)."""
    from humanoid_sim.audit import signed_distance

    if not contact.force[2] > 0:
        return None
    sole = mm.sole_geometry
    body = mm.foot_bodies[contact.foot][1]
    R = data.xmat[body].reshape(3, 3)
    # O_3 / O_4 is the main body's link frame (build_model checks it).
    xy = (R.T @ (contact.cop - data.xpos[body]))[:2]
    rect = sole.flat_corners()[:, :2]
    margin = signed_distance(xy, rect)
    w = sole.width / 2
    near = {"toe": sole.toe_front_x - xy[0], "heel": xy[0] - sole.heel_back_x}
    # The right foot's outer side is its right (-y), the left foot's its left (+y).
    outer_sign = -1.0 if contact.foot == "R" else 1.0
    near["outer"] = w - outer_sign * xy[1]
    near["inner"] = w + outer_sign * xy[1]
    return SoleCop(xy=xy, margin=margin, edges=tuple(e for e in EDGES if near[e] <= edge_tol))
