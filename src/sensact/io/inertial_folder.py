"""The log folder of an outdoor robot with wheel odometry, an IMU and (optionally) GNSS (docs/inertial.md): what
``convert bag`` writes from a bag's ``nav_msgs/Odometry``, ``sensor_msgs/Imu``, ``sensor_msgs/NavSatFix`` and
``/tf_static``, and what ``simulate outdoor`` writes::

    run/
      meta.json      "kind": "imu_gnss", the datum, the odometry's first yaw, what /tf_static said of the
                     IMU and the antenna, the truth if simulated
      odometry.csv   t_s, v_m_s, omega_rad_s: the wheel odometry's twist (REP 103: forward, counterclockwise)
      imu.csv        t_s, gyro_x_rad_s .. gyro_z_rad_s, accel_x_m_s2 .. accel_z_m_s2, in the IMU's own axes
      gnss.csv       optional: t_s, east_m, north_m, up_m, var_east_m2, var_north_m2 (reported; empty: none),
                     fixes around the datum (status -1 already dropped)
      groundtruth.csv  optional, scoring only: t_s, east_m, north_m

Times are seconds on one clock (the odometry's header stamps), SI units throughout.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.atomic import write_json, write_text
from sensact.io.csvtable import read_numeric_csv, refuse_unordered, time_origin
from sensact.io.jsonfile import read_json_object
from sensact.logs.inertial_log import Datum, InertialLog, MountGuess

KIND = "imu_gnss"
ODOMETRY, IMU, GNSS, TRUTH = "odometry.csv", "imu.csv", "gnss.csv", "groundtruth.csv"
ODOMETRY_COLUMNS = ["v_m_s", "omega_rad_s"]
IMU_COLUMNS = [f"gyro_{a}_rad_s" for a in "xyz"] + [f"accel_{a}_m_s2" for a in "xyz"]
ORIENTATION_COLUMNS = [f"orientation_{a}" for a in "xyzw"]  # optional: empty where the IMU reported none
GNSS_COLUMNS = ["east_m", "north_m", "up_m", "var_east_m2", "var_north_m2"]
MAX_RATE_RAD_S = 50.0  # beyond any gyro a ground robot carries (2,900 deg/s)
MAX_ACCEL_M_S2 = 500.0
MAX_SPEED_M_S = 50.0


def _write(path: Path, names: list[str], t: np.ndarray, values: np.ndarray) -> None:
    cells = [["" if not math.isfinite(v) else repr(v) for v in row] for row in np.asarray(values, float).tolist()]
    rows = [",".join([f"{tt:.9f}", *c]) for tt, c in zip(t.tolist(), cells, strict=True)]
    write_text(path, "\n".join([",".join(["t_s", *names]), *rows]) + "\n")


def write_inertial_log(folder: Path, log: InertialLog) -> Path:
    """``log`` as a folder; meta.json last, so that a folder with meta.json is whole."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    _write(folder / ODOMETRY, ODOMETRY_COLUMNS, log.odom_t, np.column_stack([log.odom_v_m_s, log.odom_omega_rad_s]))
    q = log.imu_orientation_xyzw
    _write(
        folder / IMU,
        IMU_COLUMNS + (ORIENTATION_COLUMNS if q is not None else []),
        log.imu_t,
        np.column_stack([log.gyro_rad_s, log.accel_m_s2, *([q] if q is not None else [])]),
    )
    if log.has_gnss:
        _write(folder / GNSS, GNSS_COLUMNS, log.gnss_t, np.column_stack([log.gnss_enu_m, log.gnss_var_reported_m2]))
    if log.truth_t is not None and log.truth_xy_m is not None:
        _write(folder / TRUTH, ["east_m", "north_m"], log.truth_t, log.truth_xy_m)
    meta = {
        "format": "sensact-log",
        "version": 1,
        "kind": KIND,
        "source": log.source,
        "datum": None if log.datum is None else log.datum.to_dict(),
        "odometry_yaw0_rad": log.odom_yaw0_rad,
        "gyro_variance_reported": None if not math.isfinite(log.gyro_var_reported) else log.gyro_var_reported,
        "tf_static": {"imu": log.imu_mount.to_dict(), "gnss": log.gnss_mount.to_dict()},
        "topics": dict(log.topics),
        **({"truth": log.truth} if log.truth is not None else {}),
    }
    write_json(folder / "meta.json", meta)
    return folder


def _table(
    path: Path, name: str, columns: list[str], *, empty_ok: tuple[str, ...] = ()
) -> tuple[np.ndarray, np.ndarray]:
    # times from the odometry's first whole second, exactly: a Unix time's 1.7e9 s holds in float64 only to
    # 2.4e-7 s, and the fit differences and interpolates them (docs/formats.md)
    origin = {"t_s": time_origin(path / ODOMETRY)}
    table = read_numeric_csv(path / name, ["t_s", *columns], what=name, origin=origin)
    t = table["t_s"]
    refuse_unordered(path / name, t, strict=True)
    values = np.column_stack([table[c] for c in columns])
    must = [i for i, c in enumerate(columns) if c not in empty_ok]
    bad = ~np.isfinite(values[:, must]).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise LogFormatError(
            f"row {row + 2} has an empty or non-finite cell ({int(bad.sum())} such rows).",
            file=path / name,
            field=columns[must[0]],
            fix="give every row every value (drop the rows a driver published as NaN).",
        )
    if t.size < 2:
        raise LogFormatError("fewer than two rows.", file=path / name, fix="record longer.")
    return t, values


