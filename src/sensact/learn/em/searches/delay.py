"""A likelihood search over the command delay (beyond the thesis).

A continuous action model may read its command ``delay`` steps late (``action_delay_max_s``), and the
M-step picks the delay whose refitted beta best explains the smoothed displacements. Between sightings
those displacements are mostly the motion model's own prediction, made with the current delay, so the
M-step hands that delay back: EM barely moves it. On MRCLAM robot 4 it stayed at 1 step while the
E-step likelihood peaks at 7 (196 log-units higher), From-Truth's delay (docs/em-real.md).

``search_delay`` asks the likelihood instead: it runs the E-step's forward pass with the current
coefficients at every ``stride``-th delay (and the largest), then at the best one's neighbours, and
keeps the most likely delay, whose E-step it then runs whole. It never lowers the likelihood; on MRCLAM
(0-15 steps) it costs 8-10 forward passes.
``fit_em`` runs it on the ridge search's schedule.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from sensact.learn.em.estep import Posteriors
from sensact.models.em_model import EMModel

COARSE_STRIDE = 3  # steps between the first pass's delays; the likelihood is smooth in the delay


def with_delay(model: EMModel, delay_steps: int) -> EMModel:
    """``model`` with its action model reading the command ``delay_steps`` late, beta unchanged."""
    action = model.action
    return model.replace(action=action.with_coefficients(action.coefficients, int(delay_steps)))


@dataclass(frozen=True)
class DelaySearch:
    """One delay search: the delay before and after (steps), the likelihood before and after, its cost."""

    iteration: int = field(default=-1, kw_only=True)  # the EM iteration it ran after (-1: on its own)
    delay_from: int
    delay_to: int
    loglik_before: float
    loglik_after: float
    forward_passes: int


def search_delay(
    model: EMModel,
    post: Posteriors,
    loglik: Callable[[EMModel], float],
    evaluate: Callable[[EMModel], Posteriors],
    max_delay: int,
    stride: int = COARSE_STRIDE,
) -> tuple[EMModel, Posteriors, DelaySearch]:
    """The delay in ``0..max_delay`` whose likelihood (``loglik``, the forward pass) is the highest, with
    the model and its E-step (``evaluate``); ``model`` and ``post`` themselves when no other delay is
    more likely."""
    current = int(model.action.delay_steps)
    tried = {current: float(post.loglik) if post.ok and np.isfinite(post.loglik) else -np.inf}

    def score(delay: int) -> float:
        if delay not in tried:
            tried[delay] = loglik(with_delay(model, delay))
        return tried[delay]

    for delay in sorted({*range(0, max_delay + 1, max(stride, 1)), max_delay}):
        score(delay)
    coarse = max(tried, key=score)
    for delay in range(max(coarse - stride + 1, 0), min(coarse + stride - 1, max_delay) + 1):
        score(delay)
    best = max(tried, key=score)
    if score(best) <= score(current):
        best = current
    passes = len(tried) - 1  # the kept delay is then smoothed once
    info = DelaySearch(current, best, float(post.loglik), float(tried[best]), passes)
    if best == current:
        return model, post, info
    moved = with_delay(model, best)
    kept = evaluate(moved)
    if not kept.ok:  # its forward pass ran, its smoother did not: stay
        return model, post, DelaySearch(current, current, float(post.loglik), float(post.loglik), passes)
    return moved, kept, info
