"""Regression core (sec. 2.3, 3.2): exact reductions to batch least squares and independent references."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.core.polyfit import (
    affine_basis_matrix,
    best_fit_rms,
    polyval,
    renormalize,
    solve_scaled_gram,
    solve_scaled_grams,
    vander,
    weighted_lstsq,
    weighted_polyfit,
)
from sensact.core.recursive import RecursivePolyFit, accumulate_vector, shift_features, solve_spd


def test_weighted_polyfit_matches_numpy_polyfit():
    rng = np.random.default_rng(0)
    x = rng.uniform(-3, 5, 200)
    y = 1.0 - 2.0 * x + 0.3 * x**3 + rng.normal(0, 0.5, x.size)
    w = rng.uniform(0.1, 2.0, x.size)
    ours = weighted_polyfit(x, y, 3, w)
    # numpy weights multiply the residuals, so they are sqrt of ours; it returns descending powers
    ref = np.polyfit(x, y, 3, w=np.sqrt(w))[::-1]
    np.testing.assert_allclose(ours, ref, rtol=1e-9, atol=1e-12)


def test_scaled_gram_solve_matches_the_svd_one_and_refuses_when_singular():
    rng = np.random.default_rng(3)
    # columns of very different size (an intercept, mm/s, rad/s), as in the action M-step
    X = np.column_stack([np.ones(5000), rng.uniform(0, 300, 5000), rng.uniform(-1, 1, 5000)])
    y = X @ [5.0, 0.9, 30.0] + rng.normal(size=5000)
    w = rng.uniform(0.1, 2.0, 5000)
    Xw = X * w[:, None]
    np.testing.assert_allclose(solve_scaled_gram(X.T @ Xw, Xw.T @ y), weighted_lstsq(X, y, w), rtol=1e-9)
    singular = np.column_stack([X, 2 * X[:, 1]])  # left to the caller, who solves from the rows
    Sw = singular * w[:, None]
    assert solve_scaled_gram(singular.T @ Sw, Sw.T @ y) is None
    # batched, a singular system among them: the others as solved one at a time, the singular one flagged
    Xs = [X, X[::2], np.column_stack([X[:, :2], X[:, 1]])]
    grams = np.stack([A.T @ A for A in Xs])
    rhs = np.stack([A.T @ y[: len(A)] for A in Xs])
    coef, ok = solve_scaled_grams(grams, rhs)
    np.testing.assert_array_equal(ok, [True, True, False])
    for k in (0, 1):
        np.testing.assert_allclose(coef[k], weighted_lstsq(Xs[k], y[: len(Xs[k])], np.ones(len(Xs[k]))), rtol=1e-9)
    assert np.isnan(coef[2]).all()


def test_affine_basis_matrix_is_exact():
    u = np.linspace(-2, 3, 17)
    a, b = 0.7, -1.3
    M = affine_basis_matrix(4, a, b)
    np.testing.assert_allclose(vander(a * u + b, 4), vander(u, 4) @ M.T, rtol=1e-12, atol=1e-12)


def test_renormalize_keeps_the_polynomial():
    coef = np.array([0.3, -1.2, 0.5, 2.0])
    x = np.linspace(10, 35, 11)
    new = renormalize(coef, 20.0, 10.0, 3.0, 0.25)
    np.testing.assert_allclose(polyval(new, (x - 3.0) / 0.25), polyval(coef, (x - 20.0) / 10.0), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("gamma", [1.0, 0.999, 0.98])
def test_recursive_fit_equals_batch_lstsq_with_forgetting(gamma):
    """Sec. 3.2.3: the incremental sums give the weighted fit with weights gamma^(n-i), at degree 4."""
    rng = np.random.default_rng(1)
    n = 600
    x = 20 + 8 * np.sin(np.linspace(0, 9, n)) + rng.normal(0, 0.3, n)  # a robot-like slow sweep
    y = 4000.0 / x + rng.normal(0, 5, n)
    fit = RecursivePolyFit(4, gamma, center=20.0, scale=10.0)
    for xi, yi in zip(x, y, strict=True):
        fit.update(xi, yi)
    w = gamma ** (n - 1 - np.arange(n))
    ref = weighted_polyfit(x, y, 4, w, center=20.0, scale=10.0)
    np.testing.assert_allclose(fit.coef, ref, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(fit.predict(x), polyval(ref, (x - 20) / 10), rtol=1e-9)


def test_solve_spd_matches_numpy_and_refuses_indefinite():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(6, 6))
    G = A @ A.T + 0.1 * np.eye(6)
    h = rng.normal(size=6)
    out, L = np.zeros(6), np.zeros((6, 6))
    assert solve_spd(G, h, 6, 0.0, L, out)
    np.testing.assert_allclose(out, np.linalg.solve(G, h), rtol=1e-10)
    before = out.copy()
    assert not solve_spd(-G, h, 6, 0.0, L, out)
    np.testing.assert_array_equal(out, before)


def test_shift_features_keeps_every_coefficient_but_the_intercept():
    """Eq. 3.2's cumulative regressors can be re-based exactly: only w_0 changes."""
    rng = np.random.default_rng(3)
    n, q = 300, 4
    X = np.column_stack([np.ones(n), np.cumsum(rng.normal(size=(n, q - 1)), axis=0)])
    y = X @ np.array([2.0, 0.5, -1.0, 0.25]) + rng.normal(0, 0.1, n)
    G, h = np.zeros((q, q)), np.zeros(q)
    for i in range(n):
        accumulate_vector(G, h, X[i], y[i], 0.99, q)
    s = np.r_[0.0, X[-1, 1:]]
    shift_features(G, h, s, q)
    shifted = np.zeros(q)
    assert solve_spd(G, h, q, 0.0, np.zeros((q, q)), shifted)
    w = 0.99 ** (n - 1 - np.arange(n))
    Xs = X - s
    ref, *_ = np.linalg.lstsq(Xs * np.sqrt(w)[:, None], y * np.sqrt(w), rcond=None)
    np.testing.assert_allclose(shifted, ref, rtol=1e-8)
    orig, *_ = np.linalg.lstsq(X * np.sqrt(w)[:, None], y * np.sqrt(w), rcond=None)
    np.testing.assert_allclose(shifted[1:], orig[1:], rtol=1e-8)


def test_best_fit_rms_is_zero_for_an_exact_polynomial_and_scale_equivariant():
    x = np.linspace(-300, 300, 31)
    assert best_fit_rms(x, 2 + 0.1 * x - 1e-4 * x**2, 2) < 1e-9
    y = np.tanh(x / 100)
    assert best_fit_rms(x, 3 * y, 3) == pytest.approx(3 * best_fit_rms(x, y, 3), rel=1e-9)
    assert np.isnan(best_fit_rms(np.empty(0), np.empty(0), 3))  # a log that timed no command
