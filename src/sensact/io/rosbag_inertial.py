"""An outdoor robot's bag (docs/inertial.md): ``nav_msgs/Odometry`` (the wheel odometry's twist), ``sensor_msgs/Imu``
(turn rates, accelerations and the covariances it reports), ``sensor_msgs/NavSatFix`` (WGS 84 fixes, their
status and reported covariance) and ``/tf_static`` (base_link to the IMU's and the antenna's frames), read into an
``InertialLog``: SI units, REP 103 axes, seconds on the bag's header stamps, fixes in east-north-up metres
around a datum sensact picks (the first fix kept) and records, through pymap3d.

A fix with status -1 (no fix) is dropped; a jump of the receiver's datum (fixes that leap and stay) is
refused; a covariance reported as NaN is ignored, and said so.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.rosbag import (
    NOT_WHEELS,
    TF_TYPES,
    WHEELS,
    Progress,
    Topic,
    _read,
    _refuse_non_finite,
    _static_tree,
    _yaw,
    routes_line,
    sensor_topics,
)
from sensact.io.rosbag_lidar2d import _one, _ordered, _pose_in, _times
from sensact.logs.inertial_log import Datum, InertialLog, MountGuess

ODOM_TYPE = "nav_msgs/Odometry"
IMU_TYPE = "sensor_msgs/Imu"
FIX_TYPE = "sensor_msgs/NavSatFix"
BASE_FRAMES = ("base_link", "base_footprint")
JUMP_M = 100.0  # a fix this far from the path's last, and every fix after it too: the receiver's datum moved
MIN_FIXES = 10


@dataclass(frozen=True)
class InertialRoles:
    odom: str
    imu: str
    gnss: str | None
    gnss_named: bool = False  # --gnss TOPIC: a receiver without fixes is then refused, not left out

    def pairs(self) -> tuple[tuple[str, str], ...]:
        """(role, topic) of each role a topic plays."""
        return tuple((k, v) for k, v in (("odom", self.odom), ("imu", self.imu), ("gnss", self.gnss)) if v)

    def lines(self) -> list[str]:
        return [f"{k}: {v}" for k, v in self.pairs()]


def has_imu(topics: list[Topic]) -> bool:
    return any(t.msgtype == IMU_TYPE and t.count for t in topics)


RAW = re.compile(r"raw", re.IGNORECASE)  # imu_tools' filters publish imu/data from imu/data_raw, rates unchanged


def inertial_roles(path: Path, topics: list[Topic], named: dict[str, str | None]) -> InertialRoles:
    """Which topic plays which part: each by its type unless named (two sensors of one type must be named)."""

    def one(role: str, msgtype: str, drop: re.Pattern | None, prefer: re.Pattern | None, what: str) -> str | None:
        given = named.get(role)
        pool = topics if given is not None else sensor_topics(topics, msgtype, drop, prefer)
        return _one(path, pool, (msgtype,), given, f"--{role}", what)

    odom = one("odom", ODOM_TYPE, NOT_WHEELS, WHEELS, "the wheel odometry (nav_msgs/Odometry)")
    imu = one("imu", IMU_TYPE, None, RAW, "the IMU (sensor_msgs/Imu)")
    gnss = one("gnss", FIX_TYPE, None, None, "the GNSS fixes (sensor_msgs/NavSatFix)")
    if odom is None or imu is None:
        raise LogFormatError(
            "an IMU's bag needs the wheel odometry and the IMU; it has no "
            + ("nav_msgs/Odometry" if odom is None else "sensor_msgs/Imu")
            + " topic. "
            + routes_line()
            + ".",
            file=path,
            fix="record the robot's /odom (diff_drive_controller's) with /imu/data.",
        )
    return InertialRoles(odom, imu, gnss, named.get("gnss") is not None)


class NoFixes(LogFormatError):
    """A receiver that recorded (almost) no fix: indoors, or before it found the sky."""


def _sec(ns: np.ndarray, t0: int) -> np.ndarray:
    return (np.asarray(ns, dtype=np.int64) - t0) / 1e9


def _cov_diag(path: Path, topic: str, covs: np.ndarray, notes: list[str], what: str) -> np.ndarray:
    """The reported variances (rows), NaN where unknown (a first element of -1 or 0 everywhere, as REP 145 says)
    or NaN (said in a note)."""
    covs = np.asarray(covs, dtype=float)
    nan = ~np.isfinite(covs).all(axis=1)
    if nan.any():
        notes.append(
            f"{topic}: {int(nan.sum())} messages report a NaN {what} covariance: ignored (sensact learns its own)"
        )
    diag = covs[:, [0, 4, 8]]
    unknown = nan | (covs[:, 0] < 0) | ~(covs[:, [0, 4, 8]] > 0).any(axis=1)
    diag[unknown] = np.nan
    return diag


MAX_OUT_OF_ORDER = 0.01  # a driver's repeated or late stamps this rare are dropped (said); more is a clock to fix


def _in_order(path: Path, topic: str, msgs: list, receive_times: bool, notes: list[str]) -> tuple[np.ndarray, list]:
    """The messages whose stamps move forward, each after the last one kept: a stamp repeated or a message late
    now and then (a driver's, a serial link's) is dropped and counted; more often, the clock is refused in one
    line with its fix."""
    ns = _times(msgs, receive_times)
    before = np.maximum.accumulate(np.concatenate([[np.iinfo(np.int64).min], ns[:-1]]))
    keep = ns > before  # after every stamp before it: the last one kept is the largest of them
    dropped = int((~keep).sum())
    if dropped > MAX_OUT_OF_ORDER * ns.size:
        _ordered(path, topic, ns)  # refuses, naming the first message out of order
    if dropped:
        notes.append(f"{topic}: {dropped} of {ns.size} messages repeat or precede an earlier stamp: dropped")
    return ns[keep], [m for m, k in zip(msgs, keep.tolist(), strict=True) if k]


def _odom(path: Path, reader, topic: str, receive_times: bool, progress: Progress | None, notes: list[str]):
    ns, msgs = _in_order(path, topic, _read(reader, topic, progress), receive_times, notes)
    tw = np.array([[m.twist.twist.linear.x, m.twist.twist.angular.z] for _, m in msgs])
    _refuse_non_finite(path, topic, "twist", tw)
    q = msgs[0][1].pose.pose.orientation
    yaw0 = _yaw(q) if np.isfinite([q.x, q.y, q.z, q.w]).all() and (q.x or q.y or q.z or q.w) else 0.0
    return ns, tw, yaw0, msgs[0][1].child_frame_id.lstrip("/")


def _imu(path: Path, reader, topic: str, receive_times: bool, progress: Progress | None, notes: list[str]):
    ns, msgs = _in_order(path, topic, _read(reader, topic, progress), receive_times, notes)
    gyro = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for _, m in msgs])
    acc = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z] for _, m in msgs])
    _refuse_non_finite(path, topic, "angular velocity", gyro)
    _refuse_non_finite(path, topic, "linear acceleration", acc)
    cov = _cov_diag(
        path, topic, np.array([np.asarray(m.angular_velocity_covariance) for _, m in msgs]), notes, "angular velocity"
    )
    var = float(np.nanmean(cov)) if np.isfinite(cov).any() else float("nan")
    q = np.array([[m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w] for _, m in msgs], float)
    said = np.array([m.orientation_covariance[0] != -1 for _, m in msgs])  # REP 145: -1, no orientation
    q[~said | ~(np.abs(np.linalg.norm(q, axis=1) - 1) < 0.01)] = np.nan
    orientation = q if np.isfinite(q).all(axis=1).any() else None
    return ns, gyro, acc, var, msgs[0][1].header.frame_id.lstrip("/"), orientation


def _fixes(path: Path, reader, topic: str, receive_times: bool, progress: Progress | None, notes: list[str]):
    import pymap3d

    ns, msgs = _in_order(path, topic, _read(reader, topic, progress), receive_times, notes)
    lla = np.array([[m.latitude, m.longitude, m.altitude] for _, m in msgs], dtype=float)
    status = np.array([m.status.status for _, m in msgs])
    covs = np.array([np.asarray(m.position_covariance) for _, m in msgs])
    kinds = np.array([m.position_covariance_type for _, m in msgs])
    good = (status >= 0) & np.isfinite(lla[:, :2]).all(axis=1)
    if (~good).any():
        notes.append(f"{topic}: {int((~good).sum())} of {len(msgs)} messages have no fix (status -1 or NaN): dropped")
    if good.sum() < MIN_FIXES:
        raise NoFixes(
            f"{topic}: only {int(good.sum())} fixes (status >= 0) of {len(msgs)} messages.",
            file=path,
            field="--gnss",
            fix="record where the receiver has a fix, or leave GNSS out: --gnss none.",
        )
    lla, ns, covs, kinds = lla[good], ns[good], covs[good], kinds[good]
    lla[:, 2] = np.where(np.isfinite(lla[:, 2]), lla[:, 2], 0.0)
    datum = Datum(float(lla[0, 0]), float(lla[0, 1]), float(lla[0, 2]))
    e, n, u = pymap3d.geodetic2enu(lla[:, 0], lla[:, 1], lla[:, 2], datum.lat_deg, datum.lon_deg, datum.alt_m)
    enu = np.column_stack([e, n, u])
    step = np.linalg.norm(np.diff(enu[:, :2], axis=0), axis=1)
    for k in np.flatnonzero(step > JUMP_M):
        after = enu[k + 1 : k + 11, :2]
        if len(after) >= 3 and np.all(np.linalg.norm(after - enu[k, :2], axis=1) > JUMP_M / 2):
            raise LogFormatError(
                f"{topic}: the fixes leap {step[k]:.0f} m at message {k + 2} and stay there: the receiver's datum "
                "or its base station changed.",
                file=path,
                field="--gnss",
                fix="cut the bag at the jump (ros2 bag convert, rosbag filter) and calibrate each part.",
            )
    diag = _cov_diag(path, topic, covs, notes, "position")
    diag[kinds == 0] = np.nan  # COVARIANCE_TYPE_UNKNOWN
    return ns, enu, diag[:, :2], datum, msgs[0][1].header.frame_id.lstrip("/")


def _mounts(path: Path, reader, topics: list[Topic], base: str, imu_frame: str, gnss_frame: str | None):
    has_tf = [t for t in topics if t.msgtype in TF_TYPES and t.name.endswith("tf_static")]
    tree = _static_tree(path, reader, topics) if has_tf else {}

    def under_base(frame: str | None) -> tuple[np.ndarray, np.ndarray] | None:
        if not frame:
            return None
        R, t, chain = _pose_in(tree, frame)
        bases = [b for b in (base, *BASE_FRAMES) if b in chain]
        if not bases or frame == bases[0]:
            return None
        Rb, tb, _ = _pose_in(tree, bases[0])
        return Rb.T @ R, Rb.T @ (t - tb)

    imu = under_base(imu_frame)
    imu_mount = MountGuess(imu_frame or None)
    if imu is not None:
        from scipy.spatial.transform import Rotation

        rpy = Rotation.from_matrix(imu[0]).as_euler("xyz")  # URDF's rpy: extrinsic x, y, z
        imu_mount = MountGuess(imu_frame, tuple(map(float, imu[1])), tuple(map(float, rpy)))
    gnss = under_base(gnss_frame)
    gnss_mount = (
        MountGuess(gnss_frame, tuple(map(float, gnss[1])), None) if gnss is not None else MountGuess(gnss_frame)
    )
    return imu_mount, gnss_mount


def read_inertial_bag(
    path: Path,
    reader,
    topics: list[Topic],
    roles: InertialRoles,
    *,
    receive_times: bool = False,
    progress: Progress | None = None,
) -> tuple[InertialLog, tuple[str, ...]]:
    notes: list[str] = []
    o_ns, tw, yaw0, child = _odom(path, reader, roles.odom, receive_times, progress, notes)
    i_ns, gyro, acc, gvar, imu_frame, orientation = _imu(path, reader, roles.imu, receive_times, progress, notes)
    t0 = int(min(o_ns[0], i_ns[0]))
    gnss_t, enu, var, datum, gnss_frame = np.zeros(0), np.zeros((0, 3)), np.zeros((0, 2)), None, None
    if roles.gnss:
        try:
            g_ns, enu, var, datum, gnss_frame = _fixes(path, reader, roles.gnss, receive_times, progress, notes)
            gnss_t = _sec(g_ns, t0)
        except NoFixes as e:
            if roles.gnss_named:
                raise
            notes.append(f"{e.problem.rstrip('.')}: learned without GNSS")
            roles = InertialRoles(roles.odom, roles.imu, None)
    imu_mount, gnss_mount = _mounts(path, reader, topics, child or "base_link", imu_frame, gnss_frame)
    if imu_mount.rpy_rad is None:
        notes.append(
            f"/tf_static does not place {imu_frame or 'the IMU'} on the robot's base: its mount is learned from scratch"
        )
    log = InertialLog(
        source=str(path),
        odom_t=_sec(o_ns, t0),
        odom_v_m_s=tw[:, 0],
        odom_omega_rad_s=tw[:, 1],
        odom_yaw0_rad=yaw0,
        imu_t=_sec(i_ns, t0),
        gyro_rad_s=gyro,
        accel_m_s2=acc,
        gyro_var_reported=gvar,
        gnss_t=gnss_t,
        gnss_enu_m=enu,
        gnss_var_reported_m2=var,
        datum=datum,
        imu_mount=imu_mount,
        gnss_mount=gnss_mount,
        imu_orientation_xyzw=orientation,
        topics=roles.pairs(),
    )
    return log, tuple(notes)
