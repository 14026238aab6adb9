"""Batch weighted polynomial least squares (sec. 2.3, eq. 2.11; weighted form eq. 3.3).

Polynomials are kept in a normalized variable ``u = (x - center) / scale`` so that the normal equations
stay well conditioned at degree 4 and beyond; ``affine_basis_matrix`` moves coefficients between two
normalizations exactly.
"""

from __future__ import annotations

from math import comb

import numpy as np


def vander(u: np.ndarray, degree: int) -> np.ndarray:
    """Columns ``u**0 .. u**degree`` (ascending powers), shape ``(n, degree + 1)``."""
    u = np.asarray(u, dtype=float)
    return u[:, None] ** np.arange(degree + 1)


def polyval(coef: np.ndarray, u: np.ndarray | float) -> np.ndarray:
    """Evaluate ascending coefficients at ``u`` by Horner's rule."""
    u = np.asarray(u, dtype=float)
    out = np.zeros_like(u)
    for c in np.asarray(coef, dtype=float)[::-1]:
        out = out * u + c
    return out


def weighted_polyfit(
    x: np.ndarray,
    y: np.ndarray,
    degree: int,
    weights: np.ndarray | None = None,
    *,
    center: float = 0.0,
    scale: float = 1.0,
) -> np.ndarray:
    """Minimize ``sum_i w_i (y_i - p(u_i))**2`` over ascending coefficients of ``p`` (eq. 3.3).

    Solved with ``lstsq`` on rows scaled by ``sqrt(w)``, which is better conditioned than forming
    ``X'DX`` explicitly.
    """
    u = (np.asarray(x, dtype=float) - center) / scale
    return weighted_lstsq(vander(u, degree), y, weights)


def weighted_lstsq(X: np.ndarray, y: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Minimize ``sum_i w_i (y_i - X_i c)**2`` by ``lstsq`` on rows scaled by ``sqrt(w)``."""
    y = np.asarray(y, dtype=float)
    if weights is not None:
        sw = np.sqrt(np.asarray(weights, dtype=float))
        X = X * sw[:, None]
        y = y * sw
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    return coef


def solve_scaled_gram(gram: np.ndarray, rhs: np.ndarray, max_cond: float = 1e10) -> np.ndarray | None:
    """``c`` with ``gram c = rhs`` (``gram = X'WX``, ``rhs = X'Wy``), the columns scaled to unit norm
    first, which for a few columns and tens of thousands of rows is several times faster than
    ``weighted_lstsq`` on the rows. None when the scaled system's condition number reaches ``max_cond``,
    where forming ``X'WX`` loses digits, so that the caller solves from the rows instead (EM's action
    M-step forms these sums once for every command delay). Unlike ``core.recursive``'s
    ``solve_normal_equations`` (the online learner's, compiled, with a ridge retry) it never regularizes."""
    coef, ok = solve_scaled_grams(gram[None], rhs[None], max_cond)
    return coef[0] if ok[0] else None


def solve_scaled_grams(grams: np.ndarray, rhs: np.ndarray, max_cond: float = 1e10) -> tuple[np.ndarray, np.ndarray]:
    """``solve_scaled_gram`` on a stack of systems, ``(B, c, c)`` and ``(B, c)``, in one call each to
    numpy's batched SVD and solve: the solutions (NaN rows where not solved) and which were solved."""
    scale = np.sqrt(np.diagonal(grams, axis1=1, axis2=2))
    scale = np.where(scale == 0, 1.0, scale)
    G = grams / (scale[:, :, None] * scale[:, None, :])
    with np.errstate(divide="ignore", invalid="ignore"):  # a singular system's condition number is inf
        ok = np.linalg.cond(G) < max_cond
    out = np.full(rhs.shape, np.nan)
    if ok.any():
        out[ok] = np.linalg.solve(G[ok], (rhs[ok] / scale[ok])[..., None])[..., 0] / scale[ok]
    return out, ok


def affine_basis_matrix(degree: int, a: float, b: float) -> np.ndarray:
    """``M`` with ``vander(a*u + b) == vander(u) @ M.T`` for every ``u``.

    Row ``k`` expands ``(a u + b)**k = sum_j C(k, j) a**j b**(k-j) u**j``. Coefficients ``c'`` in the
    new variable ``u' = a u + b`` and ``c`` in ``u`` describe the same polynomial when ``c = M.T @ c'``.
    """
    M = np.zeros((degree + 1, degree + 1))
    for k in range(degree + 1):
        for j in range(k + 1):
            M[k, j] = comb(k, j) * a**j * b ** (k - j)
    return M


def renormalize(coef: np.ndarray, center: float, scale: float, new_center: float, new_scale: float) -> np.ndarray:
    """Coefficients of the same polynomial in ``(x - new_center) / new_scale``."""
    coef = np.asarray(coef, dtype=float)
    # u = (x - c)/s = (s'/s) u' + (c' - c)/s
    M = affine_basis_matrix(len(coef) - 1, new_scale / scale, (new_center - center) / scale)
    return M.T @ coef


def best_fit_rms(x: np.ndarray, y: np.ndarray, degree: int) -> float:
    """RMS residual of the best unweighted polynomial of ``degree`` through ``(x, y)``; NaN with no points."""
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return float("nan")
    center, scale = 0.5 * (x.max() + x.min()), max(0.5 * (x.max() - x.min()), 1e-300)
    coef = weighted_polyfit(x, y, degree, center=center, scale=scale)
    resid = np.asarray(y, dtype=float) - polyval(coef, (x - center) / scale)
    return float(np.sqrt(np.mean(resid**2)))
