"""The multibody ZMP of a sampled whole-body motion, and Kajita's second preview pass that closes the gap between
the cart-table plan and the multibody robot.

World frame (x lateral, y forward, z up), flat ground z = 0, SI units.  A motion is a sequence of configurations
q (N, nq) sampled every T seconds (Pinocchio's free-flyer layout, humanoid_sim.robot.model).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from .errors import GaitError, sample_time
from .preview import CartTablePreview, PreviewResult, _finite_array


def _pin_model(model: Any) -> pin.Model:
    m = getattr(model, "model", model)
    if not isinstance(m, pin.Model):
        raise GaitError(f"model: expected a pinocchio.Model or a HumanoidModel, got {type(model).__name__}")
    return m


def _configurations(m: pin.Model, q: Any, min_samples: int) -> np.ndarray:
    q = _finite_array("q", q, (None, m.nq), f"an (N, {m.nq}) array of configurations")
    if len(q) < min_samples:
        raise GaitError(f"q: expected at least {min_samples} samples for the finite differences, got {len(q)}")
    return q


def manifold_derivatives(model: Any, q: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Velocities v (N, nv) and accelerations a (N, nv) of sampled configurations (Pinocchio's conventions:
    free-flyer twist in the base frame), by finite differences in the tangent space at each sample:

        d+ = difference(q_k, q_k+1),  d- = difference(q_k, q_k-1),  v_k = (d+ - d-) / 2T,  a_k = (d+ + d-) / T^2

    (second-order accurate in T); at the two ends the one-sided formulas through q_k, q_k+-1, q_k+-2
    (v second-order, a first-order accurate).  Needs N >= 3."""
    m = _pin_model(model)
    T = sample_time(T)
    q = _configurations(m, q, 3)
    n = len(q)
    v = np.empty((n, m.nv))
    a = np.empty((n, m.nv))
    for k in range(1, n - 1):
        dp = pin.difference(m, q[k], q[k + 1])
        dm = pin.difference(m, q[k], q[k - 1])
        v[k] = (dp - dm) / (2.0 * T)
        a[k] = (dp + dm) / (T * T)
    for k, s in ((0, 1), (n - 1, -1)):
        d1 = pin.difference(m, q[k], q[k + s])
        d2 = pin.difference(m, q[k], q[k + 2 * s])
        v[k] = s * (4.0 * d1 - d2) / (2.0 * T)
        a[k] = (d2 - 2.0 * d1) / (T * T)
    return v, a


