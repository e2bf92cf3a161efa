"""Reference trajectories of thesis chapter 3: hip (Body-17 CoM and orientation), toe points and feet.

Built once from :class:`PathParams` (arc centres, local frames and every polynomial coefficient are
precomputed); queried by (phase, phase time) or by global time on the nominal schedule (errata T-3).
World frame, SI units (m, s, rad).  Phase and segment indices are 0-based; the thesis phase number
PHASE_N is ``index + 1``.  Segment i is the SSP+DSP pair from waypoint i to waypoint i+1.

Unified left/right formulas (s = T_dir; see ``geometry``): a point at arc angle theta and radius r is
p = O + s r u(phi), phi = theta_CS + s theta, u = (sin phi, -cos phi), t = (cos phi, sin phi), so

    v = s r' u + r theta' t
    a = s (r'' - r theta'^2) u + (2 r' theta' + r theta'') t

which is eq. 3.8-3.16 (hip, r = R_k) and eq. 3.34-3.41 (toes, r = R_gen) with their time derivatives;
theta_ri and theta_CS are constant within a phase (errata T-8).

Decisions (thesis silent or damaged; details in docs/thesis-notes.md, "Reference trajectories"):

* D1 (T-3) ``sample`` clamps the phase time to [0, duration] and evaluates every polynomial at the
  clamped time, velocities and accelerations included, as the Simulink trajectory function did.
* D2 (T-4) the swing foot starts (toe point and yaw) from where that same foot last landed: the
  stored actual landing (:meth:`ReferenceTrajectory.set_landing`) or, until one is supplied, its
  planned landing; for a foot that has not yet swung, toe_R0/toe_L0 and foot_R0/foot_L0 (PRi/PLi,
  FRO_i/FLO_i).  Eqs. 3.46/3.47 literally take segment k-1, the landing of the *other* foot.
* D3 (T-5) the DSP yaw polynomial of the last segment ends at the tangent heading of the last arc at
  P_n with rate s V_n / R_{n-1} (the path "holds" its final heading, as if continued tangentially).
* D4 (T-5, L1700) angles are unwrapped so that every reported yaw is continuous along the nominal
  path: theta_CS of each segment is shifted by 2 pi to lie within pi of the previous segment's end
  heading, and each yaw polynomial's end value is start + wrap_pi(end - start).  This is the thesis's
  reduction of (theta_Forf - theta_Fori) into (-pi, pi], applied to theta_hor as well.
* D5 (T-10) the hip yaw reference is theta_CS of segment 0 at t = 0 as the thesis defines it, even
  when that differs from the robot's initial yaw (40.5 deg step in simulation 1); no smoothing.
* D6 (L1392) the hip CoM height is constant Phip[0][2]; the swing toe height polynomial starts and
  ends at the flat-toe height 0.015 m whatever the stored landing height (only its x, y are used).
* D7 a foot that is on the ground is reported at its stored toe point and stored orientation
  (possibly tilted, as landed), with zero velocity and acceleration; a swinging foot stays parallel
  to the ground (L1616) with the yaw of its start orientation.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from humanoid_sim.errors import InputError

from .geometry import arc_angle, arc_centre, cs_yaw, wrap_pi, yaw_of
from .params import TOE_FLAT_HEIGHT, PathParams
from .polynomials import cubic_bvp, eval_cubic, eval_quartic, toe_height_quartic

_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


_ZERO6 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def _central(vp: tuple[float, ...], vm: tuple[float, ...], h: float) -> np.ndarray:
    """(vp - vm) / 2h elementwise (6,): NumPy's ``(np.array(vp) - np.array(vm)) / (2.0 * h)``, the same numbers."""
    d = 2.0 * h
    return np.array([(p - m) / d for p, m in zip(vp, vm)])


