"""ROS bags written with rosbags' own writers, in ROS 1, ROS 2 sqlite3 and ROS 2 MCAP: a robot's /cmd_vel,
AprilTag transforms on /tf (or ROS 1's apriltag_ros detections), Range readings and a motion-capture
PoseStamped, as a ROS robot records them. What ``sensact simulate diffdrive --bag`` writes and the tests of
``sensact convert bag`` read."""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

FORMATS = ("mcap", "sqlite3", "ros1")
ROS1_EXTRA = {
    "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms",
    "apriltag_ros/msg/AprilTagDetection": "int32[] id\nfloat64[] size\ngeometry_msgs/PoseWithCovarianceStamped pose",
    "apriltag_ros/msg/AprilTagDetectionArray": "std_msgs/Header header\nAprilTagDetection[] detections",
}


# an F1TENTH car's messages (ackermann_msgs, and ROS 1's vesc_msgs), in neither distribution's standard set
CAR_TYPES = {
    "ackermann_msgs/msg/AckermannDrive": "float32 steering_angle\nfloat32 steering_angle_velocity\nfloat32 speed\n"
    "float32 acceleration\nfloat32 jerk",
    "ackermann_msgs/msg/AckermannDriveStamped": "std_msgs/Header header\nAckermannDrive drive",
    "vesc_msgs/msg/VescState": "float64 voltage_input\nfloat64 temperature_pcb\nfloat64 current_motor\n"
    "float64 current_input\nfloat64 speed\nfloat64 duty_cycle\nfloat64 charge_drawn\nfloat64 charge_regen\n"
    "float64 energy_drawn\nfloat64 energy_regen\nfloat64 displacement\nfloat64 distance_traveled\nint32 fault_code",
    "vesc_msgs/msg/VescStateStamped": "std_msgs/Header header\nVescState state",
}


