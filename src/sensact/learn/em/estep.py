"""The E-step (sec. 4.2): the posterior over poses given every action and observation.

``e_step(model, data)`` runs the compiled forward EKF and two-filter smoother of
``sensact.core.ekf_smoother`` and returns ``Posteriors``: alpha, gamma, the displacement moments under
xi, and ``log P(O | C, lambda)`` (eq. 4.14).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.core.ekf_smoother import OK, ekf_smoother
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel


@dataclass(frozen=True, eq=False)
class Posteriors:
    loglik: float  # log P(O | C, lambda), eq. 4.14
    ok: bool  # False if a covariance stopped being positive definite
    mean_alpha: np.ndarray  # (T, n) filtered means
    cov_alpha: np.ndarray  # (T, n, n)
    mean_gamma: np.ndarray  # (T, n) smoothed means, eq. 4.9
    cov_gamma: np.ndarray  # (T, n, n) eq. 4.10
    disp_mean: np.ndarray  # (T-1, n) D(mu_xi,t), eq. 4.18
    disp_cov: np.ndarray  # (T-1, n, n) covariance of the linearized D under xi_t
    obs_used: np.ndarray  # (K,) bool; False for pruned observations
    n_used: int


def motion_variance(geometry: str, motion_sd_mm: float, motion_sd_rad: float) -> np.ndarray:
    """The diagonal of Sigma_m in the robot frame (sec. 4.4.1)."""
    if geometry == "track":
        return np.array([motion_sd_mm**2])
    return np.array([motion_sd_mm**2, motion_sd_mm**2, motion_sd_rad**2])


def e_step(
    model: EMModel,
    data: LandmarkLog,
    motion_var: np.ndarray,
    *,
    obs_use: np.ndarray | None = None,
    prune_rad_per_step: float = 0.0,
) -> Posteriors:
    """Alpha, gamma and xi for ``model`` on ``data``. ``obs_use`` masks observations (a copy is pruned)."""
    if model.geometry != data.geometry:
        raise ValueError(f"a {model.geometry} model cannot run on a {data.geometry} log")
    T = data.n_steps
    n = model.prior_mean.size
    use = np.ones(data.n_observations, dtype=np.bool_) if obs_use is None else np.array(obs_use, dtype=np.bool_)
    f = model.sensor.height
    sb = model.sensor.sigma_bearing_rad
    mu_a = np.empty((T, n))
    P_a = np.empty((T, n, n))
    mu_g = np.empty((T, n))
    P_g = np.empty((T, n, n))
    d_mu = np.full((T - 1, n), np.nan)
    d_P = np.full((T - 1, n, n), np.nan)
    status, loglik, n_used = ekf_smoother(
        data.mode,
        data.dt_s,
        data.actions,
        np.ascontiguousarray(model.action.velocities),
        np.ascontiguousarray(motion_var, dtype=float),
        model.prior_mean.copy(),
        model.prior_cov.copy(),
        data.obs_ptr,
        data.obs_landmark,
        data.obs_height_px,
        data.obs_bearing_rad,
        use,
        data.landmarks_xy if len(data.landmarks_xy) else np.zeros((1, 2)),
        np.asarray(f.coef, dtype=float),
        f.center,
        f.scale,
        model.sensor.sigma_height_px**2,
        (sb if sb is not None else 1.0) ** 2,
        float(prune_rad_per_step),
        mu_a,
        P_a,
        mu_g,
        P_g,
        d_mu,
        d_P,
    )
    ok = status == OK and np.isfinite(loglik)
    return Posteriors(float(loglik), bool(ok), mu_a, P_a, mu_g, P_g, d_mu, d_P, use, int(n_used))