def _rz(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array(((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0)))


SSP_TABLE = ("t_start", "duration", "hip_z", "Ox", "Oy", "s", "R", "theta_cs", "c3", "c2", "c1", "c0", "t_z", "R_f",
             "theta_i", "g3", "g2", "g1", "g0", "f3", "f2", "f1", "f0", "h4", "h3", "h2", "h1", "h0", "j3", "j2", "j1",
             "j0")
"""Layout of :meth:`ReferenceTrajectory.ssp_table`: the phase's nominal window (s), the hip height (m), the arc
centre (m), side sign, radius (m) and start angle (rad), the hip angle cubic c, then the swing foot's radius cubic
g (used up to t_z, R_f after), rotation cubic f from theta_i, height quartic h and yaw cubic j (thesis 3.2.3)."""
SSP_TABLE_SIZE = len(SSP_TABLE)
DSP_TABLE = ("t_start", "duration", "hip_z", "Ox", "Oy", "s", "R", "theta_cs", "d3", "d2", "d1", "d0", "e3", "e2",
             "e1", "e0")
"""Layout of :meth:`ReferenceTrajectory.dsp_table`: as :data:`SSP_TABLE` up to theta_cs, then the hip angle cubic d
and the Body-17 yaw cubic e of the double support (thesis 3.2.3.1-3.2.3.2)."""


class TrajectoryError(InputError):
    """Invalid query of a :class:`ReferenceTrajectory` (bad phase index, foot name, landing data)."""


# ---------------------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class PhaseInfo:
    """One phase of the nominal schedule.

    index: 0-based phase index (thesis PHASE_N = index + 1); name: LFFSSP / RFFDSP / RFFSSP / LFFDSP;
    segment: 0-based path segment; is_ssp; swing_foot: "R"/"L" in an SSP, None in a DSP;
    landed_foot: in a DSP the foot that has just landed (the one that swung in this segment's SSP);
    t_start, t_end, duration: nominal times, s.
    """

    index: int
    name: str
    segment: int
    is_ssp: bool
    swing_foot: str | None
    landed_foot: str | None
    t_start: float
    t_end: float
    duration: float

    @property
    def number(self) -> int:
        """Thesis phase number PHASE_N (1-based)."""
        return self.index + 1


@dataclass(frozen=True)
class PhaseTargets:
    """Phase-end targets used by the phase selector (thesis 6.1.1, design.md section 6).

    hip_p_end: reference Body-17 CoM position at the end of the phase (P_c17,f), m.
    swing_foot: "R"/"L" in an SSP, None in a DSP.
    swing_toe_start / swing_toe_end: toe point of the swing foot at the start (P_i, the stored landing)
    and planned end (P_f) of the SSP, m; None in a DSP.
    planned_horizontal_travel: |P_f - P_i| in the ground plane, m (0 in a DSP).
    duration: nominal phase duration, s (t_DSP,k for the 1.1 t_DSP overtime rule).
    """

    phase: int
    hip_p_end: np.ndarray
    swing_foot: str | None
    swing_toe_start: np.ndarray | None
    swing_toe_end: np.ndarray | None
    planned_horizontal_travel: float
    duration: float


class RefSample:
    """Reference state at one instant; world frame, SI units.  Treat the arrays as read-only.

    hip_*: Body-17 CoM position / velocity / acceleration (m, m/s, m/s^2), Body-17 orientation
    C^(0,17) (3x3), angular velocity / acceleration (rad/s, rad/s^2).  toe_R_* / foot_R_*: right toe
    point P_tpR and Body-1 orientation C^(0,1), same layout; toe_L_* / foot_L_*: left toe point and
    Body 2.  hip_yaw, foot_R_yaw, foot_L_yaw: the yaw angles (rad, unwrapped, continuous along the
    nominal path) of those orientations.  phase, t_phase: the phase and the clamped phase time used.
    """

    __slots__ = ("phase", "t_phase",
                 "hip_p", "hip_v", "hip_a", "hip_R", "hip_w", "hip_alpha", "hip_yaw",
                 "toe_R_p", "toe_R_v", "toe_R_a", "foot_R_R", "foot_R_w", "foot_R_alpha", "foot_R_yaw",
                 "toe_L_p", "toe_L_v", "toe_L_a", "foot_L_R", "foot_L_w", "foot_L_alpha", "foot_L_yaw")

    def __repr__(self) -> str:
        return f"RefSample(phase={self.phase}, t_phase={self.t_phase:.6g}, hip_p={self.hip_p})"

    def set_foot(self, foot: str, vals: tuple) -> None:
        """Set foot "R" / "L": vals = (toe point, its velocity, its acceleration, orientation, angular velocity,
        angular acceleration, yaw)."""
        if foot == "R":
            (self.toe_R_p, self.toe_R_v, self.toe_R_a, self.foot_R_R, self.foot_R_w, self.foot_R_alpha,
             self.foot_R_yaw) = vals
        else:
            (self.toe_L_p, self.toe_L_v, self.toe_L_a, self.foot_L_R, self.foot_L_w, self.foot_L_alpha,
             self.foot_L_yaw) = vals


# ---------------------------------------------------------------------------------------------- internals
class _Footprint:
    """A foot on the ground: toe point (3,), orientation (3x3) and its unwrapped yaw."""

    __slots__ = ("p", "R", "yaw")

    def __init__(self, p: np.ndarray, R: np.ndarray, yaw: float) -> None:
        self.p, self.R, self.yaw = _ro(p), _ro(R), float(yaw)


class _Swing:
    """Swing-foot polynomials of one SSP (thesis 3.2.3.3)."""

    __slots__ = ("theta_i", "R_o", "R_f", "t_z", "g", "f", "h", "j", "yaw_i", "yaw_f", "p_start")


class _Segment:
    """Precomputed geometry and hip polynomials of one SSP+DSP pair (thesis 3.2.1-3.2.3.2)."""

    __slots__ = ("i", "s", "R", "O", "theta_cs", "theta_htotal", "theta_hssp", "t_ssp", "t_dsp",
                 "c", "d", "e", "swing_foot", "theta_land", "swing", "Ox", "Oy")


# ---------------------------------------------------------------------------------------------- generator
class ReferenceTrajectory:
    """Reference trajectory generator of thesis chapter 3 for one :class:`PathParams` path."""

    def __init__(self, params: PathParams) -> None:
        if not isinstance(params, PathParams):
            raise TrajectoryError(f"params: expected PathParams, got {type(params).__name__}")
        self.params = params
        p = params
        n_seg = p.n_segments
        self.hip_z = float(p.Phip[0, 2])  # thesis L1392: constant CoM height
        first_swing = "R" if p.first_phase == "LFFSSP" else "L"
        other = {"R": "L", "L": "R"}

        # --- arc geometry (3.2.1, 3.2.2) and hip polynomials (3.2.3.1, 3.2.3.2) ---------------------
        self._segs: list[_Segment] = []
        prev_end_heading: float | None = None
        for i in range(n_seg):
            sg = _Segment()
            sg.i = i
            sg.s = int(p.T_dir[i])
            sg.R = float(p.R[i])
            P0, P1 = p.Phip[i, :2], p.Phip[i + 1, :2]
            sg.O = _ro(arc_centre(P0, P1, sg.R, sg.s))
            sg.Ox, sg.Oy = float(sg.O[0]), float(sg.O[1])
            th_cs = cs_yaw(P0, sg.O, sg.s)
            if prev_end_heading is None:
                th_cs = wrap_pi(th_cs)
            else:  # D4: unwrap so the hip heading is continuous along the path
                th_cs = prev_end_heading + wrap_pi(th_cs - prev_end_heading)
            sg.theta_cs = th_cs
            sg.theta_htotal = arc_angle(P1, sg.O, th_cs, sg.s)
            # theta_h,SSP = theta_htotal - (PLN + ADJ)  (L1328)
            sg.theta_hssp = sg.theta_htotal - (float(p.dtheta_PLN[i]) + float(p.dtheta_ADJ[i]))
            sg.t_ssp = float(p.t_SSP[i])
            sg.t_dsp = float(p.t_SSP[i] / p.PTR[i])  # t_DSP = t_SSP / PTR (L1330)
            V_k, V_kk1, V_k1 = (float(v) for v in p.Vhip[2 * i:2 * i + 3])
            # SSP theta_h cubic (L1341-1352): 0 -> theta_h,SSP, rates V_k/R_k -> V_k,k+1/R_k
            sg.c = cubic_bvp(sg.t_ssp, 0.0, sg.theta_hssp, V_k / sg.R, V_kk1 / sg.R)
            # DSP theta_h cubic (L1354-1360, errata T-2): theta_h,SSP -> theta_htotal,
            # rates V_k,k+1/R_k -> V_k+1/R_k
            sg.d = cubic_bvp(sg.t_dsp, sg.theta_hssp, sg.theta_htotal, V_kk1 / sg.R, V_k1 / sg.R)
            sg.swing_foot = first_swing if i % 2 == 0 else other[first_swing]
            # landing arc angle of the swing toe: theta_ri + theta_Rrot = theta_h,SSP + PLN (L1505)
            sg.theta_land = sg.theta_hssp + float(p.dtheta_PLN[i])
            prev_end_heading = th_cs + sg.s * sg.theta_htotal
            self._segs.append(sg)

        # DSP hip yaw cubic theta_hor (L1440-1490); last segment per D3
        for i, sg in enumerate(self._segs):
            V_kk1, V_k1 = float(p.Vhip[2 * i + 1]), float(p.Vhip[2 * i + 2])
            start = sg.theta_cs + sg.s * sg.theta_hssp
            if i + 1 < n_seg:
                nx = self._segs[i + 1]
                end, rate_end = nx.theta_cs, nx.s * V_k1 / nx.R
            else:
                end, rate_end = sg.theta_cs + sg.s * sg.theta_htotal, sg.s * V_k1 / sg.R
            end = start + wrap_pi(end - start)  # D4
            sg.e = cubic_bvp(sg.t_dsp, start, end, sg.s * V_kk1 / sg.R, rate_end)

        # --- footprints: slot 0/1 initial right/left, slot 2+i landing of segment i -------------------
        self._slots: list[_Footprint] = [
            _Footprint(p.toe_R0, p.foot_R0, yaw_of(p.foot_R0)),
            _Footprint(p.toe_L0, p.foot_L0, yaw_of(p.foot_L0)),
        ]
        self._swing_start_slot: list[int] = []
        self._actual: set[int] = set()   # slots holding actual (set_landing) rather than planned data
        last_slot = {"R": 0, "L": 1}
        for i, sg in enumerate(self._segs):
            self._swing_start_slot.append(last_slot[sg.swing_foot])
            self._slots.append(self._planned_landing(sg, self._slots[last_slot[sg.swing_foot]].yaw))
            last_slot[sg.swing_foot] = 2 + i
        for i in range(n_seg):
            self._build_swing(i)

        # --- nominal schedule (errata 6.1: phase 2i = SSP of segment i, 2i+1 its DSP) ----------------
        self.phases: list[PhaseInfo] = []
        # per phase: for "R" and "L" either ("fix", slot) or ("swing", segment)
        self._feet: list[dict[str, tuple[str, int]]] = []
        last_slot = {"R": 0, "L": 1}
        t = 0.0
        for i, sg in enumerate(self._segs):
            sw, st = sg.swing_foot, other[sg.swing_foot]
            ssp_name = "LFFSSP" if sw == "R" else "RFFSSP"
            dsp_name = "RFFDSP" if sw == "R" else "LFFDSP"
            self.phases.append(PhaseInfo(2 * i, ssp_name, i, True, sw, None, t, t + sg.t_ssp, sg.t_ssp))
            self._feet.append({sw: ("swing", i), st: ("fix", last_slot[st])})
            t += sg.t_ssp
            last_slot[sw] = 2 + i
            self.phases.append(PhaseInfo(2 * i + 1, dsp_name, i, False, None, sw, t, t + sg.t_dsp, sg.t_dsp))
            self._feet.append({sw: ("fix", last_slot[sw]), st: ("fix", last_slot[st])})
            t += sg.t_dsp
        self._t_starts = [ph.t_start for ph in self.phases]
        self.duration = t

    # ------------------------------------------------------------------ construction helpers
    def _planned_landing(self, sg: _Segment, yaw_prev: float) -> _Footprint:
        """Planned landing of segment ``sg``'s swing foot: toe at radius R_f and arc angle
        theta_h,SSP + PLN, orientation e^(u3 theta_Forf) (eqs. 3.48/3.49, unwrapped per D4)."""
        R_f = self._r_final(sg)
        phi = sg.theta_cs + sg.s * sg.theta_land
        p = (sg.Ox + sg.s * R_f * math.sin(phi), sg.Oy - sg.s * R_f * math.cos(phi), TOE_FLAT_HEIGHT)
        # eq. 3.48 (left) / 3.49 (right): theta_Forf = theta_CS +- (theta_h,SSP + PLN) = phi
        yaw_f = yaw_prev + wrap_pi(phi - yaw_prev)
        return _Footprint(np.array(p), _rz(yaw_f), yaw_f)

    def _r_final(self, sg: _Segment) -> float:
        """R_f of eqs. 3.32/3.33: inner foot R - SW/2, outer foot R + SW/2."""
        sw = float(self.params.SW[sg.i])
        inner = (sg.swing_foot == "L") == (sg.s == 1)  # left foot inside a left turn, right in a right
        return sg.R - sw / 2 if inner else sg.R + sw / 2

    def _build_swing(self, i: int) -> None:
        """(Re)compute the swing-foot polynomials of segment i from its start footprint."""
        sg = self._segs[i]
        p = self.params
        start = self._slots[self._swing_start_slot[i]]
        w = _Swing()
        w.p_start = start.p
        w.theta_i = arc_angle(start.p, sg.O, sg.theta_cs, sg.s)           # eqs. 3.19-3.29
        w.R_o = math.hypot(sg.Ox - start.p[0], sg.Oy - start.p[1])         # eqs. 3.30/3.31
        if w.R_o < 1e-9:
            raise TrajectoryError(f"segment {i}: start toe point {start.p.tolist()} lies on the arc centre "
                                  f"{sg.O.tolist()}; theta_ri is undefined")
        w.R_f = self._r_final(sg)                                          # eqs. 3.32/3.33
        w.t_z = sg.t_ssp / float(p.k_Adj[i])                               # L1561
        w.g = cubic_bvp(w.t_z, w.R_o, w.R_f, 0.0, 0.0)                     # R_c (L1566-1574)
        rot = sg.theta_land - w.theta_i                                    # theta_Rrot / theta_Lrot (L1505)
        w.f = cubic_bvp(sg.t_ssp, 0.0, rot, 0.0, 0.0)                      # theta_rot (L1530-1537)
        w.h = toe_height_quartic(sg.t_ssp, float(p.k_SH[i]), float(p.SH[i]), TOE_FLAT_HEIGHT)  # L1590
        # foot yaw theta_For (L1680-1708): from the start footprint's yaw (D2) to theta_Forf
        # (eqs. 3.48/3.49: theta_CS +- (theta_h,SSP + PLN)), difference reduced into (-pi, pi] (L1700).
        if 2 + i not in self._actual:   # a still-planned landing follows the (possibly new) start yaw
            self._slots[2 + i] = self._planned_landing(sg, start.yaw)
        w.yaw_i = start.yaw
        phi_f = sg.theta_cs + sg.s * sg.theta_land
        w.yaw_f = w.yaw_i + wrap_pi(phi_f - w.yaw_i)
        w.j = cubic_bvp(sg.t_ssp, w.yaw_i, w.yaw_f, 0.0, 0.0)
        sg.swing = w

    # ------------------------------------------------------------------ queries
    @property
    def n_phases(self) -> int:
        return len(self.phases)

    def segment_geometry(self, i: int) -> dict[str, float | np.ndarray]:
        """Derived numbers of segment i: arc centre O (2,), theta_CS, theta_htotal, theta_h,SSP (rad,
        theta_CS unwrapped per D4), radius R, T_dir, t_SSP, t_DSP, and the swing foot."""
        sg = self._segs[self._check_index(i, len(self._segs), "segment")]
        return {"O": sg.O, "theta_cs": sg.theta_cs, "theta_htotal": sg.theta_htotal,
                "theta_hssp": sg.theta_hssp, "R": sg.R, "T_dir": sg.s, "t_ssp": sg.t_ssp, "t_dsp": sg.t_dsp,
                "swing_foot": sg.swing_foot, "R_f": sg.swing.R_f, "t_z": sg.swing.t_z}

    @staticmethod
    def _check_index(i: int, n: int, name: str) -> int:
        if not isinstance(i, (int, np.integer)) or isinstance(i, bool) or not 0 <= i < n:
            raise TrajectoryError(f"{name}: index must be an integer in [0, {n - 1}] (value: {i!r})")
        return int(i)

    def phase_at(self, t: float) -> int:
        """Index of the nominal phase containing global time t (s): t_start <= t < t_end.
        Times before 0 give phase 0, times at or after the end give the last phase."""
        k = bisect.bisect_right(self._t_starts, t) - 1
        return min(max(k, 0), len(self.phases) - 1)

    def sample_global(self, t: float, phase: int | None = None) -> RefSample:
        """Reference at global time t on the nominal schedule (errata T-3).

        With ``phase`` given, t is clamped to that phase's nominal window [t_start, t_end] (the
        simulator's use while the actual phase lasts shorter or longer than planned); otherwise the
        phase is :meth:`phase_at`.
        """
        k = self.phase_at(t) if phase is None else self._check_index(phase, len(self.phases), "phase")
        return self.sample(k, t - self.phases[k].t_start)

    def phase_end(self, phase: int) -> RefSample:
        """Reference at the nominal end of ``phase`` (thesis 6.1.1: evaluated beyond the end, clamped)."""
        k = self._check_index(phase, len(self.phases), "phase")
        return self.sample(k, self.phases[k].duration)

    def phase_targets(self, phase: int) -> PhaseTargets:
        """Targets for the phase selector: phase-end hip CoM, swing-toe start/end, planned travel."""
        k = self._check_index(phase, len(self.phases), "phase")
        ph = self.phases[k]
        end = self.sample(k, ph.duration)
        if not ph.is_ssp:
            return PhaseTargets(k, end.hip_p, None, None, None, 0.0, ph.duration)
        w = self._segs[ph.segment].swing
        toe_end = end.toe_R_p if ph.swing_foot == "R" else end.toe_L_p
        travel = math.hypot(toe_end[0] - w.p_start[0], toe_end[1] - w.p_start[1])
        return PhaseTargets(k, end.hip_p, ph.swing_foot, w.p_start, toe_end, travel, ph.duration)

    def sample(self, phase: int, t_phase: float) -> RefSample:
        """Reference of ``phase`` at local phase time ``t_phase`` (s), clamped to [0, duration] (D1)."""
        k = self._check_index(phase, len(self.phases), "phase")
        ph = self.phases[k]
        t = min(max(float(t_phase), 0.0), ph.duration)
        sg = self._segs[ph.segment]
        out = RefSample()
        out.phase, out.t_phase = k, t

        # ---- hip CoM on arc k (eqs. 3.8-3.16) and Body-17 yaw (3.2.3.2.2)
        sp, cp, thd, thdd, yaw, yawd, yawdd = self._hip_scalars(ph, sg, t)
        R = sg.R
        cen = -sg.s * R * thd * thd   # s (r'' - r theta'^2) with r = R constant
        tan = R * thdd
        out.hip_p = np.array((sg.Ox + sg.s * R * sp, sg.Oy - sg.s * R * cp, self.hip_z))
        out.hip_v = np.array((R * thd * cp, R * thd * sp, 0.0))
        out.hip_a = np.array((cen * sp + tan * cp, -cen * cp + tan * sp, 0.0))
        out.hip_R = _rz(yaw)
        out.hip_w = np.array((0.0, 0.0, yawd))
        out.hip_alpha = np.array((0.0, 0.0, yawdd))
        out.hip_yaw = yaw

        # ---- feet
        for foot, (kind, idx) in self._feet[k].items():
            if kind == "fix":
                fp = self._slots[idx]
                vals = (fp.p, _ZERO3, _ZERO3, fp.R, _ZERO3, _ZERO3, fp.yaw)
            else:
                vals = self._swing_sample(sg, t)
            out.set_foot(foot, vals)
        return out

    def _hip_scalars(self, ph: PhaseInfo, sg: _Segment, t: float) -> tuple[float, ...]:
        """sin / cos of the hip's arc angle phi, theta_h' and theta_h'', yaw and its two rates at phase time t
        (already clamped)."""
        if ph.is_ssp:
            th, thd, thdd = eval_cubic(sg.c, t)
            phi = sg.theta_cs + sg.s * th
            yaw, yawd, yawdd = phi, sg.s * thd, sg.s * thdd     # C^(0,17) = e^(u3 (theta_CS +- theta_h))
        else:
            th, thd, thdd = eval_cubic(sg.d, t)
            phi = sg.theta_cs + sg.s * th
            yaw, yawd, yawdd = eval_cubic(sg.e, t)        # theta_hor (L1440-1490)
        return math.sin(phi), math.cos(phi), thd, thdd, yaw, yawd, yawdd

    def _yaw_scalars(self, ph: PhaseInfo, sg: _Segment, t: float) -> tuple[float, float, float]:
        """:meth:`_hip_scalars`' yaw and its two rates alone (the same numbers)."""
        if ph.is_ssp:
            th, thd, thdd = eval_cubic(sg.c, t)
            return sg.theta_cs + sg.s * th, sg.s * thd, sg.s * thdd
        return eval_cubic(sg.e, t)

    def _clamped(self, phase: int, t: float) -> tuple[PhaseInfo, _Segment, float]:
        """Phase, segment and phase time clamped to the phase's nominal window, for global time t (s)."""
        ph = self.phases[phase]
        return ph, self._segs[ph.segment], min(max(float(t - ph.t_start), 0.0), ph.duration)

    def hip_reference(self, phase: int, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The controller's hip query: Body-17 CoM position (3,), [linear; angular] velocity (6,) and
        orientation (3x3) at global time t clamped to ``phase`` (as ``sample_global(t, phase)``, hip only)."""
        return self.hip_targets(phase, t)[:3]

    def hip_acceleration(self, phase: int, t: float) -> np.ndarray:
        """Body-17 CoM [linear; angular] acceleration (6,), world frame, m/s^2 and rad/s^2, at global time t clamped
        to ``phase``: the time derivative of :meth:`hip_reference`'s velocity (for controllers that feed the
        reference acceleration forward; the thesis's 5.1 does not use it)."""
        return self.hip_targets(phase, t)[3]

    def hip_targets(self, phase: int, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`hip_reference` and :meth:`hip_acceleration` at one time from one evaluation: position (3,),
        velocity (6,), orientation (3x3), acceleration (6,) (both queries are read from it)."""
        ph, sg, tc = self._clamped(phase, t)
        sp, cp, thd, thdd, yaw, yawd, yawdd = self._hip_scalars(ph, sg, tc)
        R, s = sg.R, sg.s
        p = np.array((sg.Ox + s * R * sp, sg.Oy - s * R * cp, self.hip_z))
        v6 = np.array((R * thd * cp, R * thd * sp, 0.0, 0.0, 0.0, yawd))
        a6 = np.array((R * thdd * cp - s * R * thd * thd * sp, R * thdd * sp + s * R * thd * thd * cp, 0.0,
                       0.0, 0.0, yawdd))
        return p, v6, _rz(yaw), a6

    def toe_velocity(self, phase: int, t: float, foot: str) -> np.ndarray:
        """:meth:`toe_reference`'s velocity (6,) alone; the same numbers."""
        return np.array(self._toe_velocity(phase, t, foot))

    def swing_feedforward(self, phase: int, t: float, foot: str, h: float) -> tuple[np.ndarray, ...]:
        """:meth:`toe_reference` at global time t with the central difference of :meth:`toe_velocity` over t +- h
        (s): toe point (3,), velocity (6,), orientation (3x3) and acceleration (6,), (v(t + h) - v(t - h)) / 2h:
        the balance controller's swing feed-forward in one query (the same numbers as the four)."""
        pt, v6, R = self.toe_reference(phase, t, foot)
        return pt, v6, R, _central(self._toe_velocity(phase, t + h, foot), self._toe_velocity(phase, t - h, foot), h)

    def _toe_velocity(self, phase: int, t: float, foot: str) -> tuple[float, ...]:
        """:meth:`toe_velocity` as six floats."""
        ph, sg, tc = self._clamped(phase, t)
        if self._feet[phase][foot][0] == "fix":
            return _ZERO6
        w = sg.swing
        s = sg.s
        if tc <= w.t_z:
            r, rd, _ = eval_cubic(w.g, tc)
        else:
            r, rd = w.R_f, 0.0
        rot, rotd, _ = eval_cubic(w.f, tc)
        zd = eval_quartic(w.h, tc)[1]
        phi = sg.theta_cs + s * (w.theta_i + rot)
        sp, cp = math.sin(phi), math.cos(phi)
        return (s * rd * sp + r * rotd * cp, -s * rd * cp + r * rotd * sp, zd, 0.0, 0.0, eval_cubic(w.j, tc)[1])

    def toe_reference(self, phase: int, t: float, foot: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The controller's swing query: toe point (3,), [toe-point velocity; foot angular velocity] (6,) and
        toe-body orientation (3x3) of ``foot`` ("R"/"L") at global time t clamped to ``phase``."""
        ph, sg, tc = self._clamped(phase, t)
        kind, idx = self._feet[phase][foot]
        if kind == "fix":
            fp = self._slots[idx]
            return fp.p, np.zeros(6), fp.R
        p, v, _, R, w, _, _ = self._swing_sample(sg, tc)
        return p, np.concatenate([v, w]), R

    def positions(self, t: float, phase: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Hip CoM, right toe point and left toe point reference positions (3, each) at global time t, on the
        nominal schedule or clamped to ``phase`` (as ``sample_global``, positions only)."""
        k = self.phase_at(t) if phase is None else phase
        ph, sg, tc = self._clamped(k, t)
        sp, cp, *_ = self._hip_scalars(ph, sg, tc)
        hip = np.array((sg.Ox + sg.s * sg.R * sp, sg.Oy - sg.s * sg.R * cp, self.hip_z))
        toes = []
        for foot in ("R", "L"):
            kind, idx = self._feet[k][foot]
            toes.append(self._slots[idx].p if kind == "fix" else self._swing_sample(sg, tc)[0])
        return hip, toes[0], toes[1]

    def ssp_table(self, phase: int) -> np.ndarray:
        """The numbers behind :meth:`hip_reference` and the swing foot's :meth:`toe_reference` in single-support
        ``phase``, as one float64 array (layout :data:`SSP_TABLE`), for the compiled kernel (``humanoid_sim.kernel``),
        which evaluates the same formulas from it.  Valid until the next :meth:`set_landing`."""
        k = self._check_index(phase, len(self.phases), "phase")
        ph = self.phases[k]
        if not ph.is_ssp:
            raise TrajectoryError(f"phase: {k} ({ph.name}) is not a single support phase")
        sg = self._segs[ph.segment]
        w = sg.swing
        tab = np.array([ph.t_start, ph.duration, self.hip_z, sg.Ox, sg.Oy, sg.s, sg.R, sg.theta_cs, *sg.c, w.t_z,
                        w.R_f, w.theta_i, *w.g, *w.f, *w.h, *w.j], dtype=float)
        if tab.size != SSP_TABLE_SIZE:
            raise AssertionError(f"ssp_table: {tab.size} numbers, layout expects {SSP_TABLE_SIZE}")
        return tab

    def dsp_table(self, phase: int) -> np.ndarray:
        """The numbers behind :meth:`hip_reference` in double-support ``phase`` as one float64 array (layout
        :data:`DSP_TABLE`), for the compiled kernel.  Valid until the next :meth:`set_landing`."""
        k = self._check_index(phase, len(self.phases), "phase")
        ph = self.phases[k]
        if ph.is_ssp:
            raise TrajectoryError(f"phase: {k} ({ph.name}) is not a double support phase")
        sg = self._segs[ph.segment]
        return np.array([ph.t_start, ph.duration, self.hip_z, sg.Ox, sg.Oy, sg.s, sg.R, sg.theta_cs, *sg.d, *sg.e],
                        dtype=float)

    @staticmethod
    def _swing_sample(sg: _Segment, t: float) -> tuple:
        """Swing toe (eqs. 3.34-3.41) and flat foot orientation (eqs. 3.42-3.49) at SSP time t."""
        w = sg.swing
        s = sg.s
        if t <= w.t_z:                                   # R_gen = R_c(t) for t <= t_z (L1561)
            r, rd, rdd = eval_cubic(w.g, t)
        else:
            r, rd, rdd = w.R_f, 0.0, 0.0
        rot, rotd, rotdd = eval_cubic(w.f, t)
        z, zd, zdd = eval_quartic(w.h, t)
        phi = sg.theta_cs + s * (w.theta_i + rot)
        sp, cp = math.sin(phi), math.cos(phi)
        cen = s * (rdd - r * rotd * rotd)
        tan = 2.0 * rd * rotd + r * rotdd
        p = np.array((sg.Ox + s * r * sp, sg.Oy - s * r * cp, z))
        v = np.array((s * rd * sp + r * rotd * cp, -s * rd * cp + r * rotd * sp, zd))
        a = np.array((cen * sp + tan * cp, -cen * cp + tan * sp, zdd))
        yaw, yawd, yawdd = eval_cubic(w.j, t)
        return p, v, a, _rz(yaw), np.array((0.0, 0.0, yawd)), np.array((0.0, 0.0, yawdd)), yaw

    # ------------------------------------------------------------------ touchdown data
    def set_landing(self, foot: str, phase: int, toe_point: np.ndarray, R_foot: np.ndarray) -> None:
        """Store the ACTUAL landed toe point and foot orientation (thesis L4024).

        foot: "R" or "L" (also "right"/"left"); phase: index of the SSP that ended with this
        touchdown, or of the DSP it started (same segment); toe_point (3,), world, m; R_foot: 3x3
        orientation of Body 1 (right) or Body 2 (left).  From then on the DSP and the following SSP
        hold that foot there, and its next swing starts from it (its polynomials are recomputed; the
        rest of the trajectory is unchanged).
        """
        f = {"R": "R", "L": "L", "right": "R", "left": "L"}.get(foot) if isinstance(foot, str) else None
        if f is None:
            raise TrajectoryError(f"foot: must be 'R' or 'L' (value: {foot!r})")
        k = self._check_index(phase, len(self.phases), "phase")
        i = self.phases[k].segment
        sg = self._segs[i]
        if sg.swing_foot != f:
            raise TrajectoryError(f"foot: phase {k} ({self.phases[k].name}, segment {i}) lands the "
                                  f"{sg.swing_foot} foot, not {f!r}")
        p = np.asarray(toe_point, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise TrajectoryError(f"toe_point: expected 3 finite values (value: {toe_point!r})")
        Rm = np.asarray(R_foot, dtype=float)
        # 1e-6: a rotation integrated by the simulator is orthonormal to ~1e-12; 1e-6 only rejects junk.
        if Rm.shape != (3, 3) or not np.allclose(Rm @ Rm.T, np.eye(3), atol=1e-6) or np.linalg.det(Rm) < 0:
            raise TrajectoryError(f"R_foot: expected a 3x3 rotation matrix (value: {R_foot!r})")
        planned_yaw = self._slots[2 + i].yaw
        yaw = planned_yaw + wrap_pi(yaw_of(Rm) - planned_yaw)  # D4: keep the yaw chain continuous
        saved = (self._slots[2 + i], 2 + i in self._actual,
                 self._slots[4 + i] if i + 2 < len(self._segs) else None)
        self._slots[2 + i] = _Footprint(p, Rm, yaw)
        self._actual.add(2 + i)
        if i + 2 < len(self._segs):   # the next swing of the same foot starts from this landing (D2)
            try:
                self._build_swing(i + 2)
            except TrajectoryError:    # leave the generator unchanged
                self._slots[2 + i] = saved[0]
                if not saved[1]:
                    self._actual.discard(2 + i)
                self._slots[4 + i] = saved[2]
                raise
