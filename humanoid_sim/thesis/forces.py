"""The force vector F of eq. 4.68, the actuator extraction matrix phi of eq. 4.69 and the phase selectors.

F (96,) stacks 32 three-vectors in the exact order of eq. 4.68 (L2747, errata K-12: not grouped as F/M pairs near
body 17).  F_{k,k+1} / M_{k,k+1} is the force (N) / moment (N m) that body k exerts on body k+1 at their joint,
resolved in frame k+1; the moment is about the joint point (the moment arms of eqs. 4.43-4.67 put the force there).
F_{0,k} / M_{0,k} is the ground wrench on body k, resolved in frame k, the moment about the CoM of body k
(no moment arm in eqs. 4.42-4.53, errata K-7).

T-bar (26,) is eq. 4.69 (L2753) with errata K-2 (T9 = M_{9,11y}^{(11)}: F only holds M_{9,11}^{(11)}).
"""

from __future__ import annotations

import numpy as np

F_BLOCKS: tuple[str, ...] = (
    "F0_1", "F1_3", "M0_1", "M1_3", "F0_3", "F3_9", "M0_3", "M3_9", "F9_11", "M9_11", "F11_17", "M11_17",
    "F12_17", "F17_20", "M12_17", "M17_20", "F10_12", "M10_12", "F4_10", "M4_10", "F0_4", "F2_4", "M0_4", "M2_4",
    "F0_2", "M0_2", "F20_23", "F20_24", "F20_27", "M20_23", "M20_24", "M20_27",
)
"""Eq. 4.68 (L2747), 32 blocks of 3 components (x, y, z in the frame named by the block's second body)."""

N_F = 3 * len(F_BLOCKS)  # 96
_POS = {name: i for i, name in enumerate(F_BLOCKS)}


def fslice(name: str) -> slice:
    """Slice of block ``name`` (e.g. "M3_9") in F."""
    try:
        i = _POS[name]
    except KeyError:
        raise KeyError(f"unknown F block {name!r}; eq. 4.68 blocks are {F_BLOCKS}") from None
    return slice(3 * i, 3 * i + 3)


def findex(name: str, comp: int) -> int:
    """Index in F of component ``comp`` (0 = x, 1 = y, 2 = z) of block ``name``."""
    return fslice(name).start + comp


def block(F: np.ndarray, name: str) -> np.ndarray:
    return np.asarray(F)[fslice(name)]


T_NAMES: tuple[str, ...] = (
    "T1", "T3", "T5", "T7", "T9", "T11", "T13", "T15", "T2", "T4", "T6", "T8", "T10", "T12", "T14", "T16",
    "T17", "T18", "T19", "T20", "T21", "T22", "T23", "T24", "T25", "T26",
)
"""T-bar of eq. 4.69 (L2753), in its row order."""

T_COMPONENTS: tuple[tuple[str, int], ...] = (
    ("M1_3", 1), ("M3_9", 0), ("M3_9", 1), ("M3_9", 2), ("M9_11", 1),     # T1; T3 T5 T7; T9 (errata K-2)
    ("M11_17", 0), ("M11_17", 1), ("M11_17", 2),                          # T11 T13 T15
    ("M2_4", 1), ("M4_10", 0), ("M4_10", 1), ("M4_10", 2), ("M10_12", 1),  # T2; T4 T6 T8; T10
    ("M12_17", 0), ("M12_17", 1), ("M12_17", 2),                          # T12 T14 T16
    ("M17_20", 0), ("M17_20", 1), ("M17_20", 2),                          # T17 T18 T19
    ("M20_23", 0), ("M20_23", 1), ("M20_24", 0), ("M20_24", 1),           # T20 T21; T22 T23
    ("M20_27", 0), ("M20_27", 1), ("M20_27", 2),                          # T24 T25 T26
)
"""Eq. 4.69: the F component each row of T-bar extracts."""

T_F_INDEX = np.array([findex(b, c) for b, c in T_COMPONENTS])


