"""What each touchdown does to the landing foot and to the robot: the landing audit.

At every touchdown the weld engine records, before it welds the landing foot where it is:

- ``tilt_rad``: the angle between the landing foot's main-body z axis (frame O_3 / O_4, normal to the sole) and
  the world z axis; ``toe_tilt_rad`` the same for the toe body (O_1 / O_2).  A welded foot keeps this tilt for
  the whole stance.
- ``lowest_corner_m``: the lowest world z of the landing foot's sole corners (the main-body part from the heel to
  the toe joint, and the toe part carried by the toe body; :class:`humanoid_sim.robot.sole.SoleGeometry`).  Below
  zero means the weld holds the foot sunk into the ground.
- ``momentum_change_Ns`` (3,): the change of the whole-body linear momentum across the touchdown,
  m (v_com+ - v_com-), world frame.  Whatever the touchdown law, only the ground can supply it, so it is the total
  ground impulse (gravity and the actuators give no impulse in zero time).
- ``impulses_Ns``: the ground impulse on each foot, world frame, when the law computes one (the inelastic law:
  Pinocchio's contact impulses of the welds, LOCAL frame rotated to the world; lock rows are internal joint
  impulses, not ground ones).  The thesis's least-change reset computes none.

A ground impulse is physically possible only if it pushes (world z >= 0) and lies in the friction cone:
|tangential| <= mu |normal| (:func:`cone_ratio`).  :func:`landing_summary` reduces the records for
summary.json.  Units: SI (m, rad, N s); frames: world = thesis frame 0 (x lateral, y forward, z up).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from humanoid_sim.engines.impact import ImpactResult
from humanoid_sim.robot.phases import FOOT_SPECS
from humanoid_sim.robot.sole import SoleGeometry

_FOOT_OF_FRAME = {getattr(s, a): f for f, s in FOOT_SPECS.items() for a in ("main_frame", "toe_frame")}


@dataclass(frozen=True)
class Landing:
    """One touchdown (see the module docstring); ``t`` s, ``foot`` "R"/"L", ``law`` the touchdown law."""

    t: float
    foot: str
    law: str
    tilt_rad: float
    toe_tilt_rad: float
    lowest_corner_m: float
    momentum_change_Ns: np.ndarray
    impulses_Ns: dict[str, np.ndarray] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (lists of floats)."""
        return {"t": self.t, "foot": self.foot, "law": self.law, "tilt_rad": self.tilt_rad,
                "toe_tilt_rad": self.toe_tilt_rad, "lowest_corner_m": self.lowest_corner_m,
                "momentum_change_Ns": [float(x) for x in self.momentum_change_Ns],
                "impulses_Ns": {f: [float(x) for x in p] for f, p in self.impulses_Ns.items()}}


IMPULSE_TOL_NS = 1e-3
"""N s: an impulse smaller than this counts as none (0.3 % of a zmp-gait landing's ~0.3 N s; the trailing toe's
impulse at an inelastic touchdown is ~1e-5 N s of round-off-level either sign)."""


def cone_ratio(impulse: np.ndarray) -> float:
    """|tangential| / normal of a world-frame impulse (N s): 0 for no impulse (norm < :data:`IMPULSE_TOL_NS`),
    +inf when it does not push (normal <= 0)."""
    p = np.asarray(impulse, dtype=float)
    if float(np.linalg.norm(p)) < IMPULSE_TOL_NS:
        return 0.0
    if not p[2] > 0.0:
        return float("inf")
    return float(np.hypot(p[0], p[1]) / p[2])


def landing_record(model: pin.Model, data: pin.Data, q: np.ndarray, res: ImpactResult, t: float, foot: str,
                   sole: SoleGeometry) -> Landing:
    """The :class:`Landing` of ``foot`` at configuration q (before its weld) with the touchdown's velocity reset
    ``res``; ``data`` is a scratch Pinocchio data of ``model``."""
    spec = FOOT_SPECS[foot]
    pin.framesForwardKinematics(model, data, q)
    M_main = data.oMf[model.getFrameId(spec.main_frame)]
    M_toe = data.oMf[model.getFrameId(spec.toe_frame)]
    heel, toe = sole.heel_corners(), sole.toe_corners()
    z = np.concatenate([(heel @ M_main.rotation.T + M_main.translation)[:, 2],
                        (toe @ M_toe.rotation.T + M_toe.translation)[:, 2]])
    tilt = float(np.arccos(np.clip(M_main.rotation[2, 2], -1.0, 1.0)))
    toe_tilt = float(np.arccos(np.clip(M_toe.rotation[2, 2], -1.0, 1.0)))
    mass = float(sum(model.inertias[j].mass for j in range(1, model.njoints)))
    pin.centerOfMass(model, data, q, res.v_minus)
    vc_minus = data.vcom[0].copy()
    pin.centerOfMass(model, data, q, res.v_plus)
    dp = mass * (data.vcom[0] - vc_minus)
    impulses: dict[str, np.ndarray] = {}
    if res.impulse is not None:
        pin.framesForwardKinematics(model, data, q)
        for i, frame in enumerate(res.contacts.welds):
            R = data.oMf[model.getFrameId(frame)].rotation
            f = _FOOT_OF_FRAME[frame]
            impulses[f] = impulses.get(f, np.zeros(3)) + R @ res.impulse[6 * i:6 * i + 3]
    return Landing(float(t), foot, res.law, tilt, toe_tilt, float(z.min()), dp, impulses)


def landing_summary(landings: Sequence[Landing], mu: float) -> dict[str, Any]:
    """summary.json's ``contact.landing`` section: the worst tilt (rad), the lowest corner (m), the largest momentum
    change (N s) and its worst friction-cone ratio, the worst cone ratio of the per-foot impulses that push (when
    the law gives per-foot impulses), how many per-foot impulses pull and the largest of them, how many landings
    have every impulse pushing (or below :data:`IMPULSE_TOL_NS`) and inside the cone of ``mu``, and the records."""
    if not landings:
        return {"count": 0}
    total = [cone_ratio(l.momentum_change_Ns) for l in landings]
    feet = [p for l in landings for p in l.impulses_Ns.values()]
    pushing = [cone_ratio(p) for p in feet if np.isfinite(cone_ratio(p))]
    pulling = [float(np.linalg.norm(p)) for p in feet if not np.isfinite(cone_ratio(p))]

    def ok(l: Landing) -> bool:
        parts = list(l.impulses_Ns.values()) or [l.momentum_change_Ns]
        return all(cone_ratio(p) <= mu for p in parts)

    return {"count": len(landings), "friction_coefficient": float(mu),
            "tilt_max_rad": max(l.tilt_rad for l in landings),
            "lowest_corner_m": min(l.lowest_corner_m for l in landings),
            "momentum_change_max_Ns": max(float(np.linalg.norm(l.momentum_change_Ns)) for l in landings),
            "momentum_change_cone_ratio_max": max(total) if np.isfinite(max(total)) else None,
            "foot_impulse_cone_ratio_max": max(pushing) if pushing else None,
            "foot_impulses_pulling": len(pulling),
            "foot_impulse_pulling_max_Ns": max(pulling) if pulling else None,
            "inside_cone": sum(1 for l in landings if ok(l)),
            "records": [l.as_dict() for l in landings]}
