"""A skid-steer robot driving over a field (docs/inertial.md): what a Husky or a Jackal records, its wheel
odometry, its IMU and a GNSS receiver, with the truth none of them knows.

The robot follows smooth random speeds and turn rates, stopping now and then and turning both ways. Its
odometry reports the true speed over ``gain_forward`` and the true turn rate over ``gain_turn`` (the truth is
the gain times the report), each with white noise on the wheels' speeds. The IMU sits at ``imu_xyz_m`` in
orientation ``imu_rpy_rad`` (URDF rpy, base_link -> imu_link): its gyro reads ``gyro_scale`` times the turn
rate plus a bias that wanders as a random walk, and white noise; its accelerometer reads the specific force
at its position (gravity, the robot's acceleration, the turn's centripetal pull) plus a constant bias and
noise; its stamps are ``imu_time_offset_s`` later than the odometry's (t_imu = t_odom + offset). The antenna
at ``gnss_lever_m`` (forward, left) is fixed at ``gnss_hz`` with Gaussian noise and a share of outliers,
and reports a covariance ``gnss_reported_factor`` times the true one's sd. The odometry frame starts at the
robot's first pose, which faces ``heading_rad`` counterclockwise from east.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.core.pose_models import rpy_matrix
from sensact.logs.inertial_log import Datum, InertialLog, MountGuess
from sensact.records import JsonObject

G = 9.80665  # m/s^2, standard gravity
SIM_HZ = 200.0  # the truth's rate


@dataclass(frozen=True)
class InertialConfig:
    """Every knob of the simulated robot (``--set name=value``), in SI units."""

    seconds: float = 600.0
    seed: int = 0
    # the truth the learner is after
    gain_forward: float = 1.025
    gain_turn: float = 0.86
    gyro_scale: float = 1.015
    gyro_bias0_rad_s: float = 0.004
    gyro_bias_walk: float = 2e-4  # rad/s/sqrt(s)
    gyro_noise: float = 0.002  # rad/s/sqrt(Hz)
    accel_noise: float = 0.02  # m/s^2/sqrt(Hz)
    accel_bias_m_s2: float = 0.02
    imu_rpy_rad: tuple[float, float, float] = (3.1, 0.25, -1.9)  # upside down and turned
    imu_xyz_m: tuple[float, float, float] = (0.15, -0.05, 0.25)
    imu_time_offset_s: float = 0.02
    gnss_lever_m: tuple[float, float] = (0.32, -0.18)
    gnss_sigma_m: float = 0.02  # RTK; 1.0 for a metre-grade receiver
    gnss_outliers: float = 0.03
    gnss_reported_factor: float = 2.0
    heading_rad: float = 0.7
    odom_noise_v: float = 0.03  # m/s, white on the reported speed at odom_hz
    odom_noise_omega: float = 0.04  # rad/s
    # the recording
    odom_hz: float = 50.0
    imu_hz: float = 100.0
    gnss_hz: float = 5.0  # 0: no receiver
    tf_imu: str = "true"  # what /tf_static says of the IMU: "true", "none" or "wrong"
    imu_orientation: bool = False  # the IMU reports its orientation (a 9-axis IMU's, or a filter's output)
    accel: str = "m_s2"  # the driver's accelerations: "m_s2" (REP 145), "no_gravity" (gravity taken out) or "g"
    # the driving
    speed_m_s: float = 1.2
    turn_rad_s: float = 0.6
    turns: str = "both"  # "both", "left" (never right) or "none" (straight lines only)

    def __post_init__(self) -> None:
        problems = []
        if not 10 <= self.seconds <= 36_000:
            problems.append("seconds must be in [10, 36000]")
        if min(self.gain_forward, self.gain_turn, self.gyro_scale) <= 0:
            problems.append("gain_forward, gain_turn and gyro_scale must be > 0")
        if not (1 <= self.odom_hz <= 1000 and 10 <= self.imu_hz <= 2000 and 0 <= self.gnss_hz <= 50):
            problems.append("odom_hz must be in [1, 1000], imu_hz in [10, 2000], gnss_hz in [0, 50]")
        if min(self.gnss_sigma_m, self.gyro_noise, self.accel_noise, self.gyro_bias_walk) < 0:
            problems.append("noises must be >= 0")
        if not 0 <= self.gnss_outliers < 0.5 or self.gnss_reported_factor <= 0:
            problems.append("gnss_outliers must be in [0, 0.5), gnss_reported_factor > 0")
        if self.tf_imu not in ("true", "none", "wrong") or self.turns not in ("both", "left", "none"):
            problems.append("tf_imu is true, none or wrong; turns is both, left or none")
        if self.accel not in ("m_s2", "no_gravity", "g"):
            problems.append("accel is m_s2, no_gravity or g")
        if problems:
            raise ValueError("; ".join(problems))

    def truth(self) -> JsonObject:
        r, p, y = self.imu_rpy_rad
        return {
            "odometry.gain_forward": self.gain_forward,
            "odometry.gain_turn": self.gain_turn,
            "imu.gyro.scale": self.gyro_scale,
            "imu.gyro.noise_rad_s_sqrt_hz": self.gyro_noise,
            "imu.gyro.bias_walk_rad_s_sqrt_s": self.gyro_bias_walk,
            "imu.time_offset_s": self.imu_time_offset_s,
            "imu.mount.roll_rad": r,
            "imu.mount.pitch_rad": p,
            "imu.mount.yaw_rad": y,
            "gnss.lever_arm.forward_mm": 1000 * self.gnss_lever_m[0],
            "gnss.lever_arm.left_mm": 1000 * self.gnss_lever_m[1],
            "gnss.sigma_mm": 1000 * self.gnss_sigma_m,
            "gnss.covariance_ratio": self.gnss_reported_factor,
            "gnss.heading_offset_rad": self.heading_rad,
        }


def _smooth_random(rng: np.random.Generator, n: int, hold_s: float, hz: float) -> np.ndarray:
    """Piecewise-constant random levels held ``hold_s`` on average, smoothed over a second."""
    k = max(2, int(n / (hold_s * hz)) + 2)
    knots = np.sort(rng.uniform(0, n, k))
    levels = rng.uniform(-1, 1, k + 1)
    out = levels[np.searchsorted(knots, np.arange(n))]
    w = int(hz)
    return np.convolve(np.pad(out, (w, w), mode="edge"), np.ones(w) / w, mode="same")[w:-w]


def _ease(on: np.ndarray) -> np.ndarray:
    """A 0/1 mask eased over a second at each change (exactly 0 where it is 0 for a second or more)."""
    w = int(SIM_HZ)
    return np.convolve(np.pad(on.astype(float), (w, w), mode="edge"), np.ones(w) / w, mode="same")[w:-w]


@dataclass(frozen=True, eq=False)
class InertialRun:
    config: InertialConfig
    t: np.ndarray  # truth times (s)
    xy_m: np.ndarray  # base_link in ENU
    yaw_rad: np.ndarray  # ENU heading
    log_: InertialLog

    def log(self, source: str) -> InertialLog:
        import dataclasses

        return dataclasses.replace(self.log_, source=source)


def simulate_inertial(cfg: InertialConfig) -> InertialRun:
    rng = np.random.default_rng(cfg.seed)
    n = int(cfg.seconds * SIM_HZ) + 1
    dt = 1.0 / SIM_HZ
    t = np.arange(n) * dt
    v = cfg.speed_m_s * (0.55 + 0.45 * _smooth_random(rng, n, 8.0, SIM_HZ))
    # now and then the robot stands still, and it does at first, as a robot does when the recording starts; it
    # slows to a stop and sets off again over a second (a robot has inertia: no jump in speed)
    stop = (_smooth_random(rng, n, 20.0, SIM_HZ) < -0.6) | (t < 2.0)
    v = v * _ease(~stop)
    w = cfg.turn_rad_s * _smooth_random(rng, n, 6.0, SIM_HZ)
    if cfg.turns == "left":
        w = np.abs(w)
    elif cfg.turns == "none":
        w = np.zeros(n)
    w = w * _ease(~(stop & ((np.arange(n) % int(60 * SIM_HZ) > 30 * SIM_HZ) | (t < 2.0))))  # some stops turn
    yaw = cfg.heading_rad + np.concatenate([[0.0], np.cumsum((w[1:] + w[:-1]) / 2 * dt)])
    vx, vy = v * np.cos(yaw), v * np.sin(yaw)
    xy = np.column_stack([np.concatenate([[0.0], np.cumsum((a[1:] + a[:-1]) / 2 * dt)]) for a in (vx, vy)])
    # the odometry's report
    k_o = np.arange(0, n, round(SIM_HZ / cfg.odom_hz))
    odom_v = v[k_o] / cfg.gain_forward + cfg.odom_noise_v * rng.standard_normal(k_o.size) * (v[k_o] > 1e-9)
    odom_w = w[k_o] / cfg.gain_turn + cfg.odom_noise_omega * rng.standard_normal(k_o.size) * (
        (v[k_o] > 1e-9) | (np.abs(w[k_o]) > 1e-9)
    )
    # the IMU, at its own position and orientation, on a clock offset from the odometry's
    R = rpy_matrix(*cfg.imu_rpy_rad)  # imu axes in base
    r = np.asarray(cfg.imu_xyz_m)
    k_i = np.arange(0, n, round(SIM_HZ / cfg.imu_hz))
    bias = cfg.gyro_bias0_rad_s + cfg.gyro_bias_walk * np.sqrt(dt) * np.cumsum(rng.standard_normal(n))
    dv = np.gradient(v, dt)
    dw = np.gradient(w, dt)
    f_base = np.column_stack(
        [
            dv - w**2 * r[0] - dw * r[1],
            v * w + dw * r[0] - w**2 * r[1],
            np.full(n, G),
        ]
    )[k_i]
    omega_base = np.column_stack([np.zeros(n), np.zeros(n), cfg.gyro_scale * w + bias])[k_i]
    other_bias = rng.normal(0, 0.003, 3)  # the gyro's x and y axes are off too
    gyro = omega_base @ R + other_bias + cfg.gyro_noise * np.sqrt(cfg.imu_hz) * rng.standard_normal((k_i.size, 3))
    accel = (
        f_base @ R
        + cfg.accel_bias_m_s2 * rng.uniform(-1, 1, 3)
        + cfg.accel_noise * np.sqrt(cfg.imu_hz) * rng.standard_normal((k_i.size, 3))
    )
    if cfg.accel == "no_gravity":
        accel = accel - G * R[2]  # as some drivers publish it: the robot's own acceleration only
    elif cfg.accel == "g":
        accel = accel / G
    orientation = None
    if cfg.imu_orientation:  # the IMU's axes in a levelled frame, heading from the robot's (its reference is moot)
        from scipy.spatial.transform import Rotation

        orientation = (Rotation.from_euler("z", yaw[k_i, None]) * Rotation.from_matrix(R)).as_quat()
    imu_t = t[k_i] + cfg.imu_time_offset_s
    # GNSS at the antenna
    if cfg.gnss_hz > 0:
        k_g = np.arange(int(SIM_HZ), n, round(SIM_HZ / cfg.gnss_hz))
        lf, ll = cfg.gnss_lever_m
        ant = xy[k_g] + np.column_stack(
            [lf * np.cos(yaw[k_g]) - ll * np.sin(yaw[k_g]), lf * np.sin(yaw[k_g]) + ll * np.cos(yaw[k_g])]
        )
        noise = cfg.gnss_sigma_m * rng.standard_normal((k_g.size, 2))
        out = rng.random(k_g.size) < cfg.gnss_outliers
        noise[out] = rng.normal(0, max(20 * cfg.gnss_sigma_m, 0.5), (int(out.sum()), 2))
        enu = np.column_stack([ant + noise, 2 * cfg.gnss_sigma_m * rng.standard_normal(k_g.size)])
        var = np.full((k_g.size, 2), (cfg.gnss_reported_factor * cfg.gnss_sigma_m) ** 2)
        gnss_t = t[k_g]
    else:
        enu, var, gnss_t = np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0)
    tf_rpy = {"true": cfg.imu_rpy_rad, "none": None, "wrong": (0.0, 0.0, 0.0)}[cfg.tf_imu]
    log = InertialLog(
        source="simulated",
        odom_t=t[k_o],
        odom_v_m_s=odom_v,
        odom_omega_rad_s=odom_w,
        odom_yaw0_rad=0.0,
        imu_t=imu_t,
        gyro_rad_s=gyro,
        accel_m_s2=accel,
        gyro_var_reported=cfg.gyro_noise**2 * cfg.imu_hz,
        gnss_t=gnss_t,
        gnss_enu_m=enu,
        gnss_var_reported_m2=var,
        datum=Datum(30.2849, -97.7341, 150.0) if cfg.gnss_hz > 0 else None,
        imu_mount=MountGuess("imu_link", None if tf_rpy is None else tuple(r), tf_rpy),
        gnss_mount=MountGuess("gps_link", (*cfg.gnss_lever_m, 0.5), None) if cfg.gnss_hz > 0 else MountGuess(),
        imu_orientation_xyzw=orientation,
        topics=(
            ("odom", "/odometry/wheel"),
            ("imu", "/imu/data"),
            *((("gnss", "/gps/fix"),) if cfg.gnss_hz > 0 else ()),
        ),
        truth={**cfg.truth(), "imu.gyro.bias_rad_s": float(np.mean(bias) + R[2] @ other_bias)},
        truth_t=t[:: int(SIM_HZ / 10)],
        truth_xy_m=xy[:: int(SIM_HZ / 10)],
    )
    return InertialRun(cfg, t, xy, yaw, log)
