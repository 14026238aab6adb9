"""A car-like robot's bag (docs/ackermann.md): an F1TENTH or MuSHR car's ``vesc_msgs/VescStateStamped`` (the motor's
measured ERPM, ``state.speed``), the servo's commands (``std_msgs/Float64``, /sensors/servo_position_command),
``ackermann_msgs/AckermannDriveStamped`` (/drive), ``sensor_msgs/LaserScan`` and /tf_static, read into a
``CarLog``. These types are not ROS's standard ones: their definitions come from the bag itself (a ROS 1 bag's
connection headers, a ROS 2 MCAP's schemas), which ``rosbags`` reads.

A Float64 has no header: the servo's commands are timed by when they were recorded, as the VESC driver
received them. /drive's stamps are used where they go forward (planners often leave them at 0).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.rosbag import TF_TYPES, Progress, Topic, _read, _static_tree, _yaw
from sensact.io.rosbag_lidar2d import SCAN_TYPE, _one, _ordered, _scans, _times, lidar_mount
from sensact.logs.car_log import CarLog
from sensact.logs.lidar2d_log import ScanGeometry, UrdfGuess

VESC_TYPE = "vesc_msgs/VescStateStamped"
SERVO_TYPE = "std_msgs/Float64"
DRIVE_TYPE = "ackermann_msgs/AckermannDriveStamped"
SERVO_NAME = re.compile(r"servo", re.IGNORECASE)
# where a car's stack has several of a type, the one the VESC driver used: its echo of the servo command it sent
# (beside the command it was given), the Ackermann mux's output (beside its inputs), vesc_to_odom's /odom (beside
# a particle filter's); /drive and /odom serve only to read the old yaml, so an undecided one is left out
SERVO_ECHO = re.compile(r"sensors/servo_position_command$")
DRIVE_NAME = re.compile(r"(^|/)(ackermann_cmd|drive)$")
ODOM_NAME = re.compile(r"^/?(vesc/)?odom$")
ODOM_TYPE = "nav_msgs/Odometry"
POSE_TYPES = ("geometry_msgs/PoseStamped", ODOM_TYPE)
TRUTH_NAME = re.compile(r"ground_?truth|mocap|vicon|optitrack", re.IGNORECASE)


@dataclass(frozen=True)
class CarRoles:
    scan: str
    vesc: str
    servo: str
    drive: str | None
    odom: str | None
    truth: str | None

    def lines(self) -> list[str]:
        return [f"{k}: {v}" for k, v in self.__dict__.items() if v]


def is_car_bag(topics: list[Topic]) -> bool:
    """A bag with a VESC's state or Ackermann commands is a car's, whatever else it has (its /odom and /scan
    would pass for a differential drive's)."""
    return any(t.msgtype in (VESC_TYPE, DRIVE_TYPE) and t.count for t in topics)


def _preferred(topics: list[Topic], name: re.Pattern, msgtype: str = SERVO_TYPE) -> list[Topic]:
    """``topics``, or where several of ``msgtype`` have messages, the first of them whose name is ``name``'s (by
    the order of the patterns' alternatives, then by name); none of them where no name is."""
    typed = [t for t in topics if t.msgtype == msgtype and t.count]
    if len(typed) <= 1:
        return topics
    chosen = sorted(
        (t for t in typed if name.search(t.name)), key=lambda t: (not t.name.endswith("ackermann_cmd"), t.name)
    )
    return [t for t in topics if t.msgtype != msgtype] + chosen[:1]


def car_roles(path: Path, topics: list[Topic], named: dict[str, str | None]) -> CarRoles:
    """Which topic plays which part: each by its type (the servo's Float64 by a name with "servo") unless named."""
    scan = _one(path, topics, (SCAN_TYPE,), named.get("scan"), "--scan", "the 2-D lidar's LaserScan")
    vesc = _one(path, topics, (VESC_TYPE,), named.get("vesc"), "--vesc", "the VESC's state (VescStateStamped)")
    servos = topics if named.get("servo") else _preferred([t for t in topics if SERVO_NAME.search(t.name)], SERVO_ECHO)
    servo = _one(path, servos, (SERVO_TYPE,), named.get("servo"), "--servo", "the servo's commands (Float64)")
    drives = topics if named.get("drive") else _preferred(topics, DRIVE_NAME, DRIVE_TYPE)
    drive = _one(path, drives, (DRIVE_TYPE,), named.get("drive"), "--drive", "the Ackermann commands")
    truths = [t for t in topics if t.msgtype in POSE_TYPES and TRUTH_NAME.search(t.name)]
    truth = _one(path, truths, POSE_TYPES, named.get("truth"), "--truth", "the truth")
    odoms = [t for t in topics if t.msgtype == ODOM_TYPE and not TRUTH_NAME.search(t.name) and t.name != truth]
    odoms = topics if named.get("odom") else _preferred(odoms, ODOM_NAME, ODOM_TYPE)
    odom = _one(path, odoms, (ODOM_TYPE,), named.get("odom"), "--odom", "the car's odometry (vesc_to_odom's)")
    missing = [
        what
        for what, topic in (
            ("a sensor_msgs/LaserScan (/scan)", scan),
            ("the VESC's vesc_msgs/VescStateStamped (/sensors/core)", vesc),
            ("the servo's std_msgs/Float64 (/sensors/servo_position_command)", servo),
        )
        if topic is None
    ]
    if missing:
        raise LogFormatError(
            f"a car's bag, without {' and '.join(missing)}: the speed gain, the steering and the mount need all three.",
            file=path,
            fix="record /scan, /sensors/core and /sensors/servo_position_command (or name them: --scan, --vesc, "
            "--servo).",
        )
    return CarRoles(scan, vesc, servo, drive, odom, truth)  # type: ignore[arg-type]


def _column(path: Path, topic: str, ns: np.ndarray, values: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise LogFormatError(
            f"{topic}: message {bad[0] + 1}'s {what} is not finite.",
            file=path,
            field=topic,
            fix="cut the bag before it.",
        )
    return _ordered(path, topic, ns), values


def read_car_bag(
    path: Path, reader, topics: list[Topic], roles: CarRoles, *, receive_times: bool = False, progress: Progress | None
) -> tuple[CarLog, tuple[str, ...]]:
    notes: list[str] = []
    scan_ns, ranges, scan, frame = _scans(path, reader, roles.scan, receive_times, progress)
    msgs = _read(reader, roles.vesc, progress)
    vesc_ns, erpm = _column(
        path, roles.vesc, _times(msgs, receive_times), np.array([m.state.speed for _, m in msgs], float), "speed"
    )
    msgs = _read(reader, roles.servo, progress)
    servo_ns, servo = _column(
        path, roles.servo, np.array([t for t, _ in msgs], np.int64), np.array([m.data for _, m in msgs], float), "data"
    )
    drive_ns, drive = np.zeros(0, np.int64), np.zeros((0, 2))
    if roles.drive:
        msgs = _read(reader, roles.drive, progress)
        ns = _times(msgs, receive_times)
        if np.any(np.diff(ns) <= 0):  # stamps left at 0, or going back: when they were recorded
            ns = np.array([t for t, _ in msgs], np.int64)
            notes.append(f"{roles.drive}'s stamps do not go forward: its commands are timed by when they were recorded")
        order = np.argsort(ns, kind="stable")
        drive_ns = ns[order]
        drive = np.array([[m.drive.speed, m.drive.steering_angle] for _, m in msgs], float)[order]
    odom_ns, odom = np.zeros(0, np.int64), np.zeros((0, 2))
    if roles.odom:
        msgs = _read(reader, roles.odom, progress)
        twist = np.array([[m.twist.twist.linear.x, m.twist.twist.angular.z] for _, m in msgs], float)
        odom_ns, odom = _column(path, roles.odom, _times(msgs, receive_times), twist, "twist")
    truth = None
    if roles.truth:
        msgs = _read(reader, roles.truth, progress)
        poses = [m.pose.pose if hasattr(m.pose, "pose") else m.pose for _, m in msgs]
        truth = (
            _times(msgs, receive_times),
            np.array([[p.position.x * 1000, p.position.y * 1000, _yaw(p.orientation)] for p in poses]),
        )
    has_tf = [t for t in topics if t.msgtype in TF_TYPES and t.name.endswith("tf_static")]
    tree = _static_tree(path, reader, topics) if has_tf else {}
    mount, up, flipped, base = lidar_mount(tree, frame, None)
    if mount is None:
        notes.append(f"/tf_static does not place {frame or 'the scan frame'} on the car's base: no mount to compare")
    if flipped:
        scan = ScanGeometry(
            -scan.angle_min_rad, -scan.angle_increment_rad, scan.time_increment_s, scan.range_min_mm, scan.range_max_mm
        )
        notes.append(f"{frame} is upside down in /tf_static: its beams' angles are read mirrored")
    t0 = min(int(scan_ns[0]), int(vesc_ns[0]), int(servo_ns[0]))

    def sec(ns: np.ndarray) -> np.ndarray:
        return (np.asarray(ns, dtype=np.int64) - t0) / 1e9

    log = CarLog(
        source=str(path),
        scan_t=sec(scan_ns),
        ranges_mm=ranges,
        scan=scan,
        erpm_t=sec(vesc_ns),
        erpm=erpm,
        servo_t=sec(servo_ns),
        servo=servo,
        drive_t=sec(drive_ns),
        drive=drive,
        urdf=UrdfGuess(mount, up, lidar_frame=frame or None, base_frame=base),
        odom_t=sec(odom_ns),
        odom=odom,
        truth_t=None if truth is None else sec(truth[0]),
        truth_pose=None if truth is None else truth[1],
    )
    return log, tuple(notes)
