"""A log drawn from a learned model (a parametric bootstrap, docs/uncertainty.md): the log's own commands, steps, map,
sighting times and landmarks, with the path and every reading drawn from the model EM assumes.

The path follows the time update of the filter (``core/ekf_smoother.py``): ``w_t+1 = w_t + R(theta_t)
(A(c_t) dt + e_t)`` with ``e_t`` drawn from Sigma_m in the robot frame (eq. 2.28; per action, and growing
with the turn rate under ``turn_var``, as ``actions.step_motion_var`` gives it), from ``w_0`` drawn from
the prior ``pi(w_0)``. Each sighting reads the landmark from the sensor at its mount (eq. 4.19, as
``core.pose_models.observe_height`` and ``observe_bearing`` predict it): the bearing with noise
``sigma_2``, then each channel ``f_i(d) + d sum_k a_k b^k`` (its bearing terms at the measured bearing)
with noise ``sigma_i``; a Student-t reading's noise is Student-t with its degrees of freedom. A reading
or bearing the log lacks stays missing, so the draw sees what the robot saw, and nothing more.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import PLANAR, TRACK, landmark_bearing, landmark_distance, sensor_poses
from sensact.learn.em.actions import step_motion_var
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel


def draw_path(model: EMModel, data: LandmarkLog, rng: np.random.Generator) -> np.ndarray:
    """``(T, n)``: a path of the model's motion under the log's commands, from ``w_0 ~ pi(w_0)``."""
    velocity = model.action.step_velocity(data)
    sd = np.sqrt(step_motion_var(model, data, velocity))
    n = velocity.shape[1]
    disp = velocity * data.dt_s + rng.standard_normal(velocity.shape) * sd
    w0 = rng.multivariate_normal(model.prior_mean, model.prior_cov)
    T = data.n_steps
    if data.geometry.state_is_range:  # a forward velocity shortens the distance to the beacon
        return (w0[0] - np.concatenate([[0.0], np.cumsum(disp[: T - 1, 0])])).reshape(T, n)
    theta = w0[2] + np.concatenate([[0.0], np.cumsum(disp[: T - 1, 2])])
    c, s = np.cos(theta[:-1]), np.sin(theta[:-1])
    dx = c * disp[: T - 1, 0] - s * disp[: T - 1, 1]
    dy = s * disp[: T - 1, 0] + c * disp[: T - 1, 1]
    x = w0[0] + np.concatenate([[0.0], np.cumsum(dx)])
    y = w0[1] + np.concatenate([[0.0], np.cumsum(dy)])
    return np.column_stack([x, y, theta])


def _noise(robust: str, dof: float, size: int, rng: np.random.Generator) -> np.ndarray:
    """Unit-scale reading noise: Student-t with ``dof`` degrees of freedom for a Student-t reading."""
    return rng.standard_t(dof, size) if robust == "student_t" else rng.standard_normal(size)


def draw_readings(
    model: EMModel, data: LandmarkLog, poses: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """``(readings (K, C), bearings (K,))`` the model reads at each of the log's sightings from ``poses``,
    missing where the log's are."""
    sensor = model.sensor
    at = poses[data.obs_step]
    K = data.n_observations
    bearing = np.full(K, np.nan)
    if data.geometry.has_heading:
        where = sensor_poses(at, sensor.mount.as_array())
        landmarks = data.landmarks_xy[data.obs_landmark]
        dist = landmark_distance(where, landmarks, PLANAR)
        seen = np.isfinite(data.obs_bearing_rad)
        if sensor.reads_bearing:
            true_bearing = landmark_bearing(where, landmarks)
            noise = _noise(sensor.bearing_robust, sensor.bearing_robust_param, K, rng)
            bearing = np.where(seen, wrap_angle(true_bearing + sensor.sigma_bearing_rad * noise), np.nan)
    else:
        dist = landmark_distance(at, None, TRACK)
    readings = np.full((K, len(sensor.channels)), np.nan)
    measured = np.where(np.isfinite(bearing), bearing, 0.0)
    for i, ch in enumerate(sensor.channels):
        column = data.reading_names.index(ch.name)
        mean = ch.function(dist) + dist * ch.bearing_gain(measured)
        value = mean + ch.sigma * _noise(ch.robust, ch.robust_param, K, rng)
        readings[:, i] = np.where(np.isfinite(data.obs_readings[:, column]), value, np.nan)
    return readings, bearing


def simulate_from_model(model: EMModel, data: LandmarkLog, seed: int) -> tuple[LandmarkLog, np.ndarray]:
    """A log like ``data`` drawn from ``model`` (seeded), and the path it was drawn along."""
    rng = np.random.default_rng(seed)
    poses = draw_path(model, data, rng)
    readings, bearing = draw_readings(model, data, poses, rng)
    # the model's channels in the log's column order; a column the model does not read stays as it was
    columns = np.array(data.obs_readings, copy=True)
    for i, ch in enumerate(model.sensor.channels):
        columns[:, data.reading_names.index(ch.name)] = readings[:, i]
    if data.geometry.state_is_range:
        bearing = data.obs_bearing_rad
    drawn = replace(data, obs_readings=columns, obs_bearing_rad=bearing, source=f"{data.source} (drawn, seed {seed})")
    return drawn, poses
