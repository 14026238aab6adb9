"""An odometry-IMU-GNSS model (``learn em`` on an imu_gnss log) handed to the ROS nodes that consume it
(docs/inertial.md): diff_drive_controller's multipliers and twist covariance, robot_localization's ekf with
``odom0`` and ``imu0`` blocks, navsat_transform's heading, URDF joints for the IMU and the antenna, and
Kalibr's ``imu.yaml``. SI units, REP 103 axes; each a ROS 2 parameter file where it is one."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sensact.app.ros_params import process_noise, refuse_non_finite
from sensact.errors import ModelFormatError
from sensact.records import JsonObject

MM = 1e-3
UNMEASURED_VAR = 1e6
REJECT_P = 0.999  # robot_localization's rejection thresholds: the Mahalanobis distance a good reading passes this often


def _node(doc: JsonObject, source: Path, key: str, *, optional: bool = False) -> float | None:
    node: object = doc
    for k in key.split("."):
        node = node.get(k) if isinstance(node, dict) else None
    if node is None and optional:
        return None
    if isinstance(node, bool) or not isinstance(node, int | float) or not math.isfinite(node):
        raise ModelFormatError(
            f"{key} is {node!r}, not a finite number.",
            file=source,
            field=key,
            fix="learn it again with `sensact learn em` on the odometry-IMU-GNSS log.",
        )
    return float(node)


def _header(doc: JsonObject, source: Path, what: str) -> str:
    return f"# sensact: {what}, learned from {doc.get('log', source.name)} by `sensact learn em` (SI, REP 103).\n"


def _topic(doc: JsonObject, role: str, default: str) -> str:
    topics = doc.get("topics") if isinstance(doc.get("topics"), dict) else {}
    t = topics.get(role)
    return t if isinstance(t, str) and t else default


def _rates(doc: JsonObject, source: Path) -> tuple[float, float]:
    """The odometry's drift per second (m^2/s forward, rad^2/s turning) at the log's mean speed and turn rate."""
    noise = doc.get("fit", {}).get("noise", {}) if isinstance(doc.get("fit"), dict) else {}
    v = _node(doc, source, "fit.speed_m_s")
    w = _node(doc, source, "fit.turn_rate_rad_s")
    along = noise.get("along_mm2_per_mm")
    turn, turn_d = noise.get("turn_rad2_per_rad"), noise.get("turn_rad2_per_mm")
    per_m = float(along) * MM if isinstance(along, int | float) else 0.01**2  # m^2 per m travelled
    vq = per_m * v
    wq = (float(turn) if isinstance(turn, int | float) else 0.0) * w + (
        float(turn_d) / MM if isinstance(turn_d, int | float) else 0.0
    ) * v
    return max(vq, 1e-9), max(wq, 1e-9)


def diff_drive_controller(doc: JsonObject, source: Path) -> str:
    """The multipliers that make /odom report the true motion, and the twist's covariance."""
    gf = _node(doc, source, "odometry.gain_forward", optional=True)
    gt = _node(doc, source, "odometry.gain_turn")
    radius = 1.0 if gf is None else gf
    separation = radius / gt  # angular = radius_mult r (wr - wl) / (separation_mult b)
    vq, wq = _rates(doc, source)
    cov = [vq, 1e-6, UNMEASURED_VAR, UNMEASURED_VAR, UNMEASURED_VAR, wq]
    refuse_non_finite({"multipliers": [radius, separation], "cov": cov}, source)
    note = (
        "# gain_forward was not learned (the log has no GNSS): the radius multipliers stay 1.0, and the\n"
        "# separation multiplier carries the turn gain times the gyro's scale.\n"
        if gf is None
        else ""
    )
    return (
        _header(doc, source, "diff_drive_controller's wheel multipliers and twist covariance")
        + "# These are the multipliers relative to the ones the log was recorded with: multiply your current\n"
        "# wheel_radius_multiplier and wheel_separation_multiplier by them (1.0 if you never set them).\n"
        "# twist_covariance_diagonal: vx, vy, vz, wx, wy, wz (m^2/s^2, rad^2/s^2): the learned drift per second at\n"
        f"# the log's mean speed; vz, wx, wy unmeasured ({UNMEASURED_VAR:g}).\n"
        + note
        + "diff_drive_controller:\n  ros__parameters:\n"
        f"    left_wheel_radius_multiplier: {radius!r}\n"
        f"    right_wheel_radius_multiplier: {radius!r}\n"
        f"    wheel_separation_multiplier: {separation!r}\n"
        f"    twist_covariance_diagonal: [{', '.join(repr(float(c)) for c in cov)}]\n"
    )


