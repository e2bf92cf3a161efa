"""Ground reactions of the feet from MuJoCo's contact forces, and slip / tilt / penetration measures.

Every active contact of a sole geom (toe body 1 / 2, main body 3 / 4) with the floor is read as
``mujoco.mj_contactForce`` reads it (:func:`contact_forces`: the same numbers, gathered from ``efc_force`` in one
indexing for an elliptic cone), the force (and, for condim > 3, the torque) in the contact frame ``contact.frame``
(rows: normal, first tangent, second tangent; the normal points from geom1 to geom2).  That force acts on geom2's
body, its negative on geom1's; here it is turned into the force on the foot, in the world frame (thesis frame 0,
z up), applied at ``contact.pos``.

Per foot, :class:`FootContact` gives the resultant force (N), its moment about the world origin (N m), the centre
of pressure on the ground plane z = 0 (m), the normal force of each sole geom (N), the contact points and their
normal forces, and the deepest penetration (m).  :func:`foot_loads` gives only the normal forces and the
penetration (:class:`FootLoad`, what the engine's per-update checks read), the same numbers at a fraction of the
cost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from humanoid_sim.engines.mujoco.model import FEET, MujocoModel

_EMPTY3 = np.zeros((0, 3))


@dataclass
class FootLoad:
    """How hard one foot presses on the ground (SI units): what the engine's touchdown and fall checks read.

    ``normal_toe`` / ``normal_main``: normal force (N) on the toe box and the main-body box, each the sum of its
    contacts' normal forces in MuJoCo's contact order; ``penetration`` (m, >= 0): deepest penetration of a sole
    box (0 without contact)."""

    foot: str
    normal_toe: float = 0.0
    normal_main: float = 0.0
    penetration: float = 0.0

    @property
    def normal(self) -> float:
        """Total normal force on the sole, N."""
        return self.normal_toe + self.normal_main


@dataclass
class FootContact(FootLoad):
    """Ground reaction on one foot (world frame, SI units): its :class:`FootLoad` and the wrench.

    ``force`` (3,) N and ``moment`` (3,) N m about the world origin: the resultant wrench the ground applies to
    the foot (toe and main body together), each the sum over its contacts in MuJoCo's contact order.  ``cop``
    (3,): centre of pressure on the plane z = 0 (NaN when the normal force is zero).  ``points`` (k, 3) contact
    points, ``point_normal`` (k,) their normal forces (N), ``point_force`` (k, 3) their forces on the foot
    (world frame, N), ``point_geom`` (k,) which geom (0 toe, 1 main body), in MuJoCo's contact order.
    """

    force: np.ndarray = field(default_factory=lambda: np.zeros(3))
    moment: np.ndarray = field(default_factory=lambda: np.zeros(3))
    points: np.ndarray = field(default_factory=lambda: _EMPTY3.copy())
    point_normal: np.ndarray = field(default_factory=lambda: np.zeros(0))
    point_force: np.ndarray = field(default_factory=lambda: _EMPTY3.copy())
    point_geom: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

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


_CROSS_A = np.array([1, 2, 0, 2, 0, 1])
_CROSS_B = np.array([2, 0, 1, 1, 2, 0])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (k, 3) arrays: a new (k, 3) array (np.cross costs ~40 us on arrays this small).

    Each component is the same two products and one difference as the textbook formula
    (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0), gathered in one product of (k, 6) arrays."""
    p = a[:, _CROSS_A] * b[:, _CROSS_B]
    return p[:, :3] - p[:, 3:]


@dataclass(frozen=True)
class _SoleTables:
    """Lookup tables of a model's soles.  Per geom id: ``foot`` the foot index (0 'R', 1 'L', -1 not a sole),
    ``box`` the sole box (0 toe, 1 main body).  ``pair_group[g1][g2]`` (nested lists, read per contact in Python):
    the sole's group 2 foot + box when the geom pair (g1, g2) is a sole and the floor (either order), else -1;
    ``pair_array`` the same as an (ngeom, ngeom) array (for :mod:`.compiled`).  Per sole geom id, ``corners``
    (4, 3): its bottom corners in its own frame (m)."""

    foot: np.ndarray
    box: np.ndarray
    pair_group: list[list[int]]
    pair_array: np.ndarray
    corners: dict[int, np.ndarray]


