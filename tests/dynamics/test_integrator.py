"""The fixed-step integrators: order of accuracy on a known solution, and the manifold update."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from humanoid_sim.dynamics.integrator import TABLEAUS, RungeKutta


def _free_body_model() -> pin.Model:
    model = pin.Model()
    model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "free")
    model.appendBodyToJoint(1, pin.Inertia(2.0, np.zeros(3), np.diag([0.1, 0.2, 0.3])), pin.SE3.Identity())
    return model


def test_tableaus_are_consistent() -> None:
    for tab in TABLEAUS.values():
        assert sum(tab.b) == pytest.approx(1.0, abs=1e-15)
        for ci, ai in zip(tab.c, tab.a):
            assert sum(ai) == pytest.approx(ci, abs=1e-15)  # row sums = stage times


@pytest.mark.parametrize("method, order", [("euler", 1), ("ode3", 3), ("rk4", 4)])
def test_convergence_order_on_a_spring(method: str, order: int) -> None:
    """x'' = -w^2 x on the base's x coordinate (body frame = world for a pure translation): the global error
    falls as h^order; the observed slope must be within 0.3 of the method's order."""
    model = _free_body_model()
    rk = RungeKutta(model, method)
    w = 3.0

    def f(t, q, v, stage):
        a = np.zeros(6)
        a[0] = -w * w * q[0]
        return a

    errs = []
    for n in (50, 100, 200):
        h = 1.0 / n
        q = pin.neutral(model)
        q[0] = 1.0
        v = np.zeros(6)
        for k in range(n):
            q, v = rk.step(f, k * h, q, v, h)
        errs.append(abs(q[0] - np.cos(w)))
    slopes = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(slopes - order) < 0.3), slopes


def test_configuration_stays_on_the_manifold() -> None:
    """A spinning body: the quaternion stays unit-norm (integrate, not q + h v) and the rotation angle after
    one second equals the spin rate (exact for a constant body twist)."""
    model = _free_body_model()
    rk = RungeKutta(model, "ode3")
    q = pin.neutral(model)
    v = np.array([0, 0, 0, 0.0, 0.0, 2.0])
    for k in range(100):
        q, v = rk.step(lambda t, q, v, s: np.zeros(6), k * 0.01, q, v, 0.01)
    assert np.linalg.norm(q[3:7]) == pytest.approx(1.0, abs=1e-14)
    R = pin.XYZQUATToSE3(q).rotation
    assert np.arctan2(R[1, 0], R[0, 0]) == pytest.approx(2.0, abs=1e-12)


def test_unknown_method_is_named() -> None:
    with pytest.raises(ValueError, match="expected one of .* got 'ode45'"):
        RungeKutta(_free_body_model(), "ode45")
