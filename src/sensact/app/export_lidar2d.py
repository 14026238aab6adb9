"""A wheels-and-2-D-lidar model (``learn em`` on a lidar2d log) handed to ROS (docs/lidar2d.md): ``urdf`` prints the
lidar joint's ``<origin>`` and the wheels as xacro properties, ``robot-localization`` the drive's noise as
robot_localization's process noise; metres, radians, REP 103 axes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sensact.app.ros_params import RL_STATES, process_noise, refuse_non_finite
from sensact.errors import ModelFormatError
from sensact.records import JsonObject

MM = 1e-3


BOUNDS = {  # what a differential drive and a lidar on it can be, in the model's units
    "wheel_radius_left_mm": (1e-9, 1e5),
    "wheel_radius_right_mm": (1e-9, 1e5),
    "axle_mm": (1e-6, 1e5),
    "forward_mm": (-1e5, 1e5),
    "left_mm": (-1e5, 1e5),
    "yaw_rad": (-2 * math.pi, 2 * math.pi),
    "delay_s": (-60.0, 60.0),
    "range_sigma_mm": (0.0, 1e5),
    "speed_mm_s": (0.0, 1e5),
    "turn_rate_rad_s": (0.0, 1e3),
}


def _number(doc: JsonObject, source: Path, *keys: str) -> float:
    node: object = doc
    for k in keys:
        node = node.get(k) if isinstance(node, dict) else None
    lo, hi = BOUNDS.get(keys[-1], (-math.inf, math.inf))
    if isinstance(node, bool) or not isinstance(node, int | float) or not (math.isfinite(node) and lo <= node <= hi):
        raise ModelFormatError(
            f"{'.'.join(keys)} is {node!r}, not a number in [{lo:g}, {hi:g}].",
            file=source,
            field=".".join(keys),
            fix="learn it again with `sensact learn em` on the lidar2d log.",
        )
    return float(node)


def drive_values(doc: JsonObject, source: Path) -> dict[str, float]:
    """The drive as ROS takes it: the wheels' radii and separation (m) when learned from encoders; from /odom's
    or /cmd_vel's motion, diff_drive_controller's two multipliers on the robot's nominal wheels (the learned
    numbers are gains there, and pasted as radii they would break the drive)."""
    if doc.get("drive", {}).get("source") == "wheels":
        left = _number(doc, source, "drive", "wheel_radius_left_mm") * MM
        right = _number(doc, source, "drive", "wheel_radius_right_mm") * MM
        return {
            "wheel_radius_left": left,
            "wheel_radius_right": right,
            "wheel_radius": (left + right) / 2,
            "wheel_separation": _number(doc, source, "drive", "axle_mm") * MM,
        }
    forward = _number(doc, source, "drive", "gain_forward")
    turn = _number(doc, source, "drive", "gain_turn")
    # diff_drive_controller: v = m_r r (wR + wL) / 2, w = m_r r (wR - wL) / (m_s b); turn gain m_r / m_s
    return {"wheel_radius_multiplier": forward, "wheel_separation_multiplier": forward / turn}


def urdf_snippet(doc: JsonObject, source: Path) -> str:
    """The lidar's fixed joint and the drive (radii and separation, or multipliers), as a xacro file: a
    ``<robot>`` with the xacro namespace, for ``<xacro:include>`` into the robot's description."""
    f = _number(doc, source, "lidar", "mount", "forward_mm") * MM
    y = _number(doc, source, "lidar", "mount", "left_mm") * MM
    yaw = _number(doc, source, "lidar", "mount", "yaw_rad")
    drive = drive_values(doc, source)
    urdf = doc.get("urdf") if isinstance(doc.get("urdf"), dict) else {}
    mount = urdf.get("lidar_mount") if isinstance(urdf.get("lidar_mount"), dict) else {}
    z = mount.get("up_mm")
    z = float(z) * MM if isinstance(z, int | float) and math.isfinite(z) else 0.0
    lidar = urdf.get("lidar_frame") or "base_scan"
    base = urdf.get("base_frame") or "base_link"
    note = "" if z else " z is 0: /tf_static gave no height; put the lidar's own."
    what = (
        "the wheels' radii and separation"
        if "wheel_separation" in drive
        else "diff_drive_controller's wheel_radius_multiplier and wheel_separation_multiplier (learned from the "
        "odometry's motion: gains on the robot's nominal wheels, not radii)"
    )
    props = "".join(f'  <xacro:property name="{k}" value="{v:.6f}"/>\n' for k, v in drive.items())
    return (
        '<?xml version="1.0"?>\n'
        f"<!-- sensact: learned from {doc.get('log', source.name)} (metres, radians; REP 103: x forward, y left)."
        f"{note}\n"
        f'     Include it in the robot\'s xacro: <xacro:include filename="{source.with_suffix(".urdf.xacro").name}"/>;'
        f"\n     it adds the lidar's joint ({base} to {lidar}, both links the robot's own) and, as properties, {what}."
        " -->\n"
        f'<robot name="sensact_calibration" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
        f"{props}"
        f'  <joint name="{lidar}_joint" type="fixed">\n'
        f'    <parent link="{base}"/>\n'
        f'    <child link="{lidar}"/>\n'
        f'    <origin xyz="{f:.6f} {y:.6f} {z:.6f}" rpy="0 0 {yaw:.6f}"/>\n'
        "  </joint>\n"
        "</robot>\n"
    )


