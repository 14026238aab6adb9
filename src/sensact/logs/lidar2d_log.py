"""A wheels-and-2-D-lidar log as the learner reads it (docs/lidar2d.md): the scans, what drives the robot, the URDF's
guess and, when simulated, the truth; ``sensact.io.lidar2d_folder`` reads and writes its folder."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.records import JsonObject

DRIVES = ("wheels", "odom", "cmd_vel")  # what moves the robot in the learner's eyes, best first


@dataclass(frozen=True)
class ScanGeometry:
    """A LaserScan's fixed fields, in mm, rad and s."""

    angle_min_rad: float
    angle_increment_rad: float
    time_increment_s: float  # 0: every beam at the stamp
    range_min_mm: float
    range_max_mm: float

    def angles(self, beams: int) -> np.ndarray:
        return self.angle_min_rad + self.angle_increment_rad * np.arange(beams)

    def to_dict(self) -> JsonObject:
        return dict(self.__dict__)


@dataclass(frozen=True)
class Pose2:
    forward_mm: float
    left_mm: float
    yaw_rad: float

    def to_dict(self) -> JsonObject:
        return dict(self.__dict__)


@dataclass(frozen=True)
class UrdfGuess:
    """What the robot's description says: the lidar's mount (from /tf_static), the wheels' radius and axle
    (the nominal numbers /odom was computed with); each None where nothing said it."""

    mount: Pose2 | None = None
    up_mm: float | None = None  # the lidar's height, kept for the URDF export
    wheel_radius_mm: float | None = None
    axle_mm: float | None = None
    lidar_frame: str | None = None  # the scan's frame_id and the base frame /tf_static placed it on
    base_frame: str | None = None

    def to_dict(self) -> JsonObject:
        m = None if self.mount is None else self.mount.to_dict() | {"up_mm": self.up_mm}
        return {
            "lidar_mount": m,
            "wheel_radius_mm": self.wheel_radius_mm,
            "axle_mm": self.axle_mm,
            "lidar_frame": self.lidar_frame,
            "base_frame": self.base_frame,
        }


@dataclass(frozen=True, eq=False)
class Lidar2DLog:
    """A wheels-and-lidar log in sensact's units (mm, rad, s)."""

    source: str
    scan_t: np.ndarray
    ranges_mm: np.ndarray  # (scans, beams), NaN = no return
    scan: ScanGeometry
    drive: str  # one of DRIVES: the table the robot's motion is read from
    drive_t: np.ndarray
    drive_values: np.ndarray  # wheels: (n, 2) positions; odom: (n, 3) x_mm, y_mm, yaw; cmd_vel: (n, 2)
    urdf: UrdfGuess
    truth_t: np.ndarray | None = None
    truth_pose: np.ndarray | None = None  # (n, 3) x_mm, y_mm, yaw
    truth: JsonObject | None = None  # the simulator's models

    @property
    def beams(self) -> int:
        return int(self.ranges_mm.shape[1])

    def from_its_start(self) -> Lidar2DLog:
        """The log on a clock that starts with it: a fit's finite differences in time (the delay's) are then
        sized to seconds, not lost below float64's resolution at a Unix epoch's 1.7e9 s (2.4e-7 s)."""
        from dataclasses import replace

        t0 = float(min(self.scan_t[0], self.drive_t[0]))
        if t0 == 0.0:
            return self
        return replace(
            self,
            scan_t=self.scan_t - t0,
            drive_t=self.drive_t - t0,
            truth_t=None if self.truth_t is None else self.truth_t - t0,
        )