def typestore(fmt: str):
    """ROS 2 Humble's types, or ROS 1 Noetic's with tf2_msgs and apriltag_ros registered, and a car's
    (their definitions go into the bag, as a recorder writes them)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if fmt == "ros1" else Stores.ROS2_HUMBLE)
    extra = {**ROS1_EXTRA, **CAR_TYPES} if fmt == "ros1" else CAR_TYPES
    for name, text in extra.items():
        ts.register(get_types_from_msg(text, name))
    return ts


class Msgs:
    """Message builders on one typestore."""

    def __init__(self, fmt: str):
        self.fmt, self.ts = fmt, typestore(fmt)
        self.T = self.ts.types

    def _stamp(self, t_ns: int):
        return self.T["builtin_interfaces/msg/Time"](sec=int(t_ns // 10**9), nanosec=int(t_ns % 10**9))

    def header(self, t_ns: int, frame: str):
        H = self.T["std_msgs/msg/Header"]
        if self.fmt == "ros1":
            return H(seq=0, stamp=self._stamp(t_ns), frame_id=frame)
        return H(stamp=self._stamp(t_ns), frame_id=frame)

    def vec(self, x=0.0, y=0.0, z=0.0):
        return self.T["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def quat_yaw(self, yaw: float):
        return self.T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def quat(self, x, y, z, w):
        return self.T["geometry_msgs/msg/Quaternion"](x=float(x), y=float(y), z=float(z), w=float(w))

    def twist(self, v: float, omega: float, side: float = 0.0):
        return self.T["geometry_msgs/msg/Twist"](linear=self.vec(v, side), angular=self.vec(z=omega))

    def odometry(self, t_ns: int, v: float, omega: float):
        Tw = self.T["geometry_msgs/msg/TwistWithCovariance"]
        Pw = self.T["geometry_msgs/msg/PoseWithCovariance"]
        return self.T["nav_msgs/msg/Odometry"](
            header=self.header(t_ns, "odom"),
            child_frame_id="base_link",
            pose=Pw(pose=self.pose(0, 0, 0), covariance=np.zeros(36)),
            twist=Tw(twist=self.twist(v, omega), covariance=np.zeros(36)),
        )

    def pose(self, x, y, yaw):
        P = self.T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0)
        return self.T["geometry_msgs/msg/Pose"](position=P, orientation=self.quat_yaw(yaw))

    def pose_stamped(self, t_ns: int, x: float, y: float, yaw: float):
        return self.T["geometry_msgs/msg/PoseStamped"](header=self.header(t_ns, "world"), pose=self.pose(x, y, yaw))

    def range(self, t_ns: int, r: float, lo: float = 0.02, hi: float = 6.0, frame: str = "sonar"):
        return self.T["sensor_msgs/msg/Range"](
            header=self.header(t_ns, frame),
            radiation_type=0,
            field_of_view=0.5,
            min_range=lo,
            max_range=hi,
            range=float(r),
            **({"variance": 0.0} if "variance" in self.T["sensor_msgs/msg/Range"].__dataclass_fields__ else {}),
        )

    def transform(self, t_ns: int, parent: str, child: str, xyz, quat):
        return self.T["geometry_msgs/msg/TransformStamped"](
            header=self.header(t_ns, parent),
            child_frame_id=child,
            transform=self.T["geometry_msgs/msg/Transform"](translation=self.vec(*xyz), rotation=self.quat(*quat)),
        )

    def tf(self, transforms):
        return self.T["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def detections(self, t_ns: int, frame: str, ids, xyz):
        det = self.T["apriltag_ros/msg/AprilTagDetection"]
        pwcs = self.T["geometry_msgs/msg/PoseWithCovarianceStamped"]
        pwc = self.T["geometry_msgs/msg/PoseWithCovariance"]
        P = self.T["geometry_msgs/msg/Point"]
        items = [
            det(
                id=np.array([i], dtype=np.int32),
                size=np.array([0.16]),
                pose=pwcs(
                    header=self.header(t_ns, frame),
                    pose=pwc(
                        pose=self.T["geometry_msgs/msg/Pose"](
                            position=P(x=p[0], y=p[1], z=p[2]), orientation=self.quat(0, 0, 0, 1)
                        ),
                        covariance=np.zeros(36),
                    ),
                ),
            )
            for i, p in zip(ids, xyz, strict=True)
        ]
        return self.T["apriltag_ros/msg/AprilTagDetectionArray"](header=self.header(t_ns, frame), detections=items)


# the optical frame in the camera's link frame (z forward, x right, y down): rpy (-pi/2, 0, -pi/2)
OPTICAL_QUAT = (-0.5, 0.5, -0.5, 0.5)


def write_bag(
    path: Path, fmt: str, messages: list[tuple[str, str, int, object]], m: Msgs, empty: list[tuple[str, str]] = ()
) -> Path:
    """``messages``: (topic, msgtype, receive time ns, message), written in time order; ``empty``: (topic,
    msgtype) of topics recorded with no message."""
    messages = sorted(messages, key=lambda r: r[2])
    path = Path(path).with_suffix(".bag") if fmt == "ros1" else Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # written under a temporary folder beside it and moved into place whole: an interrupted write leaves no bag
    # (a ROS 2 bag is a folder, which io.atomic's files are not)
    scratch = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    try:
        inner = scratch / path.name
        if fmt == "ros1":
            from rosbags.rosbag1 import Writer

            writer = Writer(inner)
            ser = m.ts.serialize_ros1
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if fmt == "mcap" else StoragePlugin.SQLITE3
            writer = Writer(inner, version=9, storage_plugin=plugin)
            ser = m.ts.serialize_cdr
        with writer:
            conns = {topic: writer.add_connection(topic, msgtype, typestore=m.ts) for topic, msgtype in empty}
            for topic, msgtype, t_ns, msg in messages:
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=m.ts)
                writer.write(conns[topic], int(t_ns), ser(msg, msgtype))
        os.rename(inner, path)  # refuses (never merges into) a folder that appeared meanwhile
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return path


@dataclass(frozen=True)
class RobotRecording:
    """What a differential drive with a tag camera and motion capture records, in ROS units (m, rad, REP 103
    axes, whole nanoseconds): /cmd_vel when a command changes, each tag's position in the camera's optical
    frame (z forward, x right, y down) at each sighting, the motion-capture pose (yaw 0 facing +x)."""

    cmd_ns: np.ndarray
    v_m_s: np.ndarray
    omega_rad_s: np.ndarray
    tag_ns: np.ndarray
    tag_id: np.ndarray
    tag_xyz_optical_m: np.ndarray  # (n, 3)
    truth_ns: np.ndarray
    truth_xy_m: np.ndarray  # (n, 2)
    truth_yaw_rad: np.ndarray
    camera_xyz_m: tuple[float, float, float] = (0.0, 0.0, 0.3)  # camera_link in base_link, for /tf_static
    map_xy_m: np.ndarray | None = None  # tag k's position, row k (not in the bag: the map.csv beside it)


def write_map_csv(path: Path, xy_m: np.ndarray) -> Path:
    """The map as ``convert bag --landmarks`` reads it: id,x_m,y_m, tag k on row k."""
    from sensact.io.atomic import write_text

    rows = [f"{k},{x!r},{y!r}" for k, (x, y) in enumerate(np.asarray(xy_m, dtype=float).tolist())]
    write_text(path, "\n".join(["id,x_m,y_m", *rows]) + "\n")
    return path


OPTICAL_FRAME = "camera_color_optical_frame"
RECEIVE_LAG_NS = 2_000_000  # a detection is recorded this long after its image's stamp


def write_robot_bag(path: Path, fmt: str, rec: RobotRecording, *, detections: bool = False) -> Path:
    """``rec`` as a bag: /cmd_vel (Twist, on the recording clock), /tf_static (base_link -> camera_link ->
    the optical frame), the tags on /tf (``tag36h11:ID``) or, with ``detections``, on /tag_detections as ROS
    1's apriltag_ros arrays, and /mocap/pose (PoseStamped)."""
    m = Msgs(fmt)
    msgs: list[tuple[str, str, int, object]] = [
        ("/cmd_vel", "geometry_msgs/msg/Twist", int(t), m.twist(v, w))
        for t, v, w in zip(rec.cmd_ns, rec.v_m_s, rec.omega_rad_s, strict=True)
    ]
    static = m.tf(
        [
            m.transform(0, "base_link", "camera_link", rec.camera_xyz_m, (0.0, 0.0, 0.0, 1.0)),
            m.transform(0, "camera_link", OPTICAL_FRAME, (0.0, 0.0, 0.0), OPTICAL_QUAT),
        ]
    )
    msgs.append(("/tf_static", "tf2_msgs/msg/TFMessage", int(rec.cmd_ns[0]), static))
    for t, i, p in zip(rec.tag_ns, rec.tag_id, rec.tag_xyz_optical_m, strict=True):
        if detections:
            msg = m.detections(int(t), OPTICAL_FRAME, [int(i)], [tuple(p)])
            msgs.append(("/tag_detections", "apriltag_ros/msg/AprilTagDetectionArray", int(t) + RECEIVE_LAG_NS, msg))
        else:
            tr = m.transform(int(t), OPTICAL_FRAME, f"tag36h11:{int(i)}", tuple(p), (0.0, 0.0, 0.0, 1.0))
            msgs.append(("/tf", "tf2_msgs/msg/TFMessage", int(t) + RECEIVE_LAG_NS, m.tf([tr])))
    for t, (x, y), yaw in zip(rec.truth_ns, rec.truth_xy_m, rec.truth_yaw_rad, strict=True):
        msgs.append(
            ("/mocap/pose", "geometry_msgs/msg/PoseStamped", int(t) + 500_000, m.pose_stamped(int(t), x, y, yaw))
        )
    return write_bag(path, fmt, msgs, m)


