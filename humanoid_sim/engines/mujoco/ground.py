"""The feet on MuJoCo's ground over a run: what the MuJoCo engine measures at every control update.

At each update (the state right after the update's first MuJoCo step; its time is MuJoCo's ``data.time`` less one
timestep) a meter reads

- each sole box's normal force and each foot's penetration (:func:`.contact.foot_loads`), and from them which
  feet carry at least ``f_min`` of normal force (the fall tests' "loaded" feet);
- the running maxima that ``summary.json`` reports: penetration; each sole box's slip while it supports
  (:class:`.contact.SlipMeter` on its :func:`.contact.sole_corners`, one meter per box); the tilt of a foot's main
  body while its box supports, over both feet and over the stance foot alone: from the vertical
  (:func:`.contact.sole_tilt`), or with terrain boxes in the model from the ground under the foot
  (:func:`.contact.ground_tilt`: a foot standing flat on a slope has not tilted);
- what the fall tests read: each foot's main-body tilt, the lower trunk's tilt and CoM height;
- each foot's friction (:func:`sole_friction`: normal force, how much of their friction cones its contacts use,
  their slip speed), from which :class:`SlideMeter` finds the sliding events: a foot carrying at least ``f_min``
  whose contacts sit on their friction cones (within :data:`ON_CONE_TOL`), from its first such update to the
  first update that is not, with the distance it slid.

The start-up settling is measured apart.  The robot starts at rest with its soles on z = 0 and no contact force;
the soft contact then takes the weight in a transient that presses the soles several times deeper than they then
stand, and may slide a foot (sim3_zmp: 1.04 mm within 10 ms against 0.14 mm standing after it; with the lead-in's
trailing foot on its toe, 2.47 mm at t = 4 ms and a 0.85 mm slip of the right sole at up to 0.35 m/s).  The
updates at t < :attr:`GroundMeter.settling_s` (:data:`SETTLING_TIME_CONSTANTS` time constants of the soles'
contact, 0.05 s by default) are the settling window:
its maxima and sliding are kept apart (:meth:`GroundMeter.report`), and the running maxima (``slip_max``,
``tilt_max``, ``stance_tilt_max``, ``penetration_max``: summary.json's ``foot_slip_max_m`` etc.) start again after
it, the slips from the soles' places at its end.  A run that ends within the window (a fall at once) has no walk
after it: those maxima are then the whole run's, as are the settling ones.

:class:`ReferenceGroundMeter` does it with the NumPy functions of :mod:`.contact` at every update (the reference,
``compiled=False``).  :class:`GroundMeter` gives the same numbers: one compiled call per update
(:func:`.compiled.ground_update`) reads the loads and copies the boxes' placements and the main bodies' z axes
into a buffer row, and the slip and tilt maxima are reduced from the buffer every :attr:`GroundMeter.chunk`
updates (and when read), with the same operations as the reference on each row: the sole corners and the tilts
by NumPy (its matrix product may fuse multiply-adds; its ``np.arctan2`` is not libm's ``atan2`` to the bit), the
slip meters' arithmetic compiled (:func:`.compiled.slip_reduce`).  The same call reads the feet's friction
(:func:`.compiled.sole_friction`: :func:`sole_friction`'s sums, with Python's ``math.hypot`` to the bit), except
for contacts it does not read (another ``dim`` than 1 or 3), where :func:`sole_friction` does.

Both meters fill :attr:`out` (:data:`.compiled.OUT_SIZE` floats, layout there): the fall tests' tilts there are
libm's for :class:`GroundMeter`, so a test near a threshold recomputes NumPy's (:func:`.contact.sole_tilt`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import mujoco
import numpy as np

from humanoid_sim.engines.mujoco.compiled import (
    FRICTION_SKIPPED,
    OUT_SIZE,
    ROW_FLAGS,
    ROW_FLOATS,
    contact_loads,
    ground_update,
    slip_reduce,
)
from humanoid_sim.engines.mujoco.contact import (
    SlipMeter,
    _tables,
    foot_loads,
    ground_normal,
    ground_tilt,
    in_ground_frame,
    sole_corners,
    sole_tilt,
)
from humanoid_sim.engines.mujoco.model import FEET, MujocoModel

_NO_CORNERS = np.zeros((4, 3))
"""What a slip meter is handed for a box that does not support (it reads no corners)."""

SETTLING_TIME_CONSTANTS = 10.0
"""The settling window's length in time constants of the soles' contact (MuJoCo's ``solref[0]`` of the sole geoms,
5 ms by default: 0.05 s).  The soft contact's response is critically damped (damping ratio 1): its transient
(1 + t/tau) exp(-t/tau) is down to 5e-4 of its start after 10 tau.  Measured on sim3_zmp with the lead-in's
trailing foot on its toe (``balance.flat_lead_in: false``): the penetration peaks at
2.47 mm at 4 ms, is 0.21 mm at 30 ms and 0.154 mm at 50 ms against 0.153 mm over the next 10 ms; the right
sole's settling slide (0.35 m/s at 2 ms) is over by 16 ms."""

