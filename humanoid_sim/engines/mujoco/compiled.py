"""Compiled (numba) forms of the MuJoCo engine's per-update and per-step bookkeeping.

The reference of every number here is the NumPy code of :mod:`humanoid_sim.engines.mujoco.contact`,
:mod:`humanoid_sim.engines.mujoco.state`, :func:`humanoid_sim.engines.mujoco.ground.sole_friction` and
:func:`humanoid_sim.engines.mujoco.trace.contact_record`; these functions compute the same numbers in the same order
of floating-point operations (so the same bits; ``tests/engines/test_mujoco_compiled.py`` checks that at every update
of real walks), without the ~50 small NumPy calls per read.  Where NumPy's order is its libraries' (Eigen's
quaternion norm, a BLAS matrix-vector product), it was measured on this machine's builds (pinocchio's and NumPy's
wheels): another build could differ in the last bit, which that test allows where those libraries' rounding enters.

- :func:`contact_loads`: each sole box's normal force and each foot's penetration (:func:`.contact.foot_loads`);
- :func:`ground_update`: those loads, the running penetration maximum, and a copy of what the slip and tilt
  measures read (sole boxes' placements, main bodies' z axes) into a row of a buffer that
  :class:`humanoid_sim.engines.mujoco.ground.GroundMeter` reduces with NumPy in batches (the tilt's ``np.arctan2`` is
  not libm's ``atan2`` to the bit, so it stays NumPy's); the feet's and the lower trunk's tilts by libm, for the fall
  tests' thresholds only (the engine recomputes NumPy's value near a threshold); the feet's friction
  (:func:`sole_friction`, with Python's own ``math.hypot``: :func:`py_hypot`);
- :func:`slip_reduce`: the slip meters (:class:`.contact.SlipMeter`) over a buffer's rows, from the sole corners
  NumPy computed from them (its matrix product may fuse multiply-adds: it stays NumPy's);
- :func:`contact_wrenches`: the log's foot wrenches, centres of pressure and body wrenches of a step
  (:func:`.contact.foot_contacts` and :func:`.trace.body_wrenches`), and :func:`trace_row`: a full-rate trace row
  (the time and indices, MuJoCo's state and acceleration, those wrenches) in one call per MuJoCo step;
- :func:`pin_state`, :func:`pin_acceleration`, :func:`dynamics_residual`, :func:`put_ctrl`: the state map's hot
  path (:class:`.state.StateMap`'s q, v, a, tau of MuJoCo's constraint forces, the motors' torques), and
  :func:`pin_trajectory`: q, v, a of every row of a trace in one call.

Array arguments are MuJoCo's own (``data.contact.geom``, ``data.efc_force``, ...), read for an elliptic friction
cone (a contact's normal force is its first ``efc_force`` row); the callers take the NumPy path otherwise.
NumPy's sums and small products start from +0.0 (``np.sum``, ``np.einsum``, a 3 x 3 matrix times a vector, all
measured on this code's inputs), which turns a -0.0 result into +0.0: the chains below start from 0.0 for that.
"""

from __future__ import annotations

import math

import numpy as np

from humanoid_sim.jit import AVAILABLE, njit  # noqa: F401 - AVAILABLE: whether numba is installed (else NumPy)

ENTRY_POINTS = ("contact_loads", "ground_update", "contact_wrenches", "trace_row", "pin_state", "pin_acceleration",
                "pin_trajectory", "dynamics_residual", "put_ctrl", "all_finite", "slip_reduce")
"""The functions the engine calls from Python (numba caches each with its callees)."""
CONTACT_ENTRY_POINTS = ("contact_loads", "ground_update", "contact_wrenches", "trace_row")
"""Those that read MuJoCo's contact fields: views with the contact struct's stride (numba's layout 'A') when there
are two contacts or more, C-contiguous with one or none; each is compiled for both."""


