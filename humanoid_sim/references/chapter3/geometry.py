"""Arc geometry of thesis section 3.2.1-3.2.2: arc centres, local frames CS_k,k+1 and arc angles.

Everything lives in the ground plane (world x, y; m, rad).  Angles follow the thesis: the local frame
CS_k,k+1 sits at the arc centre O_k,k+1 with yaw theta_CS; a point on the arc is located by its angle
theta measured from P_k along the direction of travel, so that P_k has theta = 0 for both turning
directions (thesis L1266 / L1303).

Unified form used throughout the generator (derived from eqs. 3.8/3.9 and 3.13/3.14, checked in the
tests against the per-direction thesis formulas): with s = T_dir,

    position(theta) = O + s * r * (sin(phi), -cos(phi)),   phi = theta_CS + s * theta,

and phi is also the direction of travel (yaw of a body whose x axis is tangent to the arc).
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi


def wrap_pi(a: float) -> float:
    """Reduce an angle to (-pi, pi] (rad)."""
    r = math.fmod(a + math.pi, TWO_PI)
    if r <= 0.0:
        r += TWO_PI
    return r - math.pi


def circle_centres(p: np.ndarray, q: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """The two solutions of eqs. 3.1/3.2: centres of the circles of ``radius`` through p and q.

    p, q: ground-plane points (2,), m.  Raises ValueError when the chord exceeds the diameter.
    """
    d = q - p
    chord = math.hypot(d[0], d[1])
    half = 0.5 * chord
    if not 0.0 < half < radius:
        raise ValueError(f"circle_centres: no minor arc of radius {radius!r} through points {chord!r} apart")
    h = math.sqrt(radius * radius - half * half)
    m = 0.5 * (p + q)
    nrm = np.array((-d[1], d[0])) / chord          # unit normal, to the left of p -> q
    return m + h * nrm, m - h * nrm


def _reduce_half_turn(a: float) -> float:
    """The reduction of the 3.2.1 pseudo-code: map an angle difference into [-pi/2, pi/2] +- 2pi."""
    if -math.pi / 2 <= a <= math.pi / 2:
        return a
    if a < -math.pi / 2:
        return a + TWO_PI
    return a - TWO_PI


def arc_centre(p: np.ndarray, q: np.ndarray, radius: float, t_dir: int) -> np.ndarray:
    """Arc centre O_k,k+1 selected by the "Version 1" pseudo-code of thesis 3.2.1 (L1151-1190).

    p = P_k, q = P_k+1 (ground plane, m); t_dir = +1 (left) / -1 (right).
    """
    o1, o2 = circle_centres(p, q, radius)
    theta1 = math.atan2(o1[1] - p[1], o1[0] - p[0])
    theta = math.atan2(q[1] - p[1], q[0] - p[0])
    a = _reduce_half_turn(theta1 - theta)
    if t_dir == 1:
        return o1 if a > 0 else o2
    return o1 if a < 0 else o2


def cs_yaw(p: np.ndarray, o: np.ndarray, t_dir: int) -> float:
    """theta_CS_k,k+1 (3.2.2.1 / 3.2.2.2): theta_Pk,Ok,k+1 -/+ pi/2 for a left/right turn (rad)."""
    theta_po = math.atan2(o[1] - p[1], o[0] - p[0])
    return theta_po - math.pi / 2 if t_dir == 1 else theta_po + math.pi / 2


def arc_angle(point: np.ndarray, o: np.ndarray, theta_cs: float, t_dir: int) -> float:
    """Angle of ``point`` in CS_k,k+1, as theta_htotal (3.2.2) and theta_ri / theta_li (eqs. 3.20-3.29).

    K_x, K_y are the components of (point - O) in CS_k,k+1 (eqs. 3.3/3.4, 3.20/3.21); the angle is
    atan2(K_x, -K_y) for a left turn (eq. 3.23) and atan2(K_x, K_y) for a right turn (eq. 3.24).
    """
    dx, dy = point[0] - o[0], point[1] - o[1]
    c, s = math.cos(theta_cs), math.sin(theta_cs)
    kx = dx * c + dy * s          # eq. 3.3 / 3.20
    ky = dy * c - dx * s          # eq. 3.4 / 3.21
    return math.atan2(kx, -ky) if t_dir == 1 else math.atan2(kx, ky)


def point_on_arc(o: np.ndarray, r: float, theta_cs: float, theta: float, t_dir: int) -> np.ndarray:
    """Ground-plane point at angle ``theta`` on the circle (o, r) in CS_k,k+1 (eqs. 3.8/3.9, 3.13/3.14)."""
    phi = theta_cs + t_dir * theta
    return np.array((o[0] + t_dir * r * math.sin(phi), o[1] - t_dir * r * math.cos(phi)))


def yaw_of(rot: np.ndarray) -> float:
    """Yaw (rad) of a rotation matrix: heading of its x axis projected on the ground plane."""
    return math.atan2(rot[1, 0], rot[0, 0])
