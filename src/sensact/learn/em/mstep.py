"""The M-step (sec. 4.3): a new action model, sensor model, prior and (optionally) Sigma_m from the
E-step's posteriors. ``learn/em/actions.py`` holds the action and motion-noise updates."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sensact.core.pose_models import apply_displacement
from sensact.learn.em.actions import motion_noise, motion_second_moments, step_motion_var, turning_variance
from sensact.learn.em.estep import Posteriors
from sensact.learn.em.landmark_step import landmark_update, normal_equations
from sensact.learn.em.mount import mount_update
from sensact.learn.em.stage import Stage
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.models.landmark_map import LandmarkMap
from sensact.models.landmark_sensor import LandmarkSensor, SampledSightings


def sample_gamma(
    post: Posteriors, steps: np.ndarray, n_samples: int, rng: np.random.Generator, sigma_points: bool = False
) -> np.ndarray:
    """``n_samples`` poses per step from N(mu_gamma,t, Sigma_gamma,t) as mu + L z (sec. 4.3.2); with
    ``sigma_points``, instead the 2n points ``z = +-sqrt(n) e_i`` of the unscented transform, which have
    the posterior's mean and covariance exactly: the M-step is then a deterministic map, as SQUAREM needs
    (``squarem.py``), and its expectations are those of infinitely many samples to third order.

    Returns ``(n_samples, len(steps), n)`` (``(2n, len(steps), n)``). numpy's normal generator stands in
    for Box-Muller.
    Any square root L of Sigma_gamma draws the same poses in distribution. On a plane L is the
    Cholesky factor of the covariance in the robot's own frame (at the mean heading), turned into the
    map's: then a map turned together with its log draws the same poses turned, so the learned model
    does not depend on which way the map's axes point.
    """
    mu = post.mean_gamma[steps]
    cov = post.cov_gamma[steps]
    n = mu.shape[1]
    if n == 3:
        c, s = np.cos(mu[:, 2]), np.sin(mu[:, 2])
        cov = into_robot_frame(cov, c, s)
    jitter = 1e-12 * np.maximum(np.trace(cov, axis1=1, axis2=2), 1e-300)[:, None, None] * np.eye(n)
    L = np.linalg.cholesky(cov + jitter)
    if sigma_points:
        z = np.broadcast_to(np.sqrt(n) * np.r_[np.eye(n), -np.eye(n)][:, None, :], (2 * n, len(steps), n))
    else:
        z = rng.standard_normal((n_samples, len(steps), n))
    offsets = np.einsum("kij,skj->ski", L, z)
    if n == 3:  # the robot-frame offsets, applied at the mean pose as a motion is
        return np.stack([apply_displacement(mu, d) for d in offsets])
    return mu[None] + offsets


def into_robot_frame(cov: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``T' Sigma T`` for each planar pose covariance, ``T`` the turn by the heading (cos ``c``, sin
    ``s``) in x-y; written out, since numpy's batched 3 x 3 products are several times slower."""
    out = cov.copy()
    xx, xy, yy = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    out[:, 0, 0] = c * c * xx + 2 * c * s * xy + s * s * yy
    out[:, 1, 1] = s * s * xx - 2 * c * s * xy + c * c * yy
    out[:, 0, 1] = out[:, 1, 0] = (c * c - s * s) * xy + c * s * (yy - xx)
    out[:, 0, 2] = out[:, 2, 0] = c * cov[:, 0, 2] + s * cov[:, 1, 2]
    out[:, 1, 2] = out[:, 2, 1] = c * cov[:, 1, 2] - s * cov[:, 0, 2]
    return out


def sensor_and_map(
    post: Posteriors,
    data: LandmarkLog,
    n_samples: int,
    rng: np.random.Generator,
    previous: LandmarkSensor,
    fit_bearing_terms: bool = True,
    mount_free: tuple[bool, bool, bool] = (False, False, False),
    landmarks: LandmarkMap | None = None,
    sigma_points: bool = False,
) -> tuple[LandmarkSensor, LandmarkMap | None]:
    """Eq. 4.25 (each f_i by regression on sampled distances), eq. 4.27 (each sigma_i) and eq. 4.28
    (sigma_2), over the readings the E-step used.

    A reading counts with its E-step weight: 1 for a Gaussian channel, the Student-t weight for a
    robust one (the t-distribution's EM update of location and scale), 0 if it was missing, outside
    its window, gated or pruned. Each f_i keeps the degree of ``previous``'s polynomial (the starting
    model sets it: a cubic in the thesis). Without ``fit_bearing_terms`` the bearing terms are held.
    The ``mount_free`` components of the sensor's mount are updated first, on the same samples
    (``mount.py``); every distance and bearing is then measured from the sensor at its mount.

    With a learned map (``landmarks``), its free positions are updated next on the same samples
    (``landmark_step.py``), then f on the distances to them; a map whose scale comes from the range readings
    holds the first length-reading channel's slope at 1 in the middle of its distances.
    """
    weights = post.weights * post.obs_used[:, None]
    rows = np.flatnonzero(weights.any(axis=1))
    if rows.size == 0:
        return previous, landmarks
    poses = sample_gamma(post, data.obs_step[rows], n_samples, rng, sigma_points)  # (S, R, n)
    seen = SampledSightings(
        poses, data.obs_landmark[rows], previous.readings_of(data)[0][rows], weights[rows], data.obs_bearing_rad[rows]
    )
    if any(mount_free):
        lm = data.landmarks_xy[seen.landmark]
        mount = mount_update(poses, lm, seen.readings, seen.weights, seen.bearings, previous, mount_free)
        previous = replace(previous, mount=mount)
    metric = -1
    if landmarks is not None:
        xy, sd = landmark_update(seen, previous, landmarks.xy, landmarks.learned)
        landmarks = replace(landmarks, xy=xy, sd=np.where(landmarks.learned[:, None], sd, np.nan))
        if landmarks.scale == "range":
            metric = next((c for c, ch in enumerate(previous.channels) if ch.name.endswith("_mm")), -1)
    xy = data.landmarks_xy if landmarks is None else landmarks.xy
    sensor = previous.update(seen, xy, data.geometry, fit_bearing_terms=fit_bearing_terms, metric=metric)
    return sensor, landmarks


