"""The zmp gait's ready stance: the initial posture with the whole-body CoM well inside the lead-in's support.

The lead-in double support (:class:`.zmp_walk.ZmpPreviewTrajectory`, phase 0) holds the first stance foot flat and
the other foot by its toe body, the thesis's double-support contact model.  Its support polygon is the hull of the
stance sole and the other foot's toe part.  From chapter 3's initial stance (the hip above the midpoint of the
toe points) the whole-body CoM lies on that polygon's edge (1.4 mm inside in sims 1-3 at 0.91 m): a robot held
like that is on the verge of tipping backwards over the line from the stance heel to the trailing toe, and the
first weight shift, whose ZMP must first move away from where the CoM is going (the cart-table model is non-minimum
phase), would leave the polygon.  So the gait starts from a ready stance: the same feet, the same hip height and
orientation, Body 17 moved horizontally until the whole-body CoM is ``margin_m`` inside the polygon (the nearest
such point to where it was).  World frame, SI units.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.optimize import minimize

from .errors import GaitError

FLAT, TOE = 1, 2   # humanoid_sim.analysis.audit kinds


def lead_in_polygon(hm: Any, q: np.ndarray, stance: str) -> np.ndarray:
    """(k, 2) CCW hull of the ``stance`` foot's sole and the other foot's toe part at configuration q."""
    from humanoid_sim.robot.sole import convex_hull, sole_polygons

    kind = np.array([[FLAT, TOE] if stance == "R" else [TOE, FLAT]])
    polys = sole_polygons(hm, np.asarray(q, dtype=float)[None, :], kind)[0]
    return convex_hull(np.vstack([p for p in polys if p is not None]))


def deepest_point_near(point: np.ndarray, polygon: np.ndarray, margin_m: float) -> np.ndarray:
    """The point nearest ``point`` at least ``margin_m`` inside the convex CCW ``polygon`` (m)."""
    P = np.asarray(polygon, dtype=float)
    e = np.roll(P, -1, axis=0) - P
    n = np.stack([-e[:, 1], e[:, 0]], axis=1) / np.linalg.norm(e, axis=1)[:, None]   # inward normals (CCW)
    b = np.einsum("ij,ij->i", n, P) + margin_m
    c = np.asarray(point, dtype=float)[:2]
    if np.all(n @ c >= b):
        return c.copy()
    res = minimize(lambda x: float((x - c) @ (x - c)), P.mean(axis=0), jac=lambda x: 2.0 * (x - c),
                   constraints=[{"type": "ineq", "fun": lambda x: n @ x - b, "jac": lambda x: n}], method="SLSQP",
                   options={"ftol": 1e-14, "maxiter": 200})
    if not res.success or np.any(n @ res.x < b - 1e-9):
        raise GaitError(f"ready stance: no point {margin_m} m inside the lead-in support polygon "
                        f"{np.round(P, 4).tolist()} ({res.message})")
    return res.x


def ready_stance(hm: Any, path: Any, q0: np.ndarray, stance: str, margin_m: float, tol: float = 1e-7,
                 max_iter: int = 20) -> np.ndarray:
    """Chapter 3's initial configuration ``q0`` (feet at the scenario's placements, Body 17 at ``path.Phip[0]``)
    with Body 17 moved horizontally so the whole-body CoM is ``margin_m`` inside :func:`lead_in_polygon`; q0 itself
    when it already is.  ``tol``: m, on the whole-body CoM."""
    from humanoid_sim.references.initial import initial_configuration

    model = hm.model
    data = model.createData()
    polygon = lead_in_polygon(hm, q0, stance)
    com = pin.centerOfMass(model, data, q0)[:2].copy()
    target = deepest_point_near(com, polygon, margin_m)
    if np.allclose(target, com, rtol=0.0, atol=0.0):
        return np.array(q0, dtype=float)
    Phip = np.array(path.Phip, dtype=float)
    hip = Phip[0, :2].copy()
    q = np.array(q0, dtype=float)
    for _ in range(max_iter):
        err = target - com
        if float(np.max(np.abs(err))) <= tol:
            return q
        hip = hip + err            # the whole-body CoM moves with Body 17 at a ratio below 1: a fixed point
        Phip[0, :2] = hip
        q = initial_configuration(hm, replace(path, Phip=Phip))
        com = pin.centerOfMass(model, data, q)[:2].copy()
    raise GaitError(f"ready stance: the whole-body CoM is {np.max(np.abs(target - com)):.2e} m from its target "
                    f"after {max_iter} iterations")