def _bool_list(on: tuple[int, ...]) -> str:
    return "[" + ", ".join("true" if i in on else "false" for i in range(15)) + "]"


def robot_localization_ekf(doc: JsonObject, source: Path) -> str:
    """An ekf node fusing the wheel odometry's twist (odom0) and the gyro's turn rate (imu0), with the process
    noise from the learned noise and rejection thresholds at REJECT_P."""
    from scipy.stats import chi2

    vq, wq = _rates(doc, source)
    q = process_noise(np.diag([vq, vq, wq]), 1.0)
    gyro = _node(doc, source, "imu.gyro.noise_rad_s_sqrt_hz")
    bias = _node(doc, source, "imu.gyro.bias_rad_s")
    hz = _node(doc, source, "imu_hz", optional=True) or 100.0
    thr2 = math.sqrt(chi2.ppf(REJECT_P, 2))
    thr1 = math.sqrt(chi2.ppf(REJECT_P, 1))
    refuse_non_finite({"q": q.ravel().tolist(), "g": gyro, "b": bias}, source)
    rows = ",\n".join("      " + ", ".join(repr(float(x)) for x in row) for row in q.tolist())
    return (
        _header(doc, source, "robot_localization's ekf for wheel odometry and an IMU")
        + "# process_noise_covariance: 15x15 per second; x, y and yaw from the odometry's learned drift at the log's\n"
        "# mean speed and turn rate, the rest robot_localization's defaults. Rejection thresholds: Mahalanobis\n"
        f"# distances a good reading passes {REJECT_P:.1%} of the time. robot_localization has no gyro bias state:\n"
        f"# the learned mean bias, {bias:.6g} rad/s about base_link's z, wanders (see the model's bias.npz);\n"
        f"# the gyro's white noise is {gyro:.6g} rad/s/sqrt(Hz), {gyro * math.sqrt(hz):.6g} rad/s per reading at\n"
        f"# {hz:.4g} Hz. Put the IMU's learned mount in the URDF (export --format urdf) so tf turns its readings.\n"
        "ekf_filter_node:\n  ros__parameters:\n"
        "    frequency: 30.0\n"
        "    two_d_mode: true\n"
        "    publish_tf: true\n"
        "    odom_frame: odom\n"
        "    base_link_frame: base_link\n"
        "    world_frame: odom\n"
        f"    odom0: {_topic(doc, 'odom', '/odom')}\n"
        f"    odom0_config: {_bool_list((6, 7, 11))}\n"
        "    odom0_differential: false\n"
        f"    odom0_twist_rejection_threshold: {thr2!r}\n"
        f"    imu0: {_topic(doc, 'imu', '/imu/data')}\n"
        f"    imu0_config: {_bool_list((11,))}\n"
        "    imu0_differential: false\n"
        "    imu0_remove_gravitational_acceleration: true\n"
        f"    imu0_twist_rejection_threshold: {thr1!r}\n"
        f"    process_noise_covariance: [\n{rows}]\n"
    )


def navsat_transform(doc: JsonObject, source: Path) -> str:
    """navsat_transform's heading: ``yaw_offset`` and ``magnetic_declination_radians`` must sum to the learned
    heading offset; only the sum is learned, so the declination is 0 and the offset carries it all."""
    if _node(doc, source, "gnss.heading_offset_rad", optional=True) is None:
        raise ModelFormatError(
            "has no heading to east-north-up: its log had no GNSS fixes.",
            file=source,
            field="gnss.heading_offset_rad",
            fix="learn from a log with sensor_msgs/NavSatFix to export --format navsat-transform.",
        )
    theta = _node(doc, source, "gnss.heading_offset_rad")
    sd = _node(doc, source, "gnss.heading_offset_rad_sd", optional=True)
    sd = math.nan if sd is None else sd
    return (
        _header(doc, source, "navsat_transform's heading to east-north-up")
        + f"# yaw_offset + magnetic_declination_radians = {theta:.6g} rad (sd {sd:.3g}),\n"
        "# the odometry frame's heading counterclockwise from east. Only their sum is learned: the declination is\n"
        "# 0.0 here and yaw_offset carries the sum; if you set your site's declination, take it from yaw_offset.\n"
        "navsat_transform:\n  ros__parameters:\n"
        "    frequency: 30.0\n"
        "    delay: 3.0  # s to wait for the odometry and the first fix before computing the transform\n"
        "    magnetic_declination_radians: 0.0  # folded into yaw_offset (only the sum is learned)\n"
        f"    yaw_offset: {theta!r}\n"
        "    zero_altitude: true\n"
        "    use_odometry_yaw: true  # the learned offset is the odometry frame's, not a magnetometer's\n"
        "    broadcast_cartesian_transform: false\n"
        "    publish_filtered_gps: false\n"
    )