def cache_ready() -> bool:
    """Whether numba's disk cache holds a current compilation of every entry point (its index matches this file's
    source); True without numba (nothing to compile), False when unsure."""
    if not AVAILABLE:
        return True
    try:
        return all(len(globals()[name]._cache._cache_file._load_index()) >= (2 if name in CONTACT_ENTRY_POINTS else 1)
                   for name in ENTRY_POINTS)
    except Exception:  # pragma: no cover - numba internals changed
        return False


ROW_FLOATS = 54
"""Floats of a :func:`ground_update` buffer row: per sole box (R toe, R main, L toe, L main) its geom's world
position (3) and rotation matrix (9, row-major), then per foot (R, L) the third column (R02, R12, R22) of its
main body's rotation matrix."""
ROW_FLAGS = 5
"""Flags of a buffer row: per sole box whether it supports (its normal force >= the threshold), then the stance
foot (0 R, 1 L, -1 none)."""
OUT_SIZE = 17
"""Floats of :func:`ground_update`'s ``out``: 0-3 the boxes' normal forces (N), 4-5 the feet's penetrations (m),
6 the running penetration maximum (m; read and updated), 7-8 the feet's main-body tilts by libm (rad), 9 the lower
trunk's tilt by libm (rad), 10 the lower trunk's CoM height (m), 11-16 per foot (R, L) its friction: normal force
(N), cone use, slip speed (m/s) (:func:`humanoid_sim.engines.mujoco.ground.sole_friction`)."""
FRICTION_SKIPPED = 8
"""Bit of :func:`ground_update`'s return: the friction was not read (a sole-floor contact of another ``dim`` than 1
or 3, or without a positive friction coefficient where one divides: the caller reads it the NumPy way)."""


@njit
def contact_loads(geom: np.ndarray, dist: np.ndarray, efc_address: np.ndarray, efc_force: np.ndarray,
                  group: np.ndarray, out: np.ndarray) -> None:
    """Write into ``out`` (6,) each sole box's normal force (N; R toe, R main, L toe, L main) and each foot's
    penetration (m, >= 0; R, L), as :func:`humanoid_sim.engines.mujoco.contact._loads` sums them: per box, its contacts'
    normal forces left to right in MuJoCo's order; per foot, max(0, deepest -dist) when it touches, else 0.

    ``geom`` (ncon, 2), ``dist`` (ncon,), ``efc_address`` (ncon,): MuJoCo's contacts; ``efc_force``: the
    constraint forces (an elliptic cone's normal force is the contact's first row; 0 without rows); ``group``
    (ngeom, ngeom): 2 foot + box of a sole-floor geom pair (either order), else -1."""
    for j in range(4):
        out[j] = 0.0
    deep0 = -math.inf
    deep1 = -math.inf
    touch0 = False
    touch1 = False
    for c in range(geom.shape[0]):
        g = group[geom[c, 0], geom[c, 1]]
        if g < 0:
            continue
        a = efc_address[c]
        out[g] += efc_force[a] if a >= 0 else 0.0
        d = -dist[c]
        if g < 2:
            touch0 = True
            if d > deep0:
                deep0 = d
        else:
            touch1 = True
            if d > deep1:
                deep1 = d
    # Python's max(0.0, deepest): 0.0 unless deepest is larger (so -0.0 stays 0.0)
    out[4] = deep0 if touch0 and deep0 > 0.0 else 0.0
    out[5] = deep1 if touch1 and deep1 > 0.0 else 0.0


@njit
def _tilt(R: np.ndarray, body: int) -> float:
    """Angle (rad) of body's z axis from the world z axis, by libm (``np.arctan2`` may differ in the last bit)."""
    return math.atan2(math.hypot(R[body, 2], R[body, 5]), R[body, 8])


_T27 = 134217729.0
"""2^27 + 1: Veltkamp's constant, splitting a double into two halves whose products are exact."""


@njit
def _add(csum: float, x: float, frac: float) -> tuple[float, float]:
    """csum + x and frac plus the sum's rounding error (|csum| >= |x|)."""
    s = csum + x
    return s, frac + ((csum - s) + x)