BAG_EPOCH_NS = 1_700_000_000 * 10**9  # a bag's clock is the wall's


def recording_of(run, camera_height_m: float = 0.3):  # -> io.rosbag_write.RobotRecording
    """A simulated camera robot's run as a ROS robot records it (``sensact simulate diffdrive --bag``): the
    commands when they change, each sighting as the tag's position in the camera's optical frame (the tags
    hang ``camera_height_m`` below it: a range from it in the ground plane is the simulator's), the poses as
    motion capture; times whole nanoseconds on a wall clock."""
    from sensact.io.rosbag_write import RobotRecording

    d, dt = run.log(), run.config.dt_s
    if d.command_names != ("v_mm_s", "omega_rad_s") or not np.isfinite(d.obs_bearing_rad).all():
        raise ValueError("a bag is written for a differential drive (v, omega) with a camera (bearings)")
    grid = BAG_EPOCH_NS + np.arange(d.n_steps, dtype=np.int64) * round(dt * 1e9)
    sent = np.flatnonzero(np.r_[True, np.any(np.diff(d.step_commands, axis=0) != 0, axis=1)])
    r, b = d.obs_readings[:, 0] / 1000.0, d.obs_bearing_rad
    xyz = np.column_stack([-r * np.sin(b), np.full(r.size, camera_height_m), r * np.cos(b)])
    fwd, left, _ = run.config.mounted_at
    poses = run.poses  # sensact's frame: heading 0 faces +y; REP 103's yaw 0 faces +x
    return RobotRecording(
        cmd_ns=grid[sent],
        v_m_s=d.step_commands[sent, 0] / 1000.0,
        omega_rad_s=d.step_commands[sent, 1],
        tag_ns=grid[d.obs_step],
        tag_id=d.obs_landmark.copy(),  # tag k is the map's landmark k
        tag_xyz_optical_m=xyz,
        truth_ns=grid,
        truth_xy_m=poses[:, :2] / 1000.0,
        truth_yaw_rad=poses[:, 2] + 0.5 * np.pi,
        camera_xyz_m=(fwd / 1000.0, left / 1000.0, camera_height_m),
        map_xy_m=d.landmarks_xy / 1000.0,
    )


