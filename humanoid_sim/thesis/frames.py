"""Thesis section 4.1.1 / 4.1.3 / 4.1.5: transformation matrices, angular velocities, angular accelerations.

Frames and units: C^(0,k) (``C[k]``) maps components in body frame k to frame 0 (world: x lateral, y forward,
z up).  w_k and alpha_k are the angular velocity (rad/s) and acceleration (rad/s^2) of frame k relative to
frame 0, resolved in frame 0.  Joint variables theta (rad) are in the order of eq. 4.1 (L1736).

Every relation of these sections has one of two shapes, and the code below is exactly those two shapes:

forward step across joint theta between bodies a (lower index side) and b, C^(a,b) = exp(u~_j theta)
(section 4.1.1, L1790-1840):
    C^(0,b) = C^(0,a) C^(a,b)
    w_b     = w_a + theta_dot C^(0,a) u_j                                   (4.1.3, e.g. w_3, L2074)
    alpha_b = alpha_a + theta_ddot C^(0,a) u_j + theta_dot w~_a C^(0,a) u_j  (4.1.5, e.g. alpha_3, L2299)
backward step (the chain is walked from b down to a, e.g. 17 -> 16 -> ... -> 2 in RFFSSP, L1860-1876):
    C^(0,a) = C^(0,b) C^(a,b)^T
    w_a     = w_b - theta_dot C^(0,b) u_j                                   (e.g. w_16, L2090)
    alpha_a = alpha_b - theta_ddot C^(0,b) u_j - theta_dot w~_b C^(0,b) u_j  (e.g. alpha_16, L2315)

The recursion order per phase (which body is supplied, which chain runs forward or backward) is the thesis's:
RFFSSP starts at body 1 (4.1.1.1, L1842), LFFSSP at body 2 (4.1.1.2, L1878), the double-support phases run two
forward chains from bodies 1 and 2 up to 17_fR and 17_fL (4.1.1.3, L1914), and the upper body hangs from
17_fR in RFFDSP and from 17_fL in LFFDSP (L1838).  In the double-support phases ``C[17]``/``w[17]``/
``alpha[17]`` are therefore aliases of the 17_fR or 17_fL entries.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humanoid_sim.errors import InputError

PHASES: tuple[str, ...] = ("LFFSSP", "RFFDSP", "RFFSSP", "LFFDSP")
"""The four basic phases in walking order (design.md section 4)."""

THETA_NAMES: tuple[str, ...] = (
    "theta3", "theta4", "theta5", "theta6", "theta7", "theta8", "theta9", "theta10", "theta11", "theta12",
    "theta13", "theta14", "theta15", "theta16", "theta17r", "theta17l", "theta18", "theta19", "theta20",
    "theta21", "theta22", "theta23", "theta24", "theta25", "theta26", "theta27",
)
"""The joint-space vector q of eq. 4.1 (L1736)."""

IDX = {name: i for i, name in enumerate(THETA_NAMES)}

# theta -> (a, b, j): C^(a,b) = exp(u~_j theta), Table 2.6 (L858-883) and section 4.1.1 (L1790-1840).
JOINTS: dict[str, tuple[int, int, int]] = {
    "theta3": (1, 3, 2), "theta4": (2, 4, 2), "theta5": (3, 5, 2), "theta6": (4, 6, 2),
    "theta7": (5, 7, 3), "theta8": (6, 8, 3), "theta9": (7, 9, 1), "theta10": (8, 10, 1),
    "theta11": (9, 11, 2), "theta12": (10, 12, 2), "theta13": (11, 13, 2), "theta14": (12, 14, 2),
    "theta15": (13, 15, 1), "theta16": (14, 16, 1), "theta17r": (15, 17, 3), "theta17l": (16, 17, 3),
    "theta18": (17, 18, 2), "theta19": (18, 19, 3), "theta20": (19, 20, 1), "theta21": (20, 21, 1),
    "theta22": (20, 22, 1), "theta23": (21, 23, 2), "theta24": (22, 24, 2), "theta25": (20, 25, 3),
    "theta26": (25, 26, 2), "theta27": (26, 27, 1),
}

Q_R_H = ("theta3", "theta5", "theta7", "theta9", "theta11", "theta13", "theta15", "theta17r")   # eq. 4.2
Q_L_H = ("theta4", "theta6", "theta8", "theta10", "theta12", "theta14", "theta16", "theta17l")  # eq. 4.3
Q_LOWER = THETA_NAMES[:16]                                                                    # eq. 4.4
Q_UPPER = THETA_NAMES[16:]                                                                    # eq. 4.5
Q_R_HR = Q_R_H[1:]   # eq. 4.6: theta3 dropped (theta3_dot = 0 in RFFSSP)
Q_L_HR = Q_L_H[1:]   # eq. 4.16: theta4 dropped (theta4_dot = 0 in LFFSSP)

Key = int | str
"""A frame key: a body number, or "17fR" / "17fL" for the two estimates of frame 17 in the DSPs."""


class PhaseError(InputError):
    """Unknown phase name or missing stance-foot data for the phase."""


def check_phase(phase: str) -> str:
    if phase not in PHASES:
        raise PhaseError(f"unknown phase {phase!r}; expected one of {PHASES}")
    return phase


def is_ssp(phase: str) -> bool:
    return check_phase(phase).endswith("SSP")


def stance_feet(phase: str) -> tuple[str, ...]:
    """Toe bodies whose kinematics are supplied: ('R',) body 1, ('L',) body 2, or both in the DSPs (L1725)."""
    check_phase(phase)
    if phase == "RFFSSP":
        return ("R",)
    if phase == "LFFSSP":
        return ("L",)
    return ("R", "L")


U = np.eye(3)
"""U[:, j-1] = u_j, the basis vectors in matrix form."""


def skew(k: np.ndarray) -> np.ndarray:
    """The tilde operator of section 4.1.1 (L1776): skew(k) @ x = k x x."""
    return np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for 3-vectors (= skew(a) @ b); explicit because np.cross is slow on single vectors."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def rot(j: int, theta: float) -> np.ndarray:
    """exp(u~_j theta): rotation by theta (rad) about basis vector u_j, j in {1, 2, 3} (section 4.1.1)."""
    c, s = np.cos(theta), np.sin(theta)
    if j == 1:
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    if j == 2:
        return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    if j == 3:
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    raise ValueError(f"axis index must be 1, 2 or 3, got {j!r}")


# Joints between adjacent REAL bodies (lower body, higher body) -> the thesis variables, from the lower to
# the higher body (Table 2.6 L858-883).  These are the 12 actuated joints of eq. 4.69 (L2753).
JOINT_GROUPS: dict[tuple[int, int], tuple[str, ...]] = {
    (1, 3): ("theta3",), (3, 9): ("theta5", "theta7", "theta9"), (9, 11): ("theta11",),
    (11, 17): ("theta13", "theta15", "theta17r"),
    (2, 4): ("theta4",), (4, 10): ("theta6", "theta8", "theta10"), (10, 12): ("theta12",),
    (12, 17): ("theta14", "theta16", "theta17l"),
    (17, 20): ("theta18", "theta19", "theta20"), (20, 23): ("theta21", "theta23"),
    (20, 24): ("theta22", "theta24"), (20, 27): ("theta25", "theta26", "theta27"),
}


def relative_rotation(theta: np.ndarray, a: int, b: int) -> np.ndarray:
    """C^(a,b) between adjacent real bodies, product of the adjacent-frame matrices of section 4.1.1
    (L1790-1840) across the virtual bodies, e.g. C^(3,9) = C^(3,5) C^(5,7) C^(7,9)."""
    try:
        names = JOINT_GROUPS[(a, b)]
    except KeyError:
        raise ValueError(f"bodies {a} and {b} are not adjacent real bodies; pairs: {sorted(JOINT_GROUPS)}") from None
    C = np.eye(3)
    for name in names:
        C = C @ rot(JOINTS[name][2], theta[IDX[name]])
    return C


@dataclass(frozen=True)
class Step:
    """One recursion step: from frame ``src`` to frame ``dst`` across joint ``theta``; sign +1 forward, -1
    backward (see the module docstring)."""

    theta: str
    src: Key
    dst: Key
    axis: int
    sign: int


def _forward(names: tuple[str, ...], top: Key = 17) -> list[Step]:
    steps = []
    for n in names:
        a, b, j = JOINTS[n]
        steps.append(Step(n, a, top if b == 17 else b, j, +1))
    return steps


def _backward(names: tuple[str, ...]) -> list[Step]:
    steps = []
    for n in reversed(names):
        a, b, j = JOINTS[n]
        steps.append(Step(n, b, a, j, -1))
    return steps


# Upper body, common to all phases (section 4.1.1 L1824-1840, 4.1.3 L2048-2066, 4.1.5 L2273-2291).
_UPPER = _forward(("theta18", "theta19", "theta20", "theta21", "theta23", "theta22", "theta24", "theta25",
                   "theta26", "theta27"))


def recursion_steps(phase: str) -> list[Step]:
    """The thesis's recursion order for the phase (4.1.1.1-4.1.1.3, 4.1.3.1-4.1.3.2, 4.1.5.1-4.1.5.2)."""
    check_phase(phase)
    if phase == "RFFSSP":   # L1842-1876: body 1 up to 17, then down the left leg to body 2
        return _forward(Q_R_H) + _backward(Q_L_H) + _UPPER
    if phase == "LFFSSP":   # L1878-1912: body 2 up to 17, then down the right leg to body 1
        return _forward(Q_L_H) + _backward(Q_R_H) + _UPPER
    # L1914-1948: both legs forward, to 17_fR and 17_fL
    return _forward(Q_R_H, "17fR") + _forward(Q_L_H, "17fL") + _UPPER