ON_CONE_TOL = 1e-4
"""A foot is on its friction cone when its contacts use at least 1 - ON_CONE_TOL of it (:func:`sole_friction`'s use).
MuJoCo's solver puts a sliding contact's force on its cone to ~1e-8 (Newton, tolerance 1e-10); a foot that does
not slide used at most 0.99916 of its cone at any control update of sim1_zmp and sim3_zmp (a foot twisting about
one sticking contact while the others slide).  1e-4 is 8 times closer to the cone than that foot and 1e4 times
farther than the solver's scatter."""

_NOT_SLIDING = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
"""An update's friction reads where no foot slides (:meth:`SlideMeter.close`)."""

MERGE_GAP_S = 0.01
"""s: two sliding stretches of one foot less than this apart (from the first one's end to the next one's start) are
one sliding event.  A trailing foot slides as it unloads, and its load crossing ``f_min`` or its cone use dipping
for an update or two splits that slide (gaps of 2-6 ms on sim1_zmp and sim3_zmp); the next gaps were 16 ms and
more (distinct slides).  10 ms lies between, and is the log's step: what the audit sees as one instant."""


# ---------------------------------------------------------------------------------------------------- friction
def sole_friction(mm: MujocoModel, data: mujoco.MjData, elliptic: bool | None = None
                  ) -> list[tuple[float, float, float]]:
    """Each foot's friction at the current ``data`` (after ``mj_step`` or ``mj_forward``): per foot (R, L) its
    sole-floor contacts' total normal force (N), the share of their friction cones they use, and their slip speed
    (m/s), both weighted by the contacts' normal forces (0 without normal force).  ``elliptic``: whether the
    model's friction cone is elliptic (None: read it from the model).

    A contact's use is how far its friction force is along its cone from the centre (0) to the surface (1), in the
    cone's own norm: with an elliptic cone (the model's default, :class:`.model.MujocoSettings`) the contact frame's
    sqrt(sum_k (f_k / mu_k)^2) / f_n over its friction directions k; with a pyramidal cone sum_k |f_k| / (mu_k f_n)
    (on a face of the pyramid = 1), both from ``efc_force`` (an elliptic contact's rows are its normal and friction
    forces, a pyramidal one's are its 2 (dim - 1) edge forces along n +- mu_k t_k).  The foot's use is 1 when every
    contact carrying its load is on its cone.  A contact's slip speed is the norm of its sliding velocity in the
    contact plane, its first two friction directions: ``efc_vel`` (J qvel, the foot relative to the floor), the
    tangential rows for an elliptic cone, (v(n + mu t) - v(n - mu t)) / (2 mu) for a pyramidal one.  A
    frictionless contact (condim 1) adds its normal force and neither use nor speed.
    """
    normal, used, slip = [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]
    if data.ncon:
        if elliptic is None:
            elliptic = mm.model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
        # a few contacts (at most 16), read as Python floats in one pass: NumPy's per-call overhead would cost more
        con, pair = data.contact, _tables(mm).pair_group
        force, vel = data.efc_force.tolist(), data.efc_vel.tolist()
        for (g1, g2), a, d, mu in zip(con.geom.tolist(), con.efc_address.tolist(), con.dim.tolist(),
                                      con.friction.tolist()):
            g = pair[g1][g2]
            if g < 0 or a < 0:
                continue                # not a sole-floor contact, or one without constraint rows
            f = g >> 1
            if d == 1:
                normal[f] += force[a]
                continue
            if elliptic:
                n = force[a]
                u = math.hypot(force[a + 1] / mu[0], force[a + 2] / mu[1]) if d == 3 else \
                    math.sqrt(sum((force[a + k] / mu[k - 1]) ** 2 for k in range(1, d)))
                v1, v2 = vel[a + 1], vel[a + 2]
            else:
                e = force[a:a + 2 * (d - 1)]
                n = sum(e)
                u = sum(abs(e[2 * k] - e[2 * k + 1]) for k in range(d - 1))
                v1 = (vel[a] - vel[a + 1]) / (2.0 * mu[0])
                v2 = (vel[a + 2] - vel[a + 3]) / (2.0 * mu[1])
            normal[f] += n
            used[f] += u
            slip[f] += n * math.hypot(v1, v2)
    return [(n, u / n, v / n) if n > 0 else (n, 0.0, 0.0) for n, u, v in zip(normal, used, slip)]


