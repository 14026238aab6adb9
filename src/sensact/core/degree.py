"""Automatic polynomial degree selection (sec. 3.3.3).

The thesis compares "a global prediction error and a local noise estimate" but gives no formula. Ours:

* **global prediction error** ``E_g``: the forgetting-weighted mean of the squared *prequential*
  residual ``r_n = y_n - p_{n-1}(x_n)`` (each point predicted by the fit before it is added);
* **local noise estimate** ``E_l``: the same weighted mean of ``(r_n - r_{n-L})**2 / 2``.

Log points ``L`` apart lie close together in ``x``, so a systematic misfit (bias) is nearly the same in
``r_n`` and ``r_{n-L}`` and cancels in the difference, while independent noise does not: white
residuals give ``E_g / E_l ~= 1`` and a degree that is too low gives ``E_g / E_l = 1 + bias^2 / noise^2``.
(This is the Durbin-Watson statistic's idea: ``E_l / E_g ~= DW / 2``.) The lag ``L`` is 1 for raw
points and the averaging window when the points are overlapping window means, whose noise is correlated
up to ``L - 1`` points apart. When the ratio exceeds ``threshold``, the degree is raised by one and the
fit restarts (sec. 3.3.3).
"""

from __future__ import annotations

import numpy as np
from numba import njit

# layout of the statistics vector
SUM_R2, SUM_DR2, COUNT = 0, 1, 2
N_STATS = 3


@njit(cache=True)
def stats_reset(stats):
    for i in range(stats.shape[0]):
        stats[i] = 0.0


@njit(cache=True)
def stats_add(stats, ring, lag, r, gamma):
    """Fold one prequential residual ``r`` into the weighted sums; ``ring[:lag]`` holds the last residuals."""
    n = int(stats[COUNT])
    i = n % lag
    if n >= lag:
        d = r - ring[i]
        stats[SUM_DR2] = gamma * stats[SUM_DR2] + 0.5 * d * d
        stats[SUM_R2] = gamma * stats[SUM_R2] + r * r
    ring[i] = r
    stats[COUNT] = n + 1.0


@njit(cache=True)
def restart_fit(G, h, stats):
    """Sec. 3.3.3: after raising the degree the regression starts again from no data."""
    for i in range(G.shape[0]):
        h[i] = 0.0
        for j in range(G.shape[1]):
            G[i, j] = 0.0
    stats_reset(stats)


@njit(cache=True)
def misfit_ratio(stats):
    """``E_g / E_l``; 1 for white residuals, larger when the polynomial misses structure."""
    if stats[SUM_DR2] <= 0.0:
        return np.nan
    return stats[SUM_R2] / stats[SUM_DR2]


@njit(cache=True)
def should_raise_degree(stats, n_eval, threshold):
    return stats[COUNT] >= n_eval and misfit_ratio(stats) > threshold


def select_degree(
    x: np.ndarray,
    y: np.ndarray,
    *,
    gamma: float = 0.999,
    start_degree: int = 1,
    max_degree: int = 6,
    n_warmup: int = 400,
    n_eval: int = 800,
    threshold: float = 1.3,
) -> tuple[int, np.ndarray]:
    """Run the online rule over a stream ``(x_n, y_n)`` in time order; return the final degree and the
    degree after each point. The chapter-3 learner runs the same rule inside its compiled loop."""
    from sensact.core.recursive import accumulate_poly, poly_eval, solve_normal_equations

    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    center = 0.5 * (np.max(x) + np.min(x))
    scale = max(0.5 * (np.max(x) - np.min(x)), 1e-300)
    P = max_degree + 1
    G, h, L, coef = np.zeros((P, P)), np.zeros(P), np.zeros((P, P)), np.zeros(P)
    stats, ring = np.zeros(N_STATS), np.zeros(1)
    degree, since = start_degree, 0
    out = np.empty(len(x), dtype=np.int64)
    for n in range(len(x)):
        u = (x[n] - center) / scale
        p = degree + 1
        if since >= n_warmup:
            stats_add(stats, ring, 1, y[n] - poly_eval(coef, u, p), gamma)
        accumulate_poly(G, h, u, y[n], gamma, p)
        since += 1
        solve_normal_equations(G, h, p, 1e-12, L, coef)
        if degree < max_degree and since >= n_warmup + n_eval and should_raise_degree(stats, 1, threshold):
            degree += 1
            restart_fit(G, h, stats)
            coef[:] = 0.0
            since = 0
        out[n] = degree
    return degree, out