def trunk_key(phase: str) -> Key:
    """Which estimate of frame 17 the upper body uses: 17 (SSP), 17_fR (RFFDSP) or 17_fL (LFFDSP) (L1838)."""
    check_phase(phase)
    return {"RFFDSP": "17fR", "LFFDSP": "17fL"}.get(phase, 17)


def orientations(phase: str, theta: np.ndarray, C_supplied: dict[Key, np.ndarray]) -> dict[Key, np.ndarray]:
    """C^(0,k) of every frame (section 4.1.1), from the supplied C^(0,1) and/or C^(0,2)."""
    C: dict[Key, np.ndarray] = dict(C_supplied)
    tk = trunk_key(phase)
    for s in recursion_steps(phase):
        if s.src == 17 and tk != 17:
            C[17] = C[tk]
        E = rot(s.axis, theta[IDX[s.theta]])
        C[s.dst] = C[s.src] @ (E if s.sign > 0 else E.T)
    return C


def angular_velocities(phase: str, C: dict[Key, np.ndarray], theta_dot: np.ndarray,
                       w_supplied: dict[Key, np.ndarray]) -> dict[Key, np.ndarray]:
    """w_k of every frame (section 4.1.3), from the supplied w_1 and/or w_2 (zero in the simulation)."""
    w: dict[Key, np.ndarray] = dict(w_supplied)
    tk = trunk_key(phase)
    for s in recursion_steps(phase):
        if s.src == 17 and tk != 17:
            w[17] = w[tk]
        n = C[s.src] @ U[:, s.axis - 1]
        w[s.dst] = w[s.src] + s.sign * theta_dot[IDX[s.theta]] * n
    return w


def angular_accelerations(phase: str, C: dict[Key, np.ndarray], w: dict[Key, np.ndarray], theta_dot: np.ndarray,
                          theta_ddot: np.ndarray, alpha_supplied: dict[Key, np.ndarray]) -> dict[Key, np.ndarray]:
    """alpha_k of every frame (section 4.1.5), from the supplied alpha_1 and/or alpha_2 (zero in the simulation)."""
    al: dict[Key, np.ndarray] = dict(alpha_supplied)
    tk = trunk_key(phase)
    for s in recursion_steps(phase):
        if s.src == 17 and tk != 17:
            al[17] = al[tk]
        n = C[s.src] @ U[:, s.axis - 1]
        i = IDX[s.theta]
        al[s.dst] = al[s.src] + s.sign * (theta_ddot[i] * n + theta_dot[i] * cross(w[s.src], n))
    return al
