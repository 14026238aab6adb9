"""A wheels-and-2-D-lidar robot's bag (docs/lidar2d.md): ``sensor_msgs/LaserScan`` (the lidar),
``sensor_msgs/JointState`` (the wheels' positions), ``nav_msgs/Odometry`` (/odom), a Twist (/cmd_vel) and
/tf_static (where the URDF puts the lidar), read into a ``Lidar2DLog`` in sensact's units (mm, REP 103 axes).

A scan is stamped at its first beam (ROS's LaserScan convention) and its beams are ``time_increment`` apart; a
range outside ``[range_min, range_max]`` (or inf, NaN) is no return. A lidar mounted upside down (its z axis
down in /tf_static) sweeps the other way: its scans are mirrored into the robot's sense of turning.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.lidar2d_folder import check_drive, check_scans
from sensact.io.rosbag import (
    MOCAP_NAME,
    NOT_WHEELS,
    TF_TYPES,
    WHEELS,
    Progress,
    Topic,
    _read,
    _stamp_ns,
    _static_tree,
    _yaw,
    sensor_topics,
)
from sensact.logs.lidar2d_log import Lidar2DLog, Pose2, ScanGeometry, UrdfGuess

SCAN_TYPE = "sensor_msgs/LaserScan"
JOINT_TYPE = "sensor_msgs/JointState"
ODOM_TYPE = "nav_msgs/Odometry"
TWIST_TYPES = ("geometry_msgs/Twist", "geometry_msgs/TwistStamped")
POSE_TYPES = ("geometry_msgs/PoseStamped", "geometry_msgs/PoseWithCovarianceStamped")
BASE_FRAMES = ("base_footprint", "base_link")
LEFT, RIGHT = re.compile(r"left|(^|_)l(_|$)", re.IGNORECASE), re.compile(r"right|(^|_)r(_|$)", re.IGNORECASE)


@dataclass(frozen=True)
class LidarRoles:
    scan: str
    joints: str | None
    odom: str | None
    cmd_vel: str | None
    truth: str | None

    def lines(self) -> list[str]:
        return [f"{k}: {v}" for k, v in self.__dict__.items() if v]


def has_laser_scan(topics: list[Topic]) -> bool:
    return any(t.msgtype == SCAN_TYPE and t.count for t in topics)


def _one(
    path: Path, topics: list[Topic], types: tuple[str, ...], named: str | None, option: str, what: str
) -> str | None:
    if named is not None:
        found = [t for t in topics if t.name == named]
        if not found:
            raise LogFormatError(
                f"no topic {named} in the bag.", file=path, field=option, fix=f"name {what} the bag has."
            )
        if found[0].msgtype not in types:
            raise LogFormatError(
                f"{named} is a {found[0].msgtype}, not {' or '.join(types)}.",
                file=path,
                field=option,
                fix=f"name {what}.",
            )
        return named
    cands = [t.name for t in topics if t.msgtype in types and t.count]
    if len(cands) > 1:
        raise LogFormatError(
            f"{len(cands)} topics could be {what}: {', '.join(cands)}.",
            file=path,
            field=option,
            fix=f"name one: {option} TOPIC.",
        )
    return cands[0] if cands else None


def lidar_roles(path: Path, topics: list[Topic], named: dict[str, str | None]) -> LidarRoles:
    """Which topic plays which part: each by its type unless named (two of one type must be named)."""
    scan = _one(path, topics, (SCAN_TYPE,), named.get("scan"), "--scan", "the 2-D lidar's LaserScan")
    truth_named = named.get("truth")
    commands = named.get("commands")
    if commands is not None and next((t.msgtype for t in topics if t.name == commands), None) == ODOM_TYPE:
        named = {**named, "odom": named.get("odom") or commands, "commands": None}  # --help: Odometry's twist
    others = [t for t in topics if t.name != truth_named]
    odoms = others if named.get("odom") else sensor_topics(others, ODOM_TYPE, NOT_WHEELS, WHEELS)
    odom = _one(path, odoms, (ODOM_TYPE,), named.get("odom"), "--odom", "the wheel odometry")
    truths = [
        t
        for t in topics
        if t.msgtype in (*POSE_TYPES, ODOM_TYPE) and (MOCAP_NAME.search(t.name) or t.name == truth_named)
    ]
    truth = _one(path, truths, (*POSE_TYPES, ODOM_TYPE), truth_named, "--truth", "the truth (motion capture)")
    roles = LidarRoles(
        scan=scan,
        joints=_one(path, topics, (JOINT_TYPE,), named.get("joints"), "--wheels", "the wheels' JointState"),
        odom=odom,
        cmd_vel=_one(path, topics, TWIST_TYPES, named.get("commands"), "--commands", "the commands (/cmd_vel)"),
        truth=truth,
    )
    if not (roles.joints or roles.odom or roles.cmd_vel):
        raise LogFormatError(
            "nothing says how the robot moved: no sensor_msgs/JointState, nav_msgs/Odometry or Twist topic.",
            file=path,
            fix="record /joint_states (the wheels' encoders), /odom or /cmd_vel with /scan.",
        )
    return roles


def _times(msgs: list, receive_times: bool) -> np.ndarray:
    if receive_times or not hasattr(msgs[0][1], "header"):
        return np.array([t for t, _ in msgs], dtype=np.int64)
    return np.array([_stamp_ns(m.header) for _, m in msgs], dtype=np.int64)


def _ordered(path: Path, topic: str, ns: np.ndarray) -> np.ndarray:
    if ns.size and np.any(np.diff(ns) <= 0):
        k = int(np.flatnonzero(np.diff(ns) <= 0)[0])
        raise LogFormatError(
            f"{topic}: message {k + 2}'s stamp is not after message {k + 1}'s.",
            file=path,
            field=topic,
            fix="pass --receive-times to time messages by when they were recorded.",
        )
    return ns


def _scans(path: Path, reader, topic: str, receive_times: bool, progress: Progress | None):
    msgs = _read(reader, topic, progress)
    first = msgs[0][1]
    n = len(first.ranges)
    geom = (float(first.angle_min), float(first.angle_increment), float(first.time_increment))
    if n < 16 or not np.isfinite(geom).all() or geom[1] == 0 or abs(geom[1]) * (n - 1) > 2 * np.pi + 1e-3:
        raise LogFormatError(
            f"{topic}: {n} beams from {geom[0]:g} rad by {geom[1]:g} rad is not a 2-D lidar's scan.",
            file=path,
            field=topic,
            fix="give the LaserScan of a scanning lidar (at least 16 beams, within one turn).",
        )
    lo, hi = float(first.range_min), float(first.range_max)
    if not (np.isfinite([lo, hi]).all() and 0 <= lo < hi <= 1e3) or not 0 <= geom[2] * n <= 1.0:
        raise LogFormatError(
            f"{topic}: range_min {lo:g} m, range_max {hi:g} m and time_increment {geom[2]:g} s are not a 2-D lidar's.",
            file=path,
            field=topic,
            fix="record the lidar driver's LaserScan as it publishes it (metres, seconds).",
        )
    ranges = np.full((len(msgs), n), np.nan)
    for k, (_, m) in enumerate(msgs):
        if len(m.ranges) != n:
            raise LogFormatError(
                f"{topic}: message {k + 1} has {len(m.ranges)} beams, the first had {n}.",
                file=path,
                field=topic,
                fix="record one lidar's scans at one resolution on this topic.",
            )
        r = np.asarray(m.ranges, dtype=np.float64)
        ranges[k] = np.where(np.isfinite(r) & (r >= lo) & (r <= hi) & (r > 0), r * 1000.0, np.nan)
    ns = _ordered(path, topic, _times(msgs, receive_times))
    scan = ScanGeometry(geom[0], geom[1], max(geom[2], 0.0), max(lo, 0.0) * 1000, hi * 1000)
    return ns, ranges, scan, first.header.frame_id.lstrip("/")


def _joint_pair(path: Path, topic: str, names: list[str], wheel_joints: tuple[str, str] | None) -> tuple[int, int]:
    if wheel_joints is not None:
        missing = [j for j in wheel_joints if j not in names]
        if missing:
            raise LogFormatError(
                f"{topic} has no joint {missing[0]} (it has {', '.join(names)}).",
                file=path,
                field="--wheel-joints",
                fix="name the left and right wheels' joints as the JointState names them.",
            )
        return names.index(wheel_joints[0]), names.index(wheel_joints[1])
    wheels = [n for n in names if "wheel" in n.lower()] or names
    left = [i for i, n in enumerate(names) if n in wheels and LEFT.search(n)]
    right = [i for i, n in enumerate(names) if n in wheels and RIGHT.search(n)]
    if len(left) != 1 or len(right) != 1 or left == right:
        raise LogFormatError(
            f"{topic}: cannot tell the left and right wheels among its joints {', '.join(names)}.",
            file=path,
            field="--wheel-joints",
            fix="name them: --wheel-joints LEFT_JOINT,RIGHT_JOINT.",
        )
    return left[0], right[0]


def _wheels(path: Path, reader, topic: str, wheel_joints, receive_times: bool, progress: Progress | None):
    msgs = _read(reader, topic, progress)
    keep, rows = [], []
    pair = pair_names = None
    for k, (_, m) in enumerate(msgs):
        names = list(m.name)
        if pair is None or len(names) <= max(pair) or (names[pair[0]], names[pair[1]]) != pair_names:
            if not names:
                continue
            try:
                pair = _joint_pair(path, topic, names, wheel_joints)
            except LogFormatError:
                if k == 0 or pair is None:
                    raise
                continue  # another publisher's joints on the same topic (an arm, a caster): not the wheels'
            pair_names = (names[pair[0]], names[pair[1]])
        pos = np.asarray(m.position, dtype=np.float64)
        if pos.size <= max(pair) or not np.isfinite(pos[list(pair)]).all():
            continue
        keep.append(k)
        rows.append(pos[list(pair)])
    if len(rows) < 2:
        raise LogFormatError(
            f"{topic}: fewer than two readings of the wheels' positions.",
            file=path,
            field=topic,
            fix="record /joint_states.",
        )
    ns = _times([msgs[k] for k in keep], receive_times)
    order = np.argsort(ns, kind="stable")
    ns, values = ns[order], np.array(rows)[order]
    uniq = np.concatenate([[True], np.diff(ns) > 0])
    return ns[uniq], values[uniq], pair_names


def _odom(path: Path, reader, topic: str, receive_times: bool, progress: Progress | None):
    msgs = _read(reader, topic, progress)
    ns = _ordered(path, topic, _times(msgs, receive_times))
    pose = np.array(
        [[m.pose.pose.position.x * 1000, m.pose.pose.position.y * 1000, _yaw(m.pose.pose.orientation)] for _, m in msgs]
    )
    if not np.isfinite(pose).all():
        raise LogFormatError(
            f"{topic}: a pose that is not finite.", file=path, field=topic, fix="cut the bag before it."
        )
    pose[:, 2] = np.unwrap(pose[:, 2])
    child = msgs[0][1].child_frame_id.lstrip("/")
    return ns, pose, child


def _cmd_vel(path: Path, reader, topic: str, receive_times: bool, progress: Progress | None):
    msgs = _read(reader, topic, progress)
    ns = (
        np.array([t for t, _ in msgs], dtype=np.int64)
        if receive_times or not hasattr(msgs[0][1], "header")
        else _times(msgs, False)
    )
    tw = [m.twist if hasattr(m, "twist") else m for _, m in msgs]
    values = np.array([[t.linear.x * 1000, t.angular.z] for t in tw])
    if not np.isfinite(values).all():
        k = int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0])
        raise LogFormatError(
            f"{topic}: message {k + 1}'s twist is not finite.", file=path, field=topic, fix="cut the bag before it."
        )
    order = np.argsort(ns, kind="stable")
    return ns[order], values[order]


def _pose_in(tree: dict, frame: str) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """``frame``'s rotation and translation in the root of its /tf_static tree, and its ancestors."""
    R, t, chain = np.eye(3), np.zeros(3), [frame]
    seen = {frame}
    while frame in tree:
        parent, Rp, tp = tree[frame]
        R, t = Rp @ R, Rp @ t + tp
        frame = parent
        if frame in seen:
            break
        seen.add(frame)
        chain.append(frame)
    return R, t, chain


