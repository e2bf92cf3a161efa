"""The soles of the feet: their rectangles, their polygons on the ground, and planar polygon geometry.

The sole rectangle of each foot is the model's ``foot_sole`` (models/thesis_humanoid.yaml). A foot touches the ground
with its whole sole when held flat, or with its toe part only (the trailing foot of a double support, heel up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from humanoid_sim.errors import InputError
from humanoid_sim.robot.phases import FOOT_SPECS

FEET = ("R", "L")
NONE, FLAT, TOE = 0, 1, 2
"""Contact kind of a foot at a step: not touching, held flat (whole sole), held by its toe body only."""


class SoleError(InputError):
    """The model's sole description is malformed or inconsistent (the message names the value)."""


@dataclass(frozen=True)
class SoleGeometry:
    """The sole rectangle of each foot (models/thesis_humanoid.yaml ``foot_sole``), m.

    ``heel_back_x``, ``toe_front_x``, ``sole_z`` are in the foot main-body frame (O_3 / O_4, at the ankle,
    x forward, y left); the toe body frame (O_1 / O_2, at the toe joint) sits at ``toe_joint`` in that frame with
    the same orientation at the zero posture.  ``width`` is the sole width (assumed, not in the thesis).
    """

    heel_back_x: float
    toe_front_x: float
    width: float
    sole_z: float
    toe_joint: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not (self.heel_back_x < self.toe_joint[0] < self.toe_front_x):
            raise SoleError(f"sole geometry: expected heel_back_x < toe joint x < toe_front_x, got "
                             f"{self.heel_back_x}, {self.toe_joint[0]}, {self.toe_front_x}")
        if not self.width > 0:
            raise SoleError(f"sole geometry: width must be > 0 m, got {self.width}")

    def _rect(self, x0: float, x1: float, z: float) -> np.ndarray:
        w = self.width / 2.0
        return np.array([[x0, -w, z], [x1, -w, z], [x1, w, z], [x0, w, z]])

    def flat_corners(self) -> np.ndarray:
        """(4, 3) corners of the whole sole in the main-body frame O_3 / O_4, m (counter-clockwise from +z)."""
        return self._rect(self.heel_back_x, self.toe_front_x, self.sole_z)

    def heel_corners(self) -> np.ndarray:
        """(4, 3) corners of the main-body part of the sole (heel to toe joint) in the main-body frame O_3 / O_4."""
        return self._rect(self.heel_back_x, self.toe_joint[0], self.sole_z)

    def toe_corners(self) -> np.ndarray:
        """(4, 3) corners of the toe part of the sole (toe joint to toe tip) in the toe body frame O_1 / O_2."""
        jx, _, jz = self.toe_joint
        return self._rect(0.0, self.toe_front_x - jx, self.sole_z - jz)

    @classmethod
    def from_model(cls, hm: Any) -> SoleGeometry:
        """From ``hm.spec.foot_sole`` and the placement of O_1 in O_3 at the neutral posture of the model."""
        fs = hm.spec.foot_sole
        try:
            heel, front, width, sole_z = (float(fs[k]) for k in ("heel_back_x", "toe_front_x", "width", "sole_z"))
        except (KeyError, TypeError, ValueError) as exc:
            raise SoleError(f"model foot_sole: expected heel_back_x, toe_front_x, width, sole_z numbers, got "
                             f"{fs!r} ({exc})") from None
        model = hm.model
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        rel = data.oMf[model.getFrameId("O_3")].actInv(data.oMf[model.getFrameId("O_1")])
        # 1e-9: the URDF writes exact zero-posture rotations; anything larger means a different toe frame layout.
        if not np.allclose(rel.rotation, np.eye(3), atol=1e-9):
            raise SoleError("model: O_1 is not aligned with O_3 at the zero posture; the toe sole cannot be placed")
        return cls(heel, front, width, sole_z, tuple(float(x) for x in rel.translation))


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points, counter-clockwise, no repeated or collinear vertices (Andrew's chain).  Plain
    Python floats: the audit builds a few hulls of 4-8 points per logged step, where NumPy's per-call overhead
    (np.unique alone ~60 us) would dominate."""
    pts = sorted(set(map(tuple, np.asarray(points, dtype=float).reshape(-1, 2).tolist())))
    if len(pts) <= 2:
        return np.array(pts, dtype=float).reshape(-1, 2)

    def half(seq: list) -> list:
        h: list = []
        for p in seq:
            while len(h) >= 2 and ((h[-1][0] - h[-2][0]) * (p[1] - h[-2][1])
                                   - (h[-1][1] - h[-2][1]) * (p[0] - h[-2][0])) <= 0:
                h.pop()
            h.append(p)
        return h

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def signed_distance(point: np.ndarray, polygon: np.ndarray) -> float:
    """Signed distance (m) from a 2-D point to the boundary of a convex polygon (CCW vertices): positive inside,
    negative outside, NaN for a non-finite point or an empty polygon.  Plain Python floats over the few edges (the
    audit calls this a few times per step; NumPy's per-call overhead would dominate), each operation in the order of
    the vectorised form, so the same doubles come out."""
    px, py = (float(x) for x in np.asarray(point, dtype=float)[:2])
    P = np.asarray(polygon, dtype=float).tolist()
    if not (math.isfinite(px) and math.isfinite(py)) or len(P) == 0:
        return float("nan")
    if len(P) == 1:   # a degenerate polygon: NumPy's own norm (a BLAS dot), as ever
        return -float(np.linalg.norm(np.array([px, py]) - np.asarray(P[0])))
    best, inside = math.inf, len(P) >= 3
    for (ax, ay), (bx, by) in zip(P, P[1:] + P[:1]):
        ex, ey = bx - ax, by - ay
        L = math.sqrt(ex * ex + ey * ey)
        if not L > 0:
            continue
        rx, ry = px - ax, py - ay
        t = min(max((rx * ex + ry * ey) / (L * L), 0.0), 1.0)   # nearest point of the segment (NumPy squares by *)
        dx, dy = rx - t * ex, ry - t * ey
        best = min(best, math.sqrt(dx * dx + dy * dy))
        inside = inside and ex * ry - ey * rx >= 0.0
    return best if inside else -best


def _project(M: pin.SE3, corners: np.ndarray) -> np.ndarray:
    world = corners @ M.rotation.T + M.translation
    return convex_hull(world[:, :2])


def sole_polygons(hm: Any, q: np.ndarray, kind: np.ndarray, sole: SoleGeometry | None = None,
                  articulated: bool = False) -> list[list[np.ndarray | None]]:
    """World sole polygons (x, y on z = 0, m) of the feet in contact at each step, from the logged configurations
    ``q`` (N, nq): the whole sole carried by O_3 / O_4 for a flat foot, the toe part carried by O_1 / O_2 for a
    foot held by its toe.  ``articulated``: for every foot in contact, the convex hull of both parts' footprints at
    their own poses (the heel part on O_3 / O_4, the toe part on O_1 / O_2) instead -- on real ground either part
    may carry load whatever the phase assumes, and a foot's centre of pressure lies in the hull of its contacts."""
    sole = sole or SoleGeometry.from_model(hm)
    model = hm.model
    data = model.createData()
    fid = {f: model.getFrameId(getattr(FOOT_SPECS[foot], a)) for foot in FEET
           for f, a in ((f"{foot}main", "main_frame"), (f"{foot}toe", "toe_frame"))}
    flat, toe, heel = sole.flat_corners(), sole.toe_corners(), sole.heel_corners()
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != model.nq or len(q) != len(kind):
        raise SoleError(f"q: expected shape ({len(kind)}, {model.nq}), got {q.shape}")
    out: list[list[np.ndarray | None]] = []
    for k in range(len(q)):
        row: list[np.ndarray | None] = [None, None]
        if np.any(kind[k] != NONE) and np.all(np.isfinite(q[k])):
            pin.framesForwardKinematics(model, data, q[k])
            for i, foot in enumerate(FEET):
                if articulated and kind[k, i] != NONE:
                    M_heel, M_toe = data.oMf[fid[f"{foot}main"]], data.oMf[fid[f"{foot}toe"]]
                    row[i] = convex_hull(np.vstack([(heel @ M_heel.rotation.T + M_heel.translation)[:, :2],
                                                    (toe @ M_toe.rotation.T + M_toe.translation)[:, :2]]))
                elif kind[k, i] == FLAT:
                    row[i] = _project(data.oMf[fid[f"{foot}main"]], flat)
                elif kind[k, i] == TOE:
                    row[i] = _project(data.oMf[fid[f"{foot}toe"]], toe)
        elif np.any(kind[k] != NONE):
            row = [np.full((1, 2), np.nan) if kind[k, i] != NONE else None for i in range(2)]
        out.append(row)
    return out


__all__ = ["FEET", "FLAT", "NONE", "SoleError", "SoleGeometry", "TOE", "convex_hull", "signed_distance",
           "sole_polygons"]