@dataclass
class SlidingEvent:
    """One foot sliding: from ``start_s``, its first control update carrying at least the meter's ``f_min`` on its
    friction cone, to ``end_s``, the first update that is not (or the run's last update), s.  ``travel_m``: the
    distance its contacts slid, m (their load-weighted slip speed at each sliding update times the time to the
    next update); ``normal_min_N`` / ``normal_max_N``: the foot's normal force over the sliding updates, N;
    ``updates``: how many sliding updates."""

    foot: str
    start_s: float
    end_s: float
    travel_m: float
    normal_min_N: float
    normal_max_N: float
    updates: int

    def as_dict(self) -> dict[str, Any]:
        """The event as summary.json lists it."""
        return asdict(self)


class SlideMeter:
    """The feet's sliding events over a run, fed one control update at a time (:meth:`update`).

    ``f_min``: the least normal force (N) of a foot that slides (a lighter foot's friction is not counted: its
    contacts are touching or leaving); ``tol``: the cone tolerance (:data:`ON_CONE_TOL`); ``merge_gap``: stretches
    of a foot's sliding less than this apart are one event (s, :data:`MERGE_GAP_S`; its travel, normal force range
    and updates are those of its sliding updates).  :attr:`events`: the closed events in order of their ends, then
    those still open (their end the last update's time)."""

    def __init__(self, f_min: float, tol: float = ON_CONE_TOL, merge_gap: float = MERGE_GAP_S) -> None:
        if not (math.isfinite(f_min) and f_min > 0):
            raise ValueError(f"SlideMeter: f_min = {f_min!r} N, expected a positive force")
        if not (math.isfinite(tol) and 0 <= tol < 1):
            raise ValueError(f"SlideMeter: tol = {tol!r}, expected a number in [0, 1)")
        if not (math.isfinite(merge_gap) and merge_gap >= 0):
            raise ValueError(f"SlideMeter: merge_gap = {merge_gap!r} s, expected a time >= 0")
        self.f_min = float(f_min)
        self.tol = float(tol)
        self.merge_gap = float(merge_gap)
        self.closed: list[SlidingEvent] = []
        self._open: list[SlidingEvent | None] = [None, None]
        self._speed = [0.0, 0.0]      # each open event's slip speed at its last update, m/s
        self._t: float | None = None  # the last update's time

    def update(self, t: float, friction: Sequence[Sequence[float]]) -> None:
        """One update at time ``t`` (s, not before the last) with the feet's (normal force N, cone use, slip speed
        m/s), R then L (:func:`sole_friction`)."""
        dt = 0.0 if self._t is None else t - self._t
        if dt < 0:
            raise ValueError(f"SlideMeter.update: t = {t!r} s before the last update's {self._t!r} s")
        self._t = t
        for i in range(2):
            ev = self._open[i]
            if ev is not None:
                ev.travel_m += self._speed[i] * dt
                ev.end_s = t
            fn, use, speed = friction[i]
            if fn >= self.f_min and use >= 1.0 - self.tol:
                if ev is None:
                    ev = self._open[i] = self._resume(i, t) or SlidingEvent(FEET[i], t, t, 0.0, fn, fn, 0)
                ev.normal_min_N = min(ev.normal_min_N, fn)
                ev.normal_max_N = max(ev.normal_max_N, fn)
                ev.updates += 1
                self._speed[i] = speed
            elif ev is not None:
                self.closed.append(ev)
                self._open[i] = None

    def _resume(self, i: int, t: float) -> SlidingEvent | None:
        """Foot i's last closed event, taken back from :attr:`closed`, when it ended less than ``merge_gap``
        before t; else None."""
        for k in range(len(self.closed) - 1, -1, -1):
            ev = self.closed[k]
            if ev.foot == FEET[i]:
                return self.closed.pop(k) if t - ev.end_s < self.merge_gap else None
        return None

    def close(self, t: float) -> None:
        """End the open events at ``t`` (s; their travel up to it), as an update at ``t`` where no foot slides."""
        self.update(t, _NOT_SLIDING)

    @property
    def events(self) -> list[SlidingEvent]:
        """The events so far (closed, then open)."""
        return self.closed + [ev for ev in self._open if ev is not None]

    def clear(self) -> list[SlidingEvent]:
        """Forget the closed events (the open ones go on); returns them."""
        done, self.closed = self.closed, []
        return done


