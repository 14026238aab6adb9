"""The log folder of a robot with wheel encoders and a 2-D lidar (docs/lidar2d.md): what ``convert bag`` writes from
a bag's ``/scan``, ``/joint_states``, ``/odom``, ``/cmd_vel`` and ``/tf_static``, what ``simulate diffdrive
--set sensor=lidar2d`` writes, and the CSV route for a robot without ROS (docs/lidar2d.md)::

    run/
      meta.json        "kind": "lidar2d", the scan's geometry, the URDF's guess, the truth if simulated
      scans.csv        t_s, r0_mm ... r<N-1>_mm: a scan a row, stamped at its first beam; empty = no return
      wheels.csv       t_s, left_rad, right_rad: the wheel joints' positions (any unit the two share)
      odom.csv         optional: t_s, x_mm, y_mm, yaw_rad of the wheel odometry
      cmd_vel.csv      optional: t_s, v_mm_s, omega_rad_s
      groundtruth.csv  optional, scoring only: t_s, x_mm, y_mm, yaw_rad

One of wheels.csv, odom.csv or cmd_vel.csv drives the robot, in that order of preference.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.atomic import write_json, write_text
from sensact.io.csvtable import read_numeric_csv, refuse_unordered, time_origin
from sensact.io.jsonfile import read_json_object
from sensact.logs.lidar2d_log import Lidar2DLog, Pose2, ScanGeometry, UrdfGuess
from sensact.records import JsonObject

KIND = "lidar2d"
SCANS, WHEELS, ODOM, CMD_VEL, TRUTH = "scans.csv", "wheels.csv", "odom.csv", "cmd_vel.csv", "groundtruth.csv"


def _cells(x: np.ndarray, fmt: str) -> list[list[str]]:
    return [["" if not math.isfinite(v) else fmt % v for v in row] for row in np.asarray(x, dtype=float).tolist()]


def write_table(path: Path, names: list[str], t: np.ndarray, values: np.ndarray, fmt: str = "%.10g") -> None:
    rows = [",".join([f"{tt:.9f}", *cells]) for tt, cells in zip(t.tolist(), _cells(values, fmt), strict=True)]
    write_text(path, "\n".join([",".join(["t_s", *names]), *rows]) + "\n")


def write_lidar2d_log(folder: Path, log: Lidar2DLog, tables: dict[str, tuple[np.ndarray, np.ndarray]]) -> Path:
    """``log``'s scans and ``tables`` (``"wheels"``, ``"odom"``, ``"cmd_vel"``: times and values) as a folder;
    meta.json last, so that a folder with meta.json is whole."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    beams = log.beams
    write_table(folder / SCANS, [f"r{i}_mm" for i in range(beams)], log.scan_t, log.ranges_mm, "%.1f")
    names = {
        "wheels": ["left_rad", "right_rad"],
        "odom": ["x_mm", "y_mm", "yaw_rad"],
        "cmd_vel": ["v_mm_s", "omega_rad_s"],
    }
    for name, (t, values) in tables.items():
        write_table(folder / f"{name}.csv", names[name], t, values)
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


def _number(node: object, path: Path, field: str, lo: float, hi: float, *, optional: bool = False) -> float | None:
    """A meta.json number in ``[lo, hi]`` (or, ``optional``, null), else one line naming the field."""
    if node is None and optional:
        return None
    if isinstance(node, bool) or not isinstance(node, int | float) or not lo <= node <= hi:
        raise LogFormatError(
            f"{field} is {node!r}, not {'null or ' if optional else ''}a number in [{lo:g}, {hi:g}].",
            file=path / "meta.json",
            field=field,
            fix="write null where the URDF says nothing."
            if optional
            else "write it as convert bag does (docs/lidar2d.md).",
        )
    return float(node)


def read_urdf(meta: JsonObject, path: Path) -> UrdfGuess:
    node = meta.get("urdf") or {}
    if not isinstance(node, dict):
        raise LogFormatError("urdf is not an object.", file=path / "meta.json", field="urdf", fix="write null or {}.")
    m = node.get("lidar_mount")
    mount = up = None
    if m is not None:
        if not isinstance(m, dict):
            raise LogFormatError(
                "urdf.lidar_mount is not an object.",
                file=path / "meta.json",
                field="urdf.lidar_mount",
                fix="null or {forward_mm, left_mm, yaw_rad}.",
            )
        vals = [_number(m.get(k), path, f"urdf.lidar_mount.{k}", lo, hi, optional=True) for k, lo, hi in
                (("forward_mm", -1e4, 1e4), ("left_mm", -1e4, 1e4), ("yaw_rad", -7.0, 7.0))]  # fmt: skip
        mount = None if None in vals else Pose2(*vals)
        up = _number(m.get("up_mm"), path, "urdf.lidar_mount.up_mm", -1e4, 1e4, optional=True)
    frames = [node.get(k) if isinstance(node.get(k), str) else None for k in ("lidar_frame", "base_frame")]
    return UrdfGuess(
        mount,
        up,
        _number(node.get("wheel_radius_mm"), path, "urdf.wheel_radius_mm", 1e-6, 1e5, optional=True),
        _number(node.get("axle_mm"), path, "urdf.axle_mm", 1e-3, 1e5, optional=True),
        *frames,
    )


