"""ZMP preview control of the cart-table model (Kajita et al. 2003, after Katayama et al. 1985).

Per horizontal world axis (x lateral, y forward), the centre of mass moves as a cart on a table of height z_c:

    X = [x, x_dot, x_ddot] (m, m/s, m/s^2),  u = x_dddot (m/s^3, the input),
    X(k+1) = A X(k) + B u(k),  A = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]],  B = [T^3/6, T^2/2, T],
    p(k) = C X(k),  C = [1, 0, -z_c/g]          (the model's ZMP on the ground, m).

The servo controller minimises  sum Qe e(i)^2 + dX(i)' Qx dX(i) + R du(i)^2  with e = p - p_ref and
dX(i) = X(i) - X(i-1), du(i) = u(i) - u(i-1), over the augmented state [e; dX]:

    A~ = [[1, C A], [0, A]],  B~ = [C B; B],  I~ = [1; 0; 0; 0],  Q~ = diag(Qe, Qx I3),
    P = DARE(A~, B~, Q~, R),  K = (R + B~' P B~)^-1 B~' P A~ = [Gi, Gx],
    Gd_1 = -Gi,  Gd_j = (R + B~' P B~)^-1 B~' X~_(j-1),  X~_1 = -Ac~' P I~,  X~_j = Ac~' X~_(j-1),  Ac~ = A~ - B~ K,

and the control law is the optimal increment  du(k) = -Gi e(k) - Gx dX(k) - sum_(j=1..N_L) Gd_j dp_ref(k+j),  summed:

    u(k) = u0 - Gi sum_(i<=k) e(i) - Gx X(k) - sum_(j=1..N_L) Gd_j p_ref(k+j),
    u0 = u(-1) + Gx X(-1) + sum_(j=1..N_L) Gd_j p_ref(j-1),  u(-1) = 0,  X(-1) = A^-1 X(0),

i.e. Kajita's law with its integrator started so that the motion before k = 0 is jerk-free.  Kajita's u0 = 0
is not translation invariant: the truncated preview sum  sum Gd_j  differs from -Gx[0] (by ~0.6 % at 1.6 s), so a
walk at rest far from the origin would start with a jerk proportional to its distance from the origin.
The reference beyond its last sample is held at its last value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.lib.stride_tricks import sliding_window_view

from .errors import GaitError

GRAVITY = 9.81
"""m/s^2, the simulator's gravity (models/thesis_humanoid.yaml)."""