def _tables(mm: MujocoModel) -> _SoleTables:
    """The :class:`_SoleTables` of ``mm`` (built once, cached on it)."""
    tables = getattr(mm, "_sole_tables", None)
    if tables is None:
        n = mm.model.ngeom
        foot = np.full(n, -1, dtype=int)
        box = np.zeros(n, dtype=int)
        pair_group = np.full((n, n), -1, dtype=int)
        corners = {}
        signs = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1]], dtype=float)
        ground = (mm.floor_geom, *mm.terrain_geoms)   # the floor and a scenario's terrain boxes
        for i, f in enumerate(FEET):
            for j, g in enumerate(mm.sole_geoms[f]):
                foot[g], box[g] = i, j
                for w in ground:
                    pair_group[w, g] = pair_group[g, w] = 2 * i + j
                corners[g] = signs * mm.model.geom_size[g]
        tables = _SoleTables(foot, box, pair_group.tolist(), pair_group, corners)
        mm._sole_tables = tables
    return tables


def contact_forces(model: mujoco.MjModel, data: mujoco.MjData, ids: np.ndarray) -> np.ndarray:
    """(k, 6) force and torque of the contacts ``ids`` (indices into ``data.contact``) in their contact frames,
    N and N m: row j is what ``mujoco.mj_contactForce(model, data, ids[j], row)`` writes.

    With an elliptic cone that is a copy of the contact's ``dim`` entries of ``efc_force`` from its
    ``efc_address`` (zeros after them, and for a contact with no constraint rows, efc_address -1); here they are
    gathered in one indexing when every contact has rows and the same ``dim``.  A pyramidal cone (MuJoCo decodes
    the pyramid's edge forces) or mixed contacts take mj_contactForce per contact."""
    ids = np.asarray(ids)
    if ids.ndim != 1 or (ids.size and ids.dtype.kind not in "iu"):
        raise TypeError(f"contact ids: expected a 1-d integer array, got {ids.dtype} of shape {ids.shape}")
    if ids.size and (ids.min() < 0 or ids.max() >= data.ncon):
        raise IndexError(f"contact ids {ids.tolist()}: expected indices in [0, ncon = {data.ncon})")
    return _contact_forces(model, data, ids.astype(np.intp, copy=False))[0]


_RANGE = np.arange(6)


def _contact_forces(model: mujoco.MjModel, data: mujoco.MjData, ids: np.ndarray) -> tuple[np.ndarray, bool]:
    """:func:`contact_forces` of valid ids (not checked), and whether the torques are zero by construction (every
    contact of the gather has dim <= 3: no torsional or rolling friction)."""
    f6 = np.zeros((ids.size, 6))
    if ids.size == 0:
        return f6, True
    con = data.contact
    adr, dim = con.efc_address[ids], con.dim[ids]
    d0 = int(dim[0])
    if model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and adr.min() >= 0 and (dim == d0).all():
        f6[:, :d0] = data.efc_force[adr[:, None] + _RANGE[:d0]]
        return f6, d0 <= 3
    for j, i in enumerate(ids.tolist()):
        mujoco.mj_contactForce(model, data, i, f6[j])
    return f6, False


def _loads(group: list[int], normal: list[float], dist: list[float]) -> dict[str, FootLoad]:
    """The :class:`FootLoad` of each foot from its contacts in MuJoCo's order: ``group`` 2 foot + box of each
    contact (-1: not a sole-floor contact), ``normal`` their normal forces (N), ``dist`` their signed distances
    (m, negative: penetration).  Each box's normal force is summed left to right (for a box's at most 4 contacts
    with a plane, numpy's sum of those forces, to the bit)."""
    sums = [0.0, 0.0, 0.0, 0.0]
    deepest = [-math.inf, -math.inf]
    touches = [False, False]
    for g, n, d in zip(group, normal, dist):
        if g < 0:
            continue                    # not a sole-floor contact (the model has none, by contype)
        f = g >> 1
        sums[g] += n
        touches[f] = True
        if -d > deepest[f]:
            deepest[f] = -d
    return {foot: FootLoad(foot, sums[2 * i], sums[2 * i + 1], max(0.0, deepest[i])) if touches[i]
            else FootLoad(foot) for i, foot in enumerate(FEET)}


