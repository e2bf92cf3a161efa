"""ZMP preview control of the cart-table model (humanoid_sim/references/zmp/preview.py).

The gains are checked against two computations that share nothing with the code under test: the Riccati
difference equation iterated to its fixed point, and a brute-force finite-horizon least-squares solve of Kajita's
cost written on the cart-table model itself (states and jerks rolled out by hand, no augmented system, no Riccati
equation).  Tracking is checked on the walk of design.md section 9."""

from __future__ import annotations

import numpy as np
import pytest

from humanoid_sim.references.zmp.errors import GaitError
from humanoid_sim.references.zmp.preview import CartTablePreview, PreviewResult
from humanoid_sim.references.zmp.zmp_reference import SupportInterval, sample

T = 0.01
Z_C = 0.929   # m, about the whole-body CoM height of the 0.93 m-hip initial posture (test_gait_multibody computes it)
G = 9.81


# ------------------------------------------------------------------------------------------------ helpers
def cart_table(T: float, z_c: float):
    A = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    B = np.array([T ** 3 / 6, T * T / 2, T])
    C = np.array([1.0, 0.0, -z_c / G])
    return A, B, C


def batch_optimal_jerk_increments(T: float, z_c: float, Qe: float, R: float, X0: np.ndarray, u_prev: float,
                                  pref: np.ndarray, M: int) -> np.ndarray:
    """du(0..M-1) minimising  sum_{i=0..M} Qe (C X(i) - pref(i))^2 + R sum_{i<M} du(i)^2  (Kajita's cost with
    Qx = 0) for X(i+1) = A X(i) + B u(i), u(i) = u_prev + du(0) + ... + du(i): one linear least-squares problem."""
    A, B, C = cart_table(T, z_c)
    CAkB = np.empty(M + 1)
    Ak = np.eye(3)
    for j in range(M + 1):
        CAkB[j] = C @ Ak @ B
        Ak = A @ Ak
    X = np.asarray(X0, dtype=float).copy()
    e_free = np.empty(M + 1)
    for i in range(M + 1):
        e_free[i] = C @ X - pref[i]
        X = A @ X + B * u_prev
    # du(l) enters u(m) for every m >= l, hence e(i) through sum_{m=l}^{i-1} C A^(i-1-m) B
    cum = np.concatenate(([0.0], np.cumsum(CAkB)))
    i = np.arange(M + 1)[:, None]
    lag = i - np.arange(M)[None, :]
    Gmat = np.where(lag > 0, cum[np.clip(lag, 0, M + 1)], 0.0)
    lhs = np.vstack([np.sqrt(Qe) * Gmat, np.sqrt(R) * np.eye(M)])
    rhs = np.concatenate([-np.sqrt(Qe) * e_free, np.zeros(M)])
    return np.linalg.lstsq(lhs, rhs, rcond=None)[0]


def walk_reference(n_steps: int = 10, ss: float = 0.7, ds: float = 0.1, step: float = 0.2, half_width: float = 0.1,
                   transfer: str = "smoothstep"):
    """design.md section 9's walk: feet at x = -+0.1 m, 0.2 m apart along y, 0.7 s single / 0.1 s double support,
    after a 0.5 s stand and a 0.5 s shift onto the first foot.  Returns times, reference, single-support mask."""
    feet = [((-half_width if i % 2 == 0 else half_width), step * i) for i in range(n_steps)]
    iv = [SupportInterval(-1.0, -0.5, (0.0, 0.0), (0.0, 0.0)), SupportInterval(-0.5, 0.0, (0.0, 0.0), feet[0])]
    t, ss_windows = 0.0, []
    for i, f in enumerate(feet):
        iv.append(SupportInterval(t, t + ss, f, f))
        ss_windows.append((t, t + ss))
        t += ss
        if i + 1 < len(feet):
            iv.append(SupportInterval(t, t + ds, f, feet[i + 1]))
            t += ds
    times, ref = sample(iv, T, transfer)
    mask = np.zeros(len(times), dtype=bool)
    for a, b in ss_windows:
        mask |= (times >= a - 1e-9) & (times <= b + 1e-9)
    return times, ref, mask


@pytest.fixture(scope="module")
def ctrl() -> CartTablePreview:
    return CartTablePreview(T, Z_C)


# ------------------------------------------------------------------------------------------------ gains
def test_riccati_solution_is_the_fixed_point_of_the_riccati_iteration(ctrl):
    A, B, C = cart_table(T, Z_C)
    At = np.zeros((4, 4))
    At[0, 0] = 1.0
    At[0, 1:] = C @ A
    At[1:, 1:] = A
    Bt = np.concatenate(([C @ B], B))[:, None]
    Q = np.diag([1.0, 0.0, 0.0, 0.0])
    P = Q.copy()
    for _ in range(20000):
        S = 1e-6 + (Bt.T @ P @ Bt)[0, 0]
        P_next = Q + At.T @ P @ At - (At.T @ P @ Bt) @ (Bt.T @ P @ At) / S
        if np.max(np.abs(P_next - P)) < 1e-12 * np.max(np.abs(P_next)):
            break
        P = P_next
    else:
        pytest.fail("the Riccati iteration did not converge")
    # 1e-8 relative: the iteration stops at 1e-12 per step and converges geometrically (rate ~0.97 per step here),
    # so it sits within ~1e-10 of the fixed point; scipy's Schur-based solve is accurate to ~1e-12.
    np.testing.assert_allclose(ctrl.P, P_next, rtol=1e-8, atol=1e-8 * np.max(np.abs(P_next)))


