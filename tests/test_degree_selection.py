"""Sec. 3.3.3: the online degree rule picks the true degree of a noisy polynomial."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.core.degree import N_STATS, misfit_ratio, select_degree, stats_add


def _sweep(n: int, seed: int) -> np.ndarray:
    """x moving slowly back and forth, as a robot's observations do."""
    rng = np.random.default_rng(seed)
    return np.interp(np.linspace(0, 12, n), np.arange(13), rng.uniform(-1, 1, 13) * 0.2 + np.tile([-1, 1], 7)[:13])


@pytest.mark.parametrize("true_degree", [1, 2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_picks_the_true_degree(true_degree, seed):
    rng = np.random.default_rng(100 + seed)
    coef = {1: [0.5, 2.0], 2: [0.5, 2.0, 1.5], 3: [0.5, 2.0, 1.5, -1.2]}[true_degree]
    x = _sweep(6000, seed)
    y = np.polyval(coef[::-1], x) + rng.normal(0, 0.3, x.size)
    degree, trace = select_degree(x, y, n_warmup=400, n_eval=800)
    assert degree == true_degree
    assert trace[-1] == degree and np.all(np.diff(trace) >= 0)


def test_ratio_is_one_for_white_residuals_and_large_for_a_misfit():
    rng = np.random.default_rng(5)
    white, ring = np.zeros(N_STATS), np.zeros(1)
    for r in rng.normal(size=5000):
        stats_add(white, ring, 1, r, 0.999)
    assert misfit_ratio(white) == pytest.approx(1.0, abs=0.15)
    biased, ring = np.zeros(N_STATS), np.zeros(1)
    for k, r in enumerate(rng.normal(size=5000)):
        stats_add(biased, ring, 1, r + 2.0 * np.sin(k / 200.0), 0.999)
    assert misfit_ratio(biased) > 2.0