def lidar_mount(tree: dict, lidar: str, base: str | None) -> tuple[Pose2 | None, float | None, bool, str | None]:
    """Where /tf_static puts the lidar's frame on the robot's base: (forward, left, yaw), its height, whether it
    is upside down, and the base frame it was found under (None when the tree does not join them)."""
    Rl, tl, chain = _pose_in(tree, lidar)
    bases = [b for b in ([base] if base else []) + list(BASE_FRAMES) if b in chain]
    if not bases:
        return None, None, False, None
    Rb, tb, _ = _pose_in(tree, bases[0])
    R = Rb.T @ Rl
    t = Rb.T @ (tl - tb)
    flipped = bool(R[2, 2] < 0)
    yaw = float(np.arctan2(R[1, 0], R[0, 0]))
    return Pose2(float(t[0] * 1000), float(t[1] * 1000), yaw), float(t[2] * 1000), flipped, bases[0]


@dataclass(frozen=True, eq=False)
class LidarBag:
    log: Lidar2DLog
    tables: dict[str, tuple[np.ndarray, np.ndarray]]  # wheels, odom, cmd_vel: times (s) and values
    notes: tuple[str, ...]
    wheel_joints: tuple[str, str] | None


def read_lidar2d_bag(
    path: Path,
    reader,
    topics: list[Topic],
    roles: LidarRoles,
    *,
    wheel_joints: tuple[str, str] | None = None,
    receive_times: bool = False,
    progress: Progress | None = None,
) -> LidarBag:
    notes: list[str] = []
    scan_ns, ranges, scan, frame = _scans(path, reader, roles.scan, receive_times, progress)
    tables: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    joints = child = None
    all_ns = [scan_ns]
    if roles.joints:
        ns, values, joints = _wheels(path, reader, roles.joints, wheel_joints, receive_times, progress)
        tables["wheels"] = (ns, values)
        all_ns.append(ns)
    if roles.odom:
        ns, pose, child = _odom(path, reader, roles.odom, receive_times, progress)
        tables["odom"] = (ns, pose)
        all_ns.append(ns)
    if roles.cmd_vel:
        ns, values = _cmd_vel(path, reader, roles.cmd_vel, receive_times, progress)
        tables["cmd_vel"] = (ns, values)
        all_ns.append(ns)
    drive_name = {"wheels": roles.joints, "odom": roles.odom, "cmd_vel": roles.cmd_vel}
    for name, (ns, values) in tables.items():
        check_drive(path, name, ns / 1e9, values, f"{drive_name[name]} message", 1)
    first_drive = next(iter(tables.values()))[0]
    check_scans(path, scan_ns / 1e9, ranges, first_drive / 1e9, f"{roles.scan} message", 1)
    truth = None
    if roles.truth:
        msgs = _read(reader, roles.truth, progress)
        ns = _times(msgs, receive_times)
        poses = [m.pose.pose if hasattr(m.pose, "pose") else m.pose for _, m in msgs]
        truth = (ns, np.array([[p.position.x * 1000, p.position.y * 1000, _yaw(p.orientation)] for p in poses]))
    has_tf = [t for t in topics if t.msgtype in TF_TYPES and t.name.endswith("tf_static")]
    tree = _static_tree(path, reader, topics) if has_tf else {}
    mount, up, flipped, base = lidar_mount(tree, frame, child)
    if mount is None:
        notes.append(
            f"/tf_static does not place {frame or 'the scan frame'} on the robot's base: no URDF mount to compare"
        )
    if flipped:  # an upside-down lidar sweeps clockwise in the robot's eyes: mirror its angles
        scan = ScanGeometry(
            -scan.angle_min_rad, -scan.angle_increment_rad, scan.time_increment_s, scan.range_min_mm, scan.range_max_mm
        )
        notes.append(f"{frame} is upside down in /tf_static: its beams' angles are read mirrored")
    t0 = min(int(ns[0]) for ns in all_ns)

    def sec(ns: np.ndarray) -> np.ndarray:
        return (np.asarray(ns, dtype=np.int64) - t0) / 1e9

    log = Lidar2DLog(
        source=str(path),
        scan_t=sec(scan_ns),
        ranges_mm=ranges,
        scan=scan,
        drive="wheels" if "wheels" in tables else ("odom" if "odom" in tables else "cmd_vel"),
        drive_t=sec(next(iter(tables.values()))[0]),
        drive_values=next(iter(tables.values()))[1],
        urdf=UrdfGuess(mount, up, lidar_frame=frame or None, base_frame=base),
        truth_t=None if truth is None else sec(truth[0]),
        truth_pose=None if truth is None else truth[1],
    )
    return LidarBag(log, {k: (sec(ns), v) for k, (ns, v) in tables.items()}, tuple(notes), joints)
