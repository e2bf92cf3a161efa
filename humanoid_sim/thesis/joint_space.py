"""Map between the thesis's Cartesian joint moments (eq. 4.68/4.69) and joint-space generalized forces.

Not a thesis formula: the thesis never forms generalized forces.  This is the bridge the tests (and the fast
path) need; it follows from virtual power.  At the joint between real bodies a and b (a lower-numbered side, see
``frames.JOINT_GROUPS``) body a exerts the force F_{a,b} at the joint point and the moment M_{a,b}; the force does
no work (the point is common to both bodies) and the moment does the power M_{a,b} . (w_b - w_a).  With
w_b - w_a = sum_i theta_dot_i n_i (n_i = world axis of joint i, section 4.1.3), the force conjugate to theta_i is

    Q_i = n_i . M_{a,b}  (N m),   M_{a,b} in frame 0 = C^(0,b) M_{a,b}^{(b)}.

Pinocchio's generalized force of the same joint is sign_i Q_i (q_pin = sign theta).

Inverse map T <- Q: at the toes and knees (one axis u_2, common to frames a and b) Q = M_y^{(b)} = T exactly.
At ankles, hips, waist and neck (three axes) M^{(b)} = S^-T Q with S = [C^(0,b)T n_i], so T is all of M^{(b)}.
At the universal shoulders (errata P-8) T20, T21 = M_{20,23x,y}^{(23)} but the joint axes are u_1^(20) and
u_2^(21): the third component M_{20,23z}^{(23)} is not workless when theta23 != 0, so Q alone does not fix T20.
Decision: :func:`T_from_Q` takes the shoulder z components as an input (they come from the arm's own dynamics,
e.g. the thesis solution F, or pinocchio's joint wrench), and :func:`Q_from_F` uses the full M_{20,23}.
"""

from __future__ import annotations

import numpy as np

from humanoid_sim.thesis.forces import T_COMPONENTS, block, fslice
from humanoid_sim.thesis.frames import IDX, JOINT_GROUPS, JOINTS, U
from humanoid_sim.thesis.kinematics import Kinematics

SHOULDERS = ((20, 23), (20, 24))


def joint_axis(kin: Kinematics, name: str) -> np.ndarray:
    """World axis n_i of joint ``name``: C^(0,a) u_j for C^(a,b) = exp(u~_j theta) (section 4.1.3)."""
    a, _b, j = JOINTS[name]
    return kin.C[a] @ U[:, j - 1]


def axes_in_frame(kin: Kinematics, group: tuple[int, int]) -> np.ndarray:
    """S = [C^(0,b)T n_i] (3 x n): the group's joint axes resolved in frame b."""
    Cb = kin.C[group[1]]
    return np.column_stack([Cb.T @ joint_axis(kin, n) for n in JOINT_GROUPS[group]])


def Q_from_moments(kin: Kinematics, moments: dict[tuple[int, int], np.ndarray]) -> np.ndarray:
    """Generalized forces Q (26,) conjugate to theta (eq. 4.1 order) from the joint moments M_{a,b}^{(b)}."""
    Q = np.zeros(26)
    for group, names in JOINT_GROUPS.items():
        m_world = kin.C[group[1]] @ moments[group]
        for n in names:
            Q[IDX[n]] = joint_axis(kin, n) @ m_world
    return Q


def moments_from_F(F: np.ndarray) -> dict[tuple[int, int], np.ndarray]:
    """The 12 joint moments M_{a,b}^{(b)} (full 3-vectors, reactions included) from F (eq. 4.68)."""
    return {g: block(F, f"M{g[0]}_{g[1]}").copy() for g in JOINT_GROUPS}


def Q_from_F(kin: Kinematics, F: np.ndarray) -> np.ndarray:
    """Generalized forces from the thesis solution F, with the full shoulder moments (errata P-8)."""
    return Q_from_moments(kin, moments_from_F(F))


def T_from_Q(kin: Kinematics, Q: np.ndarray, shoulder_z: tuple[float, float]) -> np.ndarray:
    """T-bar (26,) of eq. 4.69 from generalized forces Q, given M_{20,23z}^{(23)} and M_{20,24z}^{(24)} (N m)."""
    moments: dict[tuple[int, int], np.ndarray] = {}
    for group, names in JOINT_GROUPS.items():
        S = axes_in_frame(kin, group)
        q = np.array([Q[IDX[n]] for n in names])
        if len(names) == 1:               # toe / knee: Q = M_y^{(b)} (axis u_2 of frame b)
            if abs(S[1, 0] - 1.0) > 1e-12:
                raise RuntimeError(f"joint {names[0]} axis is not u_2 of frame {group[1]}: {S[:, 0]}")
            moments[group] = np.array([np.nan, q[0], np.nan])
        elif len(names) == 3:             # ball-like joints: M = S^-T Q
            moments[group] = np.linalg.solve(S.T, q)
        else:                             # universal shoulder: z component supplied (errata P-8)
            mz = shoulder_z[SHOULDERS.index(group)]
            xy = np.linalg.solve(S[:2, :].T, q - S[2, :] * mz)
            moments[group] = np.array([xy[0], xy[1], mz])
    T = np.zeros(26)
    for r, (name, comp) in enumerate(T_COMPONENTS):
        a, b = (int(x) for x in name[1:].split("_"))
        T[r] = moments[(a, b)][comp]
    return T


def relative_angular_velocity_power(kin: Kinematics, F: np.ndarray) -> float:
    """Sum over the 12 joints of M_{a,b} . (w_b - w_a) (W): the power of the joint moments (virtual-power check)."""
    if kin.w is None:
        raise ValueError("needs velocities")
    total = 0.0
    for (a, b) in JOINT_GROUPS:
        m_world = kin.C[b] @ np.asarray(F)[fslice(f"M{a}_{b}")]
        total += float(m_world @ (kin.w[b] - kin.w[a]))
    return total
