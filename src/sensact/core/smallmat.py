"""Small dense linear algebra for compiled per-step loops (n <= 6).

LAPACK's call overhead dominates at these sizes inside a 27,000-step loop, so the E-step uses these
hand-written kernels on preallocated work arrays. Every function works on the leading ``n`` block of
its arguments and allocates nothing.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def cholesky_shifted(A, shift, L, n, floor):
    """Lower-triangular ``L`` with ``L L' = A[:n, :n] + shift I``. Returns False if a pivot is not finite
    and above ``floor`` (the matrix is not numerically positive definite)."""
    for j in range(n):
        s = A[j, j] + shift
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not (s > floor) or not np.isfinite(s):
            return False
        d = s**0.5
        L[j, j] = d
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
        for i in range(j):
            L[i, j] = 0.0
    return True


@njit(cache=True, error_model="numpy")
def cholesky(A, L, n):
    """Lower-triangular ``L`` with ``L L' = A[:n, :n]``. Returns False if ``A`` is not positive definite."""
    return cholesky_shifted(A, 0.0, L, n, 0.0)


@njit(cache=True, error_model="numpy")
def cholesky_solve_vec(L, b, x, n):
    """``x = (L L')^-1 b``; ``x`` may alias ``b``."""
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * x[k]
        x[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]


@njit(cache=True, error_model="numpy")
def forward_substitute(L, B, n, m):
    """``B <- L^-1 B`` for the lower-triangular ``L`` (``n x n``) and ``B`` (``n x m``)."""
    for j in range(m):
        for i in range(n):
            s = B[i, j]
            for k in range(i):
                s -= L[i, k] * B[k, j]
            B[i, j] = s / L[i, i]


@njit(cache=True, error_model="numpy")
def cholesky_inverse(L, out, col, n):
    """``out = (L L')^-1`` using the work vector ``col``."""
    for j in range(n):
        for i in range(n):
            col[i] = 1.0 if i == j else 0.0
        cholesky_solve_vec(L, col, col, n)
        for i in range(n):
            out[i, j] = col[i]


@njit(cache=True, error_model="numpy")
def lu_solve_inplace(A, B, n, m):
    """Solve ``A X = B`` for a general ``n x n`` ``A`` (partial pivoting) and ``n x m`` ``B``.

    ``A`` and ``B`` are overwritten; ``B`` holds ``X`` on return. Returns False if ``A`` is singular.
    """
    for k in range(n):
        p = k
        best = abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > best:
                best = abs(A[i, k])
                p = i
        if not best > 0.0:
            return False
        if p != k:
            for j in range(n):
                A[k, j], A[p, j] = A[p, j], A[k, j]
            for j in range(m):
                B[k, j], B[p, j] = B[p, j], B[k, j]
        for i in range(k + 1, n):
            f = A[i, k] / A[k, k]
            if f != 0.0:
                for j in range(k, n):
                    A[i, j] -= f * A[k, j]
                for j in range(m):
                    B[i, j] -= f * B[k, j]
    for i in range(n - 1, -1, -1):
        for j in range(m):
            s = B[i, j]
            for k in range(i + 1, n):
                s -= A[i, k] * B[k, j]
            B[i, j] = s / A[i, i]
    return True


@njit(cache=True, error_model="numpy")
def add_sandwich(A, B, out, tmp, n):
    """``out += A B A'`` for ``n x n`` matrices, using the work array ``tmp``."""
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                s += A[i, k] * B[k, j]
            tmp[i, j] = s
    for i in range(n):
        for j in range(n):
            s = out[i, j]
            for k in range(n):
                s += tmp[i, k] * A[j, k]
            out[i, j] = s


@njit(cache=True, error_model="numpy")
def symmetrize(A, n):
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (A[i, j] + A[j, i])
            A[i, j] = v
            A[j, i] = v