def zmp_of_wrench(force: np.ndarray, moment: np.ndarray) -> np.ndarray:
    """(..., 2) point of the ground z = 0 about which a world wrench (force N, moment about the world origin N m)
    has no horizontal moment: (-M_y / f_z, M_x / f_z); NaN where f_z = 0."""
    f = np.asarray(force, dtype=float)
    n = np.asarray(moment, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.stack((-n[..., 1] / f[..., 2], n[..., 0] / f[..., 2]), axis=-1)


def multibody_zmp(model: Any, q: np.ndarray, T: float) -> np.ndarray:
    """(N, 2) ZMP on the ground z = 0 (world x, y, m) of the sampled whole-body motion q (N, nq), T s apart.

    The total ground wrench is the rate of the centroidal momentum minus gravity: f = dl/dt - m g,
    n_G = dk_G/dt about the CoM G (pin.computeCentroidalMomentumTimeVariation), moved to the origin
    n_O = n_G + G x f; velocities and accelerations from :func:`manifold_derivatives`."""
    m = _pin_model(model)
    v, a = manifold_derivatives(m, q, T)
    q = np.asarray(q, dtype=float)
    data = m.createData()
    mass = pin.computeTotalMass(m)
    g = m.gravity.linear
    force = np.empty((len(q), 3))
    moment = np.empty((len(q), 3))
    for k in range(len(q)):
        dh = pin.computeCentroidalMomentumTimeVariation(m, data, q[k], v[k], a[k])
        f = dh.linear - mass * g
        force[k] = f
        moment[k] = dh.angular + np.cross(data.com[0], f)
    return zmp_of_wrench(force, moment)


def whole_body_com(model: Any, q: np.ndarray) -> np.ndarray:
    """(N, 3) whole-body centre of mass of each configuration, world, m."""
    m = _pin_model(model)
    q = _configurations(m, q, 1)
    data = m.createData()
    return np.array([pin.centerOfMass(m, data, qk) for qk in q])


def path_derivatives(x: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and acceleration (N, d) of a path x (N, d) sampled every T s (N >= 4): central differences
    (x+ - x-) / 2T and (x+ - 2x + x-) / T^2, second-order one-sided formulas at the ends."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or len(x) < 4:
        raise GaitError(f"path: expected an (N, d) array with N >= 4, got shape {x.shape}")
    v = np.gradient(x, T, axis=0, edge_order=2)
    a = np.empty_like(x)
    a[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / (T * T)
    a[0] = (2.0 * x[0] - 5.0 * x[1] + 4.0 * x[2] - x[3]) / (T * T)
    a[-1] = (2.0 * x[-1] - 5.0 * x[-2] + 4.0 * x[-3] - x[-4]) / (T * T)
    return v, a


# ------------------------------------------------------------------------------------------------ second pass
@dataclass
class PassRecord:
    """One evaluation of the multibody ZMP in :func:`correct_hip`.

    com_plan (N, 2): the CoM plan the whole body was matched to, m; com_match_error: max |com_wb - com_plan| after
    the fixed point, m; fixed_point_iterations; zmp_error (N, 2): multibody ZMP - reference, m."""

    com_plan: np.ndarray
    com_match_error: float
    fixed_point_iterations: int
    zmp_error: np.ndarray


@dataclass
class HipCorrection:
    """Result of :func:`correct_hip`.

    hip_xy, hip_v, hip_a (N, 2): the Body-17 CoM path (m) whose whole-body posture has the corrected CoM plan,
    with its velocity (m/s) and acceleration (m/s^2) by central differences (second order; one-sided at the ends);
    q (N, nq): the postures; com_plan (N, 2): the corrected whole-body CoM plan, m; zmp_mb (N, 2): the multibody
    ZMP of q, m; zmp_error (N, 2): zmp_mb - zmp_ref, the residual; passes: every evaluation, passes[0] before
    any correction."""

    hip_xy: np.ndarray
    hip_v: np.ndarray
    hip_a: np.ndarray
    q: np.ndarray
    com_plan: np.ndarray
    zmp_mb: np.ndarray
    zmp_error: np.ndarray
    passes: list[PassRecord] = field(default_factory=list)


def match_com(model: Any, com_plan: np.ndarray, posture: Callable[[np.ndarray], np.ndarray],
              hip_xy: np.ndarray | None = None, tol: float = 1e-5, max_iter: int = 20
              ) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Body-17 CoM path hip_xy (N, 2) whose posture's whole-body CoM is com_plan (N, 2), m.

    Fixed point hip <- hip + com_plan - com_wb(posture(hip)), from hip = com_plan (or the given start); after the
    first step a per-sample, per-axis secant slope (d com_wb / d hip, clipped to [0.2, 2]) scales the step.
    Returns (hip_xy, q, max |com_wb - com_plan| in m, iterations); raises when tol (m) is not reached."""
    m = _pin_model(model)
    plan = _finite_array("com_plan", com_plan, (None, 2), "an (N, 2) array of world CoM x, y in m")
    hip = plan.copy() if hip_xy is None else _finite_array("hip_xy", hip_xy, plan.shape, f"an array {plan.shape}")
    prev_hip = prev_com = None
    err = np.inf
    for it in range(1, max_iter + 1):
        q = np.asarray(posture(hip), dtype=float)
        if q.shape != (len(plan), m.nq):
            raise GaitError(f"posture: expected it to return shape ({len(plan)}, {m.nq}), got {q.shape}")
        com = whole_body_com(m, q)[:, :2]
        r = plan - com
        err = float(np.max(np.abs(r)))
        if err <= tol:
            return hip, q, err, it
        slope = np.ones_like(hip)
        if prev_hip is not None:
            dh = hip - prev_hip
            ok = np.abs(dh) > 1e-9
            slope[ok] = np.clip((com - prev_com)[ok] / dh[ok], 0.2, 2.0)
        prev_hip, prev_com = hip, com
        hip = hip + r / slope
    raise GaitError(f"match_com: the whole-body CoM is {err:.3g} m from the plan after {max_iter} iterations "
                    f"(tolerance {tol} m); the posture function cannot reach the plan")


def correct_hip(preview: CartTablePreview, model: Any, zmp_ref: np.ndarray, plan: PreviewResult,
                posture: Callable[[np.ndarray], np.ndarray], passes: int = 2, com_tol: float = 1e-5
                ) -> HipCorrection:
    """Kajita's second pass: the Body-17 CoM path whose multibody ZMP tracks the reference.

    preview: the cart-table controller that made ``plan`` (its T is the sample time of everything here);
    zmp_ref (N, 2): the ZMP reference, m; plan: the cart-table CoM plan for it; posture(hip_xy (N, 2)) -> q (N, nq):
    the whole-body configurations with the feet on their references and Body 17's CoM at (hip_xy, hip height).
    Each pass: match the whole-body CoM to the plan (:func:`match_com`), compute the multibody ZMP error
    e = zmp_mb - zmp_ref, and add to the plan the cart-table CoM response to the reference -e (a preview run from
    rest).  ``passes`` corrections (0 = only evaluate the plan); ``com_tol``: m, for :func:`match_com`."""
    if not isinstance(preview, CartTablePreview):
        raise GaitError(f"preview: expected a CartTablePreview, got {type(preview).__name__}")
    if not isinstance(plan, PreviewResult):
        raise GaitError(f"plan: expected a PreviewResult, got {type(plan).__name__}")
    if not isinstance(passes, int) or isinstance(passes, bool) or passes < 0:
        raise GaitError(f"passes: expected an integer >= 0, got {passes!r}")
    m = _pin_model(model)
    ref = _finite_array("zmp_ref", zmp_ref, (len(plan.com), 2), f"an array of shape ({len(plan.com)}, 2) like plan.com")
    com_plan = plan.com.copy()
    hip = None
    records: list[PassRecord] = []
    for i in range(passes + 1):
        hip, q, err, its = match_com(m, com_plan, posture, hip, tol=com_tol)
        zmp_mb = multibody_zmp(m, q, preview.T)
        e = zmp_mb - ref
        records.append(PassRecord(com_plan.copy(), err, its, e))
        if i == passes:
            break
        corr = preview.run(-e, x0=np.zeros((3, 2)))
        com_plan = com_plan + corr.com
    hip_v, hip_a = path_derivatives(hip, preview.T)
    return HipCorrection(hip_xy=hip, hip_v=hip_v, hip_a=hip_a, q=q, com_plan=com_plan, zmp_mb=zmp_mb,
                         zmp_error=e, passes=records)
