"""Thesis section 4.1: kinematics of every body for one phase (positions, velocities, accelerations).

Units and frames: positions (m), velocities (m/s), accelerations (m/s^2) of the mass centres P_c,k and of the toe
points P_tpR / P_tpL, all differentiated in and resolved in frame 0 (world).  Orientations, angular velocities
and accelerations come from :mod:`frames` (sections 4.1.1, 4.1.3, 4.1.5).

Every translational relation of sections 4.1.2 (positions), 4.1.4 (velocities) and 4.1.6 (accelerations) has the
form, for a point t reached from a point s through fixed body vectors,

    P_t = P_s + sum_i  coef_i C^(0,k_i) u_(j_i)                                   (4.1.2)
    V_t = V_s + sum_i  coef_i w~_(k_i) C^(0,k_i) u_(j_i)                          (4.1.4)
    a_t = a_s + sum_i  coef_i [alpha~_(k_i) + w~_(k_i)^2] C^(0,k_i) u_(j_i)       (4.1.6)

with the SAME terms (coef, k, j) in the three sections (checked term by term against the printed relations,
L1954-2038, L2184-2263, L2405-2485).  So each relation is transcribed once, as its list of terms, in
:func:`point_relations`, citing the line of the position relation.  Deviations from the printed text:

- errata K-1: L2240 prints V_tpR = V_c,1 + ...; the position relation (L2014) and the mirror V_tpL = V_c,4 + ...
  show it must be V_c,3 + ... .  The term list of L2014 gives the corrected relation.
- The thesis prints no acceleration of the swing toe point (4.1.6.1 ends at a_c,2, 4.1.6.2 at a_c,1).  It is
  computed here from the same terms as P_tpL / P_tpR (decision: needed by the tests and by chapter 5's
  prediction terms; it is the time derivative of the printed velocity relation).
- Frame origins O_k are not printed in chapter 4; :func:`origins` derives them from P_c,k and c_k (L936-992)
  and from the coincident virtual origins (L996-1006).

Supplied data (L1725-1734): the stance toe body's C^(0,1)/C^(0,2), toe point P_tpR/P_tpL, and their
velocities and accelerations (zero in the simulation, kept as inputs because the formulas take them).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from humanoid_sim.thesis.frames import (
    Key,
    PhaseError,
    U,
    angular_accelerations,
    angular_velocities,
    check_phase,
    cross,
    orientations,
    stance_feet,
    trunk_key,
)
from humanoid_sim.thesis.params import ThesisParams

TOE_BODY = {"R": 1, "L": 2}
TOE_POINT = {"R": "tpR", "L": "tpL"}


@dataclass(frozen=True)
class FootState:
    """Data the thesis supplies for a toe body held on the ground (L1725-1734, 4.1.x.1-3).

    Attributes:
        C: C^(0,1) (right) or C^(0,2) (left), 3x3.
        P_tp: toe point P_tpR / P_tpL in frame 0 (m).
        w, V, alpha, a: angular velocity (rad/s), toe-point velocity (m/s), angular acceleration (rad/s^2) and
            toe-point acceleration (m/s^2) of the toe body, frame 0.  Zero in the simulation (welded foot).
    """

    C: np.ndarray
    P_tp: np.ndarray
    w: np.ndarray = field(default_factory=lambda: np.zeros(3))
    V: np.ndarray = field(default_factory=lambda: np.zeros(3))
    alpha: np.ndarray = field(default_factory=lambda: np.zeros(3))
    a: np.ndarray = field(default_factory=lambda: np.zeros(3))


Fixed = dict[str, FootState]
"""Stance data by foot: {"R": FootState, "L": FootState}; the phase decides which entries are used."""


@dataclass(frozen=True)
class PointRelation:
    """P_target = P_source + sum(coef * C^(0,k) u_j) and its derivatives (see module docstring)."""

    target: str
    source: str
    terms: tuple[tuple[float, Key, int], ...]
    line: str


def _upper_relations(d: ThesisParams) -> list[PointRelation]:
    """Upper-body relations common to all phases (4.1.2 L1954-1966; 4.1.4 L2184-2190; 4.1.6 L2409-2415)."""
    return [
        PointRelation("c20", "c17", ((d["c17"], 17, 3), (d["l20z"] - d["c20"], 20, 3)), "L1958"),
        PointRelation("c23", "c20", ((d["c20"], 20, 3), (-d["l20y"], 20, 2), (d["c23"] - d["l23z"], 23, 3),
                                     (-d["l23y"], 23, 2)), "L1962"),
        PointRelation("c24", "c20", ((d["c20"], 20, 3), (d["l20y"], 20, 2), (d["c24"] - d["l24z"], 24, 3),
                                     (d["l24y"], 24, 2)), "L1964"),
        PointRelation("c27", "c20", ((d["c20"], 20, 3), (d["l27"] - d["c27"], 27, 3)), "L1966"),
    ]


def _right_up(d: ThesisParams, top: Key) -> list[PointRelation]:
    """Right leg from the toe point up to P_c,17 (4.1.2.1 L1972-1980 and 4.1.2.3 L2020-2028)."""
    ctop = "c17" if top == 17 else f"c{top}"
    return [
        PointRelation("c1", "tpR", ((d["c1"] - d["l1"], 1, 1),), "L1972"),
        PointRelation("c3", "c1", ((-d["c1"], 1, 1), (d["c3x"] - d["l3x"], 3, 1), (d["l3z"] - d["c3z"], 3, 3)),
                      "L1974"),
        PointRelation("c9", "c3", ((-d["c3x"], 3, 1), (d["c3z"], 3, 3), (d["l9"] - d["c9"], 9, 3)), "L1976"),
        PointRelation("c11", "c9", ((d["c9"], 9, 3), (d["l11"] - d["c11"], 11, 3)), "L1978"),
        PointRelation(ctop, "c11", ((d["c11"], 11, 3), (d["l17z"] - d["c17"], top, 3), (d["l17y"], top, 2)),
                      "L1980" if top == 17 else "L2028"),
    ]


def _left_up(d: ThesisParams, top: Key) -> list[PointRelation]:
    """Left leg from the toe point up to P_c,17 (4.1.2.2 L1996-2004 and 4.1.2.3 L2030-2038)."""
    ctop = "c17" if top == 17 else f"c{top}"
    return [
        PointRelation("c2", "tpL", ((d["c2"] - d["l2"], 2, 1),), "L1996"),
        PointRelation("c4", "c2", ((-d["c2"], 2, 1), (d["c4x"] - d["l4x"], 4, 1), (d["l4z"] - d["c4z"], 4, 3)),
                      "L1998"),
        PointRelation("c10", "c4", ((-d["c4x"], 4, 1), (d["c4z"], 4, 3), (d["l10"] - d["c10"], 10, 3)), "L2000"),
        PointRelation("c12", "c10", ((d["c10"], 10, 3), (d["l12"] - d["c12"], 12, 3)), "L2002"),
        PointRelation(ctop, "c12", ((d["c12"], 12, 3), (d["l17z"] - d["c17"], top, 3), (-d["l17y"], top, 2)),
                      "L2004" if top == 17 else "L2038"),
    ]


def _left_down(d: ThesisParams) -> list[PointRelation]:
    """RFFSSP: from P_c,17 down the left leg to P_c,2 and P_tpL (4.1.2.1 L1982-1990)."""
    return [
        PointRelation("c12", "c17", ((d["c17"] - d["l17z"], 17, 3), (d["l17y"], 17, 2), (-d["c12"], 12, 3)),
                      "L1982"),
        PointRelation("c10", "c12", ((d["c12"] - d["l12"], 12, 3), (-d["c10"], 10, 3)), "L1984"),
        PointRelation("c4", "c10", ((d["c10"] - d["l10"], 10, 3), (d["c4x"], 4, 1), (-d["c4z"], 4, 3)), "L1986"),
        PointRelation("c2", "c4", ((d["l4x"] - d["c4x"], 4, 1), (d["c4z"] - d["l4z"], 4, 3), (d["c2"], 2, 1)),
                      "L1988"),
        PointRelation("tpL", "c4", ((d["l4x"] - d["c4x"], 4, 1), (d["c4z"] - d["l4z"], 4, 3), (d["l2"], 2, 1)),
                      "L1990"),
    ]


def _right_down(d: ThesisParams) -> list[PointRelation]:
    """LFFSSP: from P_c,17 down the right leg to P_c,1 and P_tpR (4.1.2.2 L2006-2014; errata K-1)."""
    return [
        PointRelation("c11", "c17", ((d["c17"] - d["l17z"], 17, 3), (-d["l17y"], 17, 2), (-d["c11"], 11, 3)),
                      "L2006"),
        PointRelation("c9", "c11", ((d["c11"] - d["l11"], 11, 3), (-d["c9"], 9, 3)), "L2008"),
        PointRelation("c3", "c9", ((d["c9"] - d["l9"], 9, 3), (d["c3x"], 3, 1), (-d["c3z"], 3, 3)), "L2010"),
        PointRelation("c1", "c3", ((d["l3x"] - d["c3x"], 3, 1), (d["c3z"] - d["l3z"], 3, 3), (d["c1"], 1, 1)),
                      "L2012"),
        # errata K-1: the velocity relation (L2240) prints V_c,1 as the source; the position relation is right.
        PointRelation("tpR", "c3", ((d["l3x"] - d["c3x"], 3, 1), (d["c3z"] - d["l3z"], 3, 3), (d["l1"], 1, 1)),
                      "L2014"),
    ]


def point_relations(phase: str, d: ThesisParams) -> list[PointRelation]:
    """The translational relations of the phase, in the thesis's evaluation order."""
    check_phase(phase)
    if phase == "RFFSSP":     # 4.1.2.1
        lower = _right_up(d, 17) + _left_down(d)
    elif phase == "LFFSSP":   # 4.1.2.2
        lower = _left_up(d, 17) + _right_down(d)
    else:                     # 4.1.2.3, both chains up to 17_fR and 17_fL
        lower = _right_up(d, "17fR") + _left_up(d, "17fL")
    return lower + _upper_relations(d)


