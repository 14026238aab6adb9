"""Sec. 5.1: the horizontal angles of a spinning lidar's lasers, from its own returns.

Two vertically adjacent lasers see nearly the same thing when they point the same way. Laser ``l`` at
time ``t - delta`` points where laser ``l-1`` points at ``t`` when ``delta = (theta_l - theta_l-1) / omega``,
so the lag that maximizes the normalized cross-correlation of their distance series (eq. 5.1), over the
times where both returned, gives the angle difference. The differences accumulate into ``theta'_l``, the
angles up to one common offset ``C`` (found from the car's motion in sec. 5.2).

The correlation at every lag from ``-pi/omega`` to ``pi/omega`` (in steps of ``1/f``) comes from six FFT
cross-correlations per pair (masked normalized cross-correlation); a test checks it against the direct
sum on small data.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import fft


@dataclass(frozen=True)
class IntrinsicsConfig:
    max_difference_deg: float | None = None  # the thesis's optional bound (23°) on adjacent differences
    subsample_peak: bool = True  # refine the argmax by a parabola through its neighbours
    min_pairs: int = 1000  # a lag needs this many valid pairs to count


@dataclass(frozen=True, eq=False)
class IntrinsicsResult:
    relative_rad: np.ndarray  # (n,) theta'_l by laser id; the lowest laser is 0
    differences_rad: np.ndarray  # (n-1,) theta_l - theta_l-1 in vertical order
    order: np.ndarray  # laser ids by increasing vertical angle
    peak_correlation: np.ndarray  # (n-1,)
    lags: np.ndarray  # (n-1,) the argmax lag in firings (fractional with subsample_peak)


def masked_ncc(a: np.ndarray, b: np.ndarray, max_lag: int, min_pairs: int = 1) -> np.ndarray:
    """``K(k) = corr(a[i], b[i - k])`` over ``i`` where both are valid (> 0), for ``k = -max_lag..max_lag``.

    Computed with FFTs; NaN where fewer than ``min_pairs`` pairs exist or a variance is zero.
    """
    n = fft.next_fast_len(a.size + max_lag + 1, real=True)
    ma = (a > 0).astype(float)
    mb = (b > 0).astype(float)
    xa = np.where(ma > 0, a, 0.0)
    xb = np.where(mb > 0, b, 0.0)
    F = {
        name: fft.rfft(v, n, workers=2)
        for name, v in (("ma", ma), ("xa", xa), ("xa2", xa * xa), ("mb", mb), ("xb", xb), ("xb2", xb * xb))
    }
    lags = np.arange(-max_lag, max_lag + 1)

    def xc(p: str, q: str) -> np.ndarray:
        r = fft.irfft(F[p] * np.conj(F[q]), n, workers=2)  # r[k] = sum_i p[i + k] q[i] = sum_i p[i] q[i - k]
        return r[lags % n]

    N = np.rint(xc("ma", "mb"))
    S1, S2 = xc("xa", "mb"), xc("ma", "xb")
    S11, S22, S12 = xc("xa2", "mb"), xc("ma", "xb2"), xc("xa", "xb")
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = S12 - S1 * S2 / N
        va = S11 - S1 * S1 / N
        vb = S22 - S2 * S2 / N
        k = cov / np.sqrt(va * vb)
    k[(N < min_pairs) | ~(va > 0) | ~(vb > 0)] = np.nan
    return k


def learn_relative_angles(
    distances: np.ndarray,
    vertical_rad: np.ndarray,
    firing_hz: float,
    omega_rad_s: float,
    config: IntrinsicsConfig | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> IntrinsicsResult:
    """``distances`` is (F, n): each firing's return of every laser (0 = none), firings 1/f apart."""
    cfg = config or IntrinsicsConfig()
    order = np.argsort(vertical_rad, kind="stable")
    # the angle the unit turns between firings, counterclockwise: a lag of k firings is k * step whichever
    # way the unit turns (a Velodyne turns clockwise, so step < 0 and the lags change sign, not the angles)
    step = omega_rad_s / firing_hz
    max_lag = int(np.floor(np.pi / abs(step)))
    if cfg.max_difference_deg is not None:
        max_lag = min(max_lag, int(np.ceil(np.radians(cfg.max_difference_deg) / abs(step))))
    n = len(order)
    diffs = np.zeros(n - 1)
    peaks = np.zeros(n - 1)
    lags = np.zeros(n - 1)
    for j in range(1, n):
        a = np.asarray(distances[:, order[j - 1]], dtype=float)
        b = np.asarray(distances[:, order[j]], dtype=float)
        K = masked_ncc(a, b, max_lag, cfg.min_pairs)
        i = int(np.nanargmax(K)) if np.isfinite(K).any() else max_lag
        best = float(i - max_lag)
        if cfg.subsample_peak and 0 < i < K.size - 1 and np.isfinite(K[i - 1 : i + 2]).all():
            den = K[i - 1] - 2 * K[i] + K[i + 1]
            if den < 0:
                best += 0.5 * (K[i - 1] - K[i + 1]) / den
        lags[j - 1] = best
        peaks[j - 1] = K[i] if np.isfinite(K[i]) else np.nan
        diffs[j - 1] = best * step
        if progress:
            progress("laser angles (sec. 5.1)", j, n - 1)
    rel = np.zeros(n)
    rel[order] = np.concatenate([[0.0], np.cumsum(diffs)])
    return IntrinsicsResult(rel, diffs, order, peaks, lags)