def _laser_scan(m: Msgs, t_ns: int, frame: str, run, ranges_m: np.ndarray):
    cfg = run.config
    return m.T["sensor_msgs/msg/LaserScan"](
        header=m.header(t_ns, frame),
        angle_min=float(run.angle_min_rad),
        angle_max=float(run.angle_min_rad + run.angle_increment_rad * (ranges_m.size - 1)),
        angle_increment=float(run.angle_increment_rad),
        time_increment=float(run.time_increment_s),
        scan_time=float(1 / cfg.scan_hz),
        range_min=float(cfg.range_min_mm / 1000),
        range_max=float(cfg.range_max_mm / 1000),
        ranges=np.asarray(ranges_m, dtype=np.float32),
        intensities=np.zeros(0, dtype=np.float32),
    )


def _joint_state(m: Msgs, t_ns: int, names: list[str], positions: np.ndarray):
    return m.T["sensor_msgs/msg/JointState"](
        header=m.header(t_ns, ""),
        name=list(names),
        position=np.asarray(positions, dtype=np.float64),
        velocity=np.zeros(0),
        effort=np.zeros(0),
    )


def _odom_pose(m: Msgs, t_ns: int, pose: np.ndarray, twist: np.ndarray, child: str):
    Tw = m.T["geometry_msgs/msg/TwistWithCovariance"]
    Pw = m.T["geometry_msgs/msg/PoseWithCovariance"]
    return m.T["nav_msgs/msg/Odometry"](
        header=m.header(t_ns, "odom"),
        child_frame_id=child,
        pose=Pw(pose=m.pose(*pose), covariance=np.zeros(36)),
        twist=Tw(twist=m.twist(*twist), covariance=np.zeros(36)),
    )


LIDAR_FRAME, BASE_FRAME = "base_scan", "base_footprint"
WHEEL_JOINTS = ("wheel_left_joint", "wheel_right_joint")


def write_lidar_bag(path: Path, fmt: str, run) -> Path:
    """A simulated wheels-and-lidar robot (``sim.lidar2d``) as a TurtleBot records it: /scan (LaserScan, its
    stamp the first beam's), /joint_states (the wheels' encoder angles), /odom (from them and the nominal
    wheels), /cmd_vel, /tf_static (base_footprint -> base_link -> base_scan where the URDF says) and the true
    pose on /ground_truth/pose (PoseStamped, for scoring only)."""
    m = Msgs(fmt)
    ns = lambda t: BAG_EPOCH_NS + round(float(t) * 1e9)  # noqa: E731
    msgs: list[tuple[str, str, int, object]] = []
    for t, r in zip(run.scan_t, run.ranges_m, strict=True):
        msgs.append(
            ("/scan", "sensor_msgs/msg/LaserScan", ns(t) + 5_000_000, _laser_scan(m, ns(t), LIDAR_FRAME, run, r))
        )
    for t, phi in zip(run.joint_t, run.wheel_rad, strict=True):
        msgs.append(
            (
                "/joint_states",
                "sensor_msgs/msg/JointState",
                ns(t) + 1_000_000,
                _joint_state(m, ns(t), list(WHEEL_JOINTS), phi),
            )
        )
    for t, pose, tw in zip(run.odom_t, run.odom_pose, run.odom_twist, strict=True):
        msgs.append(("/odom", "nav_msgs/msg/Odometry", ns(t) + 1_000_000, _odom_pose(m, ns(t), pose, tw, BASE_FRAME)))
    for t, v, w in zip(run.cmd_t, run.cmd_v_m_s, run.cmd_omega_rad_s, strict=True):
        msgs.append(("/cmd_vel", "geometry_msgs/msg/Twist", ns(t), m.twist(v, w)))
    for t, pose in zip(run.truth_t, run.truth_pose, strict=True):
        msgs.append(
            ("/ground_truth/pose", "geometry_msgs/msg/PoseStamped", ns(t) + 500_000, m.pose_stamped(ns(t), *pose))
        )
    f, left, yaw = run.config.urdf_mount
    static = m.tf(
        [
            m.transform(ns(0), BASE_FRAME, "base_link", (0.0, 0.0, 0.01), (0.0, 0.0, 0.0, 1.0)),
            m.transform(
                ns(0),
                "base_link",
                LIDAR_FRAME,
                (f / 1000, left / 1000, 0.19),
                (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)),
            ),
        ]
    )
    msgs.append(("/tf_static", "tf2_msgs/msg/TFMessage", ns(0), static))
    return write_bag(path, fmt, msgs, m)


