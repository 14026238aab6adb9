"""The EM loop (secs. 4.1 and 4.4.1): alternate E- and M-steps and keep the most likely model.

The likelihood of an approximate EM fluctuates, so the loop stops when ``patience`` iterations (50 in
the thesis) pass without a new best ``log P(O | C, lambda)``, or at ``max_iterations``. Outliers are
pruned in the first iteration only, and stay pruned. Ctrl-C ends the loop cleanly with the best model
so far (``stop_reason == "interrupted"``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from sensact.learn.em.config import EMConfig
from sensact.learn.em.estep import Posteriors, e_step, motion_variance
from sensact.learn.em.mstep import m_step
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.action_table import ActionTable
from sensact.models.em_model import EMModel
from sensact.models.landmark_sensor import LandmarkSensor
from sensact.models.polynomial import Polynomial1D

# (iteration, loglik, best loglik, iterations since the best) -> None
Progress = Callable[[int, float, float, int], None]

PLANAR_VELOCITY_NAMES = ("v_x_mm_s", "v_y_mm_s", "v_theta_rad_s")
TRACK_VELOCITY_NAMES = ("v_mm_s",)


def starting_height(config: EMConfig) -> Polynomial1D:
    """The poor straight line f starts from (sec. 4.4.1)."""
    return Polynomial1D(
        (config.start_height_intercept_px, config.start_height_slope_px_per_mm),
        input_name="d",
        input_unit="mm",
        output_unit="px",
    )


def initial_model(data: LandmarkLog, config: EMConfig) -> EMModel:
    """The starting model of sec. 4.4.1: every action has no effect, f is a poor line, wide sigmas."""
    n = 3 if data.geometry == "planar" else 1
    names = PLANAR_VELOCITY_NAMES if n == 3 else TRACK_VELOCITY_NAMES
    table = ActionTable(data.action_commands, np.zeros((data.n_actions, n)), data.command_names, names)
    sensor = LandmarkSensor(
        starting_height(config),
        config.start_sigma_height_px,
        config.start_sigma_bearing_rad if data.geometry == "planar" else None,
    )
    mean = np.asarray(config.start_prior_mean[:n], dtype=float)
    cov = np.diag(np.asarray(config.start_prior_sd[:n], dtype=float) ** 2)
    if data.geometry == "track" and data.n_observations:
        # a track has no landmark map to anchor the start: invert the starting f on the first sighting,
        # with the distance spread that one sighting implies
        slope = config.start_height_slope_px_per_mm
        mean = np.array([(data.obs_height_px[0] - config.start_height_intercept_px) / slope])
        cov = np.array([[(config.start_sigma_height_px / slope) ** 2]])
    return EMModel(data.geometry, table, sensor, mean, cov)


@dataclass(frozen=True, eq=False)
class EMResult:
    model: EMModel  # the model with the highest likelihood
    loglik_history: np.ndarray  # log P(O | C, lambda_i) for every iteration i
    velocity_history: np.ndarray  # (iterations, A, n) the action table of every lambda_i
    sigma_history: np.ndarray  # (iterations, 2) sigma_1, sigma_2 of every lambda_i
    best_iteration: int
    stop_reason: str  # "converged", "max_iterations", "diverged" or "interrupted"
    n_observations: int
    n_pruned: int
    seconds: float
    config: EMConfig
    posteriors: Posteriors | None = field(default=None, repr=False)  # of the best model

    @property
    def iterations(self) -> int:
        return int(self.loglik_history.size)

    @property
    def loglik_best(self) -> float:
        return float(self.loglik_history[self.best_iteration])

    def summary(self) -> dict[str, Any]:
        return {
            "iterations": self.iterations,
            "best_iteration": self.best_iteration,
            "stop_reason": self.stop_reason,
            "loglik_start": float(self.loglik_history[0]),
            "loglik_best": self.loglik_best,
            "n_observations": self.n_observations,
            "n_pruned": self.n_pruned,
            "seconds": self.seconds,
            "config": asdict(self.config),
        }


def fit_em(
    data: LandmarkLog,
    initial: EMModel | None = None,
    config: EMConfig | None = None,
    *,
    progress: Progress | None = None,
) -> EMResult:
    """Learn the action table, the sensor model and the prior from ``data`` by EM (Algorithm of ch. 4)."""
    cfg = config or EMConfig()
    model = initial or initial_model(data, cfg)
    rng = np.random.default_rng(cfg.seed)
    motion_var = motion_variance(data.geometry, cfg.motion_sd_mm, cfg.motion_sd_rad)
    n = model.prior_mean.size
    floor = np.array([cfg.prior_floor_sd[0] ** 2] * min(n, 2) + ([cfg.prior_floor_sd[1] ** 2] if n == 3 else []))
    logliks: list[float] = []
    velocities: list[np.ndarray] = []
    sigmas: list[tuple[float, float]] = []
    best_ll, best_it, best_model, best_post = -np.inf, -1, model, None
    obs_use = None
    reason = "max_iterations"
    start = time.perf_counter()
    try:
        for it in range(cfg.max_iterations):
            post = e_step(
                model,
                data,
                motion_var,
                obs_use=obs_use,
                prune_rad_per_step=cfg.prune_rad_per_step if it == 0 else 0.0,
            )
            if it == 0:
                obs_use = post.obs_used
            if not post.ok:
                reason = "diverged"
                break
            logliks.append(post.loglik)
            velocities.append(model.action.velocities.copy())
            sigmas.append((model.sensor.sigma_height_px, model.sensor.sigma_bearing_rad or np.nan))
            if post.loglik > best_ll:
                best_ll, best_it, best_model, best_post = post.loglik, it, model, post
            if progress is not None:
                progress(it, post.loglik, best_ll, it - best_it)
            if it - best_it >= cfg.patience:
                reason = "converged"
                break
            model = m_step(
                post,
                data,
                model,
                degree=cfg.sensor_degree,
                n_samples=cfg.samples_per_frame,
                floor_var=floor,
                rng=rng,
            )
    except KeyboardInterrupt:
        reason = "interrupted"
    n_pruned = 0 if obs_use is None else int(data.n_observations - obs_use.sum())
    A = data.n_actions
    return EMResult(
        best_model,
        np.asarray(logliks, dtype=float),
        np.asarray(velocities, dtype=float).reshape(-1, A, n),
        np.asarray(sigmas, dtype=float).reshape(-1, 2),
        max(best_it, 0),
        reason,
        data.n_observations,
        n_pruned,
        time.perf_counter() - start,
        cfg,
        best_post,
    )
