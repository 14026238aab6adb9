"""An outdoor robot's log as its learner reads it (docs/inertial.md): the wheel odometry's twist, the IMU's
turn rates and accelerations, and GNSS fixes in local east-north-up metres around a recorded datum, with
what /tf_static said of the IMU's and the antenna's mounts and, when simulated, the truth.
``sensact.io.inertial_folder`` reads and writes its folder; ``sensact.io.rosbag_inertial`` reads a bag.

Units are ROS's (SI, REP 103/105): s, m, rad, m/s^2; times are seconds on the odometry's clock.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.records import JsonObject


@dataclass(frozen=True)
class Datum:
    """The geodetic point the local east-north-up frame is centred on (WGS 84)."""

    lat_deg: float
    lon_deg: float
    alt_m: float

    def to_dict(self) -> JsonObject:
        return dict(self.__dict__)


@dataclass(frozen=True)
class MountGuess:
    """What /tf_static said of a sensor on base_link: its position (m) and, for the IMU, its orientation as URDF
    rpy (rad); None where it said nothing."""

    frame: str | None = None
    xyz_m: tuple[float, float, float] | None = None
    rpy_rad: tuple[float, float, float] | None = None

    def to_dict(self) -> JsonObject:
        return {"frame": self.frame, "xyz_m": self.xyz_m, "rpy_rad": self.rpy_rad}


@dataclass(frozen=True, eq=False)
class InertialLog:
    """``odom_*``: the wheel odometry's twist (REP 103 base frame: forward speed and turn rate) and the yaw of
    its first pose; ``imu_*``: the IMU's own axes (gyro rad/s, specific force m/s^2), the covariances it
    reports (NaN where it reports none); ``gnss_*``: the fixes kept (status >= 0), east/north/up m and their
    reported variances (NaN where none)."""

    source: str
    odom_t: np.ndarray  # (N,)
    odom_v_m_s: np.ndarray  # (N,)
    odom_omega_rad_s: np.ndarray  # (N,)
    odom_yaw0_rad: float
    imu_t: np.ndarray  # (M,)
    gyro_rad_s: np.ndarray  # (M, 3)
    accel_m_s2: np.ndarray  # (M, 3)
    gyro_var_reported: float  # rad^2/s^2, the diagonal's mean (NaN: none reported)
    gnss_t: np.ndarray  # (K,) empty without GNSS
    gnss_enu_m: np.ndarray  # (K, 3)
    gnss_var_reported_m2: np.ndarray  # (K, 2): east and north variances as reported (NaN: none)
    datum: Datum | None
    imu_mount: MountGuess
    gnss_mount: MountGuess
    topics: tuple[tuple[str, str], ...] = ()  # role -> the bag's topic (odom, imu, gnss), for the exports
    truth: JsonObject | None = None  # the simulator's true parameters (scoring only)
    truth_t: np.ndarray | None = None  # the simulator's true path (scoring and figures only)
    truth_xy_m: np.ndarray | None = None

    @property
    def has_gnss(self) -> bool:
        return self.gnss_t.size > 0

    @property
    def imu_hz(self) -> float:
        return float((self.imu_t.size - 1) / max(self.imu_t[-1] - self.imu_t[0], 1e-9))

    @property
    def seconds(self) -> float:
        return float(self.odom_t[-1] - self.odom_t[0])