def sliding_summary(events: list[SlidingEvent]) -> dict[str, Any]:
    """``count``, ``travel_total_m``, ``travel_max_m`` (None without events) of sliding events."""
    travel = [ev.travel_m for ev in events]
    return {"count": len(events), "travel_total_m": float(sum(travel)),
            "travel_max_m": float(max(travel)) if travel else None}


def settling_time(mm: MujocoModel) -> float:
    """The settling window's length, s: :data:`SETTLING_TIME_CONSTANTS` times the soles' contact time constant
    (the largest ``solref[0]`` of the sole and floor geoms, at least two timesteps as MuJoCo enforces)."""
    geoms = [g for f in FEET for g in mm.sole_geoms[f]] + [mm.floor_geom]
    tau = max(float(np.max(mm.model.geom_solref[geoms, 0])), 2.0 * float(mm.model.opt.timestep))
    return SETTLING_TIME_CONSTANTS * tau


class _Settling:
    """What both meters share: the settling window (module docstring), the sliding events and the report.  A meter
    calls :meth:`_start` first in each update (the update's time, the window's end) and provides :meth:`_maxima`
    and :meth:`_restart` (its running maxima, and setting them back to a run's start)."""

    mm: MujocoModel
    f_min: float
    out: np.ndarray

    def _init_settling(self, settling_s: float | None) -> None:
        self._dt = float(self.mm.model.opt.timestep)
        self.settling_s = settling_time(self.mm) if settling_s is None else float(settling_s)
        if not (math.isfinite(self.settling_s) and self.settling_s >= 0):
            raise ValueError(f"{type(self).__name__}: settling_s = {settling_s!r} s, expected a time >= 0")
        self.settled = False
        self._settling: dict[str, float] = {}
        self._settling_events: list[SlidingEvent] = []
        self.sliding = SlideMeter(self.f_min)
        self._elliptic = self.mm.model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC

    def _start(self, data: mujoco.MjData) -> float:
        """The update's time (s), ending the settling window first when the update lies past it (by more than half
        a timestep: MuJoCo's time is a running sum of timesteps)."""
        t = data.time - self._dt
        if not self.settled and t > self.settling_s - 0.5 * self._dt:
            self._settling = self._maxima()
            self.sliding.close(t)
            self._settling_events = self.sliding.clear()
            self._restart()
            self.settled = True
        return t

    def _slide(self, data: mujoco.MjData, t: float) -> None:
        """The feet's friction by :func:`sole_friction` into ``out[11:17]`` and the sliding meter."""
        friction = sole_friction(self.mm, data, self._elliptic)
        self.out[11:17] = np.ravel(friction)
        self.sliding.update(t, friction)

    def _maxima(self) -> dict[str, float]:
        raise NotImplementedError

    def _restart(self) -> None:
        raise NotImplementedError

    def report(self) -> dict[str, Any]:
        """The ground's ``settling`` and ``sliding`` entries for summary.json (SI units).

        ``settling``: ``window_s`` (the window's length), and over its updates ``penetration_max_m``,
        ``foot_slip_max_m``, ``foot_tilt_max_rad``, ``stance_tilt_max_rad`` (as the running maxima measure them)
        and ``sliding_count`` / ``sliding_travel_m`` (its sliding events, their total travel), ``ended`` (False
        when the run ended within it: then the values are the whole run's).  ``sliding``: the events after the
        window, ``loaded_above_N`` and ``on_cone_tolerance`` (what counts as sliding), ``count``,
        ``travel_total_m``, ``travel_max_m`` (None without events) and ``events`` (:meth:`SlidingEvent.as_dict`,
        in order of their ends)."""
        if self.settled:
            settling, in_window, after = self._settling, self._settling_events, self.sliding.events
        else:
            settling, in_window, after = self._maxima(), self.sliding.events, []
        done = sliding_summary(in_window)
        return {"settling": {"window_s": self.settling_s, "ended": self.settled, **settling,
                             "sliding_count": done["count"], "sliding_travel_m": done["travel_total_m"]},
                "sliding": {"loaded_above_N": self.f_min, "on_cone_tolerance": self.sliding.tol,
                            **sliding_summary(after), "events": [ev.as_dict() for ev in after]}}


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