@njit
def py_hypot(x: float, y: float) -> float:
    """Python's ``math.hypot(x, y)`` to the bit: CPython 3.11's ``vector_norm`` (scaling by a power of two, squares
    split into exact halves, compensated sums and a corrected square root; below the normal range a plain scaled
    sum), not libm's ``hypot``, which may differ in the last bit."""
    x = abs(x)
    y = abs(y)
    big = 0.0
    if x > big:
        big = x
    if y > big:
        big = y
    if math.isinf(big):
        return big
    if math.isnan(x) or math.isnan(y):
        return math.nan
    if big == 0.0:
        return big
    e = math.frexp(big)[1]
    csum, frac1, frac2, frac3 = 1.0, 0.0, 0.0, 0.0
    if e >= -1023:
        scale = math.ldexp(1.0, -e)
        for v in (x * scale, y * scale):
            t = v * _T27
            hi = t - (t - v)
            lo = v - hi
            csum, frac1 = _add(csum, hi * hi, frac1)
            csum, frac2 = _add(csum, 2.0 * hi * lo, frac2)
            frac3 += lo * lo
        h = math.sqrt(csum - 1.0 + (frac1 + frac2 + frac3))
        t = h * _T27
        hi = t - (t - h)
        lo = h - hi
        csum, frac1 = _add(csum, -hi * hi, frac1)
        csum, frac2 = _add(csum, -2.0 * hi * lo, frac2)
        csum, frac3 = _add(csum, -lo * lo, frac3)
        return (h + (csum - 1.0 + (frac1 + frac2 + frac3)) / (2.0 * h)) / scale
    for v in (x / big, y / big):     # ldexp(1.0, -e) would overflow: scaled by the largest instead
        csum, frac1 = _add(csum, v * v, frac1)
    return big * math.sqrt(csum - 1.0 + frac1)


@njit
def sole_friction(geom: np.ndarray, dim: np.ndarray, efc_address: np.ndarray, friction: np.ndarray,
                  efc_force: np.ndarray, efc_vel: np.ndarray, group: np.ndarray, out: np.ndarray, o: int) -> bool:
    """:func:`humanoid_sim.engines.mujoco.ground.sole_friction` for an elliptic cone: per foot (R, L) into
    ``out[o:o + 6]`` its contacts' normal force (N), cone use and slip speed (m/s), summed in MuJoCo's contact
    order with the same operations.  ``friction`` (ncon, 5): the contacts' coefficients; ``efc_vel``: the
    constraint rows' velocities; the rest as :func:`contact_loads`.  Returns False, writing nothing, for a
    sole-floor contact with rows whose ``dim`` is neither 1 nor 3 or whose tangential coefficients are not
    positive (the caller then takes the NumPy path)."""
    for c in range(geom.shape[0]):
        if group[geom[c, 0], geom[c, 1]] >= 0 and efc_address[c] >= 0:
            d = dim[c]
            if d != 1 and (d != 3 or not (friction[c, 0] > 0.0 and friction[c, 1] > 0.0)):
                return False
    n0, n1, u0, u1, s0, s1 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for c in range(geom.shape[0]):
        g = group[geom[c, 0], geom[c, 1]]
        a = efc_address[c]
        if g < 0 or a < 0:
            continue
        n = efc_force[a]
        if dim[c] == 1:
            u = 0.0
            slip = 0.0
        else:
            u = py_hypot(efc_force[a + 1] / friction[c, 0], efc_force[a + 2] / friction[c, 1])
            slip = n * py_hypot(efc_vel[a + 1], efc_vel[a + 2])
        if g < 2:
            n0 += n
            if dim[c] != 1:
                u0 += u
                s0 += slip
        else:
            n1 += n
            if dim[c] != 1:
                u1 += u
                s1 += slip
    for f, n, u, slip in ((0, n0, u0, s0), (1, n1, u1, s1)):
        p = o + 3 * f
        out[p] = n
        if n > 0:
            out[p + 1] = u / n
            out[p + 2] = slip / n
        else:
            out[p + 1] = 0.0
            out[p + 2] = 0.0
    return True


