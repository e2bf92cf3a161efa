"""The feet on MuJoCo's ground over a run: what the MuJoCo engine measures at every control update.

At each update (the state right after the update's first MuJoCo step) a meter reads

- each sole box's normal force and each foot's penetration (:func:`.contact.foot_loads`), and from them which
  feet carry at least ``f_min`` of normal force (the fall tests' "loaded" feet);
- the running maxima that ``summary.json`` reports: penetration; each sole box's slip while it supports
  (:class:`.contact.SlipMeter` on its :func:`.contact.sole_corners`, one meter per box); the tilt of a foot's main
  body while its box supports (:func:`.contact.sole_tilt`), over both feet and over the stance foot alone;
- what the fall tests read: each foot's main-body tilt, the lower trunk's tilt and CoM height.

:class:`ReferenceGroundMeter` does it with the NumPy functions of :mod:`.contact` at every update (the reference,
``compiled=False``).  :class:`GroundMeter` gives the same numbers: one compiled call per update
(:func:`.compiled.ground_update`) reads the loads and copies the boxes' placements and the main bodies' z axes
into a buffer row, and the slip and tilt maxima are reduced from the buffer every :attr:`GroundMeter.chunk`
updates (and when read), with the same operations as the reference on each row: the sole corners and the tilts
by NumPy (its matrix product may fuse multiply-adds; its ``np.arctan2`` is not libm's ``atan2`` to the bit), the
slip meters' arithmetic compiled (:func:`.compiled.slip_reduce`).

Both meters fill :attr:`out` (:data:`.compiled.OUT_SIZE` floats, layout there): the fall tests' tilts there are
libm's for :class:`GroundMeter`, so a test near a threshold recomputes NumPy's (:func:`.contact.sole_tilt`).
"""

from __future__ import annotations

import mujoco
import numpy as np

from humanoid_sim.engines.mujoco.compiled import (
    OUT_SIZE,
    ROW_FLAGS,
    ROW_FLOATS,
    contact_loads,
    ground_update,
    slip_reduce,
)
from humanoid_sim.engines.mujoco.contact import SlipMeter, _tables, foot_loads, sole_corners, sole_tilt
from humanoid_sim.engines.mujoco.model import FEET, MujocoModel

_NO_CORNERS = np.zeros((4, 3))
"""What a slip meter is handed for a box that does not support (it reads no corners)."""


def trunk_tilt(mm: MujocoModel, data: mujoco.MjData) -> float:
    """Angle (rad) of the lower trunk's z axis from the world z axis (its link frame is O_17, the free joint's)."""
    R = data.xmat[mm.base_body].reshape(3, 3)
    return float(np.arctan2(np.hypot(R[0, 2], R[1, 2]), R[2, 2]))


def _max(current: float, values: np.ndarray) -> float:
    """Python's ``max(current, v)`` applied for each v of ``values`` (NaN never wins), as a float."""
    if values.size:
        m = np.fmax.reduce(values)
        if m > current:
            return float(m)
    return current


class ReferenceGroundMeter:
    """The NumPy meter (module docstring): ``update`` returns the loaded feet (bit 0 R, bit 1 L) plus 4 (the fall
    tests are always to be run)."""

    def __init__(self, mm: MujocoModel, f_min: float) -> None:
        self.mm = mm
        self.f_min = f_min
        self.slip = {f: (SlipMeter(), SlipMeter()) for f in FEET}  # (toe box, main box)
        self.tilt_max = 0.0
        self.stance_tilt_max = 0.0
        self.penetration_max = 0.0
        self.out = np.zeros(OUT_SIZE)

    def update(self, data: mujoco.MjData, stance: int) -> int:
        """Read one update's state (``stance``: the flat-held foot, 0 R, 1 L, -1 none)."""
        mm, f_min, out = self.mm, self.f_min, self.out
        feet = foot_loads(mm, data)
        loaded = 0
        for i, f in enumerate(FEET):
            c = feet[f]
            out[2 * i], out[2 * i + 1], out[4 + i] = c.normal_toe, c.normal_main, c.penetration
            self.penetration_max = max(self.penetration_max, c.penetration)
            toe, main = self.slip[f]
            on = c.normal_toe >= f_min                  # the corners matter only to a supporting box
            toe.update(f, on, sole_corners(mm, data, f, 0) if on else _NO_CORNERS)
            on = c.normal_main >= f_min
            main.update(f, on, sole_corners(mm, data, f, 1) if on else _NO_CORNERS)
            tilt = out[7 + i] = sole_tilt(mm, data, f)
            if on:
                self.tilt_max = max(self.tilt_max, tilt)
                if i == stance:
                    self.stance_tilt_max = max(self.stance_tilt_max, tilt)
            if c.normal >= f_min:
                loaded |= 1 << i
        out[6] = self.penetration_max
        out[9] = trunk_tilt(mm, data)
        out[10] = data.xipos[mm.base_body][2]
        return loaded | 4

    @property
    def slip_max(self) -> float:
        """Largest slip of a sole box over the run so far, m."""
        return max(m.max_slip[f] for f in FEET for m in self.slip[f])