def foot_loads(mm: MujocoModel, data: mujoco.MjData) -> dict[str, FootLoad]:
    """Normal forces and penetration of each foot at the current ``data`` (after ``mj_forward`` or ``mj_step``):
    the part of :func:`foot_contacts` that the touchdown and fall checks read (the same numbers: both sum with
    :func:`_loads`), a few times cheaper than the whole (no contact frames, points or moments; a few contacts,
    read as Python floats)."""
    ncon = data.ncon
    if ncon == 0:
        return {foot: FootLoad(foot) for foot in FEET}
    model, con = mm.model, data.contact
    if model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC:
        # an elliptic cone's normal force is the contact's first efc row (mj_contactForce: zero without rows)
        efc = data.efc_force.tolist()
        normal = [efc[a] if a >= 0 else 0.0 for a in con.efc_address.tolist()]
    else:
        normal = _contact_forces(model, data, np.arange(ncon))[0][:, 0].tolist()
    pair_group = _tables(mm).pair_group
    group = [pair_group[g1][g2] for g1, g2 in con.geom.tolist()]
    return _loads(group, normal, con.dist.tolist())


def _sole_floor(mm: MujocoModel, foot_of: np.ndarray, geoms: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The sole-floor contacts among ``geoms`` ((ncon, 2) geom ids of MuJoCo's contacts), ordered by foot (R then
    L; MuJoCo's order within a foot): their contact indices, their sole geoms, and the sign that turns the contact
    force into the force on the foot (+1 when the sole is geom2, -1 when it is geom1; None when all are +1)."""
    g1, g2 = geoms[:, 0], geoms[:, 1]
    # the other geom of a sole's contact is ground (the floor or a terrain box): the soles collide with nothing else
    on2 = (foot_of[g2] >= 0) & (foot_of[g1] < 0)   # the force acts on geom2's body: the foot
    if on2.all():   # the usual case: MuJoCo puts the plane first, and only soles collide with it
        ids = np.argsort(foot_of[g2], kind="stable")
        return ids, g2[ids], None
    on1 = (foot_of[g1] >= 0) & (foot_of[g2] < 0)   # the force acts on geom1's body: minus it on the foot
    keep = np.flatnonzero(on1 | on2)  # others are not sole-floor contacts (the model has none, by contype)
    geom = np.where(on2, g2, g1)[keep]
    order = np.argsort(foot_of[geom], kind="stable")
    return keep[order], geom[order], np.where(on2, 1.0, -1.0)[keep[order]]


def foot_contacts(mm: MujocoModel, data: mujoco.MjData) -> dict[str, FootContact]:
    """Ground reaction of each foot at the current ``data`` (after ``mj_forward`` or ``mj_step``).

    Each foot's force and moment are sums over its contacts in MuJoCo's order (the order of ``data.contact``);
    its points, point forces, normals and geoms are in that order too."""
    if data.ncon == 0:
        return {foot: FootContact(foot) for foot in FEET}
    tables = _tables(mm)
    con = data.contact
    ids, geom, sign = _sole_floor(mm, tables.foot, con.geom)
    if ids.size == 0:
        return {foot: FootContact(foot) for foot in FEET}
    f6, no_torque = _contact_forces(mm.model, data, ids)
    frames = con.frame[ids].reshape(ids.size, 3, 3)
    P = con.pos[ids]
    # contact frame rows: normal, tangents; world vector = frame^T @ local.  fm: [force on the foot (world
    # frame), its moment about the world origin] per contact
    fm = np.empty((ids.size, 6))
    if sign is None:
        fm[:, :3] = np.einsum("kji,kj->ki", frames, f6[:, :3])
    else:
        fm[:, :3] = sign[:, None] * np.einsum("kji,kj->ki", frames, f6[:, :3])
    if sign is None and no_torque:
        # no contact torques (condim 3): their rotation would be +0.0 exactly; adding it, as the general branch
        # does, only turns a moment component of -0.0 into +0.0, and so does adding 0.0
        fm[:, 3:] = _cross(P, fm[:, :3]) + 0.0
    else:
        T = np.einsum("kji,kj->ki", frames, f6[:, 3:])
        fm[:, 3:] = _cross(P, fm[:, :3]) + (T if sign is None else sign[:, None] * T)
    feet, boxes = tables.foot[geom], tables.box[geom]
    loads = _loads((2 * feet + boxes).tolist(), f6[:, 0].tolist(), con.dist[ids].tolist())
    n_right = ids.size - int(np.count_nonzero(feet))
    out = {}
    for foot, (a, b) in zip(FEET, ((0, n_right), (n_right, ids.size))):
        load = loads[foot]
        if a == b:
            out[foot] = FootContact(foot)
            continue
        total = fm[a:b].sum(axis=0)
        out[foot] = FootContact(foot, load.normal_toe, load.normal_main, load.penetration, force=total[:3],
                                moment=total[3:], points=P[a:b], point_normal=f6[a:b, 0],
                                point_force=fm[a:b, :3], point_geom=boxes[a:b])
    return out


# ---------------------------------------------------------------------------------------- sole measures
def sole_corners(mm: MujocoModel, data: mujoco.MjData, foot: str, box: int = 1) -> np.ndarray:
    """(4, 3) world positions of the bottom corners of one of the foot's sole boxes, m (after kinematics):
    ``box`` 1 the main body's (default), 0 the toe body's."""
    g = mm.sole_geoms[foot][box]
    return data.geom_xpos[g] + _tables(mm).corners[g] @ data.geom_xmat[g].reshape(3, 3).T


def sole_tilt(mm: MujocoModel, data: mujoco.MjData, foot: str, box: int = 1) -> float:
    """Angle (rad) between a sole box's normal (the z axis of the foot's main body, ``box`` 1, or of its toe body,
    0) and the world z axis."""
    R = data.xmat[mm.foot_bodies[foot][box]].reshape(3, 3)
    return float(np.arctan2(np.hypot(R[0, 2], R[1, 2]), R[2, 2]))  # well conditioned near 0, unlike arccos


def bearing_tilt(mm: MujocoModel, data: mujoco.MjData, foot: str, main_load: float, f_min: float) -> float:
    """The tilt (rad) of the part of ``foot`` that bears its load: its main body's sole (:func:`sole_tilt`), or,
    when the main body carries less than ``f_min`` (N; ``main_load`` its normal force), its toe body's.  A foot
    on its toe with its heel lifted (a double support's toe-off) has a tilted main body on a flat toe box: it has
    not tipped.  With terrain boxes in the model the tilt is measured from the ground under the foot
    (:func:`ground_tilt`): a foot standing flat on a slope has not tipped either."""
    return ground_tilt(mm, data, foot, 1 if main_load >= f_min else 0)


def ground_tilt(mm: MujocoModel, data: mujoco.MjData, foot: str, box: int = 1) -> float:
    """Angle (rad) between a sole box's normal (the z axis of the foot's main body, ``box`` 1, or of its toe body,
    0) and the ground under the foot (:func:`ground_normal`); :func:`sole_tilt` when the model has no terrain boxes
    or that ground is level."""
    n = ground_normal(mm, data, foot) if mm.terrain_geoms else None
    if n is None or (n[0] == 0.0 and n[1] == 0.0):      # level ground: the vertical's tilt, as on the floor
        return sole_tilt(mm, data, foot, box)
    z = in_ground_frame(data.xmat[mm.foot_bodies[foot][box]].reshape(3, 3)[:, 2], n)
    return float(np.arctan2(np.hypot(z[0], z[1]), z[2]))


def in_ground_frame(z: np.ndarray, n: np.ndarray) -> np.ndarray:
    """The world vector ``z`` (3,) in a frame whose third axis is the unit ground normal ``n`` (3,) (its first two
    axes any orthonormal pair in the ground's plane): arctan2(hypot(x, y), z) of the result is the angle between
    ``z`` and ``n``, the form :func:`sole_tilt` takes from the vertical."""
    # the world axis least aligned with n makes a well-conditioned first in-plane axis
    e = np.zeros(3)
    e[int(np.argmin(np.abs(n)))] = 1.0
    e1 = np.cross(n, e)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    return np.array([float(z @ e1), float(z @ e2), float(z @ n)])


def ground_normal(mm: MujocoModel, data: mujoco.MjData, foot: str) -> np.ndarray:
    """The unit normal (3,) of the ground ``foot`` presses on, world frame: the mean of the top-face normals of the
    geoms its sole boxes touch (the floor's is +z; a terrain box's its z axis, whichever face the contact is on),
    weighted by the contacts' normal forces; +z when the foot presses on nothing."""
    soles = mm.sole_geoms[foot]
    terrain = mm.terrain_geoms
    up = np.array([0.0, 0.0, 1.0])
    ids, others = [], []
    for i, (g1, g2) in enumerate(data.contact.geom[:data.ncon].tolist()):
        other = g2 if g1 in soles else g1 if g2 in soles else -1
        if other >= 0:
            ids.append(i)
            others.append(other)
    nx = ny = nz = 0.0
    if ids:     # their normal forces gathered at once (mj_contactForce's, per contact)
        normal = _contact_forces(mm.model, data, np.array(ids, dtype=np.intp))[0][:, 0].tolist()
        axes = data.geom_xmat[:, 2::3]      # each geom's z axis
        for f, other in zip(normal, others):
            ax, ay, az = axes[other].tolist() if other in terrain else (0.0, 0.0, 1.0)
            w = max(f, 0.0)
            nx += w * ax
            ny += w * ay
            nz += w * az
    n = np.array([nx, ny, nz])
    size = float(np.linalg.norm(n))
    return n / size if size > 0.0 else up


def ground_slope(mm: MujocoModel) -> float:
    """The largest tilt (rad) of a terrain box's top face from the horizontal (0 without terrain): how far a foot
    standing flat on the terrain can be tilted from the vertical.  Terrain boxes are static geoms of the world
    body: their model orientation is their world one."""
    out = 0.0
    R = np.zeros(9)
    for g in mm.terrain_geoms:
        mujoco.mju_quat2Mat(R, mm.model.geom_quat[g])
        out = max(out, float(np.arctan2(np.hypot(R[2], R[5]), R[8])))
    return out


class SlipMeter:
    """Horizontal travel of each sole while it supports.

    ``update(foot, supporting, corners)`` with the main-body sole corners (:func:`sole_corners`): when a foot
    starts supporting, its corners are recorded; while it supports, its slip is the largest horizontal distance
    of a corner from its recorded position (m), so a rotation about the vertical counts as well as a slide.
    ``max_slip[foot]`` is the largest slip over all its supports; ``current[foot]`` that of the present support.
    """

    def __init__(self) -> None:
        self._anchor: dict[str, list[list[float]] | None] = {foot: None for foot in FEET}
        self.current = {foot: 0.0 for foot in FEET}
        self.max_slip = {foot: 0.0 for foot in FEET}

    def update(self, foot: str, supporting: bool, corners: np.ndarray) -> float:
        """The slip of ``foot`` (m) given whether it supports now and its (k, 3) sole corners (world frame, m;
        read only while it supports)."""
        if not supporting:
            self._anchor[foot] = None
            self.current[foot] = 0.0
            return 0.0
        anchor = self._anchor[foot]
        if anchor is None:
            self._anchor[foot] = np.asarray(corners, dtype=float).tolist()
            return 0.0
        # in floats, with numpy's arithmetic for np.max(np.linalg.norm(corners[:, :2] - anchor, axis=1)): the
        # largest dx^2 + dy^2, then its square root (sqrt is correctly rounded and increasing: the same number)
        largest = 0.0
        for c, a in zip(np.asarray(corners, dtype=float).tolist(), anchor, strict=True):
            dx, dy = c[0] - a[0], c[1] - a[1]
            d2 = dx * dx + dy * dy
            if d2 > largest:
                largest = d2
        s = math.sqrt(largest)
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
    from humanoid_sim.robot.sole import signed_distance

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