@pytest.mark.slow
def test_gains_match_a_brute_force_least_squares_solve_of_the_cost(ctrl):
    """Each gain is the optimal first jerk increment for a unit input of its kind, on a horizon of M = 1000 samples
    (10 s, six times the 1.6 s preview; the finite-horizon effect on the first step decays below 1e-9)."""
    M = 1000
    # Gd_j: the reference steps by 1 m at sample j; state at rest at 0
    for j in (1, 2, 5, 10, 40, 80, 120, 160):
        pref = np.zeros(M + 1)
        pref[j:] = 1.0
        du = batch_optimal_jerk_increments(T, Z_C, 1.0, 1e-6, np.zeros(3), 0.0, pref, M)
        # 1e-7 relative: lstsq on a matrix of condition ~1e9 loses ~7 digits; measured agreement ~1e-11
        assert -du[0] == pytest.approx(ctrl.Gd[j - 1], rel=1e-7), j
    # Gi: unit ZMP error, nothing else
    du = batch_optimal_jerk_increments(T, Z_C, 1.0, 1e-6, np.zeros(3), 0.0, -np.ones(M + 1), M)
    assert -du[0] == pytest.approx(ctrl.Gi, rel=1e-7)
    # Gx: a unit state increment dX(0) = X(0) - X(-1) = (A - I) X(-1) + B u(-1), zero error, constant reference
    A, B, C = cart_table(T, Z_C)
    for m in range(3):
        target = np.eye(3)[m]
        sol = np.linalg.lstsq(np.hstack([A - np.eye(3), B[:, None]]), target, rcond=None)[0]
        X_prev, u_prev = sol[:3], sol[3]
        X0 = A @ X_prev + B * u_prev
        du = batch_optimal_jerk_increments(T, Z_C, 1.0, 1e-6, X0, u_prev, np.full(M + 1, C @ X0), M)
        assert -du[0] == pytest.approx(ctrl.Gx[m], rel=1e-7), m


def test_closed_loop_run_equals_the_batch_optimum_when_the_reference_changes_within_the_preview(ctrl):
    """With every reference change within N_L samples of the start, the preview law sees all of them at every
    step, so its whole closed-loop motion is the infinite-horizon optimum: compare it with the batch solution."""
    rng = np.random.default_rng(3)
    M, n = 1000, 400
    pref = np.zeros(M + 1)
    knots = np.sort(rng.integers(1, ctrl.n_preview, size=4))
    for k, v in zip(knots, rng.uniform(-0.1, 0.1, size=4)):
        pref[k:] += v
    du = batch_optimal_jerk_increments(T, Z_C, 1.0, 1e-6, np.zeros(3), 0.0, pref, M)
    A, B, C = cart_table(T, Z_C)
    X, u, com_batch = np.zeros(3), 0.0, []
    for i in range(n):
        com_batch.append(X[0])
        u += du[i]
        X = A @ X + B * u
    ref2 = np.stack([pref[:n], -pref[:n]], axis=1)   # second axis mirrored: the axes must be independent
    res = ctrl.run(ref2, np.zeros((3, 2)))
    # 1e-8 m: both are exact solutions of the same optimum; the differences are the batch's lstsq round-off
    np.testing.assert_allclose(res.com[:, 0], com_batch, atol=1e-8)
    np.testing.assert_allclose(res.com[:, 1], -np.array(com_batch), atol=1e-8)


# ------------------------------------------------------------------------------------------------ tracking
def test_tracks_the_walk_reference_within_10_mm_in_single_support_at_1_6_s(ctrl):
    times, ref, ss = walk_reference()
    res = ctrl.run(ref)
    err = res.zmp_error
    assert err[ss].max() < 0.010   # the acceptance bound
    # the CoM sways sideways, less than the feet's +-0.1 m (measured +-81 mm; design.md noted ~+-60 mm)
    assert 0.04 < np.ptp(res.com[:, 0]) / 2 < 0.1


def test_tracking_error_grows_as_the_horizon_shrinks():
    times, ref, ss = walk_reference()
    errs = [CartTablePreview(T, Z_C, h).run(ref).zmp_error[ss].max() for h in (1.6, 0.8, 0.4)]
    assert errs[0] < errs[1] < errs[2]
    # at 0.4 s the preview is shorter than a step (0.8 s): the error is a large part of the 0.2 m step width
    assert errs[2] > 0.05