def _positive(name: str, value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise GaitError(f"{name}: expected a positive number, got {value!r}") from None
    if not (np.isfinite(v) and v > 0.0):
        raise GaitError(f"{name}: expected a finite number > 0, got {value!r}")
    return v


def _nonnegative(name: str, value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise GaitError(f"{name}: expected a number >= 0, got {value!r}") from None
    if not (np.isfinite(v) and v >= 0.0):
        raise GaitError(f"{name}: expected a finite number >= 0, got {value!r}")
    return v


def _finite_array(name: str, value: object, shape: tuple[int | None, ...], what: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise GaitError(f"{name}: expected {what}, got {type(value).__name__}") from None
    if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
        raise GaitError(f"{name}: expected {what}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise GaitError(f"{name}: expected finite values, got {a[tuple(bad)]} at index {tuple(int(i) for i in bad)}")
    return a


@dataclass(frozen=True)
class PreviewResult:
    """Output of :meth:`CartTablePreview.run`, one row per sample k (time k T from the first reference sample).

    com, com_v, com_a: (N, 2) horizontal world CoM position (m), velocity (m/s), acceleration (m/s^2), x and y;
    jerk: (N, 2) the applied input u(k) (m/s^3); zmp: (N, 2) the cart-table ZMP C X(k) on the ground (m);
    zmp_ref: (N, 2) the reference it tracked (m).
    """

    com: np.ndarray
    com_v: np.ndarray
    com_a: np.ndarray
    jerk: np.ndarray
    zmp: np.ndarray
    zmp_ref: np.ndarray

    @property
    def zmp_error(self) -> np.ndarray:
        """(N,) horizontal distance between the model ZMP and its reference, m."""
        return np.linalg.norm(self.zmp - self.zmp_ref, axis=1)


class CartTablePreview:
    """Kajita's servo preview controller for the cart-table model, the same gains on both horizontal axes.

    T: sample time (s); z_c: table height = CoM height (m); horizon_s: preview length (s), N_L = round(horizon_s / T)
    samples; Qe, Qx, R: weights of the ZMP error, the state increment and the jerk increment; g: gravity (m/s^2).
    Attributes after construction: A (3, 3), B (3,), C (3,), P (4, 4) the Riccati solution, Gi (float),
    Gx (3,), Gd (N_L,) with Gd[j - 1] = Gd_j.
    """

    def __init__(self, T: float, z_c: float, horizon_s: float = 1.6, Qe: float = 1.0, Qx: float = 0.0,
                 R: float = 1e-6, g: float = GRAVITY) -> None:
        self.T = _positive("T", T)
        self.z_c = _positive("z_c", z_c)
        self.horizon_s = _positive("horizon_s", horizon_s)
        if self.horizon_s < self.T:
            raise GaitError(f"horizon_s: expected >= T = {self.T} s, got {horizon_s!r}")
        self.Qe = _positive("Qe", Qe)
        self.Qx = _nonnegative("Qx", Qx)
        self.R = _positive("R", R)
        self.g = _positive("g", g)
        self.n_preview = int(round(self.horizon_s / self.T))
        T_ = self.T
        self.A = np.array([[1.0, T_, T_ * T_ / 2.0], [0.0, 1.0, T_], [0.0, 0.0, 1.0]])
        self.B = np.array([T_ ** 3 / 6.0, T_ * T_ / 2.0, T_])
        self.C = np.array([1.0, 0.0, -self.z_c / self.g])
        At = np.zeros((4, 4))
        At[0, 0] = 1.0
        At[0, 1:] = self.C @ self.A
        At[1:, 1:] = self.A
        Bt = np.concatenate(([self.C @ self.B], self.B))[:, None]
        Qt = np.diag([self.Qe, self.Qx, self.Qx, self.Qx])
        try:
            P = scipy.linalg.solve_discrete_are(At, Bt, Qt, np.array([[self.R]]))
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise GaitError(f"preview gains: the Riccati equation has no stabilising solution for T={self.T}, "
                            f"z_c={self.z_c}, Qe={self.Qe}, Qx={self.Qx}, R={self.R} ({exc})") from None
        self.P = P
        s = float(self.R + (Bt.T @ P @ Bt)[0, 0])
        K = (Bt.T @ P @ At)[0] / s
        self.Gi = float(K[0])
        self.Gx = K[1:].copy()
        Act = (At - Bt @ K[None, :]).T
        Gd = np.empty(self.n_preview)
        Gd[0] = -self.Gi
        X = -Act @ P[:, 0]   # I~ = e_1, so P I~ is P's first column
        for j in range(1, self.n_preview):
            Gd[j] = float(Bt[:, 0] @ X) / s
            X = Act @ X
        self.Gd = Gd

    # ------------------------------------------------------------------------------------------------ run
    def preview_term(self, zmp_ref: np.ndarray) -> np.ndarray:
        """(N, 2) feed-forward sum_(j=1..N_L) Gd_j p_ref(k+j) for every sample k, the reference held at its end."""
        n = len(zmp_ref)
        padded = np.concatenate((zmp_ref[1:], np.repeat(zmp_ref[-1:], self.n_preview, axis=0)))
        windows = sliding_window_view(padded, self.n_preview, axis=0)[:n]   # (N, 2, N_L): p_ref(k+1 .. k+N_L)
        return windows @ self.Gd

    def run(self, zmp_ref: np.ndarray, x0: np.ndarray | None = None) -> PreviewResult:
        """Plan the CoM for a ZMP reference.

        zmp_ref: (N, 2) world ZMP reference (x, y) at times k T, m.  x0: (3, 2) initial state [position; velocity;
        acceleration] of the CoM per axis (m, m/s, m/s^2); default: at rest above zmp_ref[0].
        """
        ref = _finite_array("zmp_ref", zmp_ref, (None, 2), "an (N, 2) array of world x, y ZMP positions in m")
        if len(ref) == 0:
            raise GaitError("zmp_ref: expected at least one sample, got shape (0, 2)")
        if x0 is None:
            X = np.zeros((3, 2))
            X[0] = ref[0]
        else:
            X = _finite_array("x0", x0, (3, 2), "a (3, 2) array [position; velocity; acceleration] per axis").copy()
        n = len(ref)
        ff = self.preview_term(ref)
        A, B, C, Gi, Gx = self.A, self.B, self.C, self.Gi, self.Gx
        X_prev = np.linalg.solve(A, X)   # X(-1) with u(-1) = 0
        u0 = Gx @ X_prev + self.preview_term(np.concatenate((ref[:1], ref)))[0]  # sum Gd_j p_ref(j - 1)
        com = np.empty((n, 3, 2))
        jerk = np.empty((n, 2))
        e_sum = np.zeros(2)
        for k in range(n):
            com[k] = X
            e_sum += C @ X - ref[k]
            u = u0 - Gi * e_sum - Gx @ X - ff[k]
            jerk[k] = u
            X = A @ X + np.outer(B, u)
        zmp = np.einsum("j,kjl->kl", C, com)
        return PreviewResult(com=com[:, 0].copy(), com_v=com[:, 1].copy(), com_a=com[:, 2].copy(), jerk=jerk,
                             zmp=zmp, zmp_ref=ref.copy())
