"""Range-only anchors (UWB, sonar beacons) whose positions nobody gave, learned when the log can fix them
(docs/map.md): ranges alone cannot say where the robot is facing or where an anchor is from a start nobody
knows, so at least ``slam_start.MIN_ANCHORS_GIVEN`` anchors must be given. Those fix the robot's path:

1. EM on the sightings of the given anchors alone, as on a survey (the range-only fit of
   ``searches/given_start.py`` and ``searches/facing.py``);
2. each other anchor placed on that smoothed path by least squares on its ranges (``multilaterate``);
3. EM on every sighting from there, the placed anchors moved by the M-step (``landmark_step.py``): with
   the path pinned by the given anchors, the map-and-path ridge that makes bearing logs need
   ``rounds.py``'s filter is held down.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from sensact.core.pose_models import sensor_poses
from sensact.learn.em.config import EMConfig
from sensact.learn.em.initial import initial_model
from sensact.learn.em.landmark_step import placed_landmarks
from sensact.learn.em.result import EMResult
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

GAUSS_NEWTON_STEPS = 20
MIN_RANGES = 5  # an anchor ranged fewer times from the path is left unplaced


def anchor_fit(
    composed: Callable[[LandmarkLog, EMConfig], Callable[[EMModel], EMResult]],
    data: LandmarkLog,
    start: EMModel,
    cfg: EMConfig,
) -> EMResult:
    """Steps 1-3 on ``data`` (a range-only log with some anchors' positions given), from ``start``."""
    learned = start.landmarks
    given = data.keep_sightings(learned.held[data.obs_landmark])
    first = composed(given, cfg)(initial_model(given, cfg))
    if first.posteriors is None or first.stop_reason == "interrupted":
        return first
    xy = multilaterate(first.model, first.posteriors.mean_gamma, data, learned.held)
    unplaced = ~np.isfinite(xy).all(axis=1)
    keep = ~unplaced[data.obs_landmark]  # an anchor not placed is not read until it is
    on = data.keep_sightings(keep).with_landmarks(np.where(unplaced[:, None], 0.0, xy))
    model = first.model.replace(landmarks=replace(learned, xy=np.where(unplaced[:, None], 0.0, xy)))
    res = composed(on, cfg.replace(refine_from=0))(model)
    found = res.model.landmarks
    xy = np.where(unplaced[:, None], np.nan, found.xy)
    used = np.zeros(data.n_observations, dtype=bool)
    if res.posteriors is not None:
        used[np.flatnonzero(keep)] = res.posteriors.obs_used
    placed = placed_landmarks(replace(found, xy=xy), data, used)
    return replace(res, model=res.model.replace(landmarks=placed))


def multilaterate(model: EMModel, path: np.ndarray, data: LandmarkLog, held: np.ndarray) -> np.ndarray:
    """(L, 2) each not-held anchor's position from its ranges (the first channel's reading, inverted
    through its learned function at zero bearing) off the sensor on ``path``: linear least squares on
    the squared ranges, then Gauss-Newton on the ranges themselves; NaN where ranged fewer than
    ``MIN_RANGES`` times. Held anchors keep the log's positions."""
    ch = model.sensor.channels[0]
    reading = model.sensor.readings_of(data)[0][:, 0]
    grid = np.linspace(0.0, 20000.0, 2001)
    f = ch.function(grid)
    ok_f = np.all(np.diff(f) > 0)
    distance = np.interp(reading, f, grid) if ok_f else reading  # f rising: invert it; else the reading itself
    at = sensor_poses(path[data.obs_step], model.sensor.mount.as_array())[:, :2]
    out = np.where(held[:, None], data.landmarks_xy, np.nan)
    for j in np.flatnonzero(~held):
        k = np.flatnonzero((data.obs_landmark == j) & np.isfinite(distance))
        if k.size < MIN_RANGES:
            continue
        s, d = at[k], distance[k]
        # |a|^2 - 2 a.s + |s|^2 = d^2: subtracting the mean row leaves a linear system in a
        A = -2.0 * (s - s.mean(axis=0))
        b = (d**2 - (s**2).sum(axis=1)) - (d**2 - (s**2).sum(axis=1)).mean()
        a, *_ = np.linalg.lstsq(A, b, rcond=None)
        for _ in range(GAUSS_NEWTON_STEPS):
            diff = a - s
            r = np.maximum(np.hypot(*diff.T), 1e-9)
            J = diff / r[:, None]
            step, *_ = np.linalg.lstsq(J, d - r, rcond=None)
            a = a + step
            if np.abs(step).max() < 1e-3:
                break
        out[j] = a
    return out
