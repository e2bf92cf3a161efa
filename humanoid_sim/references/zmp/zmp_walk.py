"""The feasible gait (``gait.hip_reference: zmp_preview``): chapter 3's footholds, foot paths and timing with a
Body-17 CoM path planned by ZMP preview control, as a trajectory the loop, the controllers and the kernel query
like :class:`humanoid_sim.references.chapter3.ReferenceTrajectory`.

Schedule.  Phase 0 is a standing double support of ``lead_in_s`` (the DSP type that precedes the first single
support in the cycle, e.g. LFFDSP before LFFSSP: the first stance foot held flat, the other by its toe body),
during which the weight moves onto the first stance foot; phases 1.. are the thesis's, ``lead_in_s`` later.  Global
time 0 is the start of the lead-in.

Hip.  Position and velocity of Body 17's CoM come from the plan (:func:`plan_hip`) on a uniform grid, evaluated
by cubic Hermite interpolation of (position, velocity) between grid points, at the time clamped to the phase's
nominal window (as the thesis clamps its polynomials, D1).  The height is chapter 3's constant height.  The yaw is
chapter 3's (C^(0,17) = Rz(theta_CS +- theta_h) in single support, theta_hor in double support), shifted; in the
lead-in a cubic takes it from the robot's initial yaw to theta_CS of segment 0 with the thesis's start rate
(chapter 3 steps it there at t = 0, 40.5 deg in simulation 1, errata D5).

Feet.  The thesis's (shifted); in the lead-in both feet stay where they start.  Landings learned by
:meth:`ZmpPreviewTrajectory.set_landing` move the feet as in chapter 3; the hip plan is not re-planned (landing
errors are millimetres).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from humanoid_sim.references.chapter3 import PhaseInfo, PhaseTargets, ReferenceTrajectory, RefSample, TrajectoryError
from humanoid_sim.references.chapter3.generator import DSP_TABLE, SSP_TABLE_SIZE, _central, _rz
from humanoid_sim.references.chapter3.polynomials import cubic_bvp, eval_cubic

from .errors import GaitError

GRID_HEADER = ("t_grid0", "T", "n")
"""What :meth:`ZmpPreviewTrajectory.ssp_table` / ``dsp_table`` append to chapter 3's layouts: the hip grid's first
time (global, s), its step (s) and point count, then per point (x, y, vx, vy) of Body 17's CoM (m, m/s).  A table
longer than the chapter-3 layout tells the kernel to take the hip position from the grid."""
DSP_TABLE_SIZE = len(DSP_TABLE)


def hermite(t: float, t0: float, T: float, xy: np.ndarray, vxy: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                                        np.ndarray]:
    """Cubic Hermite interpolation of a uniform grid (first time t0, step T, points xy (n, 2), rates vxy (n, 2)) at
    time t (clamped to the grid): position, velocity, acceleration (2,) each."""
    p, v, a = hermite_xy(t, t0, T, xy, vxy)
    return np.array(p), np.array(v), np.array(a)


def hermite_xy(t: float, t0: float, T: float, xy: np.ndarray, vxy: np.ndarray
               ) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
    """:func:`hermite` as (x, y) float pairs: scalar arithmetic, the controller's per-call path (a 2-vector numpy
    operation costs ~0.5 us, and the three derivatives take ~30 of them).  The same operations in the same order:
    the same numbers.  ``xy`` and ``vxy`` may be (n, 2) arrays or lists of (x, y) rows."""
    n = len(xy)
    u = (t - t0) / T
    i = min(max(int(math.floor(u)), 0), n - 2)
    s = min(max(u - i, 0.0), 1.0)
    s2, s3 = s * s, s * s * s
    h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
    d00, d10, d01, d11 = 6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s
    e00, e10, e01, e11 = 12 * s - 6, 6 * s - 4, -12 * s + 6, 6 * s - 2
    TT = T * T
    out = []
    xa, xb, va, vb = xy[i], xy[i + 1], vxy[i], vxy[i + 1]    # rows (lists on the per-call path: cheaper to index)
    for c in (0, 1):
        p0, p1 = float(xa[c]), float(xb[c])
        m0, m1 = T * float(va[c]), T * float(vb[c])
        out.append((h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1,
                    (d00 * p0 + d10 * m0 + d01 * p1 + d11 * m1) / T,
                    (e00 * p0 + e10 * m0 + e01 * p1 + e11 * m1) / TT))
    (px, vx, ax), (py, vy, ay) = out
    return (px, py), (vx, vy), (ax, ay)


@dataclass(frozen=True)
class HipPlan:
    """Body-17 CoM plan on a uniform grid: times t (n,) from 0 (global, s), xy (n, 2) m, vxy (n, 2) m/s, and what
    the planner reports (``info``: ZMP tracking, multibody error, timings).  On the same grid, when the planner
    provides them: the whole-body CoM plan ``com_xy`` (n, 2) m, ``com_vxy`` (n, 2) m/s and the ZMP reference
    ``zmp_xy`` (n, 2) m (the DCM feedback's reference); ``com_z`` the table height, m."""

    t: np.ndarray
    xy: np.ndarray
    vxy: np.ndarray
    info: dict
    com_xy: np.ndarray | None = None
    com_vxy: np.ndarray | None = None
    zmp_xy: np.ndarray | None = None
    com_z: float | None = None

    @property
    def T(self) -> float:
        return float(self.t[1] - self.t[0])


class ZmpPreviewTrajectory:
    """Chapter 3's walk led by a standing double support, with a planned hip (see the module docstring).

    ``inner``: the chapter-3 trajectory of the path; ``lead_in_s``: the standing double support, s;
    ``initial_yaw``: Body 17's yaw in the initial configuration, rad.  :meth:`set_hip_plan` installs the plan; until
    then the hip holds chapter 3's start point (used to sample the feet for planning)."""

    dsp_on_schedule = True
    """The phase selector ends this gait's double supports at their planned duration (not the 0.05 m rule)."""

    def __init__(self, inner: ReferenceTrajectory, lead_in_s: float, initial_yaw: float) -> None:
        if not isinstance(inner, ReferenceTrajectory):
            raise GaitError(f"inner: expected a ReferenceTrajectory, got {type(inner).__name__}")
        self.inner = inner
        self.lead = float(lead_in_s)
        self.params = inner.params
        self.hip_z = inner.hip_z
        first = inner.phases[0]
        lead_name = "LFFDSP" if first.name == "LFFSSP" else "RFFDSP"
        self.phases: list[PhaseInfo] = [PhaseInfo(0, lead_name, 0, False, None, None, 0.0, self.lead, self.lead)]
        self.phases += [replace(ph, index=ph.index + 1, t_start=ph.t_start + self.lead, t_end=ph.t_end + self.lead)
                        for ph in inner.phases]
        self._t_starts = [ph.t_start for ph in self.phases]
        self.duration = inner.duration + self.lead
        g = inner.segment_geometry(0)
        yaw_end = float(g["theta_cs"])
        start = yaw_end + math.remainder(float(initial_yaw) - yaw_end, 2 * math.pi)
        rate_end = float(g["T_dir"]) * float(self.params.Vhip[0]) / float(g["R"])
        self._lead_yaw = cubic_bvp(self.lead, start, yaw_end, 0.0, rate_end)
        s0 = inner.sample(0, 0.0)
        self._feet0 = {"R": (s0.toe_R_p, s0.foot_R_R, s0.foot_R_yaw), "L": (s0.toe_L_p, s0.foot_L_R, s0.foot_L_yaw)}
        self.plan: HipPlan | None = None
        self.com_plan: tuple[np.ndarray, np.ndarray, np.ndarray, float] | None = None
        """(com_xy, com_vxy, zmp_xy, com_z) of the plan when it has them (:meth:`com_targets`), else None."""

    # ------------------------------------------------------------------------------------------------ plan
    def set_hip_plan(self, plan: HipPlan) -> None:
        """Install the Body-17 CoM plan; it must cover [0, duration] on a uniform grid."""
        if plan.t[0] > 1e-9 or plan.t[-1] < self.duration - 1e-9:
            raise GaitError(f"hip plan: covers {plan.t[0]:.3f} .. {plan.t[-1]:.3f} s, expected 0 .. "
                            f"{self.duration:.3f} s")
        self.plan = plan
        self._hip_memo: tuple = (math.nan,)
        self._xy = np.ascontiguousarray(plan.xy, dtype=float)
        self._vxy = np.ascontiguousarray(plan.vxy, dtype=float)
        # the per-call queries read the grids as lists of float rows and its start and step as floats (the same
        # numbers: indexing a list costs a tenth of a numpy element read)
        self._grid = (float(plan.t[0]), plan.T)
        self._rows = (self._xy.tolist(), self._vxy.tolist())
        self.com_plan = None
        self._com_rows: tuple[list, list, list] | None = None
        if plan.com_xy is not None and plan.com_vxy is not None and plan.zmp_xy is not None and plan.com_z:
            self.com_plan = (np.ascontiguousarray(plan.com_xy, dtype=float),
                             np.ascontiguousarray(plan.com_vxy, dtype=float),
                             np.ascontiguousarray(plan.zmp_xy, dtype=float), float(plan.com_z))
            self._com_rows = (self.com_plan[0].tolist(), self.com_plan[1].tolist(), self.com_plan[2].tolist())

    def _hip(self, tg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Planned Body-17 CoM position, velocity, acceleration (3,) at global time tg (s)."""
        if self.plan is None:
            p = self.inner.sample(0, 0.0).hip_p
            return p.copy(), np.zeros(3), np.zeros(3)
        _, p, v, a = self._hip_tuples(tg)
        return np.array(p), np.array(v), np.array(a)

    def _hip_tuples(self, tg: float) -> tuple:
        """(tg, position, velocity, acceleration) of the planned Body-17 CoM at global time tg as float triples
        (a plan is set), memoised: a controller asks for the position and the acceleration at one time."""
        if tg != self._hip_memo[0]:
            t0, T = self._grid
            p, v, a = hermite_xy(tg, t0, T, *self._rows)
            self._hip_memo = (tg, (p[0], p[1], self.hip_z), (v[0], v[1], 0.0), (a[0], a[1], 0.0))
        return self._hip_memo

    def _clamp(self, k: int, t: float) -> float:
        ph = self.phases[k]
        return ph.t_start + min(max(float(t - ph.t_start), 0.0), ph.duration)

    def _check(self, k: int) -> int:
        if not isinstance(k, (int, np.integer)) or isinstance(k, bool) or not 0 <= k < len(self.phases):
            raise TrajectoryError(f"phase: index must be an integer in [0, {len(self.phases) - 1}] (value: {k!r})")
        return int(k)

    # ------------------------------------------------------------------------------------------------ queries
    @property
    def n_phases(self) -> int:
        return len(self.phases)

    def segment_geometry(self, i: int) -> dict[str, Any]:
        return self.inner.segment_geometry(i)

    def phase_at(self, t: float) -> int:
        k = bisect.bisect_right(self._t_starts, t) - 1
        return min(max(k, 0), len(self.phases) - 1)

    def sample_global(self, t: float, phase: int | None = None) -> RefSample:
        k = self.phase_at(t) if phase is None else self._check(phase)
        return self.sample(k, t - self.phases[k].t_start)

    def phase_end(self, phase: int) -> RefSample:
        k = self._check(phase)
        return self.sample(k, self.phases[k].duration)

    def sample(self, phase: int, t_phase: float) -> RefSample:
        k = self._check(phase)
        ph = self.phases[k]
        t = min(max(float(t_phase), 0.0), ph.duration)
        if k == 0:
            out = RefSample()
            out.phase, out.t_phase = 0, t
            yaw, yawd, yawdd = eval_cubic(self._lead_yaw, t)
            out.hip_R, out.hip_w, out.hip_alpha, out.hip_yaw = _rz(yaw), np.array((0, 0, yawd)), \
                np.array((0, 0, yawdd)), yaw
            zero = np.zeros(3)
            for f, (p, R, y) in self._feet0.items():
                out.set_foot(f, (p, zero, zero, R, zero, zero, y))
        else:
            out = self.inner.sample(k - 1, t)
            out.phase = k
        out.hip_p, out.hip_v, out.hip_a = self._hip(ph.t_start + t)
        return out

    def phase_targets(self, phase: int) -> PhaseTargets:
        k = self._check(phase)
        hip_end = self._hip(self.phases[k].t_end)[0]
        if k == 0:
            return PhaseTargets(0, hip_end, None, None, None, 0.0, self.lead)
        return replace(self.inner.phase_targets(k - 1), phase=k, hip_p_end=hip_end)

    def hip_reference(self, phase: int, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Body-17 CoM (3,), [linear; angular] velocity (6,), orientation (3x3) at global t clamped to ``phase``."""
        return self.hip_targets(phase, t)[:3]

    def hip_acceleration(self, phase: int, t: float) -> np.ndarray:
        """Body-17 CoM [linear; angular] acceleration (6,) at global t clamped to ``phase``: the planned hip's (the
        cubic Hermite's second derivative) and the yaw's."""
        return self.hip_targets(phase, t)[3]

    def hip_targets(self, phase: int, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`hip_reference` and :meth:`hip_acceleration` at one time from one evaluation: position (3,),
        velocity (6,), orientation (3x3), acceleration (6,) (both queries are read from it)."""
        k = self._check(phase)
        tc = self._clamp(k, t)
        if self.plan is None:
            p, v, a = self._hip(tc)
        else:
            _, p, v, a = self._hip_tuples(tc)
            p = np.array(p)
        if k == 0:
            yaw, yawd, yawdd = eval_cubic(self._lead_yaw, tc - self.phases[0].t_start)
        else:
            inner = self.inner
            ph, sg, tci = inner._clamped(k - 1, t - self.lead)
            yaw, yawd, yawdd = inner._yaw_scalars(ph, sg, tci)
        return (p, np.array((v[0], v[1], 0.0, 0.0, 0.0, yawd)), _rz(yaw),
                np.array((a[0], a[1], 0.0, 0.0, 0.0, yawdd)))

    def com_targets(self, phase: int, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """The whole-body CoM plan at global t clamped to ``phase`` (as :meth:`hip_targets`): horizontal position
        (2,) m, velocity (2,) m/s, acceleration (2,) m/s^2 (cubic Hermite of the grid) and the ZMP reference (2,) m
        (linear between grid points), world frame; None when the plan has no whole-body CoM plan."""
        if self.com_plan is None or self.plan is None:
            return None
        tc = self._clamp(self._check(phase), t)
        xy, vxy, zmp = self._com_rows
        t0, T = self._grid
        p, v, a = hermite_xy(tc, t0, T, xy, vxy)
        u = min(max((tc - t0) / T, 0.0), len(zmp) - 1.0)
        i = min(int(u), len(zmp) - 2)
        f = u - i
        za, zb = zmp[i], zmp[i + 1]
        g = 1.0 - f
        return np.array(p), np.array(v), np.array(a), np.array((za[0] * g + zb[0] * f, za[1] * g + zb[1] * f))

    def toe_velocity(self, phase: int, t: float, foot: str) -> np.ndarray:
        """:meth:`toe_reference`'s velocity (6,) alone; the same numbers."""
        k = self._check(phase)
        if k == 0:
            return np.zeros(6)
        return self.inner.toe_velocity(k - 1, t - self.lead, foot)

    def swing_feedforward(self, phase: int, t: float, foot: str, h: float) -> tuple[np.ndarray, ...]:
        """:meth:`toe_reference` at global time t with the central difference of :meth:`toe_velocity` over t +- h
        (the generator's :meth:`~humanoid_sim.references.chapter3.generator.ReferenceTrajectory.swing_feedforward`;
        the same numbers as the four queries)."""
        k = self._check(phase)
        if k == 0:
            p, R, _ = self._feet0[foot]
            return p, np.zeros(6), R, np.zeros(6)
        inner, lead = self.inner, self.lead
        pt, v6, R = inner.toe_reference(k - 1, t - lead, foot)
        return pt, v6, R, _central(inner._toe_velocity(k - 1, t + h - lead, foot),
                                   inner._toe_velocity(k - 1, t - h - lead, foot), h)

    def toe_reference(self, phase: int, t: float, foot: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k = self._check(phase)
        if k == 0:
            p, R, _ = self._feet0[foot]
            return p, np.zeros(6), R
        return self.inner.toe_reference(k - 1, t - self.lead, foot)

    def positions(self, t: float, phase: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k = self.phase_at(t) if phase is None else phase
        hip = self._hip(self._clamp(k, t))[0]
        if k == 0:
            return hip, self._feet0["R"][0], self._feet0["L"][0]
        _, r, left = self.inner.positions(t - self.lead, k - 1)
        return hip, r, left

    def set_landing(self, foot: str, phase: int, toe_point: np.ndarray, R_foot: np.ndarray) -> None:
        k = self._check(phase)
        if k == 0:
            raise TrajectoryError("phase: 0 is the standing lead-in; no foot lands in it")
        self.inner.set_landing(foot, k - 1, toe_point, R_foot)

    # ------------------------------------------------------------------------------------------------ kernel
    def _grid_part(self, k: int) -> np.ndarray:
        """The hip grid points covering phase k's nominal window (one point beyond each end)."""
        if self.plan is None:
            raise GaitError("the hip plan is not set (set_hip_plan)")
        ph = self.phases[k]
        T, t0 = self.plan.T, float(self.plan.t[0])
        i0 = max(int(math.floor((ph.t_start - t0) / T)) - 1, 0)
        i1 = min(int(math.ceil((ph.t_end - t0) / T)) + 2, len(self.plan.t))
        pts = np.concatenate((self._xy[i0:i1], self._vxy[i0:i1]), axis=1)
        return np.concatenate(([t0 + i0 * T, T, float(i1 - i0)], pts.ravel()))

    def ssp_table(self, phase: int) -> np.ndarray:
        """Chapter 3's single-support table of the phase (times shifted) with the hip grid appended
        (:data:`GRID_HEADER`)."""
        k = self._check(phase)
        if k == 0:
            raise TrajectoryError("phase: 0 (the lead-in) is not a single support phase")
        tab = self.inner.ssp_table(k - 1).copy()
        tab[0] = self.phases[k].t_start
        return np.concatenate((tab, self._grid_part(k)))

    def dsp_table(self, phase: int) -> np.ndarray:
        """Chapter 3's double-support table (times shifted; in the lead-in, its yaw cubic in place of e) with the
        hip grid appended."""
        k = self._check(phase)
        if k == 0:
            tab = np.zeros(DSP_TABLE_SIZE)
            tab[0], tab[1], tab[2] = 0.0, self.lead, self.hip_z
            tab[12:16] = self._lead_yaw
        else:
            tab = self.inner.dsp_table(k - 1).copy()
            tab[0] = self.phases[k].t_start
        return np.concatenate((tab, self._grid_part(k)))


SSP_GRID_AT = SSP_TABLE_SIZE
DSP_GRID_AT = DSP_TABLE_SIZE


def plan_hip(hm: Any, traj: ZmpPreviewTrajectory, q0: np.ndarray, horizon_s: float = 1.6, passes: int = 2,
             T: float = 0.01, transfer: str = "smoothstep", lead_out_s: float = 1.0) -> HipPlan:
    """Plan Body 17's CoM for ``traj`` (whose feet and yaw are set) from rest at configuration q0.

    1. ZMP reference (:mod:`.zmp_reference`): from the initial whole-body CoM, over the first stance sole in the
       lead-in, then the sole centres of chapter 3's footholds, moving across in each double support, and after
       the last phase a ``lead_out_s`` transfer to the midpoint of both soles (0: it stays on the last landed
       sole's centre).  The walk ends with its last phase; the lead-out is the stop the preview sees coming, so
       the last steps are planned toward standing on both feet instead of stopping dead over one;
    2. cart-table preview control (:class:`.preview.CartTablePreview`, table height = the initial whole-body CoM
       height) from rest;
    3. ``passes`` multibody corrections (:func:`.multibody.correct_hip`) with the whole-body posture of
       :class:`.posture.WalkPosture` (feet on the trajectory's, Body 17 at chapter 3's height and the
       trajectory's yaw), which turn the whole-body CoM plan into a Body-17 CoM path."""
    import time

    from humanoid_sim.robot.sole import SoleGeometry

    from .multibody import correct_hip, path_derivatives, whole_body_com
    from .posture import WalkPosture, thesis_free_toes
    from .preview import CartTablePreview
    from .zmp_reference import intervals_from_trajectory, sample

    wall0 = time.perf_counter()
    inner = traj.inner
    com0 = whole_body_com(hm.model, np.asarray(q0, dtype=float)[None, :])[0]
    sole = SoleGeometry.from_model(hm)
    intervals = intervals_from_trajectory(inner, sole, lead_in_s=traj.lead, lead_out_s=lead_out_s, start_xy=com0[:2])
    times, ref = sample(intervals, T, transfer)
    times = times + traj.lead                      # global time: 0 = the start of the lead-in
    n_need = int(math.ceil(traj.duration / T + 1e-9)) + 2   # the grid covers the end with one point to spare
    if len(times) < n_need:
        extra = n_need - len(times)
        times = np.concatenate((times, times[-1] + T * np.arange(1, extra + 1)))
        ref = np.concatenate((ref, np.repeat(ref[-1:], extra, axis=0)))
    preview = CartTablePreview(T, float(com0[2]), horizon_s)
    x0 = np.zeros((3, 2))
    x0[0] = com0[:2]
    plan = preview.run(ref, x0=x0)
    samples = [traj.sample_global(float(t)) for t in times]
    posture = WalkPosture(hm, np.array([s.toe_R_p for s in samples]), np.array([s.foot_R_R for s in samples]),
                          np.array([s.toe_L_p for s in samples]), np.array([s.foot_L_R for s in samples]),
                          np.array([s.hip_R for s in samples]), traj.hip_z, np.asarray(q0, dtype=float),
                          free_toe=thesis_free_toes(inner, times - traj.lead), T=T)
    try:
        res = correct_hip(preview, hm, ref, plan, posture, passes=passes)
    except GaitError as exc:
        raise GaitError(f"{exc} (samples are {T} s apart from the start of the {traj.lead} s lead-in: chapter 3's "
                        f"time is sample x {T} - {traj.lead} s; a lower hip, path.Phip z, gives the legs more "
                        "reach)") from None
    ssp = np.array([traj.phases[traj.phase_at(float(t))].is_ssp and t < traj.duration for t in times])
    cart = np.linalg.norm(plan.zmp - ref, axis=1)
    mb = np.linalg.norm(res.zmp_error, axis=1)
    info = {"com_height_m": float(com0[2]), "horizon_s": float(horizon_s), "passes": int(passes), "T_s": float(T),
            "cart_zmp_error_ssp_max_m": float(cart[ssp].max()) if ssp.any() else 0.0,
            "multibody_zmp_error_ssp_rms_m": float(np.sqrt(np.mean(mb[ssp] ** 2))) if ssp.any() else 0.0,
            "multibody_zmp_error_ssp_max_m": float(mb[ssp].max()) if ssp.any() else 0.0,
            "plan_wall_time_s": time.perf_counter() - wall0}
    com_v, _ = path_derivatives(res.com_plan, T)
    return HipPlan(t=times, xy=res.hip_xy, vxy=res.hip_v, info=info, com_xy=res.com_plan, com_vxy=com_v,
                   zmp_xy=np.asarray(ref, dtype=float), com_z=float(com0[2]))


def initial_state(hm: Any, scenario: Any) -> np.ndarray:
    """The walk's initial configuration: chapter 3's (:func:`humanoid_sim.references.initial.initial_configuration`), or
    for
    the zmp gait its ready stance (:func:`.stance.ready_stance`, ``gait.ready_margin_m`` inside the lead-in's
    support polygon)."""
    from humanoid_sim.references.initial import initial_configuration

    q0 = initial_configuration(hm, scenario.path)
    g = scenario.gait
    if not g.is_zmp or g.ready_margin_m <= 0.0:
        return q0
    from humanoid_sim.robot.phases import Phase

    from .stance import ready_stance

    stance = Phase(ReferenceTrajectory(scenario.path).phases[0].name).support_foot
    return ready_stance(hm, scenario.path, q0, stance, g.ready_margin_m)


def make_trajectory(hm: Any, scenario: Any, q0: np.ndarray) -> ReferenceTrajectory | ZmpPreviewTrajectory:
    """The scenario's reference: chapter 3's trajectory (``gait.hip_reference: thesis``), or the planned
    :class:`ZmpPreviewTrajectory` (``zmp_preview``)."""
    inner = ReferenceTrajectory(scenario.path)
    g = scenario.gait
    if not g.is_zmp:
        return inner
    from humanoid_sim.references.chapter3.geometry import yaw_of

    R0 = _quat_rotation(q0[3:7])
    traj = ZmpPreviewTrajectory(inner, g.lead_in_s, yaw_of(R0))
    traj.set_hip_plan(plan_hip(hm, traj, q0, g.horizon_s, g.passes, g.sample_s, g.transfer, g.lead_out_s))
    return traj


def _quat_rotation(xyzw: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    x, y, z, w = (float(c) for c in xyzw)
    return pin.Quaternion(w, x, y, z).toRotationMatrix()
