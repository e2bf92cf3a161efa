"""The QP's sole boxes: the linear rows that keep a foot's ground wrench inside its sole and friction cone, and the
QP's constant inputs (:class:`.qp.BalanceTables`) built from them per double / single support and per partial
foothold (:mod:`.foothold`).

A flat foot carries two wrenches, on its heel box (main body, heel to toe joint) and on its toe box (toe body); a
trailing foot held by its toe carries the toe box's alone (:mod:`.controller`'s module docstring).  Each box's rows
say: f_z >= 0, the friction pyramid inscribed in the cone of mu, a torsion bound, and the CoP inside the box shrunk
by the phase's margin; a partial foothold shrinks the flat foot's boxes further, and a toe box with nothing under
it gets an empty interval, which admits only the zero wrench.  Frames: a box's rows act on a wrench at its body's
frame origin with the sole plane at z = zs (m) in that frame; SI units.
"""

from __future__ import annotations

import math

import numpy as np

from humanoid_sim.controllers.balance.foothold import Foothold
from humanoid_sim.controllers.balance.qp import BalanceTables
from humanoid_sim.robot.sole import SoleGeometry


def box_rows(lo: float, hi: float, ylo: float, yhi: float, zs: float, mu: float, torsion: float) -> np.ndarray:
    """(11, 6) rows L with L w >= 0 for a wrench w = [fx fy fz nx ny nz] (at a frame origin, the sole plane at
    z = zs): fz >= 0, the friction pyramid |fx|, |fy| <= mu fz, |nz| <= torsion fz, the CoP in [lo, hi] x [ylo, yhi]
    (an empty interval, lo > hi or ylo > yhi, admits only the zero wrench).  Moments about the sole-plane point
    (0, 0, zs): n'x = nx + zs fy, n'y = ny - zs fx; CoP x = -n'y / fz, y = n'x / fz."""
    return np.array([
        [0, 0, 1, 0, 0, 0],               # fz >= 0
        [1, 0, mu, 0, 0, 0],              # friction pyramid
        [-1, 0, mu, 0, 0, 0],
        [0, 1, mu, 0, 0, 0],
        [0, -1, mu, 0, 0, 0],
        [0, 0, torsion, 0, 0, 1],         # |n_z| <= torsion fz
        [0, 0, torsion, 0, 0, -1],
        [zs, 0, -lo, 0, -1, 0],           # -n'y - lo fz >= 0
        [-zs, 0, hi, 0, 1, 0],            # n'y + hi fz >= 0
        [0, zs, -ylo, 1, 0, 0],           # n'x - ylo fz >= 0
        [0, -zs, yhi, -1, 0, 0],          # yhi fz - n'x >= 0
    ], dtype=float)


class SoleBoxes:
    """The sole boxes' rows and the QP's tables, cached (the rows are read-only arrays, shared).

    Args:
        sole: the sole geometry.
        friction: the friction coefficient the QP may use (the scenario's times ``friction_safety``).
        settings: ``BalanceSettings`` (CoP margins, heel lift, regularisation weights).
        gains: the tasks' gains (:class:`.qp.BalanceTables`); w_joint: the posture weights (26,).
    """

    def __init__(self, sole: SoleGeometry, friction: float, settings, gains: np.ndarray,
                 w_joint: np.ndarray) -> None:
        self.sole = sole
        self.mu = friction / math.sqrt(2.0)    # the pyramid |fx|, |fy| <= mu' fz lies inside the cone |f_t| <= mu fz
        # a sole spinning about its CoP resists with at most ~ mu fz times a third of its half-width (a uniform
        # pressure on a disc of that radius gives 2/3 r): conservative, the yaw moment a weld can otherwise hold
        self.torsion = friction * sole.width / 6.0
        self.s = settings
        self.gains, self.w_joint = gains, w_joint
        self._rows: dict[tuple, np.ndarray] = {}
        self._boxes: dict[bool, tuple[np.ndarray, ...]] = {}
        self._tables: dict[tuple, BalanceTables] = {}

    def rows(self, lo: float, hi: float, ylo: float, yhi: float, zs: float) -> np.ndarray:
        """:func:`box_rows` with this friction and torsion bound, cached."""
        key = (lo, hi, ylo, yhi, zs)
        rows = self._rows.get(key)
        if rows is None:
            rows = self._rows[key] = box_rows(lo, hi, ylo, yhi, zs, self.mu, self.torsion)
            rows.flags.writeable = False
        return rows

    def whole(self, dsp: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The rows of a wholly supported sole in double (``dsp``) or single support: heel box, toe box, the heel
        box of a main body held alone, a trailing toe box, each shrunk by the phase's CoP margin."""
        boxes = self._boxes.get(dsp)
        if boxes is None:
            sole, s = self.sole, self.s
            jx, _, jz = sole.toe_joint
            m = s.cop_margin_dsp_m if dsp else s.cop_margin_ssp_m
            y0, y1 = -sole.width / 2.0 + m, sole.width / 2.0 - m
            toe = self.rows(m, sole.toe_front_x - jx - m, y0, y1, sole.sole_z - jz)
            heel = self.rows(sole.heel_back_x + m, jx - m, y0, y1, sole.sole_z)
            boxes = self._boxes[dsp] = (heel, toe, heel, toe)
        return boxes

    def tables(self, dsp: bool, hold: Foothold | None = None, held: Foothold | None = None) -> BalanceTables:
        """The QP's tables: the flat foot's heel and toe boxes cut to the supported part of its sole ``hold`` (sole
        frame; each box also keeps its margin from the sole's own edges; a box with nothing left, or the toe box of
        a foot anchored with its toe bent, carries no load); a trailing foot held flat's heel box cut to its last
        stance's ``held``."""
        sole = self.sole
        jx, _, jz = sole.toe_joint
        heel, toe, main, trail = self.whole(dsp)
        m = self.s.cop_margin_dsp_m if dsp else self.s.cop_margin_ssp_m
        hw = sole.width / 2.0

        def cut_heel(h: Foothold) -> np.ndarray:     # the heel box cut to a stance's supported part
            return self.rows(max(sole.heel_back_x + m, h.x_lo), min(jx - m, h.x_hi), max(-hw + m, h.y_lo),
                             min(hw - m, h.y_hi), sole.sole_z)

        if hold is not None and not hold.whole:
            ylo, yhi = max(-hw + m, hold.y_lo), min(hw - m, hold.y_hi)
            heel = cut_heel(hold)
            toe = self.rows(max(m, hold.x_lo - jx), min(sole.toe_front_x - jx - m, hold.x_hi - jx), ylo, yhi,
                            sole.sole_z - jz) if hold.toe_loaded else self.rows(1.0, 0.0, 0.0, 0.0, sole.sole_z - jz)
        if held is not None and not held.whole:
            main = cut_heel(held)
        key = (dsp, id(heel), id(toe), id(main), id(trail))
        tables = self._tables.get(key)
        if tables is None:
            s = self.s
            tables = self._tables[key] = BalanceTables(self.gains, self.w_joint, float(s.heel_lift_rad), heel, toe,
                                                       main, trail, float(s.w_acc), float(s.w_force),
                                                       float(s.w_torque))
        return tables
