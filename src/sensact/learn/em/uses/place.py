"""A learned model put to use: where the robot was in another log, by the E-step alone (sec. 4.2).

EM learns a model and the robot's path together; a model learned on one run can then place the robot in
the next with no learning at all: the forward EKF and two-filter smoother of ``estep.e_step`` with the
model held. Only the start is unknown, and it is found the way EM finds it (beyond the thesis):

* a **planar** log with bearings: ``searches/start_race.start_candidates`` scores the grid of starts on the first
  sightings' bearings; each candidate is then scored by the whole log's ``log P(O | C, lambda)`` under
  the learned model (eq. 4.14), which needs no race: the model is no longer a poor guess;
* a **track**: every distance at which a learned f reads one of the first sightings' readings (the real
  roots of ``f(x) = o`` inside the channel's window) is a candidate, scored the same way, so that one
  outlier among the first readings cannot set the start;
* a planar log **without bearings** (UWB anchors, sonar beacons): ``range_start_candidates`` scores every
  grid position at ``RANGE_HEADINGS`` headings by the first sightings' ranges under the learned model,
  and the best few by the whole log the same way. ``learn em`` cannot do this (its start is given): under
  its starting line the ranges put the best cells metres off, while a learned f and action model read the
  window's ranges and motion as they are, so they tell the heading too;
* any log, when the caller says so: the given start; on a planar log the caller may give the position
  alone, and the heading is searched for at ``RANGE_HEADINGS`` headings, each scored by the whole log.

The log-likelihood per sighting used is a check that needs no ground truth: a model that fits a log
about as well as the one it was learned on (``EMResult.summary()['loglik_best']`` over its
``n_used``) holds there; one that fits much worse does not.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from sensact.config import config_from_dict
from sensact.core.angles import wrap_angle
from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig, upgrade_settings
from sensact.learn.em.estep import Posteriors, e_step, log_likelihood
from sensact.learn.em.fit import refuse_no_sightings
from sensact.learn.em.searches.start_race import DISTINCT_CELLS, search_grid, search_window, start_candidates
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.progress import Progress
from sensact.records import JsonObject
from sensact.reprs import compact_repr

SEARCH_WINDOW_S = 30.0  # the planar start search's window when the config sets none (MRCLAM's setting)
TRACK_SIGHTINGS = 5  # a track's start candidates come from this many first sightings
TRACK_MIN_SD = 1.0  # a track candidate's prior sd is at least this (a reading on a steep f pins it too well)
# (description, done, total): where a long search is, for a progress bar
RANGE_HEADINGS = 12  # a range-only start search tries this many headings at each grid position (30 degrees apart)
# the settings localize takes from the ones a model was learned with (its JSON's summary.config): the
# start search, the start's spread and the first-iteration gate; the rest of the E-step is the model's own
LEARNED_SETTINGS = (
    "thesis.prune_rad_per_step",
    "thesis.start_prior_sd",
    "search.start_s",
    "search.start_grid_mm",
    "search.start_candidates",
)


@dataclass(frozen=True, eq=False)
class Localized:
    __repr__ = compact_repr  # a line, never the arrays
    model: EMModel  # the learned model, with the start it was run from as its prior
    posteriors: Posteriors
    start: JsonObject  # how the start was found, and every candidate's log-likelihood

    @property
    def loglik_per_sighting(self) -> float:
        return self.posteriors.loglik / max(self.posteriors.n_used, 1)


def learned_config(learned: JsonObject | None, source: str = "model") -> EMConfig:
    """The settings to place the robot with: ``LEARNED_SETTINGS`` from the config the model was learned
    with (``learned``, a model.json's ``summary.config``; None for a model written without one), the
    defaults for the rest: the E-step takes everything else (the channels, their windows, the robust
    readings) from the model itself."""
    groups = EMConfig.regroup(upgrade_settings(learned or {}))  # a model file from before the groups: flat
    picked = {}
    for path in LEARNED_SETTINGS:
        group, _, name = path.partition(".")
        if isinstance(groups.get(group), Mapping) and name in groups[group]:
            picked[path] = groups[group][name]
    return config_from_dict(EMConfig, picked, source=source)


def track_start_candidates(model: EMModel, data: LandmarkLog) -> list[tuple[float, float]]:
    """``(distance, sd)`` for each real root of ``f_j(x) = o`` inside channel j's window, over the first
    ``TRACK_SIGHTINGS`` sightings: where a reading of each channel puts the robot, with the spread its
    sigma implies there."""
    cols = model.sensor.columns(data)
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


def start_headings() -> tuple[np.ndarray, float]:
    """The ``RANGE_HEADINGS`` headings a search without bearings tries at a position, and their spacing."""
    step = 2.0 * math.pi / RANGE_HEADINGS
    return wrap_angle(step * np.arange(RANGE_HEADINGS)), step


def range_start_candidates(
    model: EMModel, data: LandmarkLog, config: EMConfig, progress: Progress | None = None
) -> list[EMModel]:
    """Up to ``config.search.start_candidates`` starts for a planar log read without bearings: every point of
    ``searches/start_race.search_grid`` (``config.search.start_grid_mm`` cells) at each of ``RANGE_HEADINGS`` headings,
    scored by ``log P(O | C, lambda)`` (eq. 4.14) of the first ``config.search.start_s`` seconds under
    the learned model, the best of them that are a few cells or two headings apart from each other.
    Each starts with a prior sd of a grid cell in position and half a heading step in heading, so
    that the true start is within one sd of its nearest candidate in every component."""
    window = search_window(data, config.search.start_s or SEARCH_WINDOW_S)
    g = config.search.start_grid_mm
    points = search_grid(data.landmarks_xy, data.landmarks_xy[data.obs_landmark[0]], g)
    headings, step = start_headings()
    cov = np.diag([g**2, g**2, (0.5 * step) ** 2])
    scored = []
    for i, (x, y) in enumerate(points):
        if progress:
            progress("start search: grid positions scored", i, len(points))
        for theta in headings:
            mean = np.array([x, y, theta])
            ll = log_likelihood(model.replace(prior_mean=mean, prior_cov=cov), window)
            if np.isfinite(ll):
                scored.append((ll, mean))
    if progress:
        progress("start search: grid positions scored", len(points), len(points))
    scored.sort(key=lambda s: -s[0])
    chosen: list[np.ndarray] = []
    for _, mean in scored:
        if all(
            np.hypot(*(mean[:2] - m[:2])) >= DISTINCT_CELLS * g or abs(wrap_angle(mean[2] - m[2])) > 1.5 * step
            for m in chosen
        ):
            chosen.append(mean)
        if len(chosen) == config.search.start_candidates:
            break
    return [model.replace(prior_mean=m, prior_cov=cov) for m in chosen]


def localize(
    model: EMModel,
    data: LandmarkLog,
    config: EMConfig | None = None,
    start: np.ndarray | None = None,
    progress: Progress | None = None,
) -> Localized:
    """The smoothed path of ``data`` under ``model``, held; ``start`` (a pose, or a distance on a track)
    skips the search and is used with ``config.thesis.start_prior_sd``; a planar ``start`` of two numbers is
    the position alone, and the heading is searched for."""
    cfg = config or EMConfig()
    refuse_no_sightings(data)  # the start and the path are placed by the sightings
    n = model.prior_mean.size
    gate = cfg.thesis.prune_rad_per_step if data.geometry.has_heading else 0.0
    given = None if start is None else np.asarray(start, dtype=float).ravel()
    if given is not None and n == 3 and given.size == 2:
        headings, step = start_headings()
        cov = np.diag([cfg.thesis.start_prior_sd[0] ** 2, cfg.thesis.start_prior_sd[1] ** 2, (0.5 * step) ** 2])
        candidates = [model.replace(prior_mean=np.array([*given, theta]), prior_cov=cov) for theta in headings]
        how = "the given position at each heading"
    elif given is not None:
        mean = given.reshape(n)
        cov = np.diag(np.asarray(cfg.thesis.start_prior_sd[:n], dtype=float) ** 2)
        candidates = [model.replace(prior_mean=mean, prior_cov=cov)]
        how = "given"
    elif data.geometry.state_is_range:
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
    elif not model.sensor.reads_bearing or not np.isfinite(data.obs_bearing_rad).any():
        candidates = range_start_candidates(model, data, cfg, progress)
        how = "the ranges' start search"
    else:
        search = cfg.replace(start_search_s=cfg.search.start_s or SEARCH_WINDOW_S)
        candidates, _ = start_candidates(data, model, search)
        how = "the start search's candidates"
    scores = []
    for i, m in enumerate(candidates):
        if progress:
            progress("start candidates scored on the whole log", i, len(candidates))
        scores.append(log_likelihood(m, data))
    if progress:
        progress("start candidates scored on the whole log", len(candidates), len(candidates))
    best = int(np.argmax(scores)) if scores else 0
    if not scores or not np.isfinite(scores[best]):
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
