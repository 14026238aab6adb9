"""A line search along the direction EM climbs slowest (beyond the thesis).

A camera that looks forward sees every landmark about as far as it would if the robot were ``delta``
further ahead and every range function read ``f(d + delta)``: the path and the sensor's offset trade
against each other, and only the bearings to near landmarks and the turns tell them apart. EM's
alternating steps crawl along that ridge (each E-step puts the path where the current ``f`` says, each
M-step fits ``f`` to that path), so a fit from a poor start can stop with the path a few hundred
millimetres behind the robot and ``f`` off by as much.

``search_ridge`` moves along the ridge in one step: it maximizes the E-step's own
``log P(O | C, lambda)`` over ``delta`` with scipy's bounded scalar search, and keeps the move only if
the likelihood rises. Every evaluation is the E-step's forward pass alone (6-8 of them on MRCLAM), and only the shift
it keeps is smoothed; the search never lowers the likelihood. A best shift at the bracket's edge has not
found the peak, so the search starts again from there, up to ``MAX_EXPANSIONS`` times (on half of MRCLAM
robot 4's log the first search moved 495 mm, the edge, and the path stayed 157 mm behind the robot).
``fit_em`` runs it when the held stage ends and every ``search_every`` iterations after (from the start
when nothing is held), because EM keeps sliding back along the ridge between searches.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import minimize_scalar

from sensact.core.pose_models import apply_displacement
from sensact.learn.em.estep import Posteriors
from sensact.models.em_model import EMModel

RIDGE_TOLERANCE_MM = 10.0  # the search stops when delta is known to this; well inside a range sigma
MAX_EXPANSIONS = 3  # searches again from a shift at the bracket's edge, at most this many times


def shifted_forward(model: EMModel, delta_mm: float) -> EMModel:
    """``model`` with its start ``delta_mm`` further ahead (sec. 2.5.1: the robot faces +y) and every
    reading channel's ``f(d)`` replaced by ``f(d + delta)``, which reads the same from there.

    Exact for ``f`` (a polynomial in ``(d - center) / scale`` moves its center). The bearing terms
    ``d g(b)`` keep their ``d``, so they read ``delta g(b)`` differently; the next M-step refits them,
    and the search keeps a shift only if the likelihood says so, this change included."""
    fits = [
        (replace(c.function, center=c.function.center - delta_mm), c.sigma, c.bearing_terms)
        for c in model.sensor.channels
    ]
    prior = apply_displacement(model.prior_mean, np.array([0.0, delta_mm, 0.0]))[0]
    return model.replace(sensor=model.sensor.with_fits(fits, model.sensor.sigma_bearing_rad), prior_mean=prior)


@dataclass(frozen=True)
class RidgeSearch:
    """One ridge search: how far it moved the path forward, the likelihood before and after, its cost."""

    iteration: int = field(default=-1, kw_only=True)  # the EM iteration it ran after (-1: on its own)
    shift_mm: float
    loglik_before: float
    forward_passes: int
    expansions: int  # how many times the bracket was moved on from its edge
    loglik_after: float


def search_ridge(
    model: EMModel,
    post: Posteriors,
    loglik: Callable[[EMModel], float],
    evaluate: Callable[[EMModel], Posteriors],
    half_width_mm: float,
) -> tuple[EMModel, Posteriors, RidgeSearch]:
    """The model along the ridge through ``model`` (whose E-step gave ``post``) with the highest
    likelihood found, and its E-step; ``model`` and ``post`` themselves when no shift raises the
    likelihood. Each bracket is ``+-half_width_mm`` about the last move. ``loglik`` scores a shifted model
    (the forward pass of the loop's current stage); ``evaluate`` runs the whole E-step on the one kept."""
    shift, passes, expansions, before = 0.0, 0, 0, float(post.loglik)
    start_model, best_ll = model, post.loglik if post.ok and np.isfinite(post.loglik) else -np.inf
    for expansion in range(MAX_EXPANSIONS + 1):
        best, best_ll, n = _bracket_search(model, best_ll, loglik, half_width_mm)
        passes += n
        if best == 0.0:
            break
        model = shifted_forward(model, best)
        shift += best
        expansions = expansion
        if abs(best) < half_width_mm - 2 * RIDGE_TOLERANCE_MM:  # inside the bracket: the peak
            break
    if model is not start_model:
        kept = evaluate(model)
        if kept.ok:
            post = kept
        else:  # its forward pass ran, its smoother did not: stay
            model, shift = start_model, 0.0
    return model, post, RidgeSearch(shift, before, passes, expansions, float(post.loglik))


def _bracket_search(
    model: EMModel, current: float, loglik: Callable[[EMModel], float], half_width_mm: float
) -> tuple[float, float, int]:
    """The most likely shift within ``+-half_width_mm`` (0 if none beats ``model``, whose likelihood is
    ``current``), its likelihood, and the number of passes run."""
    tried: dict[float, float] = {0.0: current}

    def negative_loglik(delta: float) -> float:
        ll = loglik(shifted_forward(model, delta))
        tried[float(delta)] = ll
        return -ll if np.isfinite(ll) else np.inf

    minimize_scalar(
        negative_loglik,
        bounds=(-half_width_mm, half_width_mm),
        method="bounded",
        options={"xatol": RIDGE_TOLERANCE_MM},
    )
    best = max(tried, key=lambda d: tried[d])
    return best, tried[best], len(tried) - 1