@dataclass
class Kinematics:
    """Kinematic state of every frame and point for one phase (section 4.1).

    ``C``, ``w``, ``alpha`` are keyed by body number (1..27; plus "17fR"/"17fL" in the DSPs); ``P``, ``V``,
    ``a`` by point name: "c<k>" (mass centre of real body k, plus "c17fR"/"c17fL" in the DSPs), "tpR", "tpL".
    Velocities/accelerations are None when not computed.  All vectors in frame 0.
    """

    phase: str
    theta: np.ndarray
    C: dict[Key, np.ndarray]
    P: dict[str, np.ndarray]
    w: dict[Key, np.ndarray] | None = None
    V: dict[str, np.ndarray] | None = None
    alpha: dict[Key, np.ndarray] | None = None
    a: dict[str, np.ndarray] | None = None


def _supplied(phase: str, fixed: Fixed) -> list[tuple[str, FootState]]:
    out = []
    for foot in stance_feet(phase):
        if foot not in fixed or fixed[foot] is None:
            raise PhaseError(f"phase {phase} needs the supplied toe-body data of foot {foot!r} (L1725-1734)")
        out.append((foot, fixed[foot]))
    return out


def _alias_trunk(phase: str, pts: dict[str, np.ndarray]) -> None:
    tk = trunk_key(phase)
    if tk != 17:
        pts["c17"] = pts[f"c{tk}"]


