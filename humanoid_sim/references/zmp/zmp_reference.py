"""The ZMP reference of a walk: piecewise transfers between support points on the ground.

World frame (x lateral, y forward, z up), metres and seconds.  A walk is a list of contiguous
:class:`SupportInterval` s; in each the reference moves from ``start_xy`` to ``end_xy`` (a single support usually
holds one point: start == end).  :func:`sample` samples them every T seconds with a smooth transfer by default:
the cubic ``s(tau) = 3 tau^2 - 2 tau^3`` (zero rate at both ends, so the reference has no velocity jumps and the
CoM jerk stays small); ``transfer="linear"`` gives the straight ramp.

Support points of a flat foot come from its toe point P_tp (frames P_tpR / P_tpL of humanoid_sim.robot.model) and its
toe body's orientation (body 1 / 2), as the thesis's trajectory reports them:

* :func:`sole_centre`: the centre of the whole sole rectangle (the foot held flat);
* :func:`toe_part_centre`: the centre of the toe part of the sole (toe joint to toe tip), the only part on the
  ground for the trailing foot of a thesis double support (phases.py: its toe body is held, its heel rises).

:func:`intervals_from_trajectory` turns a chapter-3 :class:`~humanoid_sim.references.chapter3.ReferenceTrajectory` into
intervals on its nominal schedule (see its docstring for the choices).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from humanoid_sim.references.chapter3.polynomials import smoothstep
from humanoid_sim.robot.phases import other_foot
from humanoid_sim.robot.sole import SoleGeometry

from .errors import GaitError, sample_time

TRANSFERS = ("smoothstep", "linear")
CONTIGUITY_TOL = 1e-9
"""s: the end of one interval and the start of the next may differ by rounding of the schedule sums."""


@dataclass(frozen=True)
class SupportInterval:
    """From t0 to t1 (s) the ZMP reference moves from start_xy to end_xy (world x, y, m)."""

    t0: float
    t1: float
    start_xy: tuple[float, float]
    end_xy: tuple[float, float]

    def __post_init__(self) -> None:
        for name in ("t0", "t1"):
            v = getattr(self, name)
            if not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v):
                raise GaitError(f"SupportInterval.{name}: expected a finite time in s, got {v!r}")
        if not self.t1 > self.t0:
            raise GaitError(f"SupportInterval: expected t1 > t0, got t0={self.t0!r}, t1={self.t1!r}")
        for name in ("start_xy", "end_xy"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != (2,) or not np.all(np.isfinite(a)):
                raise GaitError(f"SupportInterval.{name}: expected 2 finite numbers (world x, y in m), "
                                f"got {getattr(self, name)!r}")
            object.__setattr__(self, name, (float(a[0]), float(a[1])))


def _transfer(tau: np.ndarray, transfer: str) -> np.ndarray:
    if transfer == "linear":
        return tau
    return smoothstep(tau)


def sample(intervals: Sequence[SupportInterval], T: float, transfer: str = "smoothstep"
           ) -> tuple[np.ndarray, np.ndarray]:
    """Sample contiguous intervals every T seconds: times (N,) from intervals[0].t0 to the last t1 (included when
    it falls on the grid, to 1e-9 s), and the reference (N, 2), m."""
    if transfer not in TRANSFERS:
        raise GaitError(f"transfer: expected one of {TRANSFERS}, got {transfer!r}")
    T = sample_time(T)
    iv = list(intervals)
    if not iv:
        raise GaitError("intervals: expected at least one SupportInterval, got none")
    for i, x in enumerate(iv):
        if not isinstance(x, SupportInterval):
            raise GaitError(f"intervals[{i}]: expected a SupportInterval, got {type(x).__name__}")
        if i and abs(x.t0 - iv[i - 1].t1) > CONTIGUITY_TOL:
            raise GaitError(f"intervals[{i}].t0 = {x.t0!r}: expected the previous interval's end t1 = "
                            f"{iv[i - 1].t1!r} (intervals must be contiguous)")
    t_begin, t_end = iv[0].t0, iv[-1].t1
    n = int(np.floor((t_end - t_begin) / T + 1e-9)) + 1
    times = t_begin + T * np.arange(n)
    t0 = np.array([x.t0 for x in iv])
    t1 = np.array([x.t1 for x in iv])
    idx = np.clip(np.searchsorted(t0, times, side="right") - 1, 0, len(iv) - 1)
    tau = np.clip((times - t0[idx]) / (t1[idx] - t0[idx]), 0.0, 1.0)
    s = _transfer(tau, transfer)[:, None]
    a = np.array([x.start_xy for x in iv])[idx]
    b = np.array([x.end_xy for x in iv])[idx]
    return times, a + s * (b - a)


# ------------------------------------------------------------------------------------------------ foot points
def _toe_offsets(sole: SoleGeometry) -> tuple[float, float]:
    """(x of the toe point in the toe body frame O_1 / O_2, z of the sole plane in that frame), m.

    The model places the toe point on the toe body's x axis at the toe tip (models/thesis_humanoid.yaml:
    toe_front_x = l3x + l1, 'ankle to toe point'), so its x in O_1 is toe_front_x - toe_joint_x."""
    jx, _, jz = sole.toe_joint
    return sole.toe_front_x - jx, sole.sole_z - jz


def _foot_point(toe_point: np.ndarray, R_toe: np.ndarray, local_from_toe_point: np.ndarray) -> np.ndarray:
    p = np.asarray(toe_point, dtype=float)
    R = np.asarray(R_toe, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise GaitError(f"toe_point: expected 3 finite world coordinates in m, got {toe_point!r}")
    # 1e-6: rotations from the trajectory or the simulator are orthonormal to ~1e-12; this only rejects junk.
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise GaitError(f"R_foot: expected a 3x3 rotation matrix (toe body orientation in the world), got {R_toe!r}")
    return p + R @ local_from_toe_point


def sole_centre(toe_point: np.ndarray, R_foot: np.ndarray, sole: SoleGeometry) -> np.ndarray:
    """World point (3,), m, at the centre of a flat foot's whole sole rectangle.

    toe_point: P_tpR / P_tpL in the world (m); R_foot: the toe body's (1 / 2) world orientation, equal to the foot
    main body's (3 / 4) for a flat foot (toe joint at 0, the only case where the whole sole is on the ground)."""
    x_tp, z_sole = _toe_offsets(sole)
    jx = sole.toe_joint[0]
    centre_x = 0.5 * (sole.heel_back_x + sole.toe_front_x) - jx
    return _foot_point(toe_point, R_foot, np.array([centre_x - x_tp, 0.0, z_sole]))


