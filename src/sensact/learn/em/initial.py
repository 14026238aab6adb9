"""The starting model of sec. 4.4.1: every action has no effect, each sensor function is a poor straight
line, the sigmas are wide, and Sigma_m is the configured constant (learned from it, beyond the thesis,
when ``motion_noise`` says so). EM (``fit.py``) starts here unless a learned model is given
(``uses/warm_start.py``)."""

from __future__ import annotations

import numpy as np

from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig
from sensact.learn.em.slam_start import starting_map
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.action_table import ActionTable
from sensact.models.em_model import EMModel
from sensact.models.landmark_sensor import LandmarkSensor, ReadingChannel, SensorMount
from sensact.models.linear_action import LinearActionModel
from sensact.models.polynomial import Polynomial1D


def starting_height(config: EMConfig) -> Polynomial1D:
    """The poor straight line f starts from (sec. 4.4.1)."""
    return Polynomial1D(
        (config.thesis.start_height_intercept_px, config.thesis.start_height_slope_px_per_mm),
        input_name="d",
        input_unit="mm",
        output_unit="px",
    )


def starting_sensor(data: LandmarkLog, config: EMConfig) -> LandmarkSensor:
    """Every channel starts from its poor straight line (sec. 4.4.1); the bearing, when the log has any,
    from 0.2 rad."""
    channels = []
    unit = "" if config.channels else "px"
    for cc in config.channel_configs(data.reading_names):
        # the line padded with zero higher coefficients: the same function, of the degree the M-step fits
        coef = (cc.start_intercept, cc.start_slope) + (0.0,) * (cc.degree - 1)
        f = Polynomial1D(coef, input_name="d", input_unit="mm", output_unit=unit)
        channels.append(
            ReadingChannel(
                cc.name,
                f,
                cc.start_sigma,
                cc.valid_min,
                cc.valid_max,
                cc.robust,
                cc.robust_param,
                (0.0,) * cc.bearing_degree,
            )
        )
    if data.geometry.has_heading and np.isfinite(data.obs_bearing_rad).any():
        sigma_b, robust = config.thesis.start_sigma_bearing_rad, (config.robust.bearing, config.robust.bearing_param)
    else:  # a track, or a range-only sensor (radio beacons): no bearing to learn a sigma_2 for
        sigma_b, robust = None, ("none", 0.0)
    mount = (
        SensorMount()
        if config.sensor_mount is None or not data.geometry.has_heading
        else SensorMount(*config.sensor_mount)
    )
    return LandmarkSensor(tuple(channels), sigma_b, *robust, config.robust.joint_student_t, mount)


def initial_model(data: LandmarkLog, config: EMConfig) -> EMModel:
    """The starting model of sec. 4.4.1: every action has no effect, f is a poor line, wide sigmas."""
    n, names = data.geometry.n, data.geometry.velocity_names
    if config.action.basis == "table":
        if data.n_actions == 0:
            raise ConfigError(
                "The log has continuous commands, and the action model is a table of discrete actions.",
                file=data.source,
                field="action.basis",
                fix="set action.basis to affine, cross or polynomial (docs/em-real.md).",
            )
        action = ActionTable(data.action_commands, np.zeros((data.n_actions, n)), data.command_names, names)
    else:
        if data.step_commands is None:
            raise ConfigError(
                f"The log has discrete actions only, and {config.action.basis} needs command columns.",
                file=data.source,
                field="action.basis",
                fix="use action.basis: table (the thesis's table of discrete actions).",
            )
        try:
            action = LinearActionModel.zero(
                config.action.basis,
                config.action.degree,
                data.command_names,
                names,
                config.action.zero_mean,
                config.action.inputs,
            )
        except ValueError as exc:
            raise ConfigError(
                f"{exc}.",
                file=data.source,
                field="action.zero_mean / action.inputs",
                fix=f"name only the log's commands ({', '.join(data.command_names)}) and velocity components "
                f"({', '.join(names)}).",
            ) from None
    sensor = starting_sensor(data, config)
    mean = np.asarray(config.thesis.start_prior_mean[:n], dtype=float)
    cov = np.diag(np.asarray(config.thesis.start_prior_sd[:n], dtype=float) ** 2)
    first = sensor.channels[0]
    col = data.reading_names.index(first.name) if first.name in data.reading_names else 0
    slope = first.function.coef[1] / first.function.scale if first.function.degree >= 1 else 0.0
    if data.geometry.state_is_range and data.n_observations and np.isfinite(data.obs_readings[0, col]) and slope:
        # a track has no landmark map to anchor the start: invert the starting f on the first sighting,
        # with the distance spread that one sighting implies
        f0 = first.function(0.0)
        mean = np.array([(data.obs_readings[0, col] - f0) / slope])
        cov = np.array([[(first.sigma / slope) ** 2]])
    sd = motion_sd_start(config, n)
    motion_sd = np.repeat(sd, data.n_actions, axis=0) if config.motion_noise.kind == "per_action" else sd
    turn_var = None
    if config.motion_noise.kind == "turning":
        if not data.geometry.has_heading:
            raise ConfigError(
                "motion_noise.kind turning scales the heading noise by the turn; a track has no heading.",
                file=data.source,
                field="motion_noise.kind",
                fix="use motion_noise.kind: shared.",
            )
        turn_var = 0.0  # the start: no turn dependence, the M-step learns it once Sigma_m is freed
    landmarks = None
    if not data.map_given.all():
        mean, cov, landmarks, sensor = starting_map(data, sensor, motion_sd[0], config)
    return EMModel(data.geometry, action, sensor, mean, cov, motion_sd, turn_var, landmarks)


def motion_sd_start(config: EMConfig, n: int) -> np.ndarray:
    """Sigma_m's start per step: the sideways and forward sd in the robot's frame (sec. 2.5.1: x to the
    right, y ahead), then the heading's; a track's one entry is its forward sd."""
    sd = [config.thesis.motion_sd_mm] * min(n, 2) + ([config.thesis.motion_sd_rad] if n == 3 else [])
    if n == 3 and config.motion_noise.sideways_mm is not None:
        sd[0] = config.motion_noise.sideways_mm
    return np.array([sd])


def motion_sd_floor(config: EMConfig, n: int) -> np.ndarray:
    return np.array([config.motion_noise.floor_mm] * min(n, 2) + ([config.motion_noise.floor_rad] if n == 3 else []))