class ReferenceGroundMeter(_Settling):
    """The NumPy meter (module docstring): ``update`` returns the loaded feet (bit 0 R, bit 1 L) plus 4 (the fall
    tests are always to be run).  ``settling_s``: the settling window's length (s; None: :func:`settling_time`)."""

    def __init__(self, mm: MujocoModel, f_min: float, settling_s: float | None = None) -> None:
        self.mm = mm
        self.f_min = f_min
        self.out = np.zeros(OUT_SIZE)
        self._restart()
        self._init_settling(settling_s)

    def _restart(self) -> None:
        self.slip = {f: (SlipMeter(), SlipMeter()) for f in FEET}  # (toe box, main box)
        self.tilt_max = 0.0
        self.stance_tilt_max = 0.0
        self.penetration_max = 0.0

    def _maxima(self) -> dict[str, float]:
        return {"penetration_max_m": self.penetration_max, "foot_slip_max_m": self.slip_max,
                "foot_tilt_max_rad": self.tilt_max, "stance_tilt_max_rad": self.stance_tilt_max}

    def update(self, data: mujoco.MjData, stance: int) -> int:
        """Read one update's state (``stance``: the flat-held foot, 0 R, 1 L, -1 none)."""
        t = self._start(data)
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
                if mm.terrain_geoms:     # the maxima from the ground under the foot (the fall tests' from the vertical)
                    tilt = ground_tilt(mm, data, f)
                self.tilt_max = max(self.tilt_max, tilt)
                if i == stance:
                    self.stance_tilt_max = max(self.stance_tilt_max, tilt)
            if c.normal >= f_min:
                loaded |= 1 << i
        out[6] = self.penetration_max
        out[9] = trunk_tilt(mm, data)
        out[10] = data.xipos[mm.base_body][2]
        self._slide(data, t)
        return loaded | 4

    @property
    def slip_max(self) -> float:
        """Largest slip of a sole box over the run so far, m."""
        return max(m.max_slip[f] for f in FEET for m in self.slip[f])


