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
    # the IMU's orientation where it reports one (x, y, z, w: its axes in a gravity-levelled frame); NaN rows
    # where a message said none (REP 145's -1), None where no message did
    imu_orientation_xyzw: np.ndarray | None = None
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

    def between(self, t0: float, t1: float, source: str) -> InertialLog:
        """The part of the log recorded in [t0, t1) (the odometry's clock), as if the recording had started at
        t0: the odometry's first yaw is what its own twist had turned it to by then."""
        from dataclasses import replace

        o = (self.odom_t >= t0) & (self.odom_t < t1)
        i = (self.imu_t >= t0) & (self.imu_t < t1)
        g = (self.gnss_t >= t0) & (self.gnss_t < t1)
        w, t = self.odom_omega_rad_s, self.odom_t
        turned = float(np.sum((w[1:] + w[:-1]) / 2 * np.diff(t), where=t[1:] <= t[o][0]))
        q = self.imu_orientation_xyzw
        return replace(
            self,
            source=source,
            odom_t=t[o],
            odom_v_m_s=self.odom_v_m_s[o],
            odom_omega_rad_s=w[o],
            odom_yaw0_rad=self.odom_yaw0_rad + turned,
            imu_t=self.imu_t[i],
            gyro_rad_s=self.gyro_rad_s[i],
            accel_m_s2=self.accel_m_s2[i],
            imu_orientation_xyzw=None if q is None else q[i],
            gnss_t=self.gnss_t[g],
            gnss_enu_m=self.gnss_enu_m[g],
            gnss_var_reported_m2=self.gnss_var_reported_m2[g],
        )