def read_table(path: Path, name: str, columns: list[str]) -> tuple[np.ndarray, np.ndarray]:
    # times from the scans' first whole second, exactly: a fit differences them (docs/lidar2d.md)
    table = read_numeric_csv(path / name, ["t_s", *columns], what=name, origin={"t_s": time_origin(path / SCANS)})
    t = table["t_s"]
    refuse_unordered(path / name, t, strict=True)
    values = np.column_stack([table[c] for c in columns])
    if name != SCANS and not np.isfinite(values).all():
        row = int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0])
        raise LogFormatError(
            f"row {row + 2} has an empty cell.", file=path / name, field=columns[0], fix="give every row every value."
        )
    return t, values


MAX_WHEEL_RATE = 1e7  # units of a wheel's position per second: beyond any encoder (20 turns a second of 100k ticks)
MAX_RANGE_MM = 1e6  # a range beyond a kilometre is no 2-D lidar's
MAX_GAP_S = 3600.0  # rows further apart than an hour are two recordings, or a clock that jumped


def _refuse_gap(path: Path, t: np.ndarray, row: str, first: int) -> np.ndarray:
    """``t``'s steps, refused where two rows are further apart than an hour (two recordings, a clock that
    jumped)."""
    gaps = np.diff(t)
    if gaps.size and gaps.max() > MAX_GAP_S:
        k = int(np.argmax(gaps))
        raise LogFormatError(
            f"{row}s {k + first} and {k + first + 1} are {gaps[k]:.3g} s apart: two recordings, or a clock that "
            "jumped.",
            file=path,
            field="t_s",
            fix="keep one recording, on one clock, in seconds.",
        )
    return gaps


def check_drive(path: Path, drive: str, t: np.ndarray, values: np.ndarray, row: str = "row", first: int = 2) -> None:
    """What drives the robot, checked: two rows at least, no gap of an hour, no wheel turning (or /odom or
    /cmd_vel moving) faster than any robot does."""
    if t.size < 2:
        raise LogFormatError(
            f"{t.size} {row}: the robot's motion needs at least two.", file=path, fix="record the whole run."
        )
    gaps = _refuse_gap(path, t, row, first)
    with np.errstate(over="ignore", invalid="ignore"):
        # wheels and odom: how fast their positions change; cmd_vel: the speeds it asks for
        rate = np.abs(values[:-1]) if drive == "cmd_vel" else np.abs(np.diff(values, axis=0)) / gaps[:, None]
        bad = ~(rate <= (MAX_WHEEL_RATE if drive == "wheels" else 1e5))  # mm/s and rad/s beyond any robot's
    if bad.any():
        k = int(np.flatnonzero(bad.any(axis=1))[0])
        raise LogFormatError(
            f"{row} {k + first + (drive != 'cmd_vel')} moves the robot at {float(np.max(rate[k])):.3g} per second, "
            "faster than any robot.",
            file=path,
            fix="give positions in rad (or ticks), mm and mm/s, as docs/lidar2d.md says.",
        )


def check_scans(
    path: Path, scan_t: np.ndarray, ranges_mm: np.ndarray, drive_t: np.ndarray, row: str = "row", first: int = 2
) -> None:
    """Scans (NaN: no return) checked: two at least, some returns, no gap of an hour, on the same clock as the
    robot's motion."""
    if scan_t.size < 2:
        raise LogFormatError(f"{scan_t.size} scan: a calibration needs many.", file=path, fix="record the whole run.")
    seen = np.isfinite(ranges_mm) & (ranges_mm > 0)
    if seen.sum() < 0.01 * ranges_mm.size:
        raise LogFormatError(
            f"{int(seen.sum())} of {ranges_mm.size} ranges are returns: the lidar saw nothing.",
            file=path,
            fix="record the lidar in a room, its driver's range_min and range_max as published.",
        )
    _refuse_gap(path, scan_t, row, first)
    inside = (scan_t >= drive_t[0]) & (scan_t <= drive_t[-1])
    if inside.mean() < 0.5:
        raise LogFormatError(
            f"{int(np.count_nonzero(~inside))} of {scan_t.size} scans fall outside the robot's motion's span "
            f"({drive_t[0]:g} to {drive_t[-1]:g} s; the scans run {scan_t[0]:g} to {scan_t[-1]:g} s).",
            file=path,
            field="t_s",
            fix="write both on one clock, in seconds (convert bag --receive-times where the stamps are on another).",
        )


def _refuse_absurd_ranges(path: Path, ranges_mm: np.ndarray) -> None:
    """A range below zero or beyond a kilometre is not a reading beyond range_max (no return): garbage."""
    with np.errstate(invalid="ignore"):
        bad = (ranges_mm < 0) | (ranges_mm > MAX_RANGE_MM)
    if bad.any():
        k, beam = (int(v[0]) for v in np.nonzero(bad))
        raise LogFormatError(
            f"row {k + 2}: a range of {ranges_mm[k, beam]:.6g} mm (beam {beam}).",
            file=path,
            field=f"r{beam}_mm",
            fix="write ranges in mm, an empty cell for no return.",
        )