@njit
def ground_update(geom: np.ndarray, dist: np.ndarray, dim: np.ndarray, efc_address: np.ndarray,
                  friction: np.ndarray, efc_force: np.ndarray, efc_vel: np.ndarray, group: np.ndarray,
                  ids: np.ndarray, geom_xpos: np.ndarray, geom_xmat: np.ndarray, xmat: np.ndarray, xipos: np.ndarray,
                  f_min: float, limits: np.ndarray, stance: int, rows: np.ndarray, flags: np.ndarray, row: int,
                  out: np.ndarray) -> int:
    """One control update's ground reads (module docstring).  Returns which feet carry at least ``f_min`` of
    normal force (bit 0 R, bit 1 L), plus 4 when a fall test may fire: ``limits`` = [a foot tilt, a CoM height,
    a trunk tilt]; one foot alone loaded with its libm tilt above limits[0], the trunk's CoM below limits[1] or
    its libm tilt above limits[2]; plus :data:`FRICTION_SKIPPED` when the feet's friction (out[11:17],
    :func:`sole_friction`) was not read.

    ``ids`` = [sole geom of R toe, R main, L toe, L main, main body R, main body L, lower-trunk body];
    ``geom_xpos`` / ``geom_xmat`` / ``xmat`` / ``xipos``: MuJoCo's; ``stance``: the flat-held foot (0 R, 1 L, -1
    none); ``rows`` / ``flags``: the buffer, row ``row`` written (:data:`ROW_FLOATS`, :data:`ROW_FLAGS`);
    ``out``: :data:`OUT_SIZE` floats, out[6] the running penetration maximum."""
    contact_loads(geom, dist, efc_address, efc_force, group, out)
    for f in range(2):
        p = out[4 + f]
        if p > out[6]:                    # Python's max(penetration_max, p)
            out[6] = p
    for b in range(4):
        on = out[b] >= f_min
        flags[row, b] = on
        if on:
            g = ids[b]
            for j in range(3):
                rows[row, 12 * b + j] = geom_xpos[g, j]
            for j in range(9):
                rows[row, 12 * b + 3 + j] = geom_xmat[g, j]
    flags[row, 4] = stance
    loaded = 0
    for f in range(2):
        body = ids[4 + f]
        for j in range(3):
            rows[row, 48 + 3 * f + j] = xmat[body, 3 * j + 2]
        out[7 + f] = _tilt(xmat, body)
        if out[2 * f] + out[2 * f + 1] >= f_min:
            loaded |= 1 << f
    base = ids[6]
    out[9] = _tilt(xmat, base)
    out[10] = xipos[base, 2]
    if not sole_friction(geom, dim, efc_address, friction, efc_force, efc_vel, group, out, 11):
        loaded |= FRICTION_SKIPPED
    feet = loaded & 3
    if (feet == 1 and out[7] > limits[0]) or (feet == 2 and out[8] > limits[0]) or out[10] < limits[1] \
            or out[9] > limits[2]:
        return loaded | 4
    return loaded


@njit
def _dot_col(M: np.ndarray, i: int, x0: float, x1: float, x2: float) -> float:
    """Column i of the row-major 3 x 3 matrix M (9,) dotted with x, as NumPy's ``M.reshape(3, 3).T @ x``."""
    return ((0.0 + M[i] * x0) + M[3 + i] * x1) + M[6 + i] * x2


WRENCH_FLOATS = 42
"""Floats of :func:`contact_wrenches`' output: the feet's wrenches ``fw`` (2 x 6), their centres of pressure ``cop``
(2 x 3), the foot bodies' forces ``bf`` and moments ``bm`` (4 x 3 each), row-major, in this order."""