def map_normal_equations(
    post: Posteriors, data: LandmarkLog, sensor: LandmarkSensor, n_samples: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The landmark M-step's information and gradient at ``data``'s map from one fit's posteriors, over the
    sightings its E-step used (``landmark_step.normal_equations``); a fleet sums them over its logs."""
    weights = post.weights * post.obs_used[:, None]
    rows = np.flatnonzero(weights.any(axis=1))
    L = len(data.landmarks_xy)
    if rows.size == 0:
        return np.zeros((L, 2, 2)), np.zeros((L, 2))
    poses = sample_gamma(post, data.obs_step[rows], n_samples, rng)
    readings = sensor.readings_of(data)[0][rows]
    seen = SampledSightings(poses, data.obs_landmark[rows], readings, weights[rows], data.obs_bearing_rad[rows])
    return normal_equations(seen, sensor, data.landmarks_xy)


def prior(post: Posteriors, floor_var: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """pi <- gamma_0 (sec. 4.3), with a variance floor so that it cannot collapse to a point."""
    cov = post.cov_gamma[0].copy()
    cov[np.diag_indices_from(cov)] = np.maximum(np.diag(cov), floor_var)
    return post.mean_gamma[0].copy(), cov


def m_step(
    post: Posteriors,
    data: LandmarkLog,
    model: EMModel,
    *,
    n_samples: int,
    floor_var: np.ndarray,
    rng: np.random.Generator,
    stage: Stage,
    motion_floor_sd: np.ndarray | None = None,
    max_delay_steps: int = 0,
    sigma_points: bool = False,
) -> EMModel:
    """Every update of sec. 4.3 that ``stage`` allows (its contract: Sigma_m, shared or per action as the
    model's ``motion_sd`` has one row or one per action; the channels' bearing terms; the mount's free
    components); the action model, f, the sigmas and the prior always."""
    if model.turn_var is None:
        var = np.broadcast_to((model.motion_sd**2)[0], post.disp_mean.shape)
    else:  # the steps' own variances: a turn's heading counts for less
        var = step_motion_var(model, data)[:-1]
    action = model.action.update(data, post.disp_mean, var, max_delay_steps)  # eq. 4.18 or its least squares
    motion_sd, turn_var = model.motion_sd, model.turn_var
    if stage.motion_noise:
        floor = np.zeros(model.prior_mean.size) if motion_floor_sd is None else motion_floor_sd
        groups = data.actions[:-1] if model.per_action_noise else None
        mean_disp = action.step_velocity(data)[:-1] * data.dt_s
        second = motion_second_moments(post.disp_mean, post.disp_cov, mean_disp)
        motion_sd = motion_noise(second, groups, motion_sd.shape[0], floor, motion_sd)
        if turn_var is not None:
            turn = mean_disp[:, 2] / data.dt_s
            a, turn_var = turning_variance(second[:, 2], turn, floor[2] ** 2, (model.motion_sd[0, 2] ** 2, turn_var))
            motion_sd = motion_sd.copy()
            motion_sd[0, 2] = np.sqrt(a)
    learned = model.landmarks if stage.landmarks else None
    sensor, landmarks = sensor_and_map(
        post, data, n_samples, rng, model.sensor, stage.bearing_terms, stage.mount, learned, sigma_points
    )
    mean0, cov0 = prior(post, floor_var)
    if model.landmarks is not None:
        landmarks = landmarks or model.landmarks
        if model.landmarks.held.sum() < 2:  # the start fixes the map's frame: pi stays where it is
            mean0, cov0 = model.prior_mean, model.prior_cov
    return model.replace(
        action=action,
        sensor=sensor,
        prior_mean=mean0,
        prior_cov=cov0,
        motion_sd=motion_sd,
        turn_var=turn_var,
        landmarks=model.landmarks if model.landmarks is None else landmarks,
    )
