"""One call's references of the balance controller: :class:`Targets` (Python) and the float vector the compiled
stage reads them from, with its named layout (the offsets ``T_*``; numba freezes them into the compiled code).

Layout of the target vector (:data:`TARGET_SIZE` floats), world frame, SI units: the hip's (Body-17 CoM) position
(3), [linear; angular] velocity (6), orientation (9, row-major), acceleration (6); in single support the swing toe
point's position (3), velocity (6), the toe body's orientation (9, row-major), the feed-forward acceleration (6),
the heel-return phase, the heel-return time (s) and the heel lift at lift-off (rad; < 0: measure it now); in double
support the trailing heel's lift angle (rad) in the first swing slot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TARGET_FIELDS = (("hip_p", 3), ("hip_v", 6), ("hip_R", 9), ("hip_a", 6), ("swing_p", 3), ("swing_v", 6),
                 ("swing_R", 9), ("swing_a", 6), ("return_x", 1), ("return_time", 1), ("lift0", 1))
"""(name, floats) of the target vector, in order."""
TARGET_SLICES = {}
_o = 0
for _name, _n in TARGET_FIELDS:
    TARGET_SLICES[_name] = slice(_o, _o + _n)
    _o += _n
TARGET_SIZE = _o
T_HIP_P, T_HIP_V, T_HIP_R, T_HIP_A = (TARGET_SLICES[n].start for n in ("hip_p", "hip_v", "hip_R", "hip_a"))
T_SWING_P, T_SWING_V, T_SWING_R, T_SWING_A = (TARGET_SLICES[n].start for n in ("swing_p", "swing_v", "swing_R",
                                                                               "swing_a"))
T_RETURN_X, T_RETURN_TIME, T_LIFT0 = (TARGET_SLICES[n].start for n in ("return_x", "return_time", "lift0"))
T_HEEL_ANGLE = T_SWING_P
"""Double support: the trailing heel's lift angle shares the first swing slot."""


def pack_hip(tgt: np.ndarray, p: np.ndarray, v6: np.ndarray, R: np.ndarray, a6: np.ndarray) -> None:
    """Write the hip's references into the target vector ``tgt``."""
    S = TARGET_SLICES
    tgt[S["hip_p"]], tgt[S["hip_v"]], tgt[S["hip_R"]], tgt[S["hip_a"]] = p, v6, R.ravel(), a6


def pack_swing(tgt: np.ndarray, p: np.ndarray, v6: np.ndarray, R: np.ndarray, a6: np.ndarray, return_x: float,
               return_time: float, lift0: float) -> None:
    """Write a swing's references (toe point, toe body, feed-forward, heel return) into ``tgt``."""
    S = TARGET_SLICES
    tgt[S["swing_p"]], tgt[S["swing_v"]], tgt[S["swing_R"]], tgt[S["swing_a"]] = p, v6, R.ravel(), a6
    tgt[T_RETURN_X], tgt[T_RETURN_TIME] = return_x, return_time
    tgt[T_LIFT0] = lift0


@dataclass
class Targets:
    """One call's references (``BalanceController._targets``): the plan's time t (s); the hip's (position,
    velocity (6,), orientation, acceleration (6,)); a swing's (foot, toe point, velocity (6,), toe-body orientation,
    feed-forward acceleration (6,), heel-return phase); double support's trailing heel (foot, lift angle, rad)."""

    t: float
    hip: tuple
    swing: tuple | None = None
    heel: tuple | None = None
