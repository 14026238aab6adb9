"""Sec. 5.3 and Algorithm 3: learn the car's action model, and with it better scan matching.

1. The laser angles up to an offset (sec. 5.1, ``lidar_intrinsics``); with the first scan matching and
   its ``C``, the laser angles from the scans alone (``learn_laser_angles``).
2. Repeat: scan matching (sec. 5.2), seeded by the action model's predicted motion once there is one;
   ``C`` from the motion; ``v``, ``omega`` and ``a`` per interval; C5..C10 by regression on eqs. 5.3-5.4;
   until the coefficients stop changing.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.health import Health, HealthFlag
from sensact.learn.scan_odometry import Odometry, OdometryConfig, offset_from_motion, scan_odometry
from sensact.learn.spinning_lidar_intrinsics import IntrinsicsConfig, IntrinsicsResult, learn_relative_angles
from sensact.models.velodyne_car_dynamics import CarDynamics, fit_car_dynamics


@dataclass(frozen=True)
class CarLearningConfig:
    """Every setting of Algorithm 3, flat so that ``--set name=value`` reaches each one."""

    max_iterations: int = 10
    tolerance: float = 1e-3  # stop when no coefficient moves by more than this fraction of its size
    # sec. 5.1
    max_difference_deg: float | None = None  # the thesis's optional 23° bound
    subsample_peak: bool = True
    min_pairs: int = 1000
    # sec. 5.2
    dt_s: float = 0.5
    drop_below_m: float = 1.0
    outlier_m: float = 7.0
    icp_max_iterations: int = 50
    icp_tolerance: float = 1e-5
    min_speed_m_s: float = 2.0
    voxel_m: float | None = 0.2  # thin D1 to one point per 0.2 m cell: 4x faster ICP, same accuracy (docs/car.md);
    # None: every point, as the thesis
    matcher: Literal["algorithm2", "kiss_icp"] = "algorithm2"  # OdometryConfig.matcher

    def __post_init__(self) -> None:
        """Each setting in the range Algorithm 3 can run with; ``max_difference_deg`` and ``voxel_m`` are off as
        None, never as 0 or a negative number."""
        checks = {
            "max_iterations": 1 <= self.max_iterations <= 10_000,
            "tolerance": 0 < self.tolerance < 1,
            "max_difference_deg": self.max_difference_deg is None or 0 < self.max_difference_deg <= 180,
            "min_pairs": 10 <= self.min_pairs <= 10**9,
            "dt_s": 0.01 <= self.dt_s <= 60,
            "drop_below_m": 0 <= self.drop_below_m < 1000,
            "outlier_m": 0 < self.outlier_m <= 1000,
            "icp_max_iterations": 1 <= self.icp_max_iterations <= 10_000,
            "icp_tolerance": 0 < self.icp_tolerance < 1,
            "min_speed_m_s": 0 <= self.min_speed_m_s <= 100,
            "voxel_m": self.voxel_m is None or 0.001 <= self.voxel_m <= 100,
        }
        bad = [name for name, ok in checks.items() if not ok]
        if bad:  # config_from_dict words it as the setting's error, with where it came from
            raise ValueError(
                f"{bad[0]} is {getattr(self, bad[0])!r}, outside what Algorithm 3 can run with (docs/car.md; an "
                "optional setting is off as null, not 0)."
            )

    @property
    def intrinsics(self) -> IntrinsicsConfig:
        return IntrinsicsConfig(self.max_difference_deg, self.subsample_peak, self.min_pairs)

    @property
    def odometry(self) -> OdometryConfig:
        return OdometryConfig(
            self.dt_s,
            self.drop_below_m,
            self.outlier_m,
            self.icp_max_iterations,
            self.icp_tolerance,
            self.min_speed_m_s,
            self.voxel_m or 0.0,  # OdometryConfig's "every point"
            self.matcher,
        )


@dataclass(frozen=True, eq=False)
class CarLearningResult:
    laser_angles_rad: np.ndarray  # theta_hat_l = theta'_l + C, by laser id
    offset_rad: float  # C
    intrinsics: IntrinsicsResult
    model: CarDynamics
    odometry: Odometry
    interval_times_s: np.ndarray  # (K,)
    actions: np.ndarray  # (K, 3) averaged g, b, s
    speed_m_s: np.ndarray  # (K,) from scan matching
    omega_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    history: list[dict[str, float]]  # coefficients and C per iteration
    seconds_by_stage: dict[str, float]
    converged: bool = True  # False: max_iterations ran out before the coefficients settled to tolerance

    @property
    def iterations(self) -> int:
        return len(self.history)


def average_actions(times_s: np.ndarray, actions: np.ndarray, starts_s: np.ndarray, dt_s: float) -> np.ndarray:
    """Mean of each action column over ``[start, start + dt)`` (sec. 5.4)."""
    idx = np.searchsorted(starts_s, times_s, side="right") - 1
    ok = (idx >= 0) & (times_s < starts_s[-1] + dt_s)
    out = np.zeros((len(starts_s), actions.shape[1]))
    n = np.bincount(idx[ok], minlength=len(starts_s)).astype(float)
    for j in range(actions.shape[1]):
        out[:, j] = np.bincount(idx[ok], weights=actions[ok, j], minlength=len(starts_s)) / np.maximum(n, 1)
    return out


def regression_actions(times_s: np.ndarray, actions: np.ndarray, starts_s: np.ndarray, dt_s: float) -> np.ndarray:
    """(K, 3) actions per interval for eqs. 5.3-5.4. ``v_t`` is the mean speed over interval t, so
    ``a_t = (v_t+1 - v_t) / dt`` spans from the middle of interval t to the middle of t+1: throttle and brake
    are averaged over that span, the steering over interval t itself (``omega_t`` is its mean turn rate)."""
    shifted = average_actions(times_s, actions, starts_s + 0.5 * dt_s, dt_s)
    own = average_actions(times_s, actions, starts_s, dt_s)
    return np.column_stack([shifted[:, 0], shifted[:, 1], own[:, 2]])


def motion_to_velocities(motion: np.ndarray, offset_rad: float, dt_s: float):
    """v (the component along the car's forward axis, at pi/2 - C in (x_C, y_C)), omega and a (sec. 5.3)."""
    fwd = np.array([np.cos(np.pi / 2 - offset_rad), np.sin(np.pi / 2 - offset_rad)])
    v = motion[:, :2] @ fwd / dt_s
    w = motion[:, 2] / dt_s
    a = np.r_[np.diff(v), 0.0] / dt_s  # a_t = (v_t+1 - v_t) / dt; the last has no successor
    return v, w, a


@dataclass(frozen=True, eq=False)
class LaserAnglesResult:
    """Secs. 5.1-5.2 from the scans alone: Algorithm 3's first pass, which needs no controls."""

    laser_angles_rad: np.ndarray  # theta_hat_l = theta'_l + C, by laser id
    offset_rad: float  # C
    intrinsics: IntrinsicsResult
    odometry: Odometry
    seconds_by_stage: dict[str, float]


def laser_angles(
    relative_rad: np.ndarray, offset_rad: float, omega_rad_s: float, delay_s: np.ndarray | None
) -> np.ndarray:
    """theta_hat_l = theta'_l + C (sec. 5.1), less the turn ``omega tau_l`` of a laser that fires ``tau_l``
    into its firing (``delay_s``, by laser id; None: all at once, as the thesis's HDL-64E): sec. 5.1's
    cross-correlation sees where a laser points when it fires, and scan matching uses that, but the angle
    a calibration holds is the laser's own."""
    late = 0.0 if delay_s is None else omega_rad_s * np.asarray(delay_s, dtype=float)
    return wrap_angle(relative_rad + offset_rad - late)


def learn_laser_angles(
    rot_rad: np.ndarray,
    dist: np.ndarray,
    vertical_rad: np.ndarray,
    firing_hz: float,
    omega_rad_s: float,
    config: CarLearningConfig | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    delay_s: np.ndarray | None = None,
) -> LaserAnglesResult:
    """The laser angles with respect to the car from a drive's scans alone: the relative angles (sec. 5.1),
    one pass of scan matching from identity guesses (sec. 5.2), and C from its fast motions. This is
    Algorithm 3's first iteration; the later ones only reseed ICP with the learned dynamics, which needs
    the throttle, brake and steering. ``delay_s``: see ``laser_angles``."""
    cfg = config or CarLearningConfig()
    t0 = time.perf_counter()
    rel = learn_relative_angles(dist, vertical_rad, firing_hz, omega_rad_s, cfg.intrinsics, progress)
    t1 = time.perf_counter()
    rel_rad = rel.relative_rad
    odo = scan_odometry(rot_rad, dist, vertical_rad, rel_rad, firing_hz, omega_rad_s, None, cfg.odometry, progress)
    t2 = time.perf_counter()
    C = offset_from_motion(odo.motion, cfg.odometry.dt_s, cfg.odometry.min_speed_m_s)
    stages = {"laser_angles": t1 - t0, "scan_matching": t2 - t1}
    return LaserAnglesResult(laser_angles(rel.relative_rad, C, omega_rad_s, delay_s), C, rel, odo, stages)


def learn_car(
    rot_rad: np.ndarray,
    dist: np.ndarray,
    vertical_rad: np.ndarray,
    firing_hz: float,
    omega_rad_s: float,
    action_times_s: np.ndarray,
    actions: np.ndarray,
    config: CarLearningConfig | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    delay_s: np.ndarray | None = None,
) -> CarLearningResult:
    """Algorithm 3 on one drive: firings (F,) rotations and (F, lasers) distances, actions (M, 3) = (g, b, s).
    ``delay_s``: see ``laser_angles``."""
    cfg = config or CarLearningConfig()
    dt = cfg.odometry.dt_s
    first = learn_laser_angles(rot_rad, dist, vertical_rad, firing_hz, omega_rad_s, cfg, progress, delay_s)
    rel, odo = first.intrinsics, first.odometry
    stages = {**first.seconds_by_stage, "regression": 0.0}
    guess = None
    model = None
    done = False
    history: list[dict[str, float]] = []
    for it in range(cfg.max_iterations):
        t1 = time.perf_counter()
        if guess is not None:
            odo = scan_odometry(
                rot_rad, dist, vertical_rad, rel.relative_rad, firing_hz, omega_rad_s, guess, cfg.odometry, progress
            )
        t2 = time.perf_counter()
        C = offset_from_motion(odo.motion, dt, cfg.odometry.min_speed_m_s)
        v, w, a = motion_to_velocities(odo.motion, C, dt)
        # the interval runs between the middles of two revolutions
        mid = odo.times_s + 0.5 * (2 * np.pi / abs(omega_rad_s))
        act = regression_actions(action_times_s, actions, mid, dt)
        K = len(v) - 1  # a is defined up to the last-but-one interval
        new = fit_car_dynamics(v[:K], a[:K], w[:K], act[:K])
        stages["scan_matching"] += t2 - t1
        stages["regression"] += time.perf_counter() - t2
        history.append({**new.to_dict(), "C_rad": C, "iteration": it + 1})
        history[-1].pop("kind")
        done = model is not None and np.all(
            np.abs(new.as_array() - model.as_array()) <= cfg.tolerance * np.maximum(np.abs(model.as_array()), 1e-3)
        )
        model = new
        if done:
            break
        # the model's motion, in (x_C, y_C), seeds the next scan matching (sec. 5.3)
        pv, _, pw = model.predict(act, v[0], dt)
        fwd = np.array([np.cos(np.pi / 2 - C), np.sin(np.pi / 2 - C)])
        guess = np.column_stack([pv * dt * fwd[0], pv * dt * fwd[1], pw * dt])
    assert model is not None
    angles = laser_angles(rel.relative_rad, C, omega_rad_s, delay_s)
    return CarLearningResult(angles, C, rel, model, odo, mid, act, v, w, a, history, stages, bool(done))


MAX_LASER_SPREAD_RAD = np.pi / 2  # a spinning lidar's lasers point within tens of degrees of each other


def car_health(
    model: CarDynamics | None,
    laser_angles_rad: np.ndarray,
    motion: np.ndarray | None = None,
    reach_m: float | None = None,
) -> Health:
    """Algorithm 3's result as a fit is flagged (docs/errors.md): laser angles scattered around the circle (sec. 5.1's
    cross-correlation found no common scene: a capture too short, or of a lidar standing still), dynamics
    all zero or not numbers, which are controls that explained nothing of the scans' motion, as controls on
    another clock do, and a scan match that moved the car further between two revolutions than the lidar
    sees (``motion`` (K, 3) of the odometry, ``reach_m`` the farthest return): two scans that far apart
    share no point, so the match failed, and the dynamics fitted to it are not the car's."""
    flags = []
    if motion is not None and reach_m is not None and len(motion):
        step = np.hypot(motion[:, 0], motion[:, 1])
        bad = ~np.isfinite(step) | (step > reach_m)
        if bad.any():
            flags.append(
                HealthFlag(
                    "scan_matching_failed",
                    f"{int(bad.sum())} of {len(step)} scan matches moved the car further than the lidar sees "
                    f"({reach_m:.0f} m; up to {float(np.nanmax(step)):.3g} m): dropped or damaged packets, or too "
                    "little structure; what was fitted to them is not the car's.",
                )
            )
    a = np.asarray(laser_angles_rad, dtype=float)
    spread = 0.0
    if a.size > 1 and np.all(np.isfinite(a)):  # the shortest arc that holds every angle
        s = np.sort(np.mod(a, 2 * np.pi))
        spread = float(2 * np.pi - np.max(np.diff(np.append(s, s[0] + 2 * np.pi))))
    if not np.all(np.isfinite(a)) or spread > MAX_LASER_SPREAD_RAD:
        flags.append(
            HealthFlag(
                "laser_angles_scattered",
                f"the learned laser angles spread over {np.degrees(spread):.0f} degrees: the scans did not match "
                "(a capture too short, or too little motion in it).",
            )
        )
    if model is not None:
        c = model.as_array()
        if not np.all(np.isfinite(c)) or not np.any(c[1:]):
            flags.append(
                HealthFlag(
                    "controls_explain_nothing",
                    "the car's dynamics came out zero or not numbers: the controls explain none of the scans' "
                    "motion (are actions.csv's times on the lidar's clock, in seconds?).",
                )
            )
    return Health(tuple(flags))
