"""A car model (``learn em`` on a car log) handed to its stack (docs/ackermann.md): ``vesc`` writes vesc.yaml's four
numbers and the wheelbase as the F1TENTH and MuSHR stacks read them (``ERPM = gain * speed + offset``, ``servo =
gain * angle + offset``; m/s, rad, m), ``urdf`` the lidar's joint; REP 103 axes."""

from __future__ import annotations

import math
from pathlib import Path

from sensact.errors import ModelFormatError
from sensact.records import JsonObject

VESC_KEYS = (
    "speed_to_erpm_gain",
    "speed_to_erpm_offset",
    "steering_angle_to_servo_gain",
    "steering_angle_to_servo_offset",
)


def _number(doc: JsonObject, source: Path, *keys: str) -> float:
    node: object = doc
    for k in keys:
        node = node.get(k) if isinstance(node, dict) else None
    if isinstance(node, bool) or not isinstance(node, int | float) or not math.isfinite(node):
        raise ModelFormatError(
            f"{'.'.join(keys)} is {node!r}, not a number"
            + (
                ": the log's curves did not tell the steering gain from the wheelbase (only their product, "
                "car.steering_gain_times_wheelbase_m, is known)."
                if keys[-1] in ("steering_angle_to_servo_gain", "wheelbase_mm")
                else "."
            ),
            file=source,
            field=".".join(keys),
            fix="record tighter turns both ways and learn again with `sensact learn em`.",
        )
    return float(node)


def vesc_yaml(doc: JsonObject, source: Path) -> str:
    """vesc.yaml's calibration keys, at the top level as the F1TENTH (ROS 1) file holds them."""
    values = {k: _number(doc, source, "vesc", k) for k in VESC_KEYS}
    wheelbase = _number(doc, source, "car", "wheelbase_mm") / 1000
    sds = {k: doc["vesc"].get(f"{k}_sd") for k in VESC_KEYS}
    lines = [
        f"# sensact: learned from {doc.get('log', source.name)}; replace these keys in the car's vesc.yaml.",
        "# ERPM = speed_to_erpm_gain * speed (m/s) + speed_to_erpm_offset;",
        "# servo = steering_angle_to_servo_gain * steering angle (rad, left positive)",
        "#   + steering_angle_to_servo_offset.",
        "# ROS 2 (f1tenth_stack): put them under the node's ros__parameters.",
    ]
    for k, v in values.items():
        sd = sds[k]
        note = f"  # sd {sd:.3g}" if isinstance(sd, int | float) else ""
        lines.append(f"{k}: {v:.6f}{note}")
    lines.append(f"wheelbase: {wheelbase:.4f}  # m, vesc_to_odom's")
    return "\n".join(lines) + "\n"


def urdf_snippet(doc: JsonObject, source: Path) -> str:
    """The lidar's fixed joint on the rear axle's base_link, as a xacro ``<robot>`` to include."""
    f = _number(doc, source, "lidar", "mount", "forward_mm") / 1000
    y = _number(doc, source, "lidar", "mount", "left_mm") / 1000
    yaw = _number(doc, source, "lidar", "mount", "yaw_rad")
    urdf = doc.get("urdf") if isinstance(doc.get("urdf"), dict) else {}
    mount = urdf.get("lidar_mount") if isinstance(urdf.get("lidar_mount"), dict) else {}
    z = mount.get("up_mm")
    z = float(z) / 1000 if isinstance(z, int | float) and math.isfinite(z) else 0.0
    lidar = urdf.get("lidar_frame") or "laser"
    base = urdf.get("base_frame") or "base_link"
    note = "" if z else " z is 0: /tf_static gave no height; put the lidar's own."
    return (
        '<?xml version="1.0"?>\n'
        f"<!-- sensact: learned from {doc.get('log', source.name)} (metres, radians; REP 103: x forward, y left;"
        f" {base} at the rear axle's middle).{note} -->\n"
        '<robot name="sensact_calibration" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
        f'  <joint name="{lidar}_joint" type="fixed">\n'
        f'    <parent link="{base}"/>\n'
        f'    <child link="{lidar}"/>\n'
        f'    <origin xyz="{f:.6f} {y:.6f} {z:.6f}" rpy="0 0 {yaw:.6f}"/>\n'
        "  </joint>\n"
        "</robot>\n"
    )