def positions(phase: str, theta: np.ndarray, fixed: Fixed, d: ThesisParams) -> Kinematics:
    """C^(0,k) of every frame (4.1.1) and P of every mass centre and toe point (4.1.2)."""
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (26,):
        raise ValueError(f"theta must have shape (26,) in eq. 4.1 order, got {theta.shape}")
    sup = _supplied(phase, fixed)
    C = orientations(phase, theta, {TOE_BODY[f]: np.asarray(s.C, float) for f, s in sup})
    P: dict[str, np.ndarray] = {TOE_POINT[f]: np.asarray(s.P_tp, float) for f, s in sup}
    for rel in point_relations(phase, d):
        if rel.source == "c17":
            _alias_trunk(phase, P)
        P[rel.target] = P[rel.source] + sum(c * (C[k] @ U[:, j - 1]) for c, k, j in rel.terms)
    _alias_trunk(phase, P)
    return Kinematics(phase=phase, theta=theta, C=C, P=P)


def velocities(kin: Kinematics, theta_dot: np.ndarray, fixed: Fixed,
               d: ThesisParams) -> tuple[dict[Key, np.ndarray], dict[str, np.ndarray]]:
    """w of every frame (4.1.3) and V of every point (4.1.4) for the given theta_dot (rad/s); returns (w, V)."""
    theta_dot = np.asarray(theta_dot, dtype=float)
    sup = _supplied(kin.phase, fixed)
    w = angular_velocities(kin.phase, kin.C, theta_dot, {TOE_BODY[f]: np.asarray(s.w, float) for f, s in sup})
    V: dict[str, np.ndarray] = {TOE_POINT[f]: np.asarray(s.V, float) for f, s in sup}
    C = kin.C
    for rel in point_relations(kin.phase, d):
        if rel.source == "c17":
            _alias_trunk(kin.phase, V)
        V[rel.target] = V[rel.source] + sum(c * cross(w[k], C[k] @ U[:, j - 1]) for c, k, j in rel.terms)
    _alias_trunk(kin.phase, V)
    return w, V