@njit
def _wrenches(geom: np.ndarray, pos: np.ndarray, frame: np.ndarray, dim: np.ndarray, efc_address: np.ndarray,
              efc_force: np.ndarray, group: np.ndarray, floor: int, bodies: np.ndarray, xipos: np.ndarray,
              xmat: np.ndarray, out: np.ndarray, o: int) -> bool:
    """:func:`contact_wrenches` writing its :data:`WRENCH_FLOATS` floats into ``out[o:o + 42]`` (1-d)."""
    n = geom.shape[0]
    d0 = -1
    for c in range(n):
        if group[geom[c, 0], geom[c, 1]] >= 0:
            if efc_address[c] < 0 or (d0 >= 0 and dim[c] != d0):
                return False
            d0 = dim[c]
    fw, cp, bf, bm = o, o + 12, o + 18, o + 30
    for j in range(12):
        out[fw + j] = 0.0
    for j in range(24):
        out[bf + j] = 0.0
    body_sum = np.zeros((4, 6))
    body_hit = np.zeros(4, dtype=np.bool_)
    f6 = np.zeros(6)
    for foot in range(2):
        touched = False
        w = fw + 6 * foot
        for c in range(n):
            g = group[geom[c, 0], geom[c, 1]]
            if g < 0 or (g >> 1) != foot:
                continue
            touched = True
            # the force acts on geom2's body: +1 when the sole is geom2 (the floor geom1), -1 the other way
            s = 1.0 if geom[c, 0] == floor else -1.0
            a = efc_address[c]
            for j in range(6):
                f6[j] = efc_force[a + j] if j < d0 else 0.0
            F = frame[c]
            # world force = frame^T @ local force (np.einsum's chain from 0.0), times the sign
            fx = s * (((0.0 + F[0] * f6[0]) + F[3] * f6[1]) + F[6] * f6[2])
            fy = s * (((0.0 + F[1] * f6[0]) + F[4] * f6[1]) + F[7] * f6[2])
            fz = s * (((0.0 + F[2] * f6[0]) + F[5] * f6[1]) + F[8] * f6[2])
            tx = s * (((0.0 + F[0] * f6[3]) + F[3] * f6[4]) + F[6] * f6[5])
            ty = s * (((0.0 + F[1] * f6[3]) + F[4] * f6[4]) + F[7] * f6[5])
            tz = s * (((0.0 + F[2] * f6[3]) + F[5] * f6[4]) + F[8] * f6[5])
            px, py, pz = pos[c, 0], pos[c, 1], pos[c, 2]
            # moment about the world origin: p x f plus the contact torque (contact._cross's products)
            mx = (py * fz - pz * fy) + tx
            my = (pz * fx - px * fz) + ty
            mz = (px * fy - py * fx) + tz
            out[w] += fx
            out[w + 1] += fy
            out[w + 2] += fz
            out[w + 3] += mx
            out[w + 4] += my
            out[w + 5] += mz
            # the contact's share of its body's wrench: force, and arm x force about the body's CoM
            r = foot + 2 * (g & 1)
            body = bodies[r]
            ax, ay, az = px - xipos[body, 0], py - xipos[body, 1], pz - xipos[body, 2]
            body_hit[r] = True
            body_sum[r, 0] += fx
            body_sum[r, 1] += fy
            body_sum[r, 2] += fz
            body_sum[r, 3] += ay * fz - az * fy
            body_sum[r, 4] += az * fx - ax * fz
            body_sum[r, 5] += ax * fy - ay * fx
        fz = out[w + 2]
        p = cp + 3 * foot
        if touched and fz > 0:
            out[p] = -out[w + 4] / fz
            out[p + 1] = out[w + 3] / fz
            out[p + 2] = 0.0
        else:
            out[p] = np.nan
            out[p + 1] = np.nan
            out[p + 2] = np.nan
    for r in range(4):
        if body_hit[r]:
            M = xmat[bodies[r]]
            t = body_sum[r]
            for i in range(3):
                out[bf + 3 * r + i] = _dot_col(M, i, t[0], t[1], t[2])
                out[bm + 3 * r + i] = _dot_col(M, i, t[3], t[4], t[5])
    return True


