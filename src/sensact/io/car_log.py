"""Reading a car log folder (as ``sensact simulate car`` writes it) for chapter 5's learners.

::

    car-001/
      meta.json            platform "car", lidar {file, firing_hz, rpm, vertical_deg}, truth if simulated
      velodyne.pcap        HDL-64E UDP packets
      actions.csv          t_s, throttle, brake, steering (about 20 Hz)
      groundtruth.csv      optional: t_s, x_m, y_m, theta_rad, ... (evaluation only)

The vertical laser angles are factory-known (sec. 2.5.2) and come from ``meta.json`` or a calibration
file; the horizontal ones are what is learned, and are never read from the log.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.atomic import write_json, write_stream
from sensact.io.csvtable import read_numeric_csv
from sensact.io.logfolder import LOG_FORMAT, LOG_VERSION, _write_csv, read_meta
from sensact.io.velodyne import PCAP_HEADER, encode_hdl64e, hdl64e_firings, pcap_records, read_pcap_payloads
from sensact.io.velodyne_calibration import write_calibration
from sensact.models.laser_intrinsics import LaserIntrinsics


def write_car_log(
    folder: str | Path,
    tables: dict[str, Any],
    scans: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray]],
    true_intrinsics: LaserIntrinsics | None = None,
) -> Path:
    """Write a car log folder: ``velodyne.pcap`` from the scan chunks ``(firing_times_s, theta_r, distances
    (F, 64))`` as HDL-64E packets (streamed, atomic), ``actions.csv``, ``groundtruth.csv``, the true
    calibration if given, and ``meta.json`` last."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    origin = float(tables["meta"]["lidar"].get("time_origin_s", 0.0))

    def stream(handle: Any) -> None:
        handle.write(PCAP_HEADER)
        for t, rot, dist in scans:
            inten = np.where(dist > 0, 40 + (np.arange(dist.shape[1]) % 7) * 20, 0)
            stamp = np.rint(np.mod(origin + t[::6], 3600.0) * 1e6).astype(np.uint32)
            # a Velodyne reports its rotation clockwise (seen from above): the field holds -theta_r
            payloads = encode_hdl64e(np.degrees(-rot), dist, inten, stamp)
            handle.write(pcap_records(payloads, origin + t[::6]))

    write_stream(folder / tables["meta"]["lidar"]["file"], stream)
    _write_csv(folder / "actions.csv", tables["actions"])
    if tables.get("groundtruth") is not None:
        _write_csv(folder / "groundtruth.csv", tables["groundtruth"])
    if true_intrinsics is not None:
        write_calibration(folder / "calibration_true.yaml", true_intrinsics)
    write_json(folder / "meta.json", {"format": LOG_FORMAT, "version": LOG_VERSION, **tables["meta"]})
    return folder


@dataclass(frozen=True, eq=False)
class CarLog:
    rotation_rad: np.ndarray  # (F,) theta_r per firing, counterclockwise (the packets hold it clockwise)
    distance_m: np.ndarray  # (F, 64) float32 by laser id
    vertical_rad: np.ndarray  # (64,)
    firing_hz: float
    omega_rad_s: float
    action_times_s: np.ndarray  # (M,) on the lidar's clock, from the first firing
    actions: np.ndarray  # (M, 3) throttle, brake, steering
    meta: dict[str, Any]
    groundtruth: dict[str, np.ndarray] | None


def read_car_log(folder: str | Path, vertical_rad: np.ndarray | None = None) -> CarLog:
    folder = Path(folder)
    meta = read_meta(folder)
    lidar = meta.get("lidar")
    if not isinstance(lidar, dict):
        raise LogFormatError(
            "meta.json has no lidar section.",
            file=folder / "meta.json",
            field="lidar",
            fix='add "lidar": {"file": "velodyne.pcap", "firing_hz": ..., "rpm": ..., "vertical_deg": [...]}.',
        )
    try:
        firing_hz = float(lidar.get("firing_hz", 7800.0))
        omega = float(lidar.get("rpm", 600.0)) / 60.0 * 2 * np.pi
        t0 = float(lidar.get("time_origin_s", 0.0))
        if vertical_rad is None:
            vertical_rad = np.radians(np.asarray(lidar["vertical_deg"], dtype=float))
    except (KeyError, TypeError, ValueError):
        raise LogFormatError(
            "lidar needs numeric firing_hz, rpm and vertical_deg (64 values).",
            file=folder / "meta.json",
            field="lidar.vertical_deg",
            fix="add the factory vertical angles, or pass a calibration file (--vertical-from).",
        ) from None
    times, payloads, _ = read_pcap_payloads(folder / str(lidar.get("file", "velodyne.pcap")))
    rot_deg, dist = hdl64e_firings(payloads)
    if len(vertical_rad) != dist.shape[1]:
        raise LogFormatError(
            f"{len(vertical_rad)} vertical angles for {dist.shape[1]} lasers.",
            file=folder / "meta.json",
            field="lidar.vertical_deg",
            fix="give one vertical angle per laser id.",
        )
    acts = read_numeric_csv(folder / "actions.csv", ["t_s", "throttle", "brake", "steering"], what="actions.csv")
    first = times[0] if len(times) else t0
    gt = None
    if (folder / "groundtruth.csv").is_file():
        gt = read_numeric_csv(folder / "groundtruth.csv", ["t_s", "x_m", "y_m", "theta_rad"], what="groundtruth.csv")
    return CarLog(
        np.radians(-rot_deg),
        dist,
        np.asarray(vertical_rad, dtype=float),
        firing_hz,
        omega,
        acts["t_s"] - (first - t0),
        np.column_stack([acts["throttle"], acts["brake"], acts["steering"]]),
        meta,
        gt,
    )
