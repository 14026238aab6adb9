"""The landmarks' positions, learned in the M-step when nobody surveyed them (docs/map.md; beyond the thesis,
whose map is given, and the map-as-parameter EM of the SLAM literature its ch. 5 cites).

**M-step.** As sec. 4.3 derives each update, only the observation terms of the expected complete-data
log-likelihood depend on landmark ``l``'s position ``p_l``::

    Q(p_l) = - sum_{k: landmark l} sum_i w_ki E_gamma[(o_ki - f_i(d_k) - g_ki d_k)^2] / (2 sigma_i^2)
             - sum_{k: landmark l} w_kb E_gamma[(o_kb - ang_k)^2] / (2 sigma_2^2)

with ``d_k`` and ``ang_k`` read from the sensor's pose at sighting k to ``p_l`` (eq. 4.19). The
expectation is taken over the E-step's sampled poses, as eq. 4.25's; each landmark's ``Q`` is maximized
by a few Gauss-Newton steps from its last position, every landmark at once. The sd beside each
position is the Gauss-Newton curvature's: how far the sightings alone, on the smoothed path, pin it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import landmark_bearing, sensor_poses
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.landmark_map import LandmarkMap
from sensact.models.landmark_sensor import LandmarkSensor, SampledSightings

GAUSS_NEWTON_STEPS = 5
# a learned position is reported (placed) when this many sightings were used and its sd is at most this;
# the rest are reported as not placed, not guessed (docs/map.md)
MIN_SIGHTINGS_TO_PLACE = 5
MAX_PLACED_SD_MM = 250.0


def sightings_per_landmark(data: LandmarkLog, used: np.ndarray | None = None) -> np.ndarray:
    """(L,) how many sightings of each landmark EM used (every one when ``used`` is None)."""
    keep = np.ones(data.n_observations, dtype=bool) if used is None else np.asarray(used, dtype=bool)
    return np.bincount(data.obs_landmark[keep], minlength=len(data.landmarks_xy))


def placed_landmarks(learned: LandmarkMap, data: LandmarkLog, used: np.ndarray | None) -> LandmarkMap:
    """``learned`` with each learned position marked placed or not: seen often enough (``used`` sightings)
    and pinned to ``MAX_PLACED_SD_MM`` by them."""
    n = sightings_per_landmark(data, used)
    sure = np.isfinite(learned.sd).all(axis=1) & (np.nan_to_num(learned.sd, nan=np.inf).max(axis=1) <= MAX_PLACED_SD_MM)
    return replace(
        learned, placed=learned.held | (np.isfinite(learned.xy).all(axis=1) & (n >= MIN_SIGHTINGS_TO_PLACE) & sure)
    )


def landmark_update(
    seen: SampledSightings, sensor: LandmarkSensor, xy: np.ndarray, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The ``free`` landmarks' positions maximizing ``Q`` on ``seen``, from ``xy``, and each position's sd
    (NaN where held or unplaced)."""
    L = len(xy)
    out = np.array(xy, dtype=float, copy=True)
    info = np.zeros((L, 2, 2))
    for _ in range(GAUSS_NEWTON_STEPS):
        info, grad = normal_equations(seen, sensor, out)
        step, ok = gauss_newton_step(info, grad, free)
        if not ok.any():
            break
        out[ok] += step[ok]
        if np.max(np.abs(step[ok])) < 1e-3:  # mm
            break
    return out, position_sd(info, free)


def gauss_newton_step(info: np.ndarray, grad: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each free landmark's Gauss-Newton step on ``Q`` ((L, 2); zero where not taken) and where one was
    taken: where its sightings pin both coordinates."""
    ok = free & (np.linalg.det(info) > 1e-12 * np.maximum(np.trace(info, axis1=1, axis2=2), 1e-300) ** 2)
    step = np.zeros((len(info), 2))
    if ok.any():
        step[ok] = np.linalg.solve(info[ok], grad[ok][:, :, None])[:, :, 0]
    return step, ok


def position_sd(info: np.ndarray, free: np.ndarray) -> np.ndarray:
    """(L, 2) each free position's sd from ``Q``'s curvature; NaN where held or not pinned."""
    sd = np.full((len(info), 2), np.nan)
    ok = free & (np.linalg.det(info) > 0)
    if ok.any():
        sd[ok] = np.sqrt(np.diagonal(np.linalg.inv(info[ok]), axis1=1, axis2=2))
    return sd


def normal_equations(seen: SampledSightings, sensor: LandmarkSensor, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Q``'s Gauss-Newton information (L, 2, 2) and gradient (L, 2) in each landmark's position at ``xy``:
    sums over sightings, so that logs seeing the same landmarks add theirs (``fleet --shared-map``)."""
    poses, landmark, readings, weights, bearings = seen.poses, seen.landmark, seen.readings, seen.weights, seen.bearings
    S = poses.shape[0]
    L = len(xy)
    at = sensor_poses(poses.reshape(-1, 3), sensor.mount.as_array())
    idx = np.tile(landmark, S)
    b_s = np.tile(bearings, S)
    info, grad = np.zeros((L, 2, 2)), np.zeros((L, 2))
    lm = np.asarray(xy, dtype=float)[idx]
    dx, dy = lm[:, 0] - at[:, 0], lm[:, 1] - at[:, 1]
    d = np.maximum(np.hypot(dx, dy), 1e-9)
    unit = np.column_stack([dx / d, dy / d])  # d d / d p
    for ci, ch in enumerate(sensor.channels):
        w = np.tile(weights[:, ci], S) / ch.sigma**2 / S
        use = (w > 0) & np.isfinite(np.tile(readings[:, ci], S))
        if not use.any():
            continue
        gain = ch.bearing_gain(b_s[use]) if ch.bearing_terms else 0.0
        e = np.tile(readings[:, ci], S)[use] - ch.function(d[use]) - gain * d[use]
        J = (ch.function.slope(d[use]) + gain)[:, None] * unit[use]  # d prediction / d p
        _accumulate(info, grad, idx[use], J, e, w[use])
    if sensor.reads_bearing:
        w = np.tile(weights[:, -1], S) / sensor.sigma_bearing_rad**2 / S
        use = (w > 0) & np.isfinite(b_s)
        if use.any():
            e = wrap_angle(b_s[use] - landmark_bearing(at[use], lm[use]))
            J = np.column_stack([-dy[use], dx[use]]) / (d[use] ** 2)[:, None]  # d ang / d p
            _accumulate(info, grad, idx[use], J, e, w[use])
    return info, grad


def _accumulate(info: np.ndarray, grad: np.ndarray, idx: np.ndarray, J: np.ndarray, e: np.ndarray, w: np.ndarray):
    """Add each row's ``w J'J`` and ``w J' e`` to its landmark's."""
    for a in range(2):
        grad[:, a] += np.bincount(idx, weights=w * J[:, a] * e, minlength=len(grad))
        for b in range(2):
            info[:, a, b] += np.bincount(idx, weights=w * J[:, a] * J[:, b], minlength=len(info))
