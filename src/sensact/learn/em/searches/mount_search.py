"""The sensor mount searched along its ridge by the likelihood itself (beyond the thesis; the M-step's
update of the mount is ``learn/em/mount.py``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sensact.learn.em.mount import remounted
from sensact.models.em_model import EMModel
from sensact.models.landmark_sensor import SensorMount

# the mount search (``search_mount``): each component's bracket about its current value, and how closely
# the search pins it; a forward pass is about a quarter of an E-step
SEARCH_HALF_WIDTH = (150.0, 150.0, 0.1)  # mm, mm, rad


SEARCH_TOLERANCE = (2.0, 2.0, 5e-4)


SEARCH_ROUNDS = 2  # over the free components, since they trade against each other a little


@dataclass(frozen=True)
class MountSearch:
    """One mount search: the mount and the likelihood before and after, its cost."""

    iteration: int = field(default=-1, kw_only=True)  # the EM iteration it ran after (-1: on its own)
    mount_before: SensorMount
    loglik_before: float
    mount_after: SensorMount
    loglik_after: float
    forward_passes: int


def search_mount(
    model: EMModel,
    post: Any,
    loglik: Callable[[EMModel], float],
    evaluate: Callable[[EMModel], Any],
    free: tuple[bool, bool, bool],
) -> tuple[EMModel, Any, MountSearch]:
    """The free components of the mount moved, one at a time, to where the E-step's own
    ``log P(O | C, lambda)`` (its forward pass, ``loglik``) is highest, by scipy's bounded scalar search
    within ``SEARCH_HALF_WIDTH`` of their value; a move is kept only if the likelihood rises.

    Why a search besides the M-step: the path the E-step infers was inferred with the old mount, so an
    M-step that fits the mount to it moves it only as far as that path allows. A yaw of the sensor and
    the robot's heading trade against each other in every sighting, and only the robot's forward motion
    (no side-stepping) tells them apart; EM's alternating steps crawl along that ridge as they do along
    the range offset's (``searches/ridge.py``). The likelihood itself pins it: on a simulated drive whose camera is
    yawed 0.035 rad, a model learned at yaw 0 is 17 log-units less likely than at the true yaw."""
    from scipy.optimize import minimize_scalar

    start = model
    best_ll = post.loglik if post.ok and np.isfinite(post.loglik) else -np.inf
    before, loglik_before = model.sensor.mount, float(post.loglik)
    passes = 0
    for _ in range(SEARCH_ROUNDS):
        moved_any = False
        for i in np.flatnonzero(np.asarray(free, dtype=bool)):
            base = model.sensor.mount.as_array()
            tried: dict[float, float] = {0.0: best_ll}

            def negative(
                delta: float, i: int = i, base: np.ndarray = base, tried: dict = tried, at: EMModel = model
            ) -> float:
                m = base.copy()
                m[i] += delta
                ll = loglik(remounted(at, m))
                tried[float(delta)] = ll
                return -ll if np.isfinite(ll) else np.inf

            h = SEARCH_HALF_WIDTH[i]
            minimize_scalar(negative, bounds=(-h, h), method="bounded", options={"xatol": SEARCH_TOLERANCE[i]})
            passes += len(tried) - 1
            delta = max(tried, key=lambda d: tried[d])
            if delta != 0.0 and tried[delta] > best_ll:
                m = base.copy()
                m[i] += delta
                model, best_ll, moved_any = remounted(model, m), tried[delta], True
        if not moved_any:
            break
    if model is not start:
        kept = evaluate(model)
        if kept.ok:
            post = kept
        else:
            model = start
    return model, post, MountSearch(before, loglik_before, model.sensor.mount, float(post.loglik), passes)
