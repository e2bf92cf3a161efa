"""Small dense linear algebra for the compiled twins (numba): copies into slices, products, solves.

Loops instead of NumPy's operators: numba's ``@`` goes through BLAS (~1 us a call at these sizes) and its slice
assignment also compiles the code that formats its shape-mismatch message; the loops are exact either way.  The
solves mirror LAPACK's (Cholesky as ``posv``, Gaussian elimination with partial pivoting as ``gesv``) as the NumPy
reference paths call them.  All arrays float64.
"""

from __future__ import annotations

import numpy as np

from humanoid_sim.jit import njit


@njit
def put(dst: np.ndarray, o: int, src: np.ndarray) -> None:
    """dst[o:o + src.size] = src (1-D arrays)."""
    for i in range(src.size):
        dst[o + i] = src[i]


@njit
def put_flat(dst: np.ndarray, o: int, src: np.ndarray) -> None:
    """dst[o:o + src.size] = src.ravel() (src 2-D, row-major order)."""
    n, m = src.shape
    for i in range(n):
        for j in range(m):
            dst[o + i * m + j] = src[i, j]


@njit
def put_col(dst: np.ndarray, r: int, c: int, src: np.ndarray) -> None:
    """dst[r:r + src.size, c] = src."""
    for i in range(src.size):
        dst[r + i, c] = src[i]


@njit
def put_block(dst: np.ndarray, r: int, c: int, src: np.ndarray) -> None:
    """dst[r:r + src.shape[0], c:c + src.shape[1]] = src."""
    n, m = src.shape
    for i in range(n):
        for j in range(m):
            dst[r + i, c + j] = src[i, j]


@njit
def mm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A B for small matrices (explicit loops: numba's ``@`` goes through BLAS, ~1 us per call at these sizes)."""
    n, k = A.shape
    m = B.shape[1]
    out = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for l in range(k):
                s += A[i, l] * B[l, j]
            out[i, j] = s
    return out


@njit
def mtm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A^T B for small matrices (:func:`mm` of the transposed view)."""
    return mm(A.T, B)


@njit
def mv(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A x for a small matrix."""
    n, k = A.shape
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for l in range(k):
            s += A[i, l] * x[l]
        out[i] = s
    return out


@njit
def mtv(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A^T x for a small matrix (:func:`mv` of the transposed view)."""
    return mv(A.T, x)


@njit
def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of 3-vectors."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit
def symmetric(M_upper: np.ndarray) -> np.ndarray:
    """The symmetric joint-space inertia from the upper triangle crba fills."""
    nv = M_upper.shape[0]
    M = M_upper.copy()
    for i in range(nv):
        for k in range(i):
            M[i, k] = M_upper[k, i]
    return M


@njit
def cols_times(J: np.ndarray, cols: np.ndarray, x: np.ndarray) -> np.ndarray:
    """J[:, cols] @ x."""
    out = np.zeros(J.shape[0])
    for i in range(cols.size):
        out += J[:, cols[i]] * x[i]
    return out


@njit
def cholesky_solve(Z: np.ndarray, g: np.ndarray) -> np.ndarray:
    """x with Z x = g for symmetric positive definite Z (lower Cholesky factor, as LAPACK posv); NaNs when Z is
    not positive definite (the caller reports it)."""
    n = g.size
    L = np.zeros((n, n))
    for j in range(n):
        s = Z[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return np.full(n, np.nan)
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            s = Z[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    y = np.empty(n)
    for i in range(n):
        s = g[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x


@njit
def solve3(B: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with B x = b for a 3 x 3 B (Gaussian elimination, partial pivoting)."""
    A = B.copy()
    x = b.copy()
    for c in range(3):
        piv = c
        for r in range(c + 1, 3):
            if abs(A[r, c]) > abs(A[piv, c]):
                piv = r
        if piv != c:
            for k in range(3):
                A[c, k], A[piv, k] = A[piv, k], A[c, k]
            x[c], x[piv] = x[piv], x[c]
        for r in range(c + 1, 3):
            f = A[r, c] / A[c, c]
            for k in range(c, 3):
                A[r, k] -= f * A[c, k]
            x[r] -= f * x[c]
    for c in range(2, -1, -1):
        s = x[c]
        for k in range(c + 1, 3):
            s -= A[c, k] * x[k]
        x[c] = s / A[c, c]
    return x


@njit
def solve_dense(K: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with K x = b (Gaussian elimination with partial pivoting, as LAPACK gesv); NaNs when K is singular."""
    n = b.size
    A = K.copy()
    x = b.copy()
    for c in range(n):
        piv = c
        for rr in range(c + 1, n):
            if abs(A[rr, c]) > abs(A[piv, c]):
                piv = rr
        if A[piv, c] == 0.0:
            return np.full(n, np.nan)
        if piv != c:
            for k in range(n):
                A[c, k], A[piv, k] = A[piv, k], A[c, k]
            x[c], x[piv] = x[piv], x[c]
        for rr in range(c + 1, n):
            f = A[rr, c] / A[c, c]
            if f != 0.0:
                for k in range(c, n):
                    A[rr, k] -= f * A[c, k]
                x[rr] -= f * x[c]
    for c in range(n - 1, -1, -1):
        acc = x[c]
        for k in range(c + 1, n):
            acc -= A[c, k] * x[k]
        x[c] = acc / A[c, c]
    return x
