"""The thesis's four locomotion phases as data, and the pure phase-switching rules of section 6.1.1.

Cycle (errata 6.1): LFFSSP -> RFFDSP -> RFFSSP -> LFFDSP -> LFFSSP ...  Segment k of the path is one single
support phase (SSP) followed by one double support phase (DSP).

Bodies held fixed (thesis L1725-1730, eqs. 4.75-4.94) and their floating-base contact sets (design.md s. 4):

| phase  | held fixed           | contact set                          | rows | free DOF |
|--------|----------------------|--------------------------------------|------|----------|
| LFFSSP | left foot 2, 4       | weld O_4 + lock theta4               | 7    | 25       |
| RFFDSP | 1, 3 and left toe 2  | weld O_3 + lock theta3 + weld O_2    | 13   | 19       |
| RFFSSP | right foot 1, 3      | weld O_3 + lock theta3               | 7    | 25       |
| LFFDSP | 2, 4 and right toe 1 | weld O_4 + lock theta4 + weld O_1    | 13   | 19       |

The thesis's free-DOF count is its 26 joint variables (eq. 4.1) minus the toe-lock row (eq. 4.80 / 4.84 /
4.90) minus, in double support, the 6 closed-chain rows (eqs. 4.85-4.86 / 4.91-4.92).

Decisions:
- The "support foot" of a phase is the foot held flat (main body welded, toe joint locked); in a DSP it is
  the foot that has just landed, and the other foot is held by its toe body only (its heel rises).
- DSP end, condition 2 (errata 6.2): ``elapsed - t_dsp > 0.1 t_dsp`` with ``elapsed`` the time since the
  DSP began (L4037 prints ``t - t_DSP,k``, meaningless with the global time).
- Both switching comparisons are strict, as printed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from humanoid_sim.dynamics.contact import ContactSet, FootSpec

FOOT_SPECS: dict[str, FootSpec] = {
    "R": FootSpec("R", main_frame="O_3", toe_frame="O_1", toe_joint="theta3"),
    "L": FootSpec("L", main_frame="O_4", toe_frame="O_2", toe_joint="theta4"),
}
"""Thesis feet: main body 3/4 (frames O_3/O_4), toe body 1/2 (O_1/O_2), toe joint theta3/theta4."""

TOE_POINT_FRAME = {"R": "P_tpR", "L": "P_tpL"}
THESIS_JOINT_COUNT = 26
"""Joint variables of eq. 4.1."""


def other_foot(foot: str) -> str:
    """'L' <-> 'R'."""
    if foot not in ("L", "R"):
        raise ValueError(f"foot must be 'L' or 'R', got {foot!r}")
    return "R" if foot == "L" else "L"


def foot_held_flat(foot: str) -> ContactSet:
    """Weld the foot's main body and lock its toe joint (7 rows): bodies 1, 3 (or 2, 4) fixed."""
    s = FOOT_SPECS[foot]
    return ContactSet(welds=(s.main_frame,), locks=(s.toe_joint,), name=f"{foot}-flat")


def toe_held(foot: str) -> ContactSet:
    """Weld the foot's toe body only (6 rows): body 1 (or 2) fixed, heel free."""
    s = FOOT_SPECS[foot]
    return ContactSet(welds=(s.toe_frame,), name=f"{foot}-toe")


class Phase(Enum):
    """The four basic phases of the thesis (ch. 3-4)."""

    LFFSSP = "LFFSSP"
    RFFDSP = "RFFDSP"
    RFFSSP = "RFFSSP"
    LFFDSP = "LFFDSP"

    @property
    def is_double_support(self) -> bool:
        return self in (Phase.RFFDSP, Phase.LFFDSP)

    @property
    def support_foot(self) -> str:
        """The foot held flat (weld + toe lock): 'L' in LFFSSP/LFFDSP, 'R' in RFFSSP/RFFDSP."""
        return self.value[0]

    @property
    def trailing_toe(self) -> str | None:
        """DSP: the foot held by its toe only (the previous support foot); SSP: None."""
        return other_foot(self.support_foot) if self.is_double_support else None

    @property
    def swing_foot(self) -> str | None:
        """SSP: the foot in the air (it lands at the end of the phase); DSP: None."""
        return None if self.is_double_support else other_foot(self.support_foot)

    @property
    def landing_foot(self) -> str | None:
        """SSP: the foot whose touchdown ends the phase (= swing foot); DSP: None (lift-off changes no state)."""
        return self.swing_foot

    @property
    def stance_feet(self) -> tuple[str, ...]:
        """Feet touching the ground: support foot first."""
        return (self.support_foot,) if self.trailing_toe is None else (self.support_foot, self.trailing_toe)

    @property
    def contacts(self) -> ContactSet:
        """The floating-base contact set of this phase (design.md s. 4 table)."""
        return _CONTACTS[self]

    @property
    def n_constraint_rows(self) -> int:
        return self.contacts.n_rows

    @property
    def thesis_free_dof(self) -> int:
        """Free DOF as the thesis counts them: 26 joints - 1 toe lock - 6 closed-chain rows in a DSP."""
        return THESIS_JOINT_COUNT - 1 - (6 if self.is_double_support else 0)

    @property
    def next(self) -> Phase:
        return next_phase(self)


