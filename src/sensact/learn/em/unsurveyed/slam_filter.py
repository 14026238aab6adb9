"""The landmark map carried by a filter (docs/map.md): where EM learns a map nobody surveyed.

Learned as a parameter of the M-step, the map and the path trade along a ridge: moving both together
barely changes the likelihood, so EM's alternating steps move them a little at a time and stop far from
the top (MRCLAM Dataset 6 robot 3: -6197 against the survey's -5593). Carried in the filter's state, as
EKF-SLAM does (sec. 2.4's filter with the landmarks appended, the SLAM literature the thesis cites), the
path and the map move together in every pass. So a map-free fit runs in rounds: one forward pass of the
filter over (pose, landmarks) with the current models gives the map (the landmarks do not move, so their
last filtered estimate is their smoothed one), then EM learns the models on that map as on a survey; the
rounds end when the likelihood stops rising, and the most likely round is kept.
"""

from __future__ import annotations

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import PLANAR, observe_bearing, observe_height
from sensact.learn.em.actions import step_motion_var
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

GATE = 25.0  # chi-square, 2 dof: a sighting this far off (a misread barcode) is not used
MAP_PRIOR_SD_MM = 300.0  # how far the filter may move each landmark from the last round's map


def filtered_map(
    model: EMModel, data: LandmarkLog, prior_xy: np.ndarray, held: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(L, 2) landmark positions and their sds from one filter pass over (pose, landmarks) under ``model``
    (its first reading channel and the bearing, at its mount), each landmark starting at ``prior_xy`` with
    sd ``MAP_PRIOR_SD_MM`` (``held`` ones at theirs, fixed); the robot starts at the model's prior."""
    L = len(prior_xy)
    n = 3 + 2 * L
    x = np.r_[model.prior_mean, np.nan_to_num(prior_xy).ravel()]
    P = np.zeros((n, n))
    P[:3, :3] = model.prior_cov
    P[3:, 3:] = np.diag(np.repeat(np.where(held, 0.0, MAP_PRIOR_SD_MM**2), 2))
    vel = model.action.step_velocity(data)
    var = step_motion_var(model, data, vel)
    ch = model.sensor.channels[0]
    readings = model.sensor.readings_of(data)[0][:, 0]
    gains = ch.bearing_gain(data.obs_bearing_rad) if ch.bearing_terms else np.zeros(data.n_observations)
    coef, mount = np.asarray(ch.function.coef, dtype=float), model.sensor.mount.as_array()
    noise = np.diag([ch.sigma**2, model.sensor.sigma_bearing_rad**2])
    Hr, Hb, H = np.zeros(3), np.zeros(3), np.zeros((2, 5))
    for t in range(data.n_steps):
        for k in range(data.obs_ptr[t], data.obs_ptr[t + 1]):
            o, b, j = readings[k], data.obs_bearing_rad[k], 3 + 2 * int(data.obs_landmark[k])
            if not (np.isfinite(o) and np.isfinite(b)):
                continue
            fc, sc = ch.function.center, ch.function.scale
            pr = observe_height(PLANAR, x[:3], x[j], x[j + 1], coef, fc, sc, gains[k], mount, Hr)  # eq. 4.19
            pb = observe_bearing(x[:3], x[j], x[j + 1], mount, Hb)
            H[0, :3], H[0, 3:], H[1, :3], H[1, 3:] = (
                Hr,
                -Hr[:2],
                Hb,
                -Hb[:2],
            )  # a landmark moves as the robot's opposite
            idx = [0, 1, 2, j, j + 1]
            PH = P[:, idx] @ H.T
            S = H @ PH[idx] + noise
            innov = np.array([o - pr, wrap_angle(b - pb)])
            if innov @ np.linalg.solve(S, innov) > GATE:
                continue
            K = np.linalg.solve(S, PH.T).T
            x += K @ innov
            P -= K @ PH.T
            P = 0.5 * (P + P.T)
        if t + 1 < data.n_steps:  # the time update, eq. 2.28; the landmarks stay where they are
            c, s = np.cos(x[2]), np.sin(x[2])
            v = vel[t] * data.dt_s
            x[0] += c * v[0] - s * v[1]
            x[1] += s * v[0] + c * v[1]
            x[2] += v[2]
            F = np.array([[1.0, 0.0, -s * v[0] - c * v[1]], [0.0, 1.0, c * v[0] - s * v[1]], [0.0, 0.0, 1.0]])
            R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            P[:3, :] = F @ P[:3, :]
            P[:, :3] = P[:, :3] @ F.T
            P[:3, :3] += R @ np.diag(var[t]) @ R.T
    xy = x[3:].reshape(L, 2).copy()
    sd = np.sqrt(np.diagonal(P)[3:].reshape(L, 2))
    seen = np.bincount(data.obs_landmark, minlength=L) > 0
    xy[~seen & ~held], sd[~seen | held] = np.nan, np.nan
    return xy, sd