def add_velocities(kin: Kinematics, theta_dot: np.ndarray, fixed: Fixed, d: ThesisParams) -> Kinematics:
    """Fill ``kin.w`` and ``kin.V`` (see :func:`velocities`) in place and return ``kin``."""
    kin.w, kin.V = velocities(kin, theta_dot, fixed, d)
    return kin


def at_rest(fixed: Fixed) -> Fixed:
    """The same stance data with zero velocities and accelerations (the thesis's simulation values)."""
    return {f: FootState(s.C, s.P_tp) for f, s in fixed.items() if s is not None}


def accelerations(kin: Kinematics, theta_dot: np.ndarray, theta_ddot: np.ndarray, fixed: Fixed,
                  d: ThesisParams) -> tuple[dict[Key, np.ndarray], dict[str, np.ndarray]]:
    """alpha of every frame (4.1.5) and a of every point (4.1.6) for the given theta_ddot (rad/s^2).

    Needs ``kin`` with velocities.  Returns (alpha, a) without storing them, so that the dynamics can call it
    once per unit acceleration vector (section 4.4, L2790-2800).
    """
    if kin.w is None:
        raise ValueError("accelerations need the velocities: call add_velocities first")
    sup = _supplied(kin.phase, fixed)
    alpha = angular_accelerations(kin.phase, kin.C, kin.w, np.asarray(theta_dot, float),
                                  np.asarray(theta_ddot, float),
                                  {TOE_BODY[f]: np.asarray(s.alpha, float) for f, s in sup})
    a: dict[str, np.ndarray] = {TOE_POINT[f]: np.asarray(s.a, float) for f, s in sup}
    C, w = kin.C, kin.w
    for rel in point_relations(kin.phase, d):
        if rel.source == "c17":
            _alias_trunk(kin.phase, a)
        acc = a[rel.source].copy()
        for c, k, j in rel.terms:
            n = C[k] @ U[:, j - 1]
            acc = acc + c * (cross(alpha[k], n) + cross(w[k], cross(w[k], n)))
        a[rel.target] = acc
    _alias_trunk(kin.phase, a)
    return alpha, a


def kinematics(phase: str, theta: np.ndarray, theta_dot: np.ndarray | None, theta_ddot: np.ndarray | None,
               fixed: Fixed, d: ThesisParams) -> Kinematics:
    """Everything of section 4.1 at once (velocities/accelerations only when their inputs are given)."""
    kin = positions(phase, theta, fixed, d)
    if theta_dot is not None:
        add_velocities(kin, theta_dot, fixed, d)
        if theta_ddot is not None:
            kin.alpha, kin.a = accelerations(kin, theta_dot, theta_ddot, fixed, d)
    return kin


def com_vectors(d: ThesisParams) -> dict[int, np.ndarray]:
    """c_k in frame k (m), L936-990: vector from O_k to the mass centre of real body k."""
    return {
        1: d["c1"] * U[:, 0], 2: d["c2"] * U[:, 0],
        3: d["c3x"] * U[:, 0] - d["c3z"] * U[:, 2], 4: d["c4x"] * U[:, 0] - d["c4z"] * U[:, 2],
        9: -d["c9"] * U[:, 2], 10: -d["c10"] * U[:, 2], 11: -d["c11"] * U[:, 2], 12: -d["c12"] * U[:, 2],
        17: -d["c17"] * U[:, 2], 20: -d["c20"] * U[:, 2], 23: d["c23"] * U[:, 2], 24: d["c24"] * U[:, 2],
        27: -d["c27"] * U[:, 2],
    }


def origins(kin: Kinematics, d: ThesisParams) -> dict[int, np.ndarray]:
    """Positions of every frame origin O_k (m, frame 0): O_k = P_c,k - C^(0,k) c_k for real bodies; the
    virtual origins coincide with O_3, O_4, O_11, O_12, O_17, O_20 (L996-1006) except O_21/O_22 = O_20 -/+ l20y
    u2^(20) (l_20,21 and l_20,22, L978-980)."""
    cv = com_vectors(d)
    O = {k: kin.P[f"c{k}"] - kin.C[k] @ cv[k] for k in cv}
    for k, same in ((5, 3), (7, 3), (6, 4), (8, 4), (13, 11), (15, 11), (14, 12), (16, 12), (18, 17), (19, 17),
                    (25, 20), (26, 20)):
        O[k] = O[same]
    O[21] = O[20] - d["l20y"] * kin.C[20] @ U[:, 1]
    O[22] = O[20] + d["l20y"] * kin.C[20] @ U[:, 1]
    return O