def robot_localization(doc: JsonObject, source: Path) -> tuple[str, str]:
    """robot_localization's process noise from the drive's learned noise at the log's mean speed and turn rate
    (per second, x and y averaged over headings), and sensact's own numbers beside it."""
    import yaml

    noise = doc.get("drive", {}).get("noise", {}) if isinstance(doc.get("drive"), dict) else {}
    try:
        per_mm, per_rad = (np.asarray(noise.get(k, []), dtype=float) for k in ("variance_per_mm", "variance_per_rad"))
    except (TypeError, ValueError, AttributeError):
        per_mm = per_rad = np.zeros(0)
    ok = per_mm.shape == (3,) and per_rad.shape == (3,)
    if not (ok and np.all((per_mm >= 0) & (per_mm < 1e6)) and np.all((per_rad >= 0) & (per_rad < 1e6))):
        raise ModelFormatError(
            "drive.noise is not three variances per mm and three per rad, each >= 0 and below 1e6.",
            file=source,
            field="drive.noise",
            fix="learn it again with `sensact learn em` on the lidar2d log.",
        )
    v = _number(doc, source, "fit", "speed_mm_s")
    w = _number(doc, source, "fit", "turn_rate_rad_s")
    rate = per_mm * v + per_rad * w  # mm^2/s (x, y) and rad^2/s (yaw)
    per_s = np.diag([rate[0] * MM**2, rate[1] * MM**2, rate[2]])
    q = process_noise(per_s, 1.0)
    extra = {
        "source": str(source),
        **{k + ("_m" if "multiplier" not in k else ""): v for k, v in drive_values(doc, source).items()},
        "delay_s": _number(doc, source, "drive", "delay_s"),
        # m^2, m^2, rad^2 per metre travelled, and per radian turned
        "drive_variance_per_m": [float(per_mm[0] * MM), float(per_mm[1] * MM), float(per_mm[2] / MM)],
        "drive_variance_per_rad": [float(per_rad[0] * MM**2), float(per_rad[1] * MM**2), float(per_rad[2])],
        "lidar_mount": {
            "x_m": _number(doc, source, "lidar", "mount", "forward_mm") * MM,
            "y_m": _number(doc, source, "lidar", "mount", "left_mm") * MM,
            "yaw_rad": _number(doc, source, "lidar", "mount", "yaw_rad"),
        },
        "lidar_range_sigma_m": _number(doc, source, "lidar", "range_sigma_mm") * MM,
    }
    refuse_non_finite(extra | {"process_noise_covariance": q.ravel().tolist()}, source)
    rows = ",\n".join("      " + ", ".join(repr(float(x)) for x in row) for row in q.tolist())
    node = f"ekf_filter_node:\n  ros__parameters:\n    two_d_mode: true\n    process_noise_covariance: [\n{rows}]\n"
    header = (
        f"# robot_localization parameters from {source.name}, learned by sensact from wheels and a 2-D lidar (SI,\n"
        "# REP 103). process_noise_covariance: 15x15 per second, states " + ", ".join(RL_STATES) + ";\n"
        f"# x, y and yaw from the drive's learned noise at the log's mean speed ({v * MM:.3g} m/s) and turn rate\n"
        f"# ({w:.3g} rad/s), the rest robot_localization's defaults. The wheels, mount and noise per metre and per\n"
        "# radian are in the .sensact.yaml file beside this one.\n"
    )
    text = "# sensact's wheels-and-lidar calibration beyond robot_localization's parameters (SI, REP 103).\n"
    return header + node, text + yaml.safe_dump(
        {"sensact_calibration": {"ros__parameters": extra}}, sort_keys=False, default_flow_style=None, width=120
    )
