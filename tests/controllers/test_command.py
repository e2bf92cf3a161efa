"""Optimum command accelerations (thesis 5.1) against a direct numerical minimisation of the thesis's costs.

The reference side of each test rebuilds the cost functions of eqs. 5.5, 5.18, 5.55-5.57 and 5.90 from their
definitions -- predicted task values by the truncated Taylor expansion with the *actual* task accelerations that
Pinocchio's forward kinematics gives for a trial joint acceleration (the base acceleration found by numerically
identifying the stance-foot weld constraint) -- and minimises them with scipy.  The closed forms in
humanoid_sim.controllers.thesis.command share none of that code (no reduced Jacobians, no drift algebra).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.linalg import lstsq, null_space
from scipy.optimize import LinearConstraint, minimize

from humanoid_sim.controllers.thesis.command import (
    LAYOUTS,
    Q_UPPER,
    CommandAccelerations,
    ControllerParams,
    TaskReference,
)

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _params(rng: np.random.Generator) -> ControllerParams:
    """Random but plausible weights (magnitudes as in Appendix B) and prediction times."""
    c = {}
    for ph in ("LFFSSP", "RFFSSP", "LFFDSP", "RFFDSP"):
        c[f"Delta_t1_{ph}"] = rng.uniform(0.03, 0.12)
        c[f"Delta_t2_{ph}"] = c[f"Delta_t1_{ph}"] if "DSP" in ph else rng.uniform(0.03, 0.12)
        c[f"Wp_fa_{ph}"] = rng.uniform(1e2, 1e5, 3)
        c[f"Wv_fa_{ph}"] = rng.uniform(1e1, 1e3, 6)
        c[f"Wor_fa_{ph}"] = rng.uniform(1e3, 1e5, 3)
        c[f"Wa_a_{ph}"] = rng.uniform(0.05, 1.5, 7)
        c[f"Wp_fb_{ph}"] = rng.uniform(1e2, 1e5, 3)
        c[f"Wv_fb_{ph}"] = rng.uniform(1e1, 1e4, 6)
        c[f"Wor_fb_{ph}"] = rng.uniform(1e3, 1e5, 3)
        c[f"Wa_b_{ph}"] = rng.uniform(0.05, 1.5, 8)
    for ph, st, ot in (("LFFSSP", "L", "R"), ("RFFSSP", "R", "L"), ("LFFDSP", "L", "R"), ("RFFDSP", "R", "L")):
        c[f"Wq{st}_H_{ph}"] = rng.uniform(0.1, 1e3, 7)
        c[f"WqH_{ot}_{ph}" if "SSP" in ph else f"Wq{ot}_H_{ph}"] = rng.uniform(0.1, 1e3, 8)
    for ph, toe in (("LFFSSP", 3), ("RFFSSP", 4)):
        c[f"Delta_t3_{ph}"] = rng.uniform(0.01, 0.05)
        c[f"Wp_Tetha{toe}_{ph}"] = rng.uniform(1e4, 1e6)
        c[f"Wv_Tetha{toe}_{ph}"] = rng.uniform(1e4, 1e5)
    for k in range(18, 28):
        c[f"WpTetha{k}"] = rng.uniform(10, 300)
        c[f"WvTetha{k}"] = rng.uniform(50, 150)
        c[f"Delta_t{k}"] = rng.uniform(0.1, 0.4)
    return ControllerParams.from_dict(c)


class Oracle:
    """Predicted task values from forward kinematics at a trial acceleration (independent of command.py)."""

    def __init__(self, hm, q, v, root: str) -> None:
        self.hm, self.q, self.v = hm, q, v
        self.data = hm.model.createData()
        self.root = root
        self.fid = hm.frame_id
        # Identify the affine map base acceleration -> root-weld classical acceleration, for theta_ddot = 0.
        base = np.zeros((6, 7))
        for i in range(7):
            a = np.zeros(hm.model.nv)
            if i < 6:
                a[i] = 1.0
            base[:, i] = self._acc(a, root)
        self.Mb = base[:, :6] - base[:, 6:7]
        self.c0 = base[:, 6]

    def _acc(self, a: np.ndarray, frame: str) -> np.ndarray:
        pin.forwardKinematics(self.hm.model, self.data, self.q, self.v, a)
        pin.updateFramePlacements(self.hm.model, self.data)
        return pin.getFrameClassicalAcceleration(self.hm.model, self.data, self.fid(frame), LWA).vector.copy()

    def full_acc(self, thdd: np.ndarray) -> np.ndarray:
        a = self.hm.v_from_theta_dot(thdd)
        # root weld classical acceleration = Mb a_b + (acc with a_b = 0) = 0
        r = self._acc(a, self.root)
        a[:6] = np.linalg.solve(self.Mb, -r)
        return a

    def state(self, frame: str, a: np.ndarray):
        acc = self._acc(a, frame)
        M = self.data.oMf[self.fid(frame)]
        vel = pin.getFrameVelocity(self.hm.model, self.data, self.fid(frame), LWA).vector.copy()
        return M.translation.copy(), M.rotation.copy(), vel, acc


def _skew(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def _task_residuals(orc: Oracle, a, point, body, ref: TaskReference, w, dt):
    """sqrt(W) * (reference - prediction) for position, velocity and C_diag (eqs. 5.1-5.3)."""
    p, _, vp, ap = orc.state(point, a)
    _, R, vb, ab = orc.state(body, a)
    v6 = np.concatenate([vp[:3], vb[3:]])
    a6 = np.concatenate([ap[:3], ab[3:]])
    p_pred = p + v6[:3] * dt + a6[:3] * dt**2 / 2
    v_pred = v6 + a6 * dt
    Wx = _skew(v6[3:])
    C_pred = R + Wx @ R * dt + (_skew(a6[3:]) @ R + Wx @ Wx @ R) * dt**2 / 2
    return np.concatenate([np.sqrt(w.W_p) * (ref.p - p_pred), np.sqrt(w.W_v) * (ref.v - v_pred),
                           np.sqrt(w.W_or) * (np.diag(ref.R) - np.diag(C_pred))])


def _joint_residuals(th, thd, thdd, W, dt):
    return np.sqrt(W) * (th + thd * dt + thdd * dt**2 / 2)


def _random_state(hm, rng, foot: str):
    theta = rng.uniform(-0.3, 0.3, 26)
    yaw = rng.uniform(-np.pi, np.pi)
    q = hm.q_on_foot(theta, foot, np.array([0.2, -0.1, 0.015]), pin.rpy.rpyToMatrix(0, 0, yaw))
    v = hm.v_from_theta_dot(rng.normal(scale=0.5, size=26))
    return q, v


def _ref(rng) -> TaskReference:
    R = pin.rpy.rpyToMatrix(*rng.uniform(-0.2, 0.2, 2), rng.uniform(-np.pi, np.pi))
    return TaskReference(rng.normal(scale=0.3, size=3) + [0, 0, 0.9], rng.normal(scale=0.3, size=6), R)


def _fix_base_velocity(hm, q, v, root):
    """Base twist so that the root weld is at rest (the state lies on the velocity constraint manifold)."""
    data = hm.model.createData()
    J = pin.computeFrameJacobian(hm.model, data, q, hm.frame_id(root), LWA)
    v = v.copy()
    v[:6] = -np.linalg.solve(J[:, :6], J[:, 6:] @ v[6:])
    return v


def _affine(res, n):
    """Exact affine model r(x) = r0 + Jr x of a residual that is affine in x (columns by unit steps)."""
    r0 = res(np.zeros(n))
    return r0, np.column_stack([res(e) - r0 for e in np.eye(n)])


def _argmin(res, n):
    """Direct minimisation of 1/2 |res(x)|^2 for an affine residual: linear least squares (scipy)."""
    r0, Jr = _affine(res, n)
    return lstsq(Jr, -r0)[0]


def _on_both_welds(hm, q, v, welds, locked):
    """Project v onto the velocity constraint manifold of the given welds and locked joints."""
    data = hm.model.createData()
    rows = [pin.computeFrameJacobian(hm.model, data, q, hm.frame_id(w), LWA) for w in welds]
    for k in locked:
        e = np.zeros((1, hm.model.nv))
        e[0, hm.theta_v_idx[k]] = 1.0
        rows.append(e)
    N = null_space(np.vstack(rows))
    return N @ (N.T @ v)


# Tolerance: both sides solve the same quadratic problem; the reference side's residual model is exact up to
# round-off amplified by the weights' spread (~1e7) and the conditioning of the normal equations: 1e-6 relative.
RTOL = 1e-6


@pytest.mark.parametrize("phase", ["LFFSSP", "RFFSSP"])
def test_single_support_equals_direct_minimisation(hm, phase):
    rng = np.random.default_rng({"LFFSSP": 10, "RFFSSP": 11}[phase])
    params = _params(rng)
    lay = LAYOUTS[phase]
    wa, wb = params.steps[phase]
    q, v = _random_state(hm, rng, "R" if lay.root_weld == "O_3" else "L")
    v = _fix_base_velocity(hm, q, v, lay.root_weld)
    ref_a, ref_b = _ref(rng), _ref(rng)
    ours = CommandAccelerations(hm, params).compute(phase, q, v, ref_a, ref_b)

    orc = Oracle(hm, q, v, lay.root_weld)
    th, thd = hm.theta_from_q(q), hm.theta_dot_from_v(v)
    xs, xo = lay.stance_vars, lay.other_vars

    def res1(x):  # eq. 5.5
        thdd = np.zeros(26)
        thdd[xs] = x
        a = orc.full_acc(thdd)
        return np.concatenate([_task_residuals(orc, a, "Pc_17", "O_17", ref_a, wa, wa.dt),
                               _joint_residuals(th[xs], thd[xs], x, wa.W_q, wa.dt), np.sqrt(wa.W_qdd) * x])

    x1 = _argmin(res1, len(xs))
    np.testing.assert_allclose(ours[xs], x1, rtol=RTOL, atol=RTOL * np.abs(x1).max())

    toe = lay.other_toe

    def res2(x):  # eq. 5.18 (step 2 given step 1's optimum)
        thdd = np.zeros(26)
        thdd[xs] = x1
        thdd[xo] = x
        a = orc.full_acc(thdd)
        k = xo.index(toe)
        return np.concatenate([
            _task_residuals(orc, a, lay.other_toe_point, lay.other_weld, ref_b, wb, wb.dt),
            _joint_residuals(th[xo], thd[xo], x, wb.W_q, wb.dt),
            [np.sqrt(wb.W_p_toe) * (th[toe] + thd[toe] * wb.dt3 + x[k] * wb.dt3**2 / 2),
             np.sqrt(wb.W_v_toe) * (thd[toe] + x[k] * wb.dt3)],
            np.sqrt(wb.W_qdd) * x])

    x2 = _argmin(res2, len(xo))
    np.testing.assert_allclose(ours[xo], x2, rtol=RTOL, atol=RTOL * np.abs(x2).max())
    assert ours[lay.stance_toe] == 0.0


@pytest.mark.parametrize("phase", ["LFFDSP", "RFFDSP"])
def test_double_support_equals_direct_constrained_minimisation(hm, phase):
    rng = np.random.default_rng({"LFFDSP": 12, "RFFDSP": 13}[phase])
    params = _params(rng)
    lay = LAYOUTS[phase]
    wa, wb = params.steps[phase]
    q, v = _random_state(hm, rng, "R" if lay.root_weld == "O_3" else "L")
    v = _on_both_welds(hm, q, v, [lay.root_weld, lay.other_weld], [lay.stance_toe])
    ref_a = _ref(rng)
    ours = CommandAccelerations(hm, params).compute(phase, q, v, ref_a, None)

    th, thd = hm.theta_from_q(q), hm.theta_dot_from_v(v)
    xs, xo = lay.stance_vars, lay.other_vars
    x_idx = xs + xo
    orc_a = Oracle(hm, q, v, lay.root_weld)

    def full(x):
        thdd = np.zeros(26)
        thdd[x_idx] = x
        return thdd

    # Chain b predicts Body 17 with the base eliminated through the trailing toe body (the thesis's fL chain).
    orc_b = Oracle(hm, q, v, lay.other_weld)
    n, ns = len(x_idx), len(xs)

    def res(x):  # eqs. 5.55-5.57
        xa = np.zeros(n)
        xa[:ns] = x[:ns]
        xb = np.zeros(n)
        xb[ns:] = x[ns:]
        ra = _task_residuals(orc_a, orc_a.full_acc(full(xa)), "Pc_17", "O_17", ref_a, wa, wa.dt)
        rb = _task_residuals(orc_b, orc_b.full_acc(full(xb)), "Pc_17", "O_17", ref_a, wb, wb.dt)
        return np.concatenate([ra, rb,
                               _joint_residuals(th[xs], thd[xs], x[:ns], wa.W_q, wa.dt),
                               _joint_residuals(th[xo], thd[xo], x[ns:], wb.W_q, wb.dt),
                               np.sqrt(np.concatenate([wa.W_qdd, wb.W_qdd])) * x])

    # Closure (eq. 5.59): the trailing toe body does not accelerate; identified numerically as an affine map.
    def closure(x):
        return orc_a.state(lay.other_weld, orc_a.full_acc(full(x)))[3]

    c0 = closure(np.zeros(n))
    A = np.column_stack([closure(e) - c0 for e in np.eye(n)])
    # Quadratic cost: minimise 1/2 |res|^2 exactly via its (affine) Jacobian, under A x = -c0.
    r0, Jr = _affine(res, n)
    out = minimize(lambda x: 0.5 * np.sum((r0 + Jr @ x) ** 2), np.zeros(n), jac=lambda x: Jr.T @ (r0 + Jr @ x),
                   hess=lambda x: Jr.T @ Jr, method="trust-constr", constraints=[LinearConstraint(A, -c0, -c0)],
                   options={"xtol": 1e-14, "gtol": 1e-12, "maxiter": 5000})
    np.testing.assert_allclose(ours[x_idx], out.x, rtol=RTOL, atol=RTOL * np.abs(out.x).max())
    # and the command is consistent with the closed chain
    np.testing.assert_allclose(A @ ours[x_idx] + c0, 0, atol=1e-9)


def test_upper_body_equals_scalar_minimisation(hm):
    rng = np.random.default_rng(14)
    params = _params(rng)
    ca = CommandAccelerations(hm, params)
    th, thd = rng.normal(size=10), rng.normal(size=10)
    ours = ca.upper(th, thd)
    for k in range(10):
        Wp, Wv, dt = params.upper_Wp[k], params.upper_Wv[k], params.upper_dt[k]

        def cost(x):  # eq. 5.90 with theta_k0 = theta_dot_k0 = 0
            return 0.5 * Wp * (th[k] + thd[k] * dt + x * dt**2 / 2) ** 2 + 0.5 * Wv * (thd[k] + x * dt) ** 2

        x = minimize(lambda z: cost(z[0]), [0.0], method="BFGS", options={"gtol": 1e-12}).x[0]
        assert ours[k] == pytest.approx(x, rel=1e-6, abs=1e-8)
    assert list(range(16, 26)) == Q_UPPER


def test_cdiag_helpers_match_their_definitions():
    """L w = d/dt diag(C) and the bias = diag([w]x [w]x C), against finite differences of C(t) = C0 expm([w]x t)
    and the explicit skew-matrix products (the helpers use closed forms)."""
    from scipy.linalg import expm

    from humanoid_sim.controllers.thesis.taskspace import cdiag, cdiag_rate_matrix, cdiag_second_derivative_bias

    rng = np.random.default_rng(15)
    R = pin.rpy.rpyToMatrix(*rng.uniform(-1, 1, 3))
    w = rng.normal(size=3)
    h = 1e-6
    C = lambda t: expm(_skew(w) * t) @ R  # world angular velocity w: dC/dt = [w]x C
    fd = (cdiag(C(h)) - cdiag(C(-h))) / (2 * h)
    # central difference, error O(h^2 |w|^3) ~ 1e-12 plus round-off 1e-16/h ~ 1e-10
    np.testing.assert_allclose(cdiag_rate_matrix(R) @ w, fd, atol=1e-9)
    W = _skew(w)
    np.testing.assert_allclose(cdiag_second_derivative_bias(R, w), np.diag(W @ W @ R), atol=1e-14)