def urdf_joints(doc: JsonObject, source: Path) -> str:
    """The IMU's and the antenna's fixed joints on base_link, inside a <robot> that defines their links."""
    roll, pitch, yaw = (_node(doc, source, f"imu.mount.{k}_rad") for k in ("roll", "pitch", "yaw"))
    tf = doc.get("tf_static") if isinstance(doc.get("tf_static"), dict) else {}
    imu_tf = tf.get("imu") if isinstance(tf.get("imu"), dict) else {}
    gnss_tf = tf.get("gnss") if isinstance(tf.get("gnss"), dict) else {}

    def xyz(node: dict) -> list[float] | None:
        v = node.get("xyz_m")
        return [float(x) for x in v] if isinstance(v, list) and len(v) == 3 else None

    imu_xyz = xyz(imu_tf)
    imu_frame = imu_tf.get("frame") or "imu_link"
    lines = [
        f"<!-- sensact: the IMU's and the GNSS antenna's joints, learned from {doc.get('log', source.name)} (metres,",
        "     radians, REP 103). The IMU's orientation is learned; its position is /tf_static's"
        + ("" if imu_xyz else " (none given: 0, put yours)")
        + ". -->",
        '<robot name="sensact_calibration">',
        '  <link name="base_link"/>',
        f'  <link name="{imu_frame}"/>',
        f'  <joint name="{imu_frame}_joint" type="fixed">',
        '    <parent link="base_link"/>',
        f'    <child link="{imu_frame}"/>',
        f'    <origin xyz="{" ".join(f"{v:.6f}" for v in (imu_xyz or [0.0, 0.0, 0.0]))}"'
        f' rpy="{roll:.6f} {pitch:.6f} {yaw:.6f}"/>',
        "  </joint>",
    ]
    f = _node(doc, source, "gnss.lever_arm.forward_mm", optional=True)
    left = _node(doc, source, "gnss.lever_arm.left_mm", optional=True)
    if f is not None and left is not None:
        g_xyz = xyz(gnss_tf)
        z = g_xyz[2] if g_xyz else 0.0
        frame = gnss_tf.get("frame") or "gps_link"
        lines += [
            "  <!-- the antenna: forward and left learned; its height is /tf_static's"
            + ("" if g_xyz else " (none: 0)")
            + " -->",
            f'  <link name="{frame}"/>',
            f'  <joint name="{frame}_joint" type="fixed">',
            '    <parent link="base_link"/>',
            f'    <child link="{frame}"/>',
            f'    <origin xyz="{f * MM:.6f} {left * MM:.6f} {z:.6f}" rpy="0 0 0"/>',
            "  </joint>",
        ]
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


ACCEL_RANDOM_WALK = 1e-3  # m/s^3/sqrt(Hz): not learned here (it needs hours still); a typical MEMS part's


def kalibr_imu(doc: JsonObject, source: Path) -> str:
    """Kalibr's imu.yaml (its IMU noise model) with the units spelled out."""
    gyro = _node(doc, source, "imu.gyro.noise_rad_s_sqrt_hz")
    walk = _node(doc, source, "imu.gyro.bias_walk_rad_s_sqrt_s")
    acc = _node(doc, source, "imu.accel.noise_m_s2_sqrt_hz")
    hz = _node(doc, source, "imu_hz", optional=True) or 100.0
    return (
        _header(doc, source, "Kalibr's IMU noise model")
        + "# In-motion values, from the robot's own drive: not a static Allan-variance recording, so they already\n"
        "# hold the vibration Kalibr's users otherwise inflate a static recording's values 10-20x for.\n"
        f"# accelerometer_random_walk is not learned here: a typical MEMS part's {ACCEL_RANDOM_WALK:g}.\n"
        f"rostopic: {_topic(doc, 'imu', '/imu/data')}\n"
        f"update_rate: {hz!r}  # Hz\n"
        f"accelerometer_noise_density: {acc!r}  # m/s^2/sqrt(Hz) (continuous-time white noise)\n"
        f"accelerometer_random_walk: {ACCEL_RANDOM_WALK!r}  # m/s^3/sqrt(Hz) (not learned)\n"
        f"gyroscope_noise_density: {gyro!r}  # rad/s/sqrt(Hz) (continuous-time white noise)\n"
        f"gyroscope_random_walk: {walk!r}  # rad/s^2/sqrt(Hz) (the bias's random walk, learned)\n"
    )
