"""A learned model put to use: where the robot was in another log, by the E-step alone (sec. 4.2).

EM learns a model and the robot's path together; a model learned on one run can then place the robot in
the next with no learning at all: the forward EKF and two-filter smoother of ``estep.e_step`` with the
model held. Only the start is unknown, and it is found the way EM finds it (beyond the thesis):

* a **planar** log with bearings: ``start.start_candidates`` scores the grid of starts on the first
  sightings' bearings; each candidate is then scored by the whole log's ``log P(O | C, lambda)`` under
  the learned model (eq. 4.14), which needs no race: the model is no longer a poor guess;
* a **track**: every distance at which a learned f reads one of the first sightings' readings (the real
  roots of ``f(x) = o`` inside the channel's window) is a candidate, scored the same way, so that one
  outlier among the first readings cannot set the start;
* a planar log **without bearings**, or any log when the caller says so: the given start.

The log-likelihood per sighting used is a check that needs no ground truth: a model that fits a log
about as well as the one it was learned on (``EMResult.summary()['loglik_best']`` over its
``n_used``) holds there; one that fits much worse does not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig
from sensact.learn.em.estep import Posteriors, channel_columns, e_step, log_likelihood
from sensact.learn.em.fit import refuse_no_sightings
from sensact.learn.em.start import start_candidates
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

SEARCH_WINDOW_S = 30.0  # the planar start search's window when the config sets none (MRCLAM's setting)
TRACK_SIGHTINGS = 5  # a track's start candidates come from this many first sightings
TRACK_MIN_SD = 1.0  # a track candidate's prior sd is at least this (a reading on a steep f pins it too well)


@dataclass(frozen=True, eq=False)
class Localized:
    model: EMModel  # the learned model, with the start it was run from as its prior
    posteriors: Posteriors
    start: dict[str, Any]  # how the start was found, and every candidate's log-likelihood

    @property
    def loglik_per_sighting(self) -> float:
        return self.posteriors.loglik / max(self.posteriors.n_used, 1)


def track_start_candidates(model: EMModel, data: LandmarkLog) -> list[tuple[float, float]]:
    """``(distance, sd)`` for each real root of ``f_j(x) = o`` inside channel j's window, over the first
    ``TRACK_SIGHTINGS`` sightings: where a reading of each channel puts the robot, with the spread its
    sigma implies there."""
    cols = channel_columns(model.sensor, data)
    out = []
    for k in range(min(TRACK_SIGHTINGS, data.n_observations)):
        for ch, col in zip(model.sensor.channels, cols, strict=True):
            o = data.obs_readings[k, col]
            if not math.isfinite(o):
                continue
            f = ch.function
            c = np.array(f.coef)
            c[0] -= o
            if not np.any(c[1:]):
                continue  # a flat f reads every distance alike
            for u in np.polynomial.polynomial.polyroots(c):
                if abs(u.imag) > 1e-9 * max(1.0, abs(u.real)):
                    continue
                x = f.center + f.scale * u.real
                if ch.valid_min <= x <= ch.valid_max:
                    slope = abs(float(f.slope(x)))
                    sd = ch.sigma / slope if slope > 0 else math.inf
                    out.append((float(x), max(sd, TRACK_MIN_SD)))
    return out


def localize(
    model: EMModel, data: LandmarkLog, config: EMConfig | None = None, start: np.ndarray | None = None
) -> Localized:
    """The smoothed path of ``data`` under ``model``, held; ``start`` (a pose, or a distance on a track)
    skips the search and is used with ``config.start_prior_sd``."""
    cfg = config or EMConfig()
    refuse_no_sightings(data)  # the start and the path are placed by the sightings
    n = model.prior_mean.size
    gate = cfg.prune_rad_per_step if data.geometry == "planar" else 0.0
    if start is not None:
        mean = np.asarray(start, dtype=float).reshape(n)
        cov = np.diag(np.asarray(cfg.start_prior_sd[:n], dtype=float) ** 2)
        candidates = [model.replace(prior_mean=mean, prior_cov=cov)]
        how = "given"
    elif data.geometry == "track":
        found = track_start_candidates(model, data)
        if not found:
            raise ConfigError(
                "no learned f reads any of the log's first readings inside its window, so the start cannot be "
                "found from them.",
                file=data.source,
                field="start",
                fix="give the start distance with --start.",
            )
        candidates = [model.replace(prior_mean=np.array([x]), prior_cov=np.array([[sd**2]])) for x, sd in found]
        how = "the first readings through the learned f"
    else:
        if model.sensor.sigma_bearing_rad is None or not np.isfinite(data.obs_bearing_rad).any():
            raise ConfigError(
                "the log has no bearings to search for the start with.",
                file=data.source,
                field="start",
                fix="give the start pose with --start X_MM,Y_MM,HEADING_RAD (as start_prior_mean in em_config.yaml).",
            )
        search = replace(cfg, start_search_s=cfg.start_search_s or SEARCH_WINDOW_S)
        candidates, _ = start_candidates(data, model, search)
        how = "the start search's candidates"
    scores = [log_likelihood(m, data) for m in candidates]
    best = int(np.argmax(scores))
    if not np.isfinite(scores[best]):
        raise ConfigError(
            f"the filter failed from every start tried ({len(candidates)}): the model does not fit this log.",
            file=data.source,
            field="start",
            fix="check that the model was learned on this robot and sensor, or give the start with --start.",
        )
    chosen = candidates[best]
    post = e_step(chosen, data, prune_rad_per_step=gate)
    info = {
        "how": how,
        "prior_mean": chosen.prior_mean.tolist(),
        "candidates": [
            {"prior_mean": m.prior_mean.tolist(), "loglik": s} for m, s in zip(candidates, scores, strict=True)
        ],
        "chosen": best,
    }
    return Localized(chosen, post, info)
