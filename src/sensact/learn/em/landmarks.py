"""The landmarks' positions, learned in the M-step when nobody surveyed them (issue 92; beyond the thesis,
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

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import landmark_bearing, sensor_poses
from sensact.models.landmark_sensor import LandmarkSensor

GAUSS_NEWTON_STEPS = 5


def landmark_update(
    poses: np.ndarray,
    landmark: np.ndarray,
    readings: np.ndarray,
    weights: np.ndarray,
    bearings: np.ndarray,
    sensor: LandmarkSensor,
    xy: np.ndarray,
    free: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The free landmarks' positions maximizing ``Q`` on ``poses`` ((S, R, 3) samples of the robot at the
    R sightings, whose landmarks are ``landmark``), and each position's sd (NaN where held or unplaced)."""
    S = poses.shape[0]
    L = len(xy)
    out = np.array(xy, dtype=float, copy=True)
    at = sensor_poses(poses.reshape(-1, 3), sensor.mount.as_array())
    idx = np.tile(landmark, S)
    b_s = np.tile(bearings, S)
    info = np.zeros((L, 2, 2))
    for _ in range(GAUSS_NEWTON_STEPS):
        info, grad = np.zeros((L, 2, 2)), np.zeros((L, 2))
        lm = out[idx]
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
        ok = free & (np.linalg.det(info) > 1e-12 * np.maximum(np.trace(info, axis1=1, axis2=2), 1e-300) ** 2)
        if not ok.any():
            break
        step = np.linalg.solve(info[ok], grad[ok][:, :, None])[:, :, 0]
        out[ok] += step
        if np.max(np.abs(step)) < 1e-3:  # mm
            break
    sd = np.full((L, 2), np.nan)
    ok = free & (np.linalg.det(info) > 0)
    if ok.any():
        sd[ok] = np.sqrt(np.diagonal(np.linalg.inv(info[ok]), axis1=1, axis2=2))
    return out, sd


def _accumulate(info: np.ndarray, grad: np.ndarray, idx: np.ndarray, J: np.ndarray, e: np.ndarray, w: np.ndarray):
    """Add each row's ``w J'J`` and ``w J' e`` to its landmark's."""
    for a in range(2):
        grad[:, a] += np.bincount(idx, weights=w * J[:, a] * e, minlength=len(grad))
        for b in range(2):
            info[:, a, b] += np.bincount(idx, weights=w * J[:, a] * J[:, b], minlength=len(info))
