"""The M-step (sec. 4.3): new action table, sensor model and prior from the E-step's posteriors."""

from __future__ import annotations

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.polyfit import weighted_polyfit
from sensact.core.pose_models import landmark_bearing, landmark_distance
from sensact.learn.em.estep import Posteriors
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.models.landmark_sensor import LandmarkSensor
from sensact.models.polynomial import Polynomial1D


def action_velocities(post: Posteriors, data: LandmarkLog, previous: np.ndarray) -> np.ndarray:
    """Eq. 4.18: mu_a is the mean of D(mu_xi,t) over Q(a) = {t : c_t = a}, divided by dt.

    An action that never ran keeps its previous velocity.
    """
    a = data.actions[:-1]
    valid = a >= 0
    counts = np.bincount(a[valid], minlength=data.n_actions).astype(float)
    out = np.array(previous, dtype=float, copy=True)
    seen = counts > 0
    for i in range(out.shape[1]):
        sums = np.bincount(a[valid], weights=post.disp_mean[valid, i], minlength=data.n_actions)
        out[seen, i] = sums[seen] / counts[seen] / data.dt_s
    return out


def sample_gamma(post: Posteriors, steps: np.ndarray, n_samples: int, rng: np.random.Generator) -> np.ndarray:
    """``n_samples`` poses per step from N(mu_gamma,t, Sigma_gamma,t) as mu + L z (sec. 4.3.2).

    Returns ``(n_samples, len(steps), n)``. numpy's normal generator stands in for Box-Muller.
    """
    mu = post.mean_gamma[steps]
    cov = post.cov_gamma[steps]
    n = mu.shape[1]
    jitter = 1e-12 * np.maximum(np.trace(cov, axis1=1, axis2=2), 1e-300)[:, None, None] * np.eye(n)
    L = np.linalg.cholesky(cov + jitter)
    z = rng.standard_normal((n_samples, len(steps), n))
    return mu[None] + np.einsum("kij,skj->ski", L, z)


def sensor_model(
    post: Posteriors, data: LandmarkLog, degree: int, n_samples: int, rng: np.random.Generator, previous: LandmarkSensor
) -> LandmarkSensor:
    """Eq. 4.25 (f by regression on sampled distances), eq. 4.27 (sigma_1) and eq. 4.28 (sigma_2).

    Frames without an observation, and pruned observations, take no part (sec. 4.4.1).
    """
    has_h = np.isfinite(data.obs_height_px)
    has_b = np.isfinite(data.obs_bearing_rad) if data.geometry == "planar" else np.zeros_like(has_h)
    rows = np.flatnonzero(post.obs_used & (has_h | has_b))
    if has_h[rows].sum() <= degree + 1:
        return previous
    w = sample_gamma(post, data.obs_step[rows], n_samples, rng)  # (S, R, n)
    lm = data.landmarks_xy[data.obs_landmark[rows]]
    h_rows = has_h[rows]
    dist = np.concatenate([landmark_distance(w[s], lm, data.mode)[h_rows] for s in range(n_samples)])
    height = np.tile(data.obs_height_px[rows][h_rows], n_samples)
    center, scale = float(dist.mean()), float(dist.std()) or 1.0
    coef = weighted_polyfit(dist, height, degree, center=center, scale=scale)
    prev = previous.height
    f = Polynomial1D(tuple(coef), center, scale, prev.input_name, prev.input_unit, prev.output_unit)
    sigma_h = float(np.sqrt(np.mean((f(dist) - height) ** 2)))
    sigma_b = previous.sigma_bearing_rad
    b_rows = has_b[rows]
    if b_rows.any():
        ob = data.obs_bearing_rad[rows][b_rows]
        err = np.concatenate([wrap_angle(landmark_bearing(w[s][b_rows], lm[b_rows]) - ob) for s in range(n_samples)])
        sigma_b = float(np.sqrt(np.mean(err**2)))
    return LandmarkSensor(f, max(sigma_h, 1e-9), None if sigma_b is None else max(sigma_b, 1e-9))


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
    degree: int,
    n_samples: int,
    floor_var: np.ndarray,
    rng: np.random.Generator,
) -> EMModel:
    velocities = action_velocities(post, data, model.action.velocities)
    sensor = sensor_model(post, data, degree, n_samples, rng, model.sensor)
    mean0, cov0 = prior(post, floor_var)
    return model.replace(
        action=model.action.with_velocities(velocities), sensor=sensor, prior_mean=mean0, prior_cov=cov0
    )