@njit
def contact_wrenches(geom: np.ndarray, pos: np.ndarray, frame: np.ndarray, dim: np.ndarray,
                     efc_address: np.ndarray, efc_force: np.ndarray, group: np.ndarray, floor: int,
                     bodies: np.ndarray, xipos: np.ndarray, xmat: np.ndarray, out: np.ndarray) -> bool:
    """The ground's wrench on each foot and on each foot body at the current MuJoCo data (after ``mj_step`` or
    ``mj_forward``), as :func:`humanoid_sim.engines.mujoco.contact.foot_contacts` and :func:`humanoid_sim.engines.
    mujoco.trace.contact_record` compute them.  Returns False, writing nothing, when a sole-floor contact has no
    constraint rows or the contacts' ``dim`` differ (the callers then take the NumPy path, which reads such
    contacts with ``mj_contactForce``).

    ``geom`` (ncon, 2), ``pos`` (ncon, 3), ``frame`` (ncon, 9), ``dim``, ``efc_address``: MuJoCo's contacts;
    ``group``: as :func:`contact_loads`; ``floor``: the ground plane's geom id; ``bodies`` (4,): the foot bodies
    by log row (R toe, L toe, R main, L main: thesis bodies 1-4).  Writes ``out`` (:data:`WRENCH_FLOATS`,): ``fw``
    (2, 6), per foot (R, L) the force (N, world frame) and its moment about the world origin (N m); ``cop`` (2, 3),
    the centre of pressure on z = 0 (m; NaN without positive normal force); ``bf`` / ``bm`` (4, 3), per foot body
    (log row = body - 1) the force and the moment about its CoM, in the body frame (N, N m), zero for a body
    without contact."""
    return _wrenches(geom, pos, frame, dim, efc_address, efc_force, group, floor, bodies, xipos, xmat, out, 0)


@njit
def trace_row(geom: np.ndarray, pos: np.ndarray, frame: np.ndarray, dim: np.ndarray, efc_address: np.ndarray,
              efc_force: np.ndarray, group: np.ndarray, floor: int, bodies: np.ndarray, xipos: np.ndarray,
              xmat: np.ndarray, qpos: np.ndarray, qvel: np.ndarray, qacc: np.ndarray, t: float, k: int, basic: int,
              update: int, wrenches: bool, block: np.ndarray, i: int) -> bool:
    """Row ``i`` of ``block`` (a full-rate trace's row, :mod:`humanoid_sim.engines.mujoco.trace`): ``t`` (s),
    ``k`` (the loop step), ``basic`` (the basic phase), ``update`` (the control update), MuJoCo's ``qpos``,
    ``qvel`` (the state at the MuJoCo step's start) and ``qacc``, then with ``wrenches`` the ground's wrenches of
    :func:`contact_wrenches` (the contact arguments as there).  Returns whether the wrenches were written (False:
    not asked, or :func:`contact_wrenches` declined; the caller writes them)."""
    row = block[i]
    row[0] = t
    row[1] = k
    row[2] = basic
    row[3] = update
    o = 4
    for j in range(qpos.size):
        row[o + j] = qpos[j]
    o += qpos.size
    for j in range(qvel.size):
        row[o + j] = qvel[j]
    o += qvel.size
    for j in range(qacc.size):
        row[o + j] = qacc[j]
    o += qacc.size
    if not wrenches:
        return False
    return _wrenches(geom, pos, frame, dim, efc_address, efc_force, group, floor, bodies, xipos, xmat, row, o)


