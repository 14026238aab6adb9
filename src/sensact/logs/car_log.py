"""A car-like robot's log as the learner reads it (docs/ackermann.md): its 2-D scans, the VESC's measured motor ERPM,
the servo positions sent, the ``/drive`` commands, what ``/tf_static`` says of the lidar and, when simulated,
the truth; ``sensact.io.car_folder`` reads and writes its folder."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from sensact.logs.lidar2d_log import ScanGeometry, UrdfGuess
from sensact.records import JsonObject


@dataclass(frozen=True, eq=False)
class CarLog:
    """A car's log in sensact's units (mm, rad, s); the VESC's in its own (ERPM, servo units), as its yaml is."""

    source: str
    scan_t: np.ndarray
    ranges_mm: np.ndarray  # (scans, beams), NaN = no return
    scan: ScanGeometry
    erpm_t: np.ndarray
    erpm: np.ndarray  # the motor's measured electrical RPM (VescState.speed)
    servo_t: np.ndarray
    servo: np.ndarray  # the servo positions the driver sent
    drive_t: np.ndarray  # /drive's commands, (n, 2) speed_m_s, steering_angle_rad; may be empty
    drive: np.ndarray
    urdf: UrdfGuess  # the lidar's mount from /tf_static (the wheels' fields are not a car's)
    odom_t: np.ndarray = field(default_factory=lambda: np.zeros(0))  # /odom's twist, (n, 2) v_m_s, omega_rad_s:
    odom: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # vesc_to_odom's, through the old yaml
    truth_t: np.ndarray | None = None
    truth_pose: np.ndarray | None = None  # (n, 3) x_mm, y_mm, yaw of the rear axle
    truth: JsonObject | None = None  # the simulator's models

    @property
    def beams(self) -> int:
        return int(self.ranges_mm.shape[1])

    def from_its_start(self) -> CarLog:
        """The log on a clock that starts with it (a delay's finite differences are then not lost below float64's
        resolution at a Unix epoch)."""
        t0 = float(min(self.scan_t[0], self.erpm_t[0], self.servo_t[0]))
        if t0 == 0.0:
            return self
        return replace(
            self,
            scan_t=self.scan_t - t0,
            erpm_t=self.erpm_t - t0,
            servo_t=self.servo_t - t0,
            drive_t=self.drive_t - t0,
            odom_t=self.odom_t - t0,
            truth_t=None if self.truth_t is None else self.truth_t - t0,
        )