def phi() -> np.ndarray:
    """The 26 x 96 extraction matrix of eq. 4.69: T-bar = phi F."""
    P = np.zeros((26, N_F))
    P[np.arange(26), T_F_INDEX] = 1.0
    return P


def selector(items: list[tuple[str, int | None]]) -> np.ndarray:
    """Rows extracting whole blocks (comp None) or single components of F (the Phi_ZGR / Phi_ZR / K_c
    matrices of eqs. 4.75, 4.77, 4.79, 4.81, 4.83, 4.87, 4.89, 4.93 and section 5.2)."""
    rows = []
    for name, comp in items:
        comps = range(3) if comp is None else [comp]
        for c in comps:
            r = np.zeros(N_F)
            r[findex(name, c)] = 1.0
            rows.append(r)
    return np.array(rows)


# Ground wrenches forced to zero (eqs. 4.75, 4.79, 4.83, 4.89) and joint reactions forced to zero on the welded
# foot (eqs. 4.77, 4.81, 4.87, 4.93), by phase.
ZERO_GROUND: dict[str, list[tuple[str, int | None]]] = {
    "RFFSSP": [("F0_4", None), ("M0_4", None), ("F0_2", None), ("M0_2", None)],   # eq. 4.75
    "LFFSSP": [("F0_3", None), ("M0_3", None), ("F0_1", None), ("M0_1", None)],   # eq. 4.79
    "RFFDSP": [("F0_4", None), ("M0_4", None)],                                   # eq. 4.83
    "LFFDSP": [("F0_3", None), ("M0_3", None)],                                   # eq. 4.89
}
ZERO_REACTION: dict[str, list[tuple[str, int | None]]] = {
    "RFFSSP": [("F1_3", None), ("M1_3", 0), ("M1_3", 2)],   # eq. 4.77
    "LFFSSP": [("F2_4", None), ("M2_4", 0), ("M2_4", 2)],   # eq. 4.81
    "RFFDSP": [("F1_3", None), ("M1_3", 0), ("M1_3", 2)],   # eq. 4.87
    "LFFDSP": [("F2_4", None), ("M2_4", 0), ("M2_4", 2)],   # eq. 4.93
}
LOCKED_TOE: dict[str, str] = {"RFFSSP": "theta3", "RFFDSP": "theta3", "LFFSSP": "theta4", "LFFDSP": "theta4"}
"""The toe joint whose acceleration is zero (eqs. 4.76, 4.80, 4.84, 4.90)."""

# K_c of computed torque control (section 5.2.1-5.2.4, L3812-3880): whole F_{1,3}, M_{1,3} (T1 = 0) and the
# ground wrenches of the bodies off the ground.
CTC_ZERO: dict[str, list[tuple[str, int | None]]] = {
    "RFFSSP": [("F1_3", None), ("M1_3", None), ("F0_4", None), ("M0_4", None), ("F0_2", None), ("M0_2", None)],
    "LFFSSP": [("F2_4", None), ("M2_4", None), ("F0_3", None), ("M0_3", None), ("F0_1", None), ("M0_1", None)],
    "RFFDSP": [("F1_3", None), ("M1_3", None), ("F0_4", None), ("M0_4", None)],
    "LFFDSP": [("F2_4", None), ("M2_4", None), ("F0_3", None), ("M0_3", None)],
}


def default_w_act() -> np.ndarray:
    """Diagonal of W_act (eqs. 5.96/5.98): 1000 on the actuator components of F, 1 elsewhere.

    The printed Wact_LFFDSP = Wact_RFFDSP (L4883, L5184) is OCR-damaged (72/75 of 96 entries); errata A-3
    reconstructs it by the rule stated at L3858 ("considerably big" weights on the actuator torques), which is
    exactly 1000 on the 26 indices phi extracts.
    """
    w = np.ones(N_F)
    w[T_F_INDEX] = 1000.0
    return w