def toe_part_centre(toe_point: np.ndarray, R_foot: np.ndarray, sole: SoleGeometry) -> np.ndarray:
    """World point (3,), m, at the centre of the toe part of the sole (toe joint to toe tip) of toe body 1 / 2
    with world orientation R_foot and toe point toe_point (m); valid for any toe joint angle."""
    x_tp, z_sole = _toe_offsets(sole)
    return _foot_point(toe_point, R_foot, np.array([-0.5 * x_tp, 0.0, z_sole]))


# ------------------------------------------------------------------------------------------------ thesis walk
TRAILING_POINTS = ("toe", "sole")


def intervals_from_trajectory(traj, sole: SoleGeometry, lead_in_s: float = 1.0, lead_out_s: float = 0.0,
                              trailing: str = "toe", start_xy: Sequence[float] | None = None
                              ) -> list[SupportInterval]:
    """Support intervals of a chapter-3 walk on its nominal schedule (global time, s, 0 = the first phase).

    - single support on foot F (phase 2i): from F's sole centre to F's *trailing point*;
    - double support (phase 2i + 1): from the trailing foot's trailing point to the landed foot's sole centre;
    - trailing point: ``"toe"`` (default) the toe-part centre: the thesis's double support holds the trailing foot
      by its toe body only, so the whole-sole centre lies ~40 mm behind the support polygon at the start of the
      transfer; the single support then rolls the ZMP forward inside the stance sole to meet it.  ``"sole"``: the
      whole-sole centre (start == end in single support; the reference leaves the support polygon early in each
      double support);
    - lead-in (``lead_in_s`` > 0): an interval [-lead_in_s, -lead_in_s / 2) holding ``start_xy`` (default: the
      midpoint of the two sole centres; pass the initial whole-body CoM for a start at rest) and a transfer
      [-lead_in_s / 2, 0) to the first stance sole centre, both feet flat: the weight shift the thesis's walk lacks
      before its first single support;
    - lead-out (``lead_out_s`` > 0): a transfer after the last phase to the midpoint of both sole centres.

    The feet are the trajectory's (planned landings, or the stored ones after ``set_landing``).
    """
    if trailing not in TRAILING_POINTS:
        raise GaitError(f"trailing: expected one of {TRAILING_POINTS}, got {trailing!r}")
    for name, v in (("lead_in_s", lead_in_s), ("lead_out_s", lead_out_s)):
        if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
            raise GaitError(f"{name}: expected a finite duration >= 0 s, got {v!r}")

    def foot(phase: int, f: str, t_phase: float) -> tuple[np.ndarray, np.ndarray]:
        s = traj.sample(phase, t_phase)
        return (s.toe_R_p, s.foot_R_R) if f == "R" else (s.toe_L_p, s.foot_L_R)

    def centre(phase: int, f: str, t_phase: float = 0.0) -> tuple[float, float]:
        return tuple(sole_centre(*foot(phase, f, t_phase), sole)[:2])

    def trail(phase: int, f: str) -> tuple[float, float]:
        fn = toe_part_centre if trailing == "toe" else sole_centre
        return tuple(fn(*foot(phase, f, 0.0), sole)[:2])

    out: list[SupportInterval] = []
    first = traj.phases[0]
    stance0 = other_foot(first.swing_foot)
    if lead_in_s > 0:
        if start_xy is None:
            mid = 0.5 * (np.array(centre(0, "R")) + np.array(centre(0, "L")))
        else:
            mid = np.asarray(start_xy, dtype=float)
            if mid.shape != (2,) or not np.all(np.isfinite(mid)):
                raise GaitError(f"start_xy: expected 2 finite numbers (world x, y in m), got {start_xy!r}")
        c0 = centre(0, stance0)
        out.append(SupportInterval(-float(lead_in_s), -0.5 * lead_in_s, tuple(mid), tuple(mid)))
        out.append(SupportInterval(-0.5 * lead_in_s, first.t_start, tuple(mid), c0))
    for ph in traj.phases:
        if ph.is_ssp:
            stance = other_foot(ph.swing_foot)
            out.append(SupportInterval(ph.t_start, ph.t_end, centre(ph.index, stance), trail(ph.index, stance)))
        else:
            lead = ph.landed_foot
            back = other_foot(lead)
            out.append(SupportInterval(ph.t_start, ph.t_end, trail(ph.index, back), centre(ph.index, lead)))
    if lead_out_s > 0:
        last = traj.phases[-1]
        k = last.index
        mid = 0.5 * (np.array(centre(k, "R", last.duration)) + np.array(centre(k, "L", last.duration)))
        out.append(SupportInterval(last.t_end, last.t_end + float(lead_out_s), out[-1].end_xy, tuple(mid)))
    return out