_CYCLE = (Phase.LFFSSP, Phase.RFFDSP, Phase.RFFSSP, Phase.LFFDSP)


def next_phase(phase: Phase) -> Phase:
    """The phase that follows ``phase`` in the cycle LFFSSP -> RFFDSP -> RFFSSP -> LFFDSP -> LFFSSP."""
    return _CYCLE[(_CYCLE.index(phase) + 1) % 4]


def _phase_contacts(phase: Phase) -> ContactSet:
    s = foot_held_flat(phase.support_foot)
    if phase.trailing_toe is not None:
        t = toe_held(phase.trailing_toe)
        return ContactSet(welds=s.welds + t.welds, locks=s.locks, name=phase.value)
    return ContactSet(welds=s.welds, locks=s.locks, name=phase.value)


_CONTACTS = {p: _phase_contacts(p) for p in Phase}


def touchdown_contacts(ssp: Phase) -> ContactSet:
    """Constraints that hold right after the touchdown ending ``ssp``: the stance foot stays flat and the
    landing foot is at rest and flat (eqs. 4.95/4.98: V_tp = w = 0 and theta4' (theta3') = 0).  The
    velocity-level content equals the next DSP's set plus the stance foot's heel (its theta_dot = 0 holds
    through the thesis's reset, which does not change theta3' / theta4' of the stance foot)."""
    if ssp.is_double_support:
        raise ValueError(f"touchdown ends a single support phase, got {ssp.value}")
    stance = foot_held_flat(ssp.support_foot)
    landing = foot_held_flat(ssp.landing_foot)
    return stance.union(landing, name=f"{ssp.value}->{next_phase(ssp).value}")


# --------------------------------------------------------------------------------------- switching rules
@dataclass(frozen=True)
class SwitchThresholds:
    """Phase-switching thresholds of section 6.1.1 (L3984-4040), SI units."""

    toe_flat_height: float = 0.015                 # m: toe-point height when the toe body lies flat
    touchdown_tolerance: float = 0.001             # m: SSP ends when P_z - 0.015 < 0.001
    min_horizontal_progress_fraction: float = 0.3  # of the planned horizontal toe travel
    dsp_hip_distance: float = 0.05                 # m: |P_c17 - P_c17,f| below which a DSP ends
    dsp_overtime_fraction: float = 0.1             # a DSP ends once it lasted (1 + 0.1) t_DSP


def _vec3(p: np.ndarray, name: str) -> np.ndarray:
    p = np.asarray(p, dtype=float)
    if p.shape != (3,):
        raise ValueError(f"{name} must be a 3-vector (m, world), got shape {p.shape}")
    return p


def ssp_should_end(swing_toe_p: np.ndarray, toe_start_p: np.ndarray, toe_end_ref_p: np.ndarray,
                   thresholds: SwitchThresholds = SwitchThresholds()) -> bool:
    """Section 6.1.1.1: the SSP ends when the swing toe point (world, m) is low AND has covered more than
    0.3 of its planned horizontal travel: ``P_z - 0.015 < 0.001`` and
    ``|P_xy - P_i,xy| > 0.3 |P_f,xy - P_i,xy|`` (P_i: toe point at the phase start; P_f: reference at the
    phase end).  There is no time-out (errata 6.2)."""
    p = _vec3(swing_toe_p, "swing_toe_p")
    p0 = _vec3(toe_start_p, "toe_start_p")
    pf = _vec3(toe_end_ref_p, "toe_end_ref_p")
    if not (p[2] - thresholds.toe_flat_height) < thresholds.touchdown_tolerance:
        return False  # still in the air (most steps): the travel need not be measured
    moved = math.hypot(p[0] - p0[0], p[1] - p0[1])
    planned = math.hypot(pf[0] - p0[0], pf[1] - p0[1])
    return bool(moved > thresholds.min_horizontal_progress_fraction * planned)


def dsp_should_end(hip_com_p: np.ndarray, hip_end_ref_p: np.ndarray, elapsed: float, t_dsp: float,
                   thresholds: SwitchThresholds = SwitchThresholds()) -> bool:
    """Section 6.1.1.2: the DSP ends when the CoM of body 17 is within 0.05 m (3-D) of its phase-end
    reference OR the phase has lasted more than 1.1 t_DSP (``elapsed - t_dsp > 0.1 t_dsp``, errata 6.2)."""
    p = _vec3(hip_com_p, "hip_com_p")
    pf = _vec3(hip_end_ref_p, "hip_end_ref_p")
    if not t_dsp > 0.0:
        raise ValueError(f"t_dsp must be > 0 s, got {t_dsp}")
    if not elapsed >= 0.0:
        raise ValueError(f"elapsed must be >= 0 s, got {elapsed}")
    near = np.linalg.norm(p - pf) < thresholds.dsp_hip_distance
    overtime = (elapsed - t_dsp) > thresholds.dsp_overtime_fraction * t_dsp
    return bool(near or overtime)