def test_zmp_is_x_minus_zc_over_g_times_the_finite_difference_acceleration(ctrl):
    """The model's ZMP C X equals x - z_c/g x'' with x'' from the produced CoM positions alone.  Over one sample
    the CoM is a cubic, so the central second difference is exactly x''(k) + T/6 (u(k) - u(k-1))."""
    times, ref, _ = walk_reference()
    res = ctrl.run(ref)
    x = res.com
    fd2 = (x[2:] - 2 * x[1:-1] + x[:-2]) / T ** 2
    zmp_fd = x[1:-1] - Z_C / G * fd2
    predicted = res.zmp[1:-1] - Z_C / G * T / 6 * np.diff(res.jerk, axis=0)[:-1]
    # 1e-9 m: fd2 divides position round-off (~1e-16 m) by T^2 = 1e-4 and the CoM moves ~2 m (ulp 4e-16)
    np.testing.assert_allclose(zmp_fd, predicted, atol=1e-9)
    # the O(T) term is sub-millimetre (largest in the start-up transient, ~1 mm)
    assert np.max(np.abs(zmp_fd - res.zmp[1:-1])) < 2e-3
    # and the logged velocity / acceleration are those of the positions (exact for the piecewise cubic)
    np.testing.assert_allclose(res.com_a[1:], res.com_a[:-1] + T * res.jerk[:-1], atol=1e-12)
    np.testing.assert_allclose(res.com[1:], res.com[:-1] + T * res.com_v[:-1] + T * T / 2 * res.com_a[:-1]
                               + T ** 3 / 6 * res.jerk[:-1], atol=1e-12)


def test_plan_is_invariant_under_a_translation_of_the_reference(ctrl):
    times, ref, _ = walk_reference(n_steps=4)
    a = ctrl.run(ref)
    shift = np.array([3.0, -250.0])
    b = ctrl.run(ref + shift)
    # 1e-9 m: the same arithmetic on numbers up to 250 m (ulp ~3e-14) accumulated over ~500 steps
    np.testing.assert_allclose(b.com - shift, a.com, atol=1e-9)


def test_standing_reference_keeps_the_com_at_rest(ctrl):
    ref = np.tile([0.05, 1.3], (300, 1))
    res = ctrl.run(ref)
    np.testing.assert_allclose(res.com, ref, atol=1e-12)
    assert np.max(np.abs(res.com_v)) < 1e-12


def test_reference_beyond_the_end_is_held_at_its_last_value(ctrl):
    times, ref, _ = walk_reference(n_steps=3)
    padded = np.concatenate([ref, np.repeat(ref[-1:], 500, axis=0)])
    a, b = ctrl.run(ref), ctrl.run(padded)
    np.testing.assert_array_equal(a.com, b.com[:len(ref)])


def test_sixty_second_plan_tracks_to_its_end(ctrl):
    """A 60 s walk plans in one run (its time is bench.py's ``gaits.zmp_preview.plan_s`` business, not a test's)
    and tracks at its end as in its middle: the servo's integral state does not wind up over 75 steps."""
    times, ref, ssp = walk_reference(n_steps=75)
    assert times[-1] >= 59.0
    err = CartTablePreview(T, Z_C).run(ref).zmp_error
    middle, end = err[(times > 20.0) & (times < 30.0) & ssp], err[(times > times[-1] - 10.0) & ssp]
    assert end.max() <= 0.010                      # the single-support bound
    # the same steps repeat, so the steady state repeats: 1e-6 m allows the round-off of 6000 servo steps
    assert abs(end.max() - middle.max()) < 1e-6


# ------------------------------------------------------------------------------------------------ input errors
@pytest.mark.parametrize("kw, fragment", [
    ({"T": 0.0}, "T: expected a finite number > 0"),
    ({"T": float("nan")}, "T: expected a finite number > 0"),
    ({"z_c": -0.9}, "z_c: expected a finite number > 0"),
    ({"horizon_s": 0.005}, "horizon_s: expected >= T"),
    ({"R": 0.0}, "R: expected a finite number > 0"),
    ({"Qx": -1.0}, "Qx: expected a finite number >= 0"),
    ({"T": "fast"}, "T: expected a positive number, got 'fast'"),
])
def test_bad_parameters_are_named(kw, fragment):
    args = {"T": T, "z_c": Z_C, **kw}
    with pytest.raises(GaitError, match=fragment):
        CartTablePreview(**args)


@pytest.mark.parametrize("ref, x0, fragment", [
    (np.zeros((10, 3)), None, r"zmp_ref: expected an \(N, 2\) array.*shape \(10, 3\)"),
    (np.zeros((0, 2)), None, "zmp_ref: expected at least one sample"),
    (np.array([[0.0, 0.0], [np.nan, 0.0]]), None, r"zmp_ref: expected finite values, got nan at index \(1, 0\)"),
    (np.zeros((10, 2)), np.zeros((2, 2)), r"x0: expected a \(3, 2\) array"),
    (np.zeros((10, 2)), np.full((3, 2), np.inf), "x0: expected finite values"),
])
def test_bad_run_inputs_are_named(ctrl, ref, x0, fragment):
    with pytest.raises(GaitError, match=fragment):
        ctrl.run(ref, x0)


def test_result_type(ctrl):
    res = ctrl.run(np.zeros((5, 2)))
    assert isinstance(res, PreviewResult)
    assert res.com.shape == res.com_v.shape == res.com_a.shape == res.zmp.shape == res.jerk.shape == (5, 2)
