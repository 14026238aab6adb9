"""Where the robot starts, when nobody says (beyond the thesis, whose robots started at a known pose).

A real log begins wherever the robot happened to be. With a landmark map and bearings, the EKF can
only lock on from a start near the truth, so ``search_start`` tries a grid of starting positions over
the mapped area. At each position the heading is the one that makes the first bearing exact, so only
positions need a grid. Each candidate prior is scored by ``log P(O | C, lambda)`` of the first
``start_search_s`` seconds under the starting model, the E-step's own likelihood; the best one
becomes ``pi(w_0)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.learn.em.config import EMConfig
from sensact.learn.em.estep import e_step
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

MIN_OBSERVATIONS = 10  # the window grows until it holds this many sightings


def search_start(data: LandmarkLog, model: EMModel, config: EMConfig) -> tuple[EMModel, dict[str, Any]]:
    """The model with ``pi(w_0)`` replaced by the most likely grid candidate, and a summary."""
    first = np.flatnonzero(np.isfinite(data.obs_bearing_rad))
    if data.geometry != "planar" or first.size == 0 or len(data.landmarks_xy) == 0:
        raise ValueError("the start search needs a planar log with bearings to mapped landmarks")
    stop = round(config.start_search_s / data.dt_s) + 1
    stop = max(stop, int(data.obs_step[min(MIN_OBSERVATIONS, data.n_observations) - 1]) + 2)
    window = data.slice_steps(0, min(stop, data.n_steps))
    k0 = first[0]
    t0 = data.obs_step[k0]
    lm = data.landmarks_xy
    g = config.start_search_grid_mm
    lo = lm.min(axis=0) - 4 * g
    hi = lm.max(axis=0) + 4 * g
    xs = np.arange(lo[0], hi[0] + g / 2, g)
    ys = np.arange(lo[1], hi[1] + g / 2, g)
    target = lm[data.obs_landmark[k0]]
    cov = np.diag([g**2, g**2, 0.3**2])
    # the starting f is a guess, so the search trusts the bearings alone: the readings get a spread
    # that makes them uninformative
    chans = model.sensor.channels
    vague = model.sensor.with_fits([(c.function, 1e9, c.bearing_terms) for c in chans], model.sensor.sigma_bearing_rad)
    scorer = model.replace(sensor=vague)
    best = (-np.inf, None)
    tried = 0
    for x in xs:
        for y in ys:
            d = target - (x, y)
            if np.hypot(*d) < g:
                continue
            # the heading that puts the first sighting's landmark at its measured bearing (sec. 2.5.1:
            # theta = 0 faces +y, bearings counterclockwise from forward); the robot's heading is
            # held by the starting model (no motion) until that sighting
            theta = float(wrap_angle(np.arctan2(d[1], d[0]) - 0.5 * np.pi - data.obs_bearing_rad[k0]))
            prior_mean = np.array([x, y, theta])
            post = e_step(scorer.replace(prior_mean=prior_mean, prior_cov=cov), window)
            tried += 1
            if post.ok and post.loglik > best[0]:
                best = (post.loglik, model.replace(prior_mean=prior_mean, prior_cov=cov))
    if best[1] is None:
        raise ValueError(f"{data.source}: no start candidate gave a finite likelihood; set start_prior_mean by hand")
    chosen = best[1]
    info = {
        "candidates": tried,
        "window_steps": window.n_steps,
        "first_sighting_step": int(t0),
        "loglik": float(best[0]),
        "prior_mean": chosen.prior_mean.tolist(),
    }
    return chosen, info
