"""A map nobody surveyed, learned in rounds (docs/map.md): each round a filter carries the map
(``slam_filter.py``) and EM learns the models on it as on a survey; the rounds end when the likelihood
stops rising, the most likely kept, and one last EM whose M-step moves the map (``landmark_step.py``)
finishes the climb. docs/map.md says why rounds and not the M-step alone."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace as dc_replace

import numpy as np

from sensact.learn.em.config import EMConfig
from sensact.learn.em.initial import initial_model
from sensact.learn.em.landmark_step import placed_landmarks
from sensact.learn.em.loop import stage_loglik
from sensact.learn.em.result import EMResult
from sensact.learn.em.unsurveyed.slam_filter import filtered_map
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

# EM from a start, on a log and settings bound in: what every policy of fit.py takes and gives
Fit = Callable[[EMModel], EMResult]


MAX_MAP_ROUNDS = 8


def map_rounds(
    composed: Callable[[LandmarkLog, EMConfig], Fit], data: LandmarkLog, start: EMModel, cfg: EMConfig
) -> EMResult:
    """A log whose map nobody surveyed: rounds of the filter's map (``slam_filter.py``), then EM on it as on
    a survey (``composed``: ``fit.py``'s policies on a log and settings), from the last round's models
    (nothing held after the first), until two rounds in a row are less likely than the best; then EM from
    the best round with the map moved by its M-step (``landmark_step.py``). Rounds are compared on the
    sightings both kept (``more_likely``), since each run prunes its own. The EKF-SLAM start map
    (``slam_start.py``) fixes the frame (the robot's start)."""
    learned, settings = start.landmarks, cfg
    xy, sd = learned.xy, np.full_like(learned.xy, np.nan)
    model = initial_model(data.with_landmarks(xy), cfg)  # the first round: as on a survey, from the poor start
    best: EMResult | None = None
    worse = 0
    for k in range(MAX_MAP_ROUNDS):
        res = composed(data.with_landmarks(xy), settings)(model)
        res = dc_replace(res, model=res.model.replace(landmarks=dc_replace(learned, xy=xy, sd=sd)))
        if best is not None and not more_likely(res, best, data):
            worse += 1
            if worse == 2:  # two rounds in a row less likely than the best: it has stopped climbing
                break
        else:
            best, worse = res, 0
        if res.stop_reason == "interrupted":
            break
        model = res.model.replace(landmarks=None)
        # from a learned model nothing is held, and the map fixes the frame: no start search
        settings = settings.replace(refine_from=0, start_search_s=None) if k == 0 else settings
        xy, sd = filtered_map(model, data, xy, learned.held)
    res = best
    if res.stop_reason != "interrupted":
        # near the top the ridge is short: the M-step's own map update finishes the climb (landmark_step.py)
        final = composed(data.with_landmarks(res.model.landmarks.xy), settings)(res.model)
        res = final if more_likely(final, res, data) else res
    used = None if res.posteriors is None else res.posteriors.obs_used
    return dc_replace(res, model=res.model.replace(landmarks=placed_landmarks(res.model.landmarks, data, used)))


def more_likely(a: EMResult, b: EMResult, data: LandmarkLog) -> bool:
    """Whether fit ``a`` (with its learned map) is more likely than ``b``, each scored on the sightings both
    kept (each run prunes its own), robust readings as configured."""
    common = np.ones(data.n_observations, dtype=bool)
    for r in (a, b):
        if r.posteriors is not None:
            common &= r.posteriors.obs_used

    def score(r: EMResult) -> float:
        return stage_loglik(r.model, data.with_landmarks(r.model.landmarks.xy), common, robust=True)

    return score(a) > score(b)
