"""A line search along the direction EM climbs slowest (beyond the thesis).

A camera that looks forward sees every landmark about as far as it would if the robot were ``delta``
further ahead and every range function read ``f(d + delta)``: the path and the sensor's offset trade
against each other, and only the bearings to near landmarks and the turns tell them apart. EM's
alternating steps crawl along that ridge (each E-step puts the path where the current ``f`` says, each
M-step fits ``f`` to that path), so a fit from a poor start can stop with the path a few hundred
millimetres behind the robot and ``f`` off by as much.

``search_ridge`` moves along the ridge in one step: it maximizes the E-step's own
``log P(O | C, lambda)`` over ``delta`` with scipy's bounded scalar search, and keeps the move only if
the likelihood rises. Every evaluation is one E-step (6-8 of them on MRCLAM), and the search never
lowers the likelihood. A best shift at the bracket's edge has not found the peak, so the search
starts again from there, up to ``MAX_EXPANSIONS`` times (on half of MRCLAM robot 4's log the first
search moved 495 mm, the edge, and the path stayed 157 mm behind the robot). ``fit_em`` runs it
when the held stage ends and every ``search_every`` iterations after (from the start when nothing is
held), because EM keeps sliding back along the ridge between searches.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

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


def search_ridge(
    model: EMModel, post: Posteriors, evaluate: Callable[[EMModel], Posteriors], half_width_mm: float
) -> tuple[EMModel, Posteriors, dict[str, Any]]:
    """The model along the ridge through ``model`` (whose E-step gave ``post``) with the highest
    likelihood found, and its E-step; ``model`` and ``post`` themselves when no shift raises the
    likelihood. Each bracket is ``+-half_width_mm`` about the last move; ``evaluate`` is the E-step of
    the loop's current stage."""
    info = {"shift_mm": 0.0, "loglik_before": float(post.loglik), "e_steps": 0, "expansions": 0}
    for expansion in range(MAX_EXPANSIONS + 1):
        best, best_post, e_steps = _bracket_search(model, post, evaluate, half_width_mm)
        info["e_steps"] += e_steps
        if best == 0.0:
            break
        model, post = shifted_forward(model, best), best_post
        info["shift_mm"] += best
        info["expansions"] = expansion
        if abs(best) < half_width_mm - 2 * RIDGE_TOLERANCE_MM:  # inside the bracket: the peak
            break
    info["loglik_after"] = float(post.loglik)
    return model, post, info


def _bracket_search(
    model: EMModel, post: Posteriors, evaluate: Callable[[EMModel], Posteriors], half_width_mm: float
) -> tuple[float, Posteriors, int]:
    """The most likely shift within ``+-half_width_mm`` (0 if none beats ``model``), its E-step, and
    the number of E-steps run."""
    tried: dict[float, Posteriors] = {0.0: post}

    def negative_loglik(delta: float) -> float:
        p = evaluate(shifted_forward(model, delta))
        tried[float(delta)] = p
        return -p.loglik if p.ok and np.isfinite(p.loglik) else np.inf

    minimize_scalar(
        negative_loglik,
        bounds=(-half_width_mm, half_width_mm),
        method="bounded",
        options={"xatol": RIDGE_TOLERANCE_MM},
    )
    ok = {d: p for d, p in tried.items() if p.ok and np.isfinite(p.loglik)}
    best = max(ok, key=lambda d: ok[d].loglik)
    return best, ok[best], len(tried) - 1