def _refuse_beyond(path: Path, name: str, values: np.ndarray, limit: float, what: str, columns: list[str]) -> None:
    over = np.abs(values) > limit
    if over.any():
        row, col = (int(v[0]) for v in np.nonzero(over))
        raise LogFormatError(
            f"row {row + 2}'s {columns[col]} is {values[row, col]:g}: beyond any {what} ({limit:g}).",
            file=path / name,
            field=columns[col],
            fix="write SI units (m/s, rad/s, m/s^2), as ROS's messages carry them.",
        )


def _mount(node: object, path: Path, field: str) -> MountGuess:
    if not isinstance(node, dict):
        return MountGuess()

    def triple(v: object, k: str) -> tuple[float, float, float] | None:
        if v is None:
            return None
        if not (
            isinstance(v, list) and len(v) == 3 and all(isinstance(x, int | float) and math.isfinite(x) for x in v)
        ):
            raise LogFormatError(
                f"{field}.{k} is {v!r}, not three numbers or null.",
                file=path / "meta.json",
                field=f"{field}.{k}",
                fix="write it as convert bag does, or null.",
            )
        return (float(v[0]), float(v[1]), float(v[2]))

    frame = node.get("frame")
    return MountGuess(
        frame if isinstance(frame, str) else None,
        triple(node.get("xyz_m"), "xyz_m"),
        triple(node.get("rpy_rad"), "rpy_rad"),
    )


def _orientation(path: Path) -> np.ndarray | None:
    """imu.csv's orientation columns where it has them (all four, empty cells where a message had none)."""
    with open(path / IMU, newline="") as f:
        header = f.readline().strip().split(",")
    if not any(c in header for c in ORIENTATION_COLUMNS):
        return None
    if not all(c in header for c in ORIENTATION_COLUMNS):
        raise LogFormatError(
            f"{IMU} has some of {', '.join(ORIENTATION_COLUMNS)}, not all four.",
            file=path / IMU,
            fix="give the quaternion's four columns, or none.",
        )
    _, q = _table(path, IMU, ORIENTATION_COLUMNS, empty_ok=tuple(ORIENTATION_COLUMNS))
    return q


def read_inertial_log(path: Path) -> InertialLog:
    path = Path(path)
    meta = read_json_object(path / "meta.json", LogFormatError, "write it as `sensact convert bag` does.")
    ot, ov = _table(path, ODOMETRY, ODOMETRY_COLUMNS)
    _refuse_beyond(path, ODOMETRY, ov[:, :1], MAX_SPEED_M_S, "ground robot's speed (m/s)", ODOMETRY_COLUMNS[:1])
    _refuse_beyond(path, ODOMETRY, ov[:, 1:], MAX_RATE_RAD_S, "turn rate (rad/s)", ODOMETRY_COLUMNS[1:])
    it, iv = _table(path, IMU, IMU_COLUMNS)
    orientation = _orientation(path)
    _refuse_beyond(path, IMU, iv[:, :3], MAX_RATE_RAD_S, "gyro's rate (rad/s)", IMU_COLUMNS[:3])
    _refuse_beyond(path, IMU, iv[:, 3:], MAX_ACCEL_M_S2, "accelerometer's reading (m/s^2)", IMU_COLUMNS[3:])
    if (path / GNSS).is_file():
        gt, gv = _table(path, GNSS, GNSS_COLUMNS, empty_ok=("up_m", "var_east_m2", "var_north_m2"))
    else:
        gt, gv = np.zeros(0), np.zeros((0, 5))
    truth_t = truth_xy = None
    if (path / TRUTH).is_file():
        truth_t, truth_xy = _table(path, TRUTH, ["east_m", "north_m"])
    d = meta.get("datum")
    datum = None
    if isinstance(d, dict) and all(isinstance(d.get(k), int | float) for k in ("lat_deg", "lon_deg", "alt_m")):
        datum = Datum(float(d["lat_deg"]), float(d["lon_deg"]), float(d["alt_m"]))
    tf = meta.get("tf_static") if isinstance(meta.get("tf_static"), dict) else {}
    yaw0 = meta.get("odometry_yaw0_rad", 0.0)
    gvar = meta.get("gyro_variance_reported")
    truth = meta.get("truth")
    topics = meta.get("topics") if isinstance(meta.get("topics"), dict) else {}
    return InertialLog(
        source=str(meta.get("source", path)),
        odom_t=ot,
        odom_v_m_s=ov[:, 0],
        odom_omega_rad_s=ov[:, 1],
        odom_yaw0_rad=float(yaw0) if isinstance(yaw0, int | float) and math.isfinite(yaw0) else 0.0,
        imu_t=it,
        gyro_rad_s=iv[:, :3],
        accel_m_s2=iv[:, 3:],
        gyro_var_reported=float(gvar) if isinstance(gvar, int | float) else float("nan"),
        gnss_t=gt,
        gnss_enu_m=gv[:, :3],
        gnss_var_reported_m2=gv[:, 3:5],
        datum=datum,
        imu_mount=_mount(tf.get("imu"), path, "tf_static.imu"),
        gnss_mount=_mount(tf.get("gnss"), path, "tf_static.gnss"),
        topics=tuple((str(k), str(v)) for k, v in topics.items() if isinstance(v, str)),
        imu_orientation_xyzw=orientation,
        truth=truth if isinstance(truth, dict) else None,
        truth_t=truth_t,
        truth_xy_m=truth_xy,
    )