IMU_FRAME, GNSS_FRAME = "imu_link", "gps_link"


def _imu(m: Msgs, t_ns: int, gyro: np.ndarray, accel: np.ndarray, gyro_var: float, q: np.ndarray | None):
    cov = np.zeros(9)
    cov[[0, 4, 8]] = gyro_var
    q_cov = np.eye(3).ravel() * 1e-3
    if q is None or not np.isfinite(q).all():
        q = np.array([0.0, 0.0, 0.0, 1.0])
        q_cov = np.zeros(9)
        q_cov[0] = -1.0  # no orientation: a 6-axis IMU's, as REP 145 says
    return m.T["sensor_msgs/msg/Imu"](
        header=m.header(t_ns, IMU_FRAME),
        orientation=m.quat(*q),
        orientation_covariance=q_cov,
        angular_velocity=m.vec(*gyro),
        angular_velocity_covariance=cov,
        linear_acceleration=m.vec(*accel),
        linear_acceleration_covariance=np.eye(3).ravel() * 0.01,
    )


def _navsat(m: Msgs, t_ns: int, lla: tuple[float, float, float], var_en: np.ndarray, status: int):
    st = m.T["sensor_msgs/msg/NavSatStatus"](status=status, service=1)
    cov = np.zeros(9)
    cov[0], cov[4], cov[8] = var_en[0], var_en[1], 4 * var_en[0]
    return m.T["sensor_msgs/msg/NavSatFix"](
        header=m.header(t_ns, GNSS_FRAME),
        status=st,
        latitude=float(lla[0]),
        longitude=float(lla[1]),
        altitude=float(lla[2]),
        position_covariance=cov,
        position_covariance_type=2,  # COVARIANCE_TYPE_DIAGONAL_KNOWN
    )


def write_inertial_bag(path: Path, fmt: str, run) -> Path:
    """A simulated outdoor robot (``sim.inertial``) as a Husky records it: /odometry/wheel (nav_msgs/Odometry from
    the wheels), /imu/data (sensor_msgs/Imu, no orientation), /gps/fix (sensor_msgs/NavSatFix, WGS 84 around
    the simulator's datum) and /tf_static (base_link -> imu_link, base_link -> gps_link, as the simulator's
    ``tf_imu`` says)."""
    import pymap3d

    log = run.log_
    m = Msgs(fmt)
    ns = lambda t: BAG_EPOCH_NS + round(float(t) * 1e9)  # noqa: E731
    msgs: list[tuple[str, str, int, object]] = []
    dt = np.diff(log.odom_t, prepend=log.odom_t[0])
    yaw = log.odom_yaw0_rad + np.cumsum(log.odom_omega_rad_s * dt)
    x = np.cumsum(log.odom_v_m_s * np.cos(yaw) * dt)
    y = np.cumsum(log.odom_v_m_s * np.sin(yaw) * dt)
    for k, t in enumerate(log.odom_t):
        msgs.append(
            (
                "/odometry/wheel",
                "nav_msgs/msg/Odometry",
                ns(t) + 1_000_000,
                _odom_pose(m, ns(t), (x[k], y[k], yaw[k]), (log.odom_v_m_s[k], log.odom_omega_rad_s[k]), "base_link"),
            )
        )
    qs = log.imu_orientation_xyzw if log.imu_orientation_xyzw is not None else [None] * log.imu_t.size
    for t, g, a, q in zip(log.imu_t, log.gyro_rad_s, log.accel_m_s2, qs, strict=True):
        imu = _imu(m, ns(t), g, a, log.gyro_var_reported, q)
        msgs.append(("/imu/data", "sensor_msgs/msg/Imu", ns(t) + 500_000, imu))
    if log.has_gnss:
        d = log.datum
        lat, lon, alt = pymap3d.enu2geodetic(
            log.gnss_enu_m[:, 0], log.gnss_enu_m[:, 1], log.gnss_enu_m[:, 2], d.lat_deg, d.lon_deg, d.alt_m
        )
        for k, t in enumerate(log.gnss_t):
            msgs.append(
                (
                    "/gps/fix",
                    "sensor_msgs/msg/NavSatFix",
                    ns(t) + 2_000_000,
                    _navsat(m, ns(t), (lat[k], lon[k], alt[k]), log.gnss_var_reported_m2[k], 2),
                )
            )
    transforms = []
    im = log.imu_mount
    if im.rpy_rad is not None and im.xyz_m is not None:
        from scipy.spatial.transform import Rotation

        q = Rotation.from_euler("xyz", im.rpy_rad).as_quat()  # extrinsic x, y, z: URDF's rpy
        transforms.append(m.transform(ns(0), "base_link", IMU_FRAME, im.xyz_m, tuple(q)))
    gm = log.gnss_mount
    if gm.xyz_m is not None:
        transforms.append(m.transform(ns(0), "base_link", GNSS_FRAME, gm.xyz_m, (0.0, 0.0, 0.0, 1.0)))
    if transforms:
        msgs.append(("/tf_static", "tf2_msgs/msg/TFMessage", ns(0), m.tf(transforms)))
    return write_bag(path, fmt, msgs, m)


