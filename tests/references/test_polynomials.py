"""The boundary-value polynomials of thesis 3.2.3 (humanoid_sim.references.chapter3.polynomials) against their
boundary conditions, the closed-form Hermite cubic, and finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from humanoid_sim.references.chapter3.polynomials import (
    cubic_bvp,
    eval_cubic,
    eval_quartic,
    smoothstep,
    toe_height_quartic,
)


@pytest.mark.parametrize("T, p0, pT, v0, vT", [(1.0, 0.0, 1.0, 0.0, 0.0), (0.8, 0.3, -0.2, 1.5, -0.7),
                                                (2.5, -1.0, 4.0, 0.0, 2.0)])
def test_cubic_is_the_hermite_cubic(T, p0, pT, v0, vT) -> None:
    c = cubic_bvp(T, p0, pT, v0, vT)
    # closed form (Hermite basis in s = t / T): p = h00 p0 + h10 T v0 + h01 pT + h11 T vT
    for t in np.linspace(0.0, T, 7):
        s = t / T
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        assert eval_cubic(c, t)[0] == pytest.approx(h00 * p0 + h10 * T * v0 + h01 * pT + h11 * T * vT, abs=1e-12)
    assert eval_cubic(c, 0.0)[:2] == pytest.approx((p0, v0), abs=1e-12)
    assert eval_cubic(c, T)[:2] == pytest.approx((pT, vT), abs=1e-12)


def test_cubic_rest_to_rest_coefficients_by_hand() -> None:
    # p(0) = 0, p(1) = 1, rest at both ends: p = 3 t^2 - 2 t^3
    assert cubic_bvp(1.0, 0.0, 1.0, 0.0, 0.0) == pytest.approx((-2.0, 3.0, 0.0, 0.0), abs=1e-14)
    with pytest.raises(ValueError, match="duration T must be > 0"):
        cubic_bvp(0.0, 0.0, 1.0, 0.0, 0.0)


def test_toe_height_meets_its_five_conditions() -> None:
    t_ssp, k_sh, sh, z0 = 0.8, 0.4, 0.06, 0.015
    q = toe_height_quartic(t_ssp, k_sh, sh, z0)
    assert eval_quartic(q, 0.0)[:2] == pytest.approx((z0, 0.0), abs=1e-12)
    assert eval_quartic(q, t_ssp)[:2] == pytest.approx((z0, 0.0), abs=1e-12)
    assert eval_quartic(q, k_sh * t_ssp)[0] == pytest.approx(sh, abs=1e-12)


@pytest.mark.parametrize("t", [0.0, 0.13, 0.5, 0.77])
def test_derivatives_match_central_differences(t) -> None:
    c = cubic_bvp(0.8, 0.3, -0.2, 1.5, -0.7)
    q = toe_height_quartic(0.8, 0.4, 0.06, 0.015)
    e = 1e-5
    for f, coeffs in ((eval_cubic, c), (eval_quartic, q)):
        p, v, a = f(coeffs, t)
        assert v == pytest.approx((f(coeffs, t + e)[0] - f(coeffs, t - e)[0]) / (2 * e), abs=1e-7)
        assert a == pytest.approx((f(coeffs, t + e)[1] - f(coeffs, t - e)[1]) / (2 * e), abs=1e-6)
        assert p == pytest.approx(np.polyval(coeffs, t), abs=1e-14)   # highest power first, as numpy's


def test_smoothstep() -> None:
    x = np.array([0.0, 0.25, 0.5, 1.0])
    np.testing.assert_allclose(smoothstep(x), [0.0, 0.15625, 0.5, 1.0], atol=1e-15)   # x^2 (3 - 2 x) by hand
    e = 1e-6
    assert (smoothstep(e) - smoothstep(-e)) / (2 * e) == pytest.approx(0.0, abs=1e-9)  # flat at both ends
    assert (smoothstep(1 + e) - smoothstep(1 - e)) / (2 * e) == pytest.approx(0.0, abs=1e-9)