class GroundMeter(_Settling):
    """The compiled meter (module docstring), the same numbers as :class:`ReferenceGroundMeter`.

    ``limits``: (foot tilt, CoM height, trunk tilt) near which the fall tests are to be run (rad, m, rad; the
    caller's thresholds with a margin for libm's tilts; None: always); ``chunk``: updates buffered between two
    reductions of the slip and tilt maxima; ``settling_s``: the settling window's length (s; None:
    :func:`settling_time`)."""

    def __init__(self, mm: MujocoModel, f_min: float, limits: tuple[float, float, float] | None = None,
                 chunk: int = 1024, settling_s: float | None = None) -> None:
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
        self._init_settling(settling_s)

    def _restart(self) -> None:
        self._reduce()
        self.out[6] = 0.0
        self._slip[:] = 0.0
        self._last[:] = -2
        self._tilt = [0.0, 0.0]

    def _maxima(self) -> dict[str, float]:
        return {"penetration_max_m": self.penetration_max, "foot_slip_max_m": self.slip_max,
                "foot_tilt_max_rad": self.tilt_max, "stance_tilt_max_rad": self.stance_tilt_max}

    def update(self, data: mujoco.MjData, stance: int) -> int:
        """Read one update's state (``stance``: the flat-held foot, 0 R, 1 L, -1 none); returns the loaded feet
        (bit 0 R, bit 1 L), plus 4 when a fall test may fire (``limits``)."""
        t = self._start(data)
        if data is not self._data:    # MjData's fixed-size arrays do not move: views taken once
            self._data = data
            self._fixed = (data.geom_xpos, data.geom_xmat, data.xmat, data.xipos)
        con = data.contact
        xpos, gmat, xmat, xipos = self._fixed
        code = ground_update(con.geom, con.dist, con.dim, con.efc_address, con.friction, data.efc_force, data.efc_vel,
                             self._group, self._ids, xpos, gmat, xmat, xipos, self.f_min, self._limits, stance,
                             self._rows, self._flags, self._n, self.out)
        if self.mm.terrain_geoms:
            self._ground_relative(data)
        self._n += 1
        if self._n == self.chunk:
            self._reduce()
        if code & FRICTION_SKIPPED:
            self._slide(data, t)
        else:
            f = self.out.tolist()
            self.sliding.update(t, ((f[11], f[12], f[13]), (f[14], f[15], f[16])))
        return code & ~FRICTION_SKIPPED

    def _ground_relative(self, data: mujoco.MjData) -> None:
        """The buffer row just written: each supporting main body's z axis in the frame of the ground under its
        foot (:func:`.contact.in_ground_frame`), so that the reduction's tilt is :func:`.contact.ground_tilt`'s."""
        row = self._n
        for i, f in enumerate(FEET):
            if self._flags[row, 1 + 2 * i]:
                n = ground_normal(self.mm, data, f)
                if not (n[0] == 0.0 and n[1] == 0.0):
                    z = self._rows[row, 48 + 3 * i:51 + 3 * i]
                    z[:] = in_ground_frame(z.copy(), n)

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


__all__ = ["MERGE_GAP_S", "ON_CONE_TOL", "SETTLING_TIME_CONSTANTS", "GroundMeter", "ReferenceGroundMeter", "SlideMeter",
           "SlidingEvent", "end_loads", "settling_time", "sliding_summary", "sole_friction", "trunk_tilt"]
