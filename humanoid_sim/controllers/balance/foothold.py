"""Partial footholds: the part of a flat stance foot's sole that the ground supports, from the foot's rotation and
its measured centre of pressure (Wiedebach et al. 2016, the partial-foothold detection of IHMC's Atlas walking).

The QP (:mod:`.controller`) keeps each flat foot's CoP inside its heel box and toe box, which assumes ground under
the whole sole. On a bar, a step's edge or a stone it is under part of it, and a CoP the QP puts beyond that part
rolls the foot about the support's edge: the foot turns away from its anchor while its measured CoP sits on the
edge. Two rules, for each stance of a foot (touchdown to lift-off):

- **Toe box.** A foot whose toe joint was bent by more than ``foothold_toe_bent_rad`` when it was anchored (its toe
  box came down on something its heel box did not: a bar under the toe) carries no load on its toe box: the
  QP's ground wrench of that box is zero, and the toe's motor just holds the toe.  When the foot trails next (held
  by that toe in double support), its heel lifts from the bend it stood with (:meth:`FootholdTracker.toe_bend`),
  not from a main body parallel to the toe box, which would drive the heel into the floor.
- **Cuts.** When the loaded foot has turned about one of its sole axes by more than ``foothold_tilt_rad`` from its
  anchor, it is turning about the support's edge, and the measured CoP lies on that edge: the sole is cut along
  the axis through the CoP, and the CoP is kept ``foothold_cut_margin_m`` inside the side that did not drop. A cut
  is made only where it leaves both sides of what is still supported at least ``foothold_min_width_m`` wide: a
  foot turning about an edge of its support (the CoP there) is tipping, a balance problem that no cut mends. A
  pitch is read only with the CoP on the heel box: with the CoP on the toe box, the main body pitching is the heel
  rising about the toe joint (a robot rolling over its toes after a forward push), not the ground missing. Cuts
  only shrink the support, until the foot lifts. A stance's turn is not read in its first ``foothold_settle_s``:
  the anchor is taken at touchdown, and a foot that lands turned settles flat onto the ground within a few
  milliseconds, which is no missing ground.

Frames: the sole frame is the foot's main body frame (x forward, y left, z up), the sole plane at z = ``sole_z``;
the toe box's x is measured from the toe joint. Units: SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from humanoid_sim.robot.phases import FOOT_SPECS


@dataclass
class Foothold:
    """The supported part of one stance of a flat foot, sole frame (m): x in [x_lo, x_hi], y in [y_lo, y_hi] (the
    cuts; infinite where none), and whether the toe box carries load.

    Attributes:
        foot: "R" or "L".
        anchor: where the stance is held (the anchor's translation, world, m: it marks the stance; the engine
            copies a kept anchor at every phase change).
        toe_loaded: False when the foot was anchored with its toe bent.
        toe_angle: the toe joint's angle when the foot was anchored, rad.
        cuts: the cuts made, as (time s, axis "x" / "y", bound m) in order.
        t_start: when the stance began (its first update), s.
    """

    foot: str
    anchor: tuple[float, float, float]
    toe_loaded: bool = True
    toe_angle: float = 0.0
    x_lo: float = -math.inf
    x_hi: float = math.inf
    y_lo: float = -math.inf
    y_hi: float = math.inf
    cuts: list[tuple[float, str, float]] = field(default_factory=list)
    t_start: float = -math.inf

    @property
    def whole(self) -> bool:
        """Whether the whole sole is supported (no cut, toe box loaded)."""
        return self.toe_loaded and not self.cuts


def sole_cop(R: np.ndarray, o: np.ndarray, wrench: np.ndarray, f_min: float) -> tuple[float, float] | None:
    """The centre of pressure (x, y) in a sole frame (rotation R (3, 3), sole-plane point o (3,), world) of a ground
    wrench (6,) [force N; moment about the world origin N m], or None when the force along the sole's normal is
    below ``f_min`` (N)."""
    f, n = wrench[:3], wrench[3:]
    nrm = R[:, 2]
    fn = float(nrm @ f)
    if not fn >= f_min:
        return None
    n_o = n - np.cross(o, f)                     # the moment about o
    r = np.cross(nrm, n_o) / fn                  # the point of the plane where the tangential moment vanishes
    loc = R.T @ r
    return float(loc[0]), float(loc[1])


class FootholdTracker:
    """The :class:`Foothold` of the current flat stance foot (module docstring).

    Args:
        model: the controller's Pinocchio model.
        sole: the sole geometry (``humanoid_sim.robot.sole.SoleGeometry``): heel_back_x, toe_front_x, width, sole_z.
        settings: ``BalanceSettings`` (foothold_tilt_rad, foothold_cut_margin_m, foothold_min_width_m,
            foothold_toe_bent_rad).
        f_min: the normal force below which the foot's CoP is not read, N.
    """

    def __init__(self, model: pin.Model, sole, settings, f_min: float = 20.0) -> None:
        self.model = model
        self.data = model.createData()
        self.sole = sole
        self.s = settings
        self.f_min = float(f_min)
        self.fid = {f: model.getFrameId(FOOT_SPECS[f].main_frame) for f in FOOT_SPECS}
        self.hold: Foothold | None = None
        self._seen: tuple = (None, None, None)     # the anchors last read, their foot, its anchor's rotation^T
        self.last: dict[str, Foothold] = {}
        """Each foot's previous stance (a trailing foot's toe bend)."""
        self.history: list[Foothold] = []
        """Every stance that was not wholly supported, in order."""

    def update(self, t: float, foot: str, anchors, q: np.ndarray, data: pin.Data | None,
               foot_wrenches: np.ndarray | None) -> Foothold | None:
        """The foothold of the flat ``foot`` at time ``t`` (s), after reading its rotation from its anchor and its
        measured CoP.  ``anchors``: the observation's (``Observation.anchors``); ``data``: forward kinematics at
        ``q`` already computed, or None; ``foot_wrenches``: ``Observation.foot_wrenches`` (None: no cut)."""
        hold = self.hold
        if anchors is not self._seen[0] or foot != self._seen[1]:   # a new phase: the same stance, or a new one
            spec = FOOT_SPECS[foot]
            anchor = anchors.placements[spec.main_frame]
            at = anchor.translation
            key = (float(at[0]), float(at[1]), float(at[2]))
            self._seen = (anchors, foot, anchor.rotation.T.copy())
            if hold is None or hold.foot != foot or hold.anchor != key:
                angle = float(anchors.joint_positions.get(spec.toe_joint, 0.0))
                bent = abs(angle) > self.s.foothold_toe_bent_rad
                if hold is not None:
                    self.last[hold.foot] = hold
                hold = self.hold = Foothold(foot, key, toe_loaded=not bent, toe_angle=angle, t_start=t)
                if bent:
                    self.history.append(hold)
        if foot_wrenches is None or hold is None or t - hold.t_start < self.s.foothold_settle_s:
            return hold
        if data is None:
            data = self.data
            pin.forwardKinematics(self.model, data, q)
        M = pin.updateFramePlacement(self.model, data, self.fid[foot])
        R = M.rotation
        # the turn from the anchor about the sole's x and y axes, from where the sole's normal went (in the
        # anchor's frame, n = (sin b cos a, -sin a, cos a cos b) for a turn a about x then b about y)
        n = self._seen[2] @ R[:, 2]
        tilt = (-math.asin(max(-1.0, min(1.0, float(n[1])))), math.atan2(float(n[0]), float(n[2])))
        s = self.s
        lim = s.foothold_tilt_rad
        if abs(tilt[0]) <= lim and abs(tilt[1]) <= lim:
            return hold
        o = M.translation + self.sole.sole_z * R[:, 2]
        cop = sole_cop(R, o, foot_wrenches[0 if foot == "R" else 1], self.f_min)
        if cop is None:
            return hold
        sole, m, w = self.sole, s.foothold_cut_margin_m, s.foothold_min_width_m
        hw = sole.width / 2.0
        if abs(tilt[0]) > lim:      # a roll about x: a turn by a > 0 raises the +y side, the -y side dropped
            y = cop[1]
            lo, hi = max(-hw, hold.y_lo), min(hw, hold.y_hi)      # what is still supported
            if hi - y >= w and y - lo >= w:
                if tilt[0] > 0.0 and y + m > hold.y_lo:
                    hold.y_lo = y + m
                    self._cut(hold, t, "y", hold.y_lo)
                elif tilt[0] < 0.0 and y - m < hold.y_hi:
                    hold.y_hi = y - m
                    self._cut(hold, t, "y", hold.y_hi)
        # a pitch about y: a turn by a > 0 lowers the +x (toe) side.  Only with the CoP on the heel box: the main
        # body also pitches about the toe joint while the toe box stays flat (the heel rising as the robot rolls
        # over its toes), which is no edge of the ground
        x = cop[0]
        if abs(tilt[1]) > lim and x <= sole.toe_joint[0] - m:
            lo, hi = max(sole.heel_back_x, hold.x_lo), min(sole.toe_front_x, hold.x_hi)
            if hi - x >= w and x - lo >= w:
                if tilt[1] > 0.0 and x - m < hold.x_hi:
                    hold.x_hi = x - m
                    self._cut(hold, t, "x", hold.x_hi)
                elif tilt[1] < 0.0 and x + m > hold.x_lo:
                    hold.x_lo = x + m
                    self._cut(hold, t, "x", hold.x_lo)
        return hold

    def _cut(self, hold: Foothold, t: float, axis: str, bound: float) -> None:
        if hold.whole:
            self.history.append(hold)
        hold.cuts.append((t, axis, bound))

    def stance(self, foot: str) -> Foothold | None:
        """``foot``'s current stance, or its last one once another foot's stance has started (None before any)."""
        return self.hold if self.hold is not None and self.hold.foot == foot else self.last.get(foot)

    def toe_bend(self, foot: str) -> float:
        """The toe joint's angle (rad) that ``foot`` kept through its stance (:meth:`stance`: the current one, or its
        last) when that stance was anchored with its toe bent; 0 otherwise."""
        last = self.stance(foot)      # the current hold until the next stance's first update moves it to ``last``
        return 0.0 if last is None or last.toe_loaded else last.toe_angle

