"""The log folder of a car-like robot (docs/ackermann.md): what ``convert bag`` writes from an F1TENTH or MuSHR bag's
``/scan``, ``/sensors/core``, ``/sensors/servo_position_command``, ``/drive`` and ``/tf_static``, and what
``sensact simulate car`` writes::

    run/
      meta.json        "kind": "car", the scan's geometry, /tf_static's lidar mount, the truth if simulated
      scans.csv        t_s, r0_mm ... r<N-1>_mm: a scan a row, stamped at its first beam; empty = no return
      vesc.csv         t_s, erpm: the motor's measured speed (VescState.speed, electrical RPM)
      servo.csv        t_s, servo: the servo positions sent (the VESC driver's units, 0 to 1)
      drive.csv        optional: t_s, speed_m_s, steering_angle_rad (/drive's AckermannDriveStamped)
      odom.csv         optional: t_s, v_m_s, omega_rad_s (/odom's twist: vesc_to_odom through the old yaml)
      groundtruth.csv  optional, scoring only: t_s, x_mm, y_mm, yaw_rad of the rear axle
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.atomic import write_json
from sensact.io.jsonfile import read_json_object
from sensact.io.lidar2d_folder import (
    SCANS,
    TRUTH,
    check_scans,
    read_scans,
    read_table,
    read_truth,
    read_urdf,
    write_table,
)
from sensact.logs.car_log import CarLog

KIND = "car"
VESC, SERVO, DRIVE, ODOM = "vesc.csv", "servo.csv", "drive.csv", "odom.csv"
MAX_ERPM = 1e6  # beyond any hobby motor's electrical RPM (100k mechanical RPM on 10 pole pairs)


def write_car_log(folder: Path, log: CarLog) -> Path:
    """``log`` as a folder; meta.json last, so that a folder with meta.json is whole."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_table(folder / SCANS, [f"r{i}_mm" for i in range(log.beams)], log.scan_t, log.ranges_mm, "%.1f")
    write_table(folder / VESC, ["erpm"], log.erpm_t, log.erpm[:, None])
    write_table(folder / SERVO, ["servo"], log.servo_t, log.servo[:, None])
    if log.drive_t.size:
        write_table(folder / DRIVE, ["speed_m_s", "steering_angle_rad"], log.drive_t, log.drive)
    if log.odom_t.size:
        write_table(folder / ODOM, ["v_m_s", "omega_rad_s"], log.odom_t, log.odom)
    if log.truth_pose is not None:
        write_table(folder / TRUTH, ["x_mm", "y_mm", "yaw_rad"], log.truth_t, log.truth_pose)
    meta = {
        "format": "sensact-log",
        "version": 1,
        "kind": KIND,
        "source": log.source,
        "scan": log.scan.to_dict(),
        "urdf": log.urdf.to_dict(),
        **({"truth": log.truth} if log.truth is not None else {}),
    }
    write_json(folder / "meta.json", meta)
    return folder


def _signal(path: Path, name: str, column: str, limit: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    """One timed column, checked: ordered, finite, within ``limit``, and two rows at least."""
    if not (path / name).is_file():
        raise LogFormatError(f"no {name}: a car's log needs {what}.", file=path, fix="see docs/ackermann.md.")
    t, v = read_table(path, name, [column])
    v = v[:, 0]
    if t.size < 2:
        raise LogFormatError(f"{t.size} rows: {what} needs many.", file=path / name, fix="record the whole run.")
    bad = np.flatnonzero(~(np.abs(v) <= limit))
    if bad.size:
        raise LogFormatError(
            f"row {bad[0] + 2}: {column} {v[bad[0]]:.6g} is beyond {limit:g}.",
            file=path / name,
            field=column,
            fix=f"write {what} in the VESC driver's own units (docs/ackermann.md).",
        )
    return t, v


def read_car_log(folder: Path) -> CarLog:
    """A car log folder, checked: scans as a lidar2d folder's, the VESC's ERPM, the servo's positions."""
    path = Path(folder)
    meta = read_json_object(path / "meta.json", LogFormatError, "write it as convert bag does (docs/ackermann.md).")
    geom, scan_t, ranges = read_scans(path, meta)
    erpm_t, erpm = _signal(path, VESC, "erpm", MAX_ERPM, "the VESC's measured motor speed (ERPM)")
    servo_t, servo = _signal(path, SERVO, "servo", 1e3, "the servo positions sent")
    check_scans(path / SCANS, scan_t, ranges, erpm_t)
    drive_t, drive = np.zeros(0), np.zeros((0, 2))
    if (path / DRIVE).is_file():
        drive_t, drive = read_table(path, DRIVE, ["speed_m_s", "steering_angle_rad"])
    odom_t, odom = np.zeros(0), np.zeros((0, 2))
    if (path / ODOM).is_file():
        odom_t, odom = read_table(path, ODOM, ["v_m_s", "omega_rad_s"])
    truth_t, truth_pose, truth = read_truth(path, meta)
    return CarLog(
        source=str(path),
        scan_t=scan_t,
        ranges_mm=ranges,
        scan=geom,
        erpm_t=erpm_t,
        erpm=erpm,
        servo_t=servo_t,
        servo=servo,
        drive_t=drive_t,
        drive=drive,
        urdf=read_urdf(meta, path),
        odom_t=odom_t,
        odom=odom,
        truth_t=truth_t,
        truth_pose=truth_pose,
        truth=truth,
    )