CAR_LIDAR_FRAME = "laser"


def write_car_bag(path: Path, fmt: str, run) -> Path:
    """A simulated car (``sim.car``) as an F1TENTH car records it: /scan, /sensors/core (VescStateStamped, the
    measured ERPM in ``state.speed``), /sensors/servo_position_command (Float64, no header), /drive
    (AckermannDriveStamped), /odom (vesc_to_odom through the yaml) and /tf_static (base_link -> laser where the
    URDF says)."""
    m = Msgs(fmt)
    T = m.T
    ns = lambda t: BAG_EPOCH_NS + round(float(t) * 1e9)  # noqa: E731
    msgs: list[tuple[str, str, int, object]] = []
    cfg = run.config
    for t, r in zip(run.scan_t, run.ranges_m, strict=True):
        msgs.append(
            ("/scan", "sensor_msgs/msg/LaserScan", ns(t) + 2_000_000, _laser_scan(m, ns(t), CAR_LIDAR_FRAME, run, r))
        )
    zeros = dict.fromkeys(
        ("voltage_input", "temperature_pcb", "current_motor", "current_input", "duty_cycle", "charge_drawn",
         "charge_regen", "energy_drawn", "energy_regen", "displacement", "distance_traveled"), 0.0
    )  # fmt: skip
    for t, e in zip(run.vesc_t, run.erpm, strict=True):
        state = T["vesc_msgs/msg/VescState"](speed=float(e), fault_code=0, **zeros)
        msgs.append(
            (
                "/sensors/core",
                "vesc_msgs/msg/VescStateStamped",
                ns(t) + 500_000,
                T["vesc_msgs/msg/VescStateStamped"](header=m.header(ns(t), ""), state=state),
            )
        )
    for t, s in zip(run.servo_t, run.servo, strict=True):
        msgs.append(
            ("/sensors/servo_position_command", "std_msgs/msg/Float64", ns(t), T["std_msgs/msg/Float64"](data=float(s)))
        )
    for t, v, a in zip(run.drive_t, run.drive_speed_m_s, run.drive_angle_rad, strict=True):
        drive = T["ackermann_msgs/msg/AckermannDrive"](
            steering_angle=float(a), steering_angle_velocity=0.0, speed=float(v), acceleration=0.0, jerk=0.0
        )
        msgs.append(
            (
                "/drive",
                "ackermann_msgs/msg/AckermannDriveStamped",
                ns(t) + 100_000,
                T["ackermann_msgs/msg/AckermannDriveStamped"](header=m.header(ns(t), "base_link"), drive=drive),
            )
        )
    for t, pose, tw in zip(run.odom_t, run.odom_pose, run.odom_twist, strict=True):
        msgs.append(("/odom", "nav_msgs/msg/Odometry", ns(t) + 1_000_000, _odom_pose(m, ns(t), pose, tw, "base_link")))
    f, left, yaw = cfg.urdf_mount
    static = m.tf(
        [
            m.transform(
                ns(0),
                "base_link",
                CAR_LIDAR_FRAME,
                (f / 1000, left / 1000, 0.1),
                (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)),
            )
        ]
    )
    msgs.append(("/tf_static", "tf2_msgs/msg/TFMessage", ns(0), static))
    return write_bag(path, fmt, msgs, m)
