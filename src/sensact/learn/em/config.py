"""EM's settings. Defaults are the thesis's constants (ch. 4), with their source."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EMConfig:
    # the fixed motion noise Sigma_m, per time step (sec. 4.4.1: 10 mm, 10 mm, 0.1 rad at 30 Hz;
    # sec. 4.4.3: 10 mm on the track)
    motion_sd_mm: float = 10.0
    motion_sd_rad: float = 0.1
    sensor_degree: int = 3  # f is a cubic, sec. 4.1
    samples_per_frame: int = 1  # N_s, sec. 4.3.2
    patience: int = 50  # stop after this many iterations without a new best likelihood, sec. 4.4.1
    max_iterations: int = 5000
    prune_rad_per_step: float = 0.6  # first-iteration outlier gate on the bearing innovation, sec. 4.4.1
    seed: int = 0  # the M-step's sampling
    # the starting model (sec. 4.4.1): no motion, a poor linear f, sigma_1 = 10 px, sigma_2 = 0.2 rad
    start_height_intercept_px: float = 20.0
    start_height_slope_px_per_mm: float = -0.002
    start_sigma_height_px: float = 10.0
    start_sigma_bearing_rad: float = 0.2
    # the starting prior pi(w_0); on a track only the first entries are used
    start_prior_mean: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start_prior_sd: tuple[float, float, float] = (300.0, 300.0, 0.3)
    prior_floor_sd: tuple[float, float] = (1.0, 1e-3)  # keeps pi = gamma_0 from collapsing (mm, rad)

    def __post_init__(self) -> None:
        problems = []
        if not (self.motion_sd_mm > 0 and self.motion_sd_rad > 0):
            problems.append("motion_sd_mm and motion_sd_rad must be > 0")
        if self.sensor_degree < 1:
            problems.append("sensor_degree must be >= 1")
        if self.samples_per_frame < 1:
            problems.append("samples_per_frame must be >= 1")
        if self.patience < 1 or self.max_iterations < 1:
            problems.append("patience and max_iterations must be >= 1")
        if not (self.start_sigma_height_px > 0 and self.start_sigma_bearing_rad > 0):
            problems.append("start sigmas must be > 0")
        if min(self.start_prior_sd) <= 0:
            problems.append("start_prior_sd must be > 0")
        if problems:
            raise ValueError("; ".join(problems))
