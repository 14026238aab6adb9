"""Sequential change detection on a stream of standardized scores (beyond the thesis, for sec. 4.4.3).

A stream is a score per reading that is N(0, 1) while the model holds (a standardized innovation, or
one weighted by its sensitivity to a parameter). It is summed into bins of fixed duration,
``b = sum(w u) / sqrt(sum(w^2))``, again N(0, 1) per bin under the model. Then:

* **scale**: a real log's innovations are correlated in time (the model never fits a real robot
  exactly), which a test that assumes independence reads as changes. The bins are divided by their
  long-run standard deviation, from the successive differences of batch sums (robust, by the median
  absolute difference, and blind to one step change, which moves a single difference); never below 1.
* **two-sided CUSUM** (Page 1954) with reference ``k``; its threshold ``h`` from Siegmund's
  approximation of the in-control run length, so that ``tests`` streams of ``n`` bins raise a false alarm
  with probability about ``false_alarm``.
* **persistence**: a crossing is a change only when the shift goes on: the bins from the CUSUM's change
  point (its last zero) to the end of the log must still sit off those before it (off zero, the model's
  expectation, when too few came before), beyond the normal quantile of ``false_alarm`` shared by the
  streams and both signs. A crossing that does not persist is an episode (a real log's burst of misfit
  after a gap in sightings, say), reported but not a change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.stats import norm

# Siegmund's correction for the CUSUM's overshoot of its threshold (Siegmund 1985, eq. 2.57)
OVERSHOOT = 1.166


def binned(u: np.ndarray, w: np.ndarray, t_s: np.ndarray, width_s: float, duration_s: float) -> np.ndarray:
    """Scores ``u`` (weights ``w``, times ``t_s``) summed into bins of ``width_s``: ``sum(w u) / sqrt(sum(w^2))``,
    NaN for a bin without weight."""
    n_bins = max(1, math.ceil(duration_s / width_s))
    idx = np.clip(np.floor(np.asarray(t_s) / width_s).astype(np.int64), 0, n_bins - 1)
    num = np.bincount(idx, weights=w * u, minlength=n_bins)
    den = np.sqrt(np.bincount(idx, weights=w * w, minlength=n_bins))
    out = np.full(n_bins, np.nan)
    ok = den > 0
    out[ok] = num[ok] / den[ok]
    return out


def long_run_scale(bins: np.ndarray, batch: int) -> float:
    """The bins' long-run standard deviation, at least 1: the robust spread of the successive differences
    of their sums over ``batch`` bins (1 when there are too few batches to tell)."""
    b = bins[np.isfinite(bins)]
    n = len(b) // batch
    if batch < 1 or n < 4:
        return 1.0
    sums = b[: n * batch].reshape(n, batch).sum(axis=1) / math.sqrt(batch)
    mad = float(np.median(np.abs(np.diff(sums))))
    return max(1.0, 1.4826 * mad / math.sqrt(2.0))


def cusum_threshold(n_bins: int, tests: int, false_alarm: float, k: float) -> float:
    """The one-sided CUSUM threshold ``h`` whose in-control average run length, by Siegmund's
    approximation ``(exp(2k(h + c)) - 2k(h + c) - 1) / (2 k^2)``, is ``2 tests n_bins / false_alarm``."""
    target = 2.0 * tests * max(n_bins, 1) / false_alarm

    def excess(h: float) -> float:
        a = 2.0 * k * (h + OVERSHOOT)
        return (math.expm1(a) - a) / (2.0 * k * k) - target

    return float(brentq(excess, 0.0, 600.0 / (2.0 * k)))  # exp stays finite


@dataclass(frozen=True)
class Crossing:
    """A CUSUM crossing: at bin ``alarm``, from the change point ``start`` (bins), with the sign of the
    shift, and the standardized sum of every bin from ``start`` to the log's end (``persists``)."""

    alarm: int
    start: int
    sign: int
    persists: float
    confirmed: bool


def persistence(bins: np.ndarray, start: int, sign: int, settle: int) -> float:
    """How far the bins from ``start`` to the end sit off, in standard deviations of their mean, the way
    ``sign`` says: off what came before them when at least ``settle`` bins did (a model that misfits the
    whole log alike has not changed), else off zero (the model's own expectation)."""
    post = bins[start:]
    post = post[np.isfinite(post)]
    if post.size == 0:
        return 0.0
    pre = bins[:start]
    pre = pre[np.isfinite(pre)]
    if pre.size < settle:
        return sign * float(post.sum()) / math.sqrt(post.size)
    return sign * float(post.mean() - pre.mean()) / math.sqrt(1.0 / post.size + 1.0 / pre.size)


def cusum_crossings(bins: np.ndarray, h: float, k: float, confirm: float, settle: int = 1) -> list[Crossing]:
    """Every crossing of the two-sided CUSUM on ``bins`` (already scaled), up to and including the first
    confirmed one (a change: ``persistence`` beyond ``confirm``); after an unconfirmed one (an episode)
    the CUSUM restarts."""
    out: list[Crossing] = []
    up = down = 0.0
    zero_up = zero_down = 0
    for i, v in enumerate(bins):
        if not np.isfinite(v):
            continue
        up = max(0.0, up + v - k)
        down = max(0.0, down - v - k)
        if up == 0.0:
            zero_up = i + 1
        if down == 0.0:
            zero_down = i + 1
        for stat, start, sign in ((up, zero_up, 1), (down, zero_down, -1)):
            if stat <= h:
                continue
            persists = persistence(bins, start, sign, settle)
            ok = persists > confirm
            out.append(Crossing(i, min(start, i), sign, persists, ok))
            if ok:
                return out
            up = down = 0.0
            zero_up = zero_down = i + 1
            break
    return out


def cusum_path(bins: np.ndarray, k: float) -> np.ndarray:
    """The two-sided CUSUM statistic ``max(up, down)`` after each bin (for figures); restarts not applied."""
    up = down = 0.0
    out = np.zeros(len(bins))
    for i, v in enumerate(bins):
        if np.isfinite(v):
            up = max(0.0, up + v - k)
            down = max(0.0, down - v - k)
        out[i] = max(up, down)
    return out


def confirm_quantile(tests: int, false_alarm: float) -> float:
    """The persistence test's critical value: the normal quantile of ``false_alarm`` shared by ``tests``
    streams and both signs."""
    return float(norm.isf(false_alarm / (2.0 * tests)))
