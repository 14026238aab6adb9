"""What a finished fit says about itself, with no ground truth: every check of ``lost_signs`` and
``fit_health`` run once on a fit, each warning as one line for the user."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from sensact.health import Health
from sensact.learn.em.checks.fit_health import em_health
from sensact.learn.em.checks.lost_signs import (
    describe_correlated,
    describe_held_sideways,
    describe_lost_fit,
    describe_pruned,
    held_sideways_noise,
    lost_fit_signs,
    residual_autocorrelation,
)
from sensact.learn.em.config import EMConfig
from sensact.learn.em.result import EMResult, LostSign, smoothed_distances
from sensact.logs.landmark_log import LandmarkLog


@dataclass(frozen=True)
class Diagnostics:
    """Signs, without ground truth, of how far to trust a fit (``lost_signs``); ``warnings`` has one line for
    each that calls for the user's attention."""

    pruned_fraction: float  # the share of sightings the gates dropped
    residual_lag1_autocorrelation: Mapping[str, float | None]  # each channel's; above 0.5 sigma is a lower bound
    lost_signs: tuple[LostSign, ...]  # a range function that turns over or bends, an unsettled fit
    held_sideways: Mapping[str, float] | None  # a robot that side-steps held to no sideways mean
    warnings: tuple[str, ...] = field(default=())
    health: Health = field(default_factory=Health)  # degenerate or unfinished: written, flagged, exit 3


def diagnose(result: EMResult, data: LandmarkLog, cfg: EMConfig) -> Diagnostics:
    """The fit's checks without truth, each warning as one line."""
    post = result.posteriors
    dist = None if post is None else smoothed_distances(result.model, post, data)  # what both checks read
    signs: list[LostSign] = []
    autocorrelation: dict[str, float | None] = {}
    warnings: list[str] = []
    if post is not None:
        history, best = result.loglik_history, result.best_iteration
        signs = lost_fit_signs(result.model, post, data, history, best, cfg, dist=dist)
        if signs:
            warnings.append(describe_lost_fit(signs))
        autocorrelation = residual_autocorrelation(result.model, post, data)
        warnings += describe_correlated(autocorrelation)
    pruned = describe_pruned(result.pruned_fraction)
    if pruned:
        warnings.append(pruned)
    held = held_sideways_noise(result.model, cfg.motion_noise.kind)
    if held:
        warnings.append(describe_held_sideways(held))
    health = em_health(result, data, autocorrelation, dist=dist)
    return Diagnostics(result.pruned_fraction, autocorrelation, tuple(signs), held, tuple(warnings), health)