class GroundMeter:
    """The compiled meter (module docstring), the same numbers as :class:`ReferenceGroundMeter`.

    ``limits``: (foot tilt, CoM height, trunk tilt) near which the fall tests are to be run (rad, m, rad; the
    caller's thresholds with a margin for libm's tilts; None: always); ``chunk``: updates buffered between two
    reductions of the slip and tilt maxima."""

    def __init__(self, mm: MujocoModel, f_min: float, limits: tuple[float, float, float] | None = None,
                 chunk: int = 1024) -> None:
        if mm.model.opt.cone != mujoco.mjtCone.mjCONE_ELLIPTIC:
            raise ValueError("GroundMeter reads an elliptic cone's normal forces; use ReferenceGroundMeter")
        if not (isinstance(chunk, int) and chunk >= 1):
            raise ValueError(f"GroundMeter: chunk = {chunk!r}, expected an integer >= 1")
        self.mm = mm
        self.f_min = float(f_min)
        self._limits = np.array([-np.inf, np.inf, -np.inf] if limits is None else limits, dtype=float)
        self.chunk = chunk
        tables = _tables(mm)
        self._group = tables.pair_array
        geoms = [g for f in FEET for g in mm.sole_geoms[f]]
        self._ids = np.array(geoms + [mm.foot_bodies[f][1] for f in FEET] + [mm.base_body], dtype=np.intp)
        self._corners = np.array([tables.corners[g] for g in geoms])   # (4, 4, 3): per box, its own frame
        self._rows = np.zeros((chunk, ROW_FLOATS))
        self._flags = np.zeros((chunk, ROW_FLAGS), dtype=np.int8)
        self._n = 0
        self.out = np.zeros(OUT_SIZE)
        self._slip = np.zeros(4)                                # slip_reduce's state: the maxima,
        self._last = np.full(4, -2, dtype=np.intp)              # whether a support is carried in,
        self._anchor = np.zeros((4, 4, 3))                      # each box's corners when its support began
        self._tilt = [0.0, 0.0]                                  # tilt_max, stance_tilt_max of reduced rows
        self._data: mujoco.MjData | None = None

    def update(self, data: mujoco.MjData, stance: int) -> int:
        """Read one update's state (``stance``: the flat-held foot, 0 R, 1 L, -1 none); returns the loaded feet
        (bit 0 R, bit 1 L), plus 4 when a fall test may fire (``limits``)."""
        if data is not self._data:    # MjData's fixed-size arrays do not move: views taken once
            self._data = data
            self._fixed = (data.geom_xpos, data.geom_xmat, data.xmat, data.xipos)
        con = data.contact
        xpos, gmat, xmat, xipos = self._fixed
        loaded = ground_update(con.geom, con.dist, con.efc_address, data.efc_force, self._group, self._ids, xpos,
                               gmat, xmat, xipos, self.f_min, self._limits, stance, self._rows, self._flags, self._n,
                               self.out)
        self._n += 1
        if self._n == self.chunk:
            self._reduce()
        return loaded

    # ------------------------------------------------------------------ the maxima
    @property
    def penetration_max(self) -> float:
        """Deepest penetration of a sole box so far, m."""
        return float(self.out[6])

    @property
    def slip_max(self) -> float:
        """Largest slip of a sole box over the run so far, m."""
        self._reduce()
        return float(max(self._slip.tolist()))

    @property
    def tilt_max(self) -> float:
        """Largest tilt of a foot's main body while its box supports, rad."""
        self._reduce()
        return self._tilt[0]

    @property
    def stance_tilt_max(self) -> float:
        """The same for the stance foot alone, rad."""
        self._reduce()
        return self._tilt[1]

    def _reduce(self) -> None:
        """Fold the buffered rows into the maxima, each row as :class:`ReferenceGroundMeter` reads it: the sole
        corners of every supporting box by one stacked matrix product (per row the product :func:`.contact.
        sole_corners` computes), the slip meters in one compiled pass (:func:`.compiled.slip_reduce`), the
        supporting main bodies' tilts by one ``np.arctan2``."""
        n = self._n
        if n == 0:
            return
        rows, flags = self._rows[:n], self._flags[:n]
        row, box = np.nonzero(flags[:, :4])                     # supporting boxes, in row order
        if row.size:
            first = (12 * box)[:, None]
            R = rows[row[:, None], first + _ROTATION].reshape(-1, 3, 3)
            corners = rows[row[:, None], first + _POSITION][:, None, :] + np.matmul(self._corners[box],
                                                                                    R.transpose(0, 2, 1))
        else:
            corners = np.zeros((0, 4, 3))
        slip_reduce(corners, row, box, n, self._last, self._anchor, self._slip)
        row, foot = np.nonzero(flags[:, 1:4:2])                 # supporting main boxes (R, L)
        if row.size:
            z = rows[row[:, None], 48 + 3 * foot[:, None] + _POSITION]   # their bodies' z axes
            tilt = np.arctan2(np.hypot(z[:, 0].copy(), z[:, 1].copy()), z[:, 2].copy())
            self._tilt[0] = _max(self._tilt[0], tilt)
            self._tilt[1] = _max(self._tilt[1], tilt[flags[row, 4] == foot])
        self._n = 0


_POSITION = np.arange(3)
"""Offsets of a box's geom position in a buffer row (after 12 b), and of a foot's main-body z axis (after 48 + 3 f)."""
_ROTATION = np.arange(3, 12)
"""Offsets of a box's geom rotation matrix (row-major) in a buffer row, after 12 b."""


def end_loads(mm: MujocoModel, data: mujoco.MjData, out: np.ndarray, compiled: bool) -> None:
    """Each sole box's normal force and each foot's penetration at the current ``data`` into ``out`` (6,): the
    first six entries of :attr:`GroundMeter.out`'s layout (:func:`.compiled.contact_loads`, or
    :func:`.contact.foot_loads` when ``compiled`` is False)."""
    if compiled:
        con = data.contact
        contact_loads(con.geom, con.dist, con.efc_address, data.efc_force, _tables(mm).pair_array, out)
        return
    feet = foot_loads(mm, data)
    for i, f in enumerate(FEET):
        out[2 * i], out[2 * i + 1], out[4 + i] = feet[f].normal_toe, feet[f].normal_main, feet[f].penetration


__all__ = ["GroundMeter", "ReferenceGroundMeter", "end_loads", "trunk_tilt"]
