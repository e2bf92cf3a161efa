"""The balance controller's QP in NumPy (:func:`qp_numpy`, the reference of the compiled
:func:`humanoid_sim.controllers.balance.compiled.balance_qp`), its constant inputs (:class:`BalanceTables`) and the
ground wrenches of a solution (:class:`BoxWrenches`).  SI units; wrenches [f; n] (N, N m).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np


class BalanceTables(NamedTuple):
    """The balance controller's constant QP inputs (per single / double support): ``gains`` (kp, kd, weight of the
    hip, trunk, swing tasks, then kp, kd of the posture), ``w_joint`` (26,) posture weights, ``heel_lift_rad``
    (rad), the sole boxes' wrench rows (11, 6) ``heel``, ``toe`` (the flat foot's heel and toe boxes), ``main``
    (the heel box of a foot held by its main body alone, without its toe lock: a trailing foot kept flat), ``trail``
    (a trailing foot's toe box) (:func:`.boxes.box_rows`), the regularisation weights ``w_acc``, ``w_force``,
    ``w_torque``."""

    gains: np.ndarray
    w_joint: np.ndarray
    heel_lift_rad: float
    heel: np.ndarray
    toe: np.ndarray
    main: np.ndarray
    trail: np.ndarray
    w_acc: float
    w_force: float
    w_torque: float


def rot_y(ang: float) -> np.ndarray:
    """Rotation by ``ang`` (rad) about the local y axis (a foot's pitch: heel up for ang > 0 about the toe joint)."""
    c, sn = math.cos(ang), math.sin(ang)
    return np.array([[c, 0.0, sn], [0.0, 1.0, 0.0], [-sn, 0.0, c]])


def pd(omega: float) -> tuple[float, float]:
    """(stiffness, damping) = (omega^2, 2 omega) of a critically damped PD of natural frequency omega (rad/s)."""
    return omega * omega, 2.0 * omega


class BoxWrenches(Mapping):
    """A command's ground wrenches per flat foot's box, computed when read (``Command.extra["box_wrenches"]``):
    {main-body weld frame: (heel-box wrench W_m in the main-body frame, toe-box wrench W_t in the toe-body frame)},
    [f; n] (N, N m) at each frame's origin, W_m = lam_weld - X W_t.  ``x``: the QP's solution [a (nv); lam (m); W_t
    (6 per flat foot)]; ``X``: per flat foot, the toe-to-main wrench map; ``kinds``: per weld, 0 for a flat foot."""

    def __init__(self, x: np.ndarray, X: np.ndarray, kinds: np.ndarray, welds: tuple[str, ...], nv: int,
                 m: int) -> None:
        self._args = (x, X, kinds, welds, nv, m)
        self._map: dict[str, tuple[np.ndarray, np.ndarray]] | None = None

    def _items(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        if self._map is None:
            x, X, kinds, welds, nv, m = self._args
            out, j = {}, 0
            for i, kind in enumerate(kinds):
                if kind == 0:
                    Wt = x[nv + m + 6 * j:nv + m + 6 * j + 6].copy()
                    out[welds[i]] = (x[nv + 6 * i:nv + 6 * i + 6] - X[j] @ Wt, Wt)
                    j += 1
            self._map = out
        return self._map

    def __getitem__(self, frame: str) -> tuple[np.ndarray, np.ndarray]:
        return self._items()[frame]

    def __iter__(self):
        return iter(self._items())

    def __len__(self) -> int:
        return len(self._items())


def qp_numpy(A: np.ndarray, w: np.ndarray, b: np.ndarray, M_upper: np.ndarray, h: np.ndarray, J: np.ndarray,
             rhs_shift: np.ndarray, nw: int, box_kind: np.ndarray, split: tuple, tables: BalanceTables,
             unload: np.ndarray) -> tuple[np.ndarray, ...]:
    """The controller's QP from its task rows and the phase's constraint rows, in NumPy: the reference of the
    compiled :func:`humanoid_sim.controllers.balance.compiled.balance_qp` (arguments and results there; x = [a (nv);
    lam (m); W_t (6 per flat foot)]).  Cost: the weighted task rows, w_acc |a|^2 + w_force |(lam, W_t)|^2, the
    torques w_torque
    |tau[6:]|^2 (tau[6:] = Tx x + h[6:]: in double support the feet can squeeze or twist each other through the
    ground without changing the motion; the smallest torques pick the split) and ``unload`` on each weld's normal
    force.  Equalities: the base rows of M a + h - J^T lam = 0 (no actuator there); no lock multiplier but the toe
    box's share lam_lock = j_toe . W_t (the toe motor holds the rest); J a = -gamma.  Inequalities C x >= 0, 11 rows
    a box: a flat foot's heel box carries W_m = lam_weld - X W_t (main-body frame), its toe box W_t (toe-body frame);
    a foot held by its toe alone, lam_weld on its toe box.  Returns (G, g, C, lo, ne, cop, M, Tx) as balance_qp: the
    equality rows then the inequality rows in one C, as DAQP takes them."""
    split_weld, split_lock, X, jt = split
    heel, toe, main, trail = tables.heel, tables.toe, tables.main, tables.trail
    w_acc, w_force, w_torque = tables.w_acc, tables.w_force, tables.w_torque
    nv, m, ns = M_upper.shape[0], J.shape[0], len(split_weld)
    n = nv + m + 6 * ns
    M = M_upper.copy()                       # crba fills the upper triangle: mirror it
    lower = np.tril_indices(nv, -1)
    M[lower] = M.T[lower]
    G = np.zeros((n, n))
    WA = A * w[:, None]
    G[:nv, :nv] = A.T @ WA
    g = np.zeros(n)
    g[:nv] = WA.T @ b
    Tx = np.zeros((nv - 6, n))
    Tx[:, :nv] = M[6:]
    Tx[:, nv:nv + m] = -J[:, 6:].T
    G += w_torque * (Tx.T @ Tx)
    g -= w_torque * (Tx.T @ h[6:])
    G[np.diag_indices(n)] += np.concatenate([np.full(nv, w_acc), np.full(n - nv, w_force)])
    for i, extra in enumerate(unload):
        G[nv + 6 * i + 2, nv + 6 * i + 2] += extra
    n_lock = m - nw
    Ceq = np.zeros((6 + n_lock + m, n))
    beq = np.zeros(6 + n_lock + m)
    Ceq[:6, :nv] = M[:6]
    Ceq[:6, nv:nv + m] = -J[:, :6].T
    beq[:6] = -h[:6]
    Ceq[6 + np.arange(n_lock), nv + nw + np.arange(n_lock)] = 1.0
    for j in range(ns):
        Ceq[6 + split_lock[j] - nw, nv + m + 6 * j:nv + m + 6 * j + 6] = -jt[j]
    Ceq[6 + n_lock:, :nv] = J
    beq[6 + n_lock:] = -rhs_shift
    blocks, cop = [], []
    for i, kind in enumerate(box_kind):
        cw = slice(nv + 6 * i, nv + 6 * i + 6)
        if kind == 0:
            j = int(np.flatnonzero(split_weld == i)[0])
            ct = slice(nv + m + 6 * j, nv + m + 6 * j + 6)
            bh = np.zeros((len(heel), n))
            bh[:, cw] = heel
            bh[:, ct] = -heel @ X[j]
            bt = np.zeros((len(toe), n))
            bt[:, ct] = toe
            blocks += [bh, bt]
            cop += ([False] * 7 + [True] * 4) * 2
        else:
            blk = np.zeros((len(heel), n))
            blk[:, cw] = trail if kind == 1 else main
            blocks.append(blk)
            cop += [False] * 7 + [True] * 4
    return G, g, np.vstack([Ceq] + blocks), np.concatenate([beq, np.zeros(len(cop))]), len(beq), \
        np.array(cop, dtype=bool), M, Tx