# ---------------------------------------------------------------------------------------- the state map's hot path
@njit
def _rotate_back(x: float, y: float, z: float, w: float, u: np.ndarray, out: np.ndarray) -> None:
    """out[:3] = R.T @ u[:3], R the rotation of the quaternion (x, y, z, w) as :func:`humanoid_sim.engines.mujoco.state.
    _rotation_xyzw` makes it, ``pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()`` -- Eigen's
    arithmetic: the squared norm summed as (x^2 + z^2) + (y^2 + w^2) (two 2-double packets), each coefficient
    divided by its square root, Eigen's rotation-matrix formula -- and the product as NumPy's (measured: the same
    bits)."""
    s = (x * x + z * z) + (y * y + w * w)
    if s > 0.0:
        n = math.sqrt(s)
        x, y, z, w = x / n, y / n, z / n, w / n
    tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    u0, u1, u2 = u[0], u[1], u[2]
    # column i of R dotted with u (R row-major: R[0] = (1 - (tyy + tzz), txy - twz, txz + twy), ...)
    out[0] = ((0.0 + (1.0 - (tyy + tzz)) * u0) + (txy + twz) * u1) + (txz - twy) * u2
    out[1] = ((0.0 + (txy - twz) * u0) + (1.0 - (txx + tzz)) * u1) + (tyz + twx) * u2
    out[2] = ((0.0 + (txz + twy) * u0) + (tyz - twx) * u1) + (1.0 - (txx + tyy)) * u2