def read_scans(path: Path, meta: JsonObject) -> tuple[ScanGeometry, np.ndarray, np.ndarray]:
    """The scan's geometry (meta.json) and scans.csv, checked: ordered times, ranges in mm, NaN where no return
    (a car's folder holds its scans the same way)."""
    node = meta.get("scan")
    if not isinstance(node, dict):
        raise LogFormatError("no scan geometry.", file=path / "meta.json", field="scan", fix="see docs/lidar2d.md.")
    geom = ScanGeometry(
        _number(node.get("angle_min_rad"), path, "scan.angle_min_rad", -7.0, 7.0),
        _number(node.get("angle_increment_rad"), path, "scan.angle_increment_rad", -1.0, 1.0),
        _number(node.get("time_increment_s"), path, "scan.time_increment_s", 0.0, 0.1),
        _number(node.get("range_min_mm"), path, "scan.range_min_mm", 0.0, 1e6),
        _number(node.get("range_max_mm"), path, "scan.range_max_mm", 1.0, 1e6),
    )
    if not geom.range_min_mm < geom.range_max_mm:
        raise LogFormatError(
            f"scan.range_min_mm {geom.range_min_mm:g} is not below range_max_mm {geom.range_max_mm:g}.",
            file=path / "meta.json",
            field="scan.range_max_mm",
            fix="give the LaserScan's range_min and range_max, in mm.",
        )
    header = []
    if (path / SCANS).is_file():
        with (path / SCANS).open(encoding="utf-8", errors="replace") as f:
            header = f.readline().strip().split(",")
    beams = [c for c in header if c.startswith("r") and c.endswith("_mm")]
    if not beams:
        raise LogFormatError(
            "no scans (a header t_s, r0_mm, r1_mm, ...).", file=path / SCANS, fix="see docs/lidar2d.md."
        )
    scan_t, ranges = read_table(path, SCANS, beams)
    if not 1e-5 <= abs(geom.angle_increment_rad) * (len(beams) - 1) <= 2 * np.pi + 1e-6:
        raise LogFormatError(
            f"{len(beams)} beams of {geom.angle_increment_rad:g} rad span no angle, or more than a turn.",
            file=path / "meta.json",
            field="scan.angle_increment_rad",
            fix="give the LaserScan's angle_increment, in radians.",
        )
    _refuse_absurd_ranges(path / SCANS, ranges)
    ranges = np.where((ranges >= geom.range_min_mm) & (ranges <= geom.range_max_mm), ranges, np.nan)
    return geom, scan_t, ranges


def read_truth(path: Path, meta: JsonObject) -> tuple[np.ndarray | None, np.ndarray | None, JsonObject | None]:
    """groundtruth.csv and meta.json's truth, for scoring only (None where absent)."""
    truth_t = truth_pose = None
    if (path / TRUTH).is_file():
        truth_t, truth_pose = read_table(path, TRUTH, ["x_mm", "y_mm", "yaw_rad"])
    truth = meta.get("truth")
    if truth is not None and not (isinstance(truth, dict) and all(isinstance(v, dict) for v in truth.values())):
        raise LogFormatError(
            "truth is not an object of objects.", file=path / "meta.json", field="truth", fix="drop it (scoring only)."
        )
    return truth_t, truth_pose, truth if isinstance(truth, dict) else None


def read_lidar2d_log(folder: Path) -> Lidar2DLog:
    """A lidar2d log folder, checked: the scan's geometry in meta.json, ordered times, ranges in mm."""
    path = Path(folder)
    meta = read_json_object(path / "meta.json", LogFormatError, "write it as convert bag does (docs/lidar2d.md).")
    geom, scan_t, ranges = read_scans(path, meta)
    sources = [
        (drive, name, columns)
        for drive, name, columns in (
            ("wheels", WHEELS, ["left_rad", "right_rad"]),
            ("odom", ODOM, ["x_mm", "y_mm", "yaw_rad"]),
            ("cmd_vel", CMD_VEL, ["v_mm_s", "omega_rad_s"]),
        )
        if (path / name).is_file()
    ]
    if not sources:
        raise LogFormatError(
            "nothing drives the robot: no wheels.csv, odom.csv or cmd_vel.csv.",
            file=path,
            fix="convert a bag with /joint_states, /odom or /cmd_vel, or write wheels.csv (docs/lidar2d.md).",
        )
    drive, name, columns = sources[0]
    drive_t, values = read_table(path, name, columns)
    check_drive(path / name, drive, drive_t, values)
    check_scans(path / SCANS, scan_t, ranges, drive_t)
    truth_t, truth_pose, truth = read_truth(path, meta)
    return Lidar2DLog(
        source=str(path),
        scan_t=scan_t,
        ranges_mm=ranges,
        scan=geom,
        drive=drive,
        drive_t=drive_t,
        drive_values=values,
        urdf=read_urdf(meta, path),
        truth_t=truth_t,
        truth_pose=truth_pose,
        truth=truth,
    )