@njit
def _gather(x: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """x[idx] (a new array)."""
    out = np.empty(idx.size)
    for i in range(idx.size):
        out[i] = x[idx[i]]
    return out


@njit
def pin_state(qpos: np.ndarray, qvel: np.ndarray, q_gather: np.ndarray, v_gather: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Pinocchio's (q, v) (new arrays) from MuJoCo's (qpos, qvel), as :meth:`humanoid_sim.engines.mujoco.state.StateMap.
    q_from_qpos` / ``v_from_qvel`` compute them: the gathers, and v's base linear rows rotated into the base
    frame (MuJoCo's quaternion is (w, x, y, z))."""
    q = _gather(qpos, q_gather)
    v = _gather(qvel, v_gather)
    _rotate_back(qpos[4], qpos[5], qpos[6], qpos[3], qvel, v)
    return q, v


@njit
def pin_acceleration(q: np.ndarray, v: np.ndarray, qacc: np.ndarray, v_gather: np.ndarray) -> np.ndarray:
    """Pinocchio's acceleration a (a new array) from MuJoCo's qacc at the state (q, v), as :meth:`humanoid_sim.
    mujoco.state.StateMap.a_from_qacc`: a = qacc[v_gather], then a[:3] = R.T @ qacc[:3] - w x u (u, w: v's base
    linear and angular rows)."""
    a = _gather(qacc, v_gather)
    _rotate_back(q[3], q[4], q[5], q[6], qacc, a)
    u0, u1, u2, w0, w1, w2 = v[0], v[1], v[2], v[3], v[4], v[5]
    a[0] = a[0] - (w1 * u2 - w2 * u1)
    a[1] = a[1] - (w2 * u0 - w0 * u2)
    a[2] = a[2] - (w0 * u1 - w1 * u0)
    return a


@njit
def _gather_into(x: np.ndarray, idx: np.ndarray, out: np.ndarray) -> None:
    """out[:] = x[idx]."""
    for i in range(idx.size):
        out[i] = x[idx[i]]


@njit
def pin_trajectory(rows: np.ndarray, qpos_at: int, qvel_at: int, qacc_at: int, nq: int, nv: int,
                   q_gather: np.ndarray, v_gather: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pinocchio's (q, v, a) (new (n, nq), (n, nv), (n, nv) arrays) of every row of ``rows`` (n, width), which holds
    MuJoCo's qpos (``nq`` floats from column ``qpos_at``), qvel and qacc (``nv`` floats each, from ``qvel_at`` and
    ``qacc_at``): per row :func:`pin_state`, then :func:`pin_acceleration` at that (q, v), the same operations."""
    n = rows.shape[0]
    Q = np.empty((n, q_gather.size))
    V = np.empty((n, v_gather.size))
    A = np.empty((n, v_gather.size))
    for r in range(n):
        q, v, a = Q[r], V[r], A[r]
        x, u, acc = rows[r, qpos_at:qpos_at + nq], rows[r, qvel_at:qvel_at + nv], rows[r, qacc_at:qacc_at + nv]
        _gather_into(x, q_gather, q)
        _gather_into(u, v_gather, v)
        _rotate_back(x[4], x[5], x[6], x[3], u, v)
        _gather_into(acc, v_gather, a)
        _rotate_back(q[3], q[4], q[5], q[6], acc, a)
        u0, u1, u2, w0, w1, w2 = v[0], v[1], v[2], v[3], v[4], v[5]
        a[0] = a[0] - (w1 * u2 - w2 * u1)
        a[1] = a[1] - (w2 * u0 - w0 * u2)
        a[2] = a[2] - (w0 * u1 - w1 * u0)
    return Q, V, A


@njit
def dynamics_residual(rnea: np.ndarray, tau: np.ndarray, q: np.ndarray, qfrc_constraint: np.ndarray,
                      v_gather: np.ndarray) -> float:
    """max |rnea - tau - tau_c| (NaN if one is NaN), tau_c = :meth:`humanoid_sim.engines.mujoco.state.StateMap.
    tau_from_qfrc` of MuJoCo's constraint forces at q, as ``np.max(np.abs(rnea - tau - tau_c))``."""
    tau_c = _gather(qfrc_constraint, v_gather)
    _rotate_back(q[3], q[4], q[5], q[6], qfrc_constraint, tau_c)
    worst = 0.0
    for i in range(rnea.size):
        r = abs((rnea[i] - tau[i]) - tau_c[i])
        if r != r:
            return r
        if r > worst:
            worst = r
    return worst


@njit
def put_ctrl(tau: np.ndarray, gather: np.ndarray, ctrl: np.ndarray) -> bool:
    """``ctrl[:] = tau[gather]`` (the motors' torques from Pinocchio's tau) when they are all finite; else False,
    ``ctrl`` unchanged."""
    for i in range(gather.size):
        if not math.isfinite(tau[gather[i]]):
            return False
    for i in range(gather.size):
        ctrl[i] = tau[gather[i]]
    return True


@njit
def all_finite(x: np.ndarray) -> bool:
    """Whether every entry of the 1-d array x is finite."""
    for i in range(x.size):
        if not math.isfinite(x[i]):
            return False
    return True


@njit
def slip_reduce(corners: np.ndarray, row: np.ndarray, box: np.ndarray, n: int, last: np.ndarray,
                anchor: np.ndarray, slip: np.ndarray) -> None:
    """:class:`humanoid_sim.engines.mujoco.contact.SlipMeter`, one per sole box, over a buffer of n updates: ``corners``
    (m, 4, 3) the supporting boxes' sole corners (world frame, m), row ``row[j]`` of the buffer and box ``box[j]``,
    in row order.  A box's support begins at a row that does not follow its previous supporting row: its corners
    are anchored there; at each later row of the support its slip is sqrt of the largest dx^2 + dy^2 of a corner
    from its anchor (in SlipMeter's order of operations), ``slip[b]`` the largest so far (Python's max).

    ``last`` (4,): per box the buffer row of its last supporting row, -1 for the row before the buffer (a support
    carried in; ``anchor[b]`` (4, 4, 3) holds its corners), any other value for none; on return, -1 where the
    box supports at row n - 1, else -2."""
    for j in range(corners.shape[0]):
        r, b = row[j], box[j]
        if last[b] != r - 1:                          # a support begins: its corners are the anchor
            for c in range(4):
                for k in range(3):
                    anchor[b, c, k] = corners[j, c, k]
        else:
            largest = 0.0
            for c in range(4):
                dx = corners[j, c, 0] - anchor[b, c, 0]
                dy = corners[j, c, 1] - anchor[b, c, 1]
                d2 = dx * dx + dy * dy
                if d2 > largest:
                    largest = d2
            s = math.sqrt(largest)
            if s > slip[b]:
                slip[b] = s
        last[b] = r
    for b in range(4):
        last[b] = -1 if last[b] == n - 1 else -2
