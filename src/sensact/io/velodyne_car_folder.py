"""Reading a car log folder (as ``sensact simulate car`` writes it) for chapter 5's learners.

::

    car-001/
      meta.json            platform "car", lidar {file, vertical_deg, firing_hz, rpm, time_origin_s}, truth if simulated
      velodyne.pcap        the lidar's UDP packets: an HDL-64E, HDL-32E, VLP-32C, VLP-16 or Ouster OS-1
      actions.csv          t_s, throttle, brake, steering (about 20 Hz)
      groundtruth.csv      optional: t_s, x_m, y_m, theta_rad, ... (evaluation only)

The vertical laser angles are factory-known (sec. 2.5.2) and come from ``meta.json`` or a calibration
file; the horizontal ones are what is learned, and are never read from the log.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.atomic import write_json, write_stream
from sensact.io.csvtable import read_numeric_csv, refuse_apart, refuse_unordered
from sensact.io.logfolder import LOG_FORMAT, LOG_VERSION, _write_csv, read_meta
from sensact.io.spinning_lidar_packets import encode_packets, packet_fields, velodyne_unit
from sensact.io.velodyne import (
    DATA_PORT,
    DUAL_RETURN,
    PACKET,
    PAYLOAD_BYTES,
    PCAP_HEADER,
    _capture_chunks,
    _udp_fields,
    clock_steps_us,
    firings_in_place,
    iter_payloads,
    pcap_records,
    slots_from_clock,
    spin_from_clock,
    udp_traffic,
)
from sensact.io.velodyne_calibration import ouster_metadata, write_calibration
from sensact.models.laser_intrinsics import LaserIntrinsics
from sensact.models.spinning_lidar import (
    MODEL_NAMES,
    OUSTER_BEAMS,
    OUSTER_PORT,
    UNITS,
    UNREAD_PRODUCTS,
    LidarUnit,
    ouster_payload_bytes,
    ouster_unit,
)
from sensact.records import JsonObject


def write_car_log(
    folder: str | Path,
    tables: JsonObject,
    scans: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray]],
    true_intrinsics: LaserIntrinsics | None = None,
) -> Path:
    """Write a car log folder: the lidar's capture (``lidar.file``) from the scan chunks ``(firing_times_s,
    theta_r, distances (F, lasers))`` as ``lidar.model``'s packets (streamed, atomic), ``actions.csv``,
    ``groundtruth.csv``, the true calibration if given, and ``meta.json`` last."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    lidar = tables["meta"]["lidar"]
    origin = float(lidar.get("time_origin_s", 0.0))
    unit = UNITS[lidar.get("model", "HDL-64E")]
    if not unit.velodyne:  # an OS-1 of as many beams as angles, and as many columns as fit in a turn
        unit = ouster_unit(len(lidar["vertical_deg"]), round(float(lidar["firing_hz"]) * 60.0 / float(lidar["rpm"])))
    n = unit.firings_per_packet

    def stream(handle: Any) -> None:
        handle.write(PCAP_HEADER)
        for t, rot, dist in scans:
            # a Velodyne reports its rotation clockwise (seen from above), as an OS-1 counts its encoder
            payloads = encode_packets(unit, np.degrees(-rot), dist, origin + t[::n])
            handle.write(pcap_records(payloads, origin + t[::n], unit.port))

    write_stream(folder / lidar["file"], stream)
    _write_csv(folder / "actions.csv", tables["actions"])
    if tables.get("groundtruth") is not None:
        _write_csv(folder / "groundtruth.csv", tables["groundtruth"])
    if true_intrinsics is not None:
        if unit.velodyne:
            write_calibration(folder / "calibration_true.yaml", true_intrinsics)
        else:
            write_json(folder / "metadata_true.json", ouster_metadata(true_intrinsics))
    write_json(folder / "meta.json", {"format": LOG_FORMAT, "version": LOG_VERSION, **tables["meta"]})
    return folder


SPIN_TOLERANCE = 0.02  # a stated firing rate or rpm this far from what the packets show is probably wrong
CAR_LOG_DOCS = 'docs/formats.md, "Car log folders"'


@dataclass(frozen=True, eq=False)
class CarLog:
    rotation_rad: np.ndarray  # (F,) theta_r per firing, counterclockwise (the packets hold it clockwise)
    distance_m: np.ndarray  # (F, lasers) float32 by laser id
    vertical_rad: np.ndarray  # (lasers,)
    firing_hz: float
    omega_rad_s: float  # d theta_r / dt, counterclockwise: negative for a Velodyne, which turns clockwise
    action_times_s: np.ndarray | None  # (M,) on the lidar's clock, from the first firing; None: no actions.csv
    actions: np.ndarray | None  # (M, 3) throttle, brake, steering
    meta: JsonObject
    groundtruth: dict[str, np.ndarray] | None
    notes: tuple[str, ...] = ()  # what the reader measured, for the user to see
    warnings: tuple[str, ...] = ()  # what in the folder contradicts itself
    factory: LaserIntrinsics | None = None  # the calibration file the vertical angles came from, if one
    model: str = "HDL-64E"  # a name of sensact.models.spinning_lidar.UNITS
    delay_s: np.ndarray | None = None  # (lasers,) when each laser fires after its firing's start; None: at once


# what a spinning lidar's rate can be: a Velodyne or an Ouster turns 300-1200 rpm and fires at most ~100 kHz
SPIN_LIMITS = {"rpm": (1.0, 6000.0), "firing_hz": (1.0, 1e6)}


def _lidar_number(lidar: JsonObject, name: str, meta_file: Path) -> float | None:
    if name not in lidar:
        return None
    lo, hi = SPIN_LIMITS.get(name, (-np.inf, np.inf))
    try:
        value = float(lidar[name])
        if not (np.isfinite(value) and lo <= value <= hi):
            raise ValueError
        return value
    except (TypeError, ValueError, OverflowError):
        raise LogFormatError(
            f"lidar.{name} is {lidar[name]!r}, not a number in [{lo:g}, {hi:g}].",
            file=meta_file,
            field=f"lidar.{name}",
            fix="give the lidar's own (its datasheet's), or leave it out to measure it from the packets.",
        ) from None


def _spin_value(
    stated: float | None, measured: float | None, name: str, unit: str, notes: list[str], warnings: list[str]
) -> float | None:
    """The stated value wins (the user said so), but one the packets contradict is reported."""
    if stated is None:
        if measured is not None:
            notes.append(f"{name} {measured:.6g} {unit}, measured from the packets' clock")
        return measured
    if measured is not None and abs(stated - measured) > SPIN_TOLERANCE * measured:
        warnings.append(
            f"meta.json's lidar.{name} is {stated:.6g} {unit} but the packets show {measured:.6g} {unit}; "
            f"using {stated:.6g} (leave lidar.{name} out to use the measured value)"
        )
    return stated


@dataclass(frozen=True, eq=False)
class _Capture:
    """What chapter 5 keeps of a lidar capture, read a chunk at a time: the payloads themselves (a 200-s
    drive's are 330 MB) are never all held, and each distance is written once, where the learner reads it."""

    unit: LidarUnit
    times_s: np.ndarray  # (P,) capture times
    timestamp_us: np.ndarray  # (P,) the sensor's clock, µs (a Velodyne's past the hour)
    rotation: np.ndarray  # (P, firings per packet) each firing's rotation, 0.01° clockwise
    distance_m: np.ndarray  # (R, lasers) float32 by laser id: the first P * n rows the firings as they came
    repeated: int  # packets left out as byte-for-byte repeats of earlier ones


_RECORD_OVERHEAD = 16 + 28  # a record header, raw IPv4 and UDP headers: the least around a payload
_OUSTER_BEAMS_BY_SIZE = {ouster_payload_bytes(b): b for b in OUSTER_BEAMS}


@lru_cache(maxsize=8)
def _hash_multipliers(words: int) -> np.ndarray:
    return 2 * np.random.default_rng(20081).integers(1, 2**62, (2, words), dtype=np.uint64) + 1


def _payload_keys(payloads: np.ndarray) -> np.ndarray:
    """A 128-bit key (two uint64) per payload row, for finding repeats without holding the payloads: two
    64-bit linear hashes of its words with odd multipliers, so two packets that differ in any one word
    always differ in both."""
    words_n = (payloads.shape[1] + 7) // 8
    padded = np.zeros((len(payloads), words_n * 8), dtype=np.uint8)
    padded[:, : payloads.shape[1]] = payloads
    words = padded.view(np.uint64)
    with np.errstate(over="ignore"):
        return np.stack([(words * m).sum(axis=1, dtype=np.uint64) for m in _hash_multipliers(words_n)], axis=1)


def _lidar_stream(pcap: Path, port: int | None = None) -> tuple[int, int] | None:
    """The (port, payload bytes) of the lidar data in the capture's first chunk: a Velodyne's (1206 bytes,
    to port 2368) or an OS-1's (its legacy packet for 16 to 128 beams, to port 7502), or either's to
    ``port`` when a unit was set to send elsewhere; None when it holds neither."""
    sizes = {PAYLOAD_BYTES: DATA_PORT} | dict.fromkeys(_OUSTER_BEAMS_BY_SIZE, OUSTER_PORT)
    for link, frames in _capture_chunks(pcap):
        ok, _, ports, got = _udp_fields(pcap, link, frames)
        found = Counter(
            (p, n)
            for p, n in zip(ports[ok].tolist(), got[ok].tolist(), strict=True)
            if n in sizes and p == (sizes[n] if port is None else port)
        )
        return found.most_common(1)[0][0] if found else None
    return None


def _unit_of(pcap: Path, size: int, payloads: np.ndarray) -> LidarUnit:
    if size != PAYLOAD_BYTES:
        return ouster_unit(_OUSTER_BEAMS_BY_SIZE[size])
    packets = np.ascontiguousarray(payloads).view(PACKET).reshape(-1)
    product = int(np.bincount(packets["status_value"]).argmax()) if len(packets) else 0
    if product in UNREAD_PRODUCTS:
        raise LogFormatError(
            f"{UNREAD_PRODUCTS[product]} packets (product id {product:#04x}), whose lasers sensact does not lay out.",
            file=pcap,
            field="lidar.file",
            fix="learn car reads " + ", ".join(MODEL_NAMES) + " captures.",
        )
    unit = velodyne_unit(packets)
    if np.any(packets["status_type"] == DUAL_RETURN):
        if unit.name == "HDL-64E":
            raise LogFormatError(
                "dual-return HDL-64E packets (return mode 0x39), which chapter 5 does not read.",
                file=pcap,
                fix="capture with the unit set to Strongest or Last return.",
            )
        return unit.in_dual_return()
    return unit


def max_slots(packets: int) -> int:
    """The most packet periods a capture of ``packets`` packets may span by its clock: the rest are dropped
    ones, whose empty firings are held in place (``read_car_log`` refuses a capture that spans more)."""
    return 2 * packets + 1000


def _read_capture(pcap: Path, port: int | None = None) -> _Capture:
    """The capture's lidar data packets, a chunk at a time: repeats of an earlier packet left out (a unit
    stamps each packet with its own clock, so two alike are one packet captured twice, which would be read
    as two firings: laser angles 96.6 degrees off on a capture with its packets doubled), and damaged
    packets refused (``_say_damaged``). The unit is told from the first chunk's packets. The distances go
    straight into one float32 array sized for the most packets the file can hold; the pages it never writes
    are never in memory."""
    stream = _lidar_stream(pcap, port)
    if stream is None:
        where = "port 2368, or an Ouster OS-1's to port 7502" if port is None else f"port {port}"
        raise LogFormatError(
            f"no lidar data packets (a Velodyne's 1206-byte UDP payloads to {where}); it holds {udp_traffic(pcap)}.",
            file=pcap,
            fix="capture the lidar's data port, or name it in meta.json (lidar.port); sensact learn car reads "
            + ", ".join(MODEL_NAMES)
            + " packets.",
        )
    port, size = stream
    seen: set[tuple[int, int]] = set()
    times, stamps, rotations = [], [], []
    repeated = kept = 0
    unit: LidarUnit | None = None
    distance = np.zeros((0, 0), dtype=np.float32)
    bad: dict[str, list[int]] = {}  # how many packets, and the first, by what is wrong
    for chunk_times, payloads, _ in iter_payloads(pcap, port, size):
        if not len(payloads):
            continue
        keep = np.zeros(len(payloads), dtype=bool)
        for i, key in enumerate(map(tuple, _payload_keys(payloads).tolist())):
            if key not in seen:
                seen.add(key)
                keep[i] = True
        repeated += int((~keep).sum())
        if unit is None:
            unit = _unit_of(pcap, size, payloads[keep])
            rows = pcap.stat().st_size // (_RECORD_OVERHEAD + size) * unit.firings_per_packet
            distance = np.zeros((rows, unit.lasers), dtype=np.float32)
        fields = packet_fields(unit, payloads[keep])
        for what, flag in fields.damaged.items():
            count = bad.setdefault(what, [0, -1])
            if flag.any() and count[0] == 0:
                count[1] = kept + int(np.argmax(flag))
            count[0] += int(flag.sum())
        at = kept * unit.firings_per_packet
        dist = fields.distance
        np.multiply(dist, np.float32(unit.distance_unit_m), out=distance[at : at + len(dist)], casting="unsafe")
        times.append(chunk_times[keep])
        stamps.append(fields.stamp_us)
        rotations.append(fields.rotation)
        kept += int(keep.sum())
    assert unit is not None  # the first chunk held the stream
    capture = _Capture(
        unit, np.concatenate(times), np.concatenate(stamps), np.concatenate(rotations), distance, repeated
    )
    _refuse_backwards(pcap, capture.times_s)
    for what, (count, first) in bad.items():
        if count:
            _say_damaged(pcap, unit.name, count, kept, first, what)
    _refuse_clock_jumps(pcap, capture)
    return capture


def _isolated_jumps(t: np.ndarray, gap: float) -> np.ndarray:
    """Which values of a clock jump away from both neighbours while the neighbours agree with each other
    (one damaged stamp), by more than ``gap``; a dropped packet is one step, not a jump there and back. The
    first and the last value, with one neighbour each, are damaged when they are that far from it."""
    out = np.zeros(t.size, dtype=bool)
    if t.size >= 3:
        into, out_of = t[1:-1] - t[:-2], t[2:] - t[1:-1]
        out[1:-1] = (np.abs(into) > gap) & (np.abs(into + out_of) <= gap)
    if t.size >= 2:
        out[0], out[-1] = abs(t[1] - t[0]) > gap, abs(t[-1] - t[-2]) > gap
    return out


def _say_damaged(pcap: Path, unit: str, count: int, of: int, first: int, what: str) -> None:
    """One line for packets damaged on disk or on the wire: a block id that is not the unit's, a rotation
    over 359.99 degrees or, on an HDL-64E, unlike its block pair's (the upper and lower blocks of a firing
    share one), an OS-1 encoder count past a turn, or a
    sensor or capture time that jumps from both neighbours. One such packet cuts a revolution short (laser
    angles 155 degrees RMS off) or, by its clock, asks for an hour of empty firings; the scan matching does
    not bridge them, so they are refused rather than learned from."""
    raise LogFormatError(
        f"{count} of its {of} packets are damaged, the first (packet {first}) in its {what}: no {unit} sends "
        "such a packet.",
        file=pcap,
        fix="copy the capture again, or cut it before the damage (editcap -r).",
    )


def _refuse_clock_jumps(pcap: Path, capture: _Capture) -> None:
    ts = capture.timestamp_us
    sensor_us = int(ts[0]) + np.r_[0, np.cumsum(clock_steps_us(ts))]  # across the hour's wrap
    bad = _isolated_jumps(sensor_us.astype(float), 100_000.0)  # 0.1 s: over a hundred packet periods
    bad |= _isolated_jumps(np.asarray(capture.times_s, dtype=float), 1.0)
    if bad.any():
        _say_damaged(pcap, capture.unit.name, int(bad.sum()), len(bad), int(np.argmax(bad)), "time stamp")


def _refuse_backwards(pcap: Path, times: np.ndarray) -> None:
    steps = np.diff(np.asarray(times, dtype=float))
    if steps.size and (np.mean(steps < 0) > 0.05 or not np.any(steps > 0)):
        raise LogFormatError(
            "the capture's packet times "
            + ("run backwards." if np.mean(steps < 0) > 0.05 else "never advance (a bogus capture clock)."),
            file=pcap,
            fix="capture the lidar again, or give the capture as it was recorded (packets in the order they came).",
        )


def _vertical_angles(
    lidar: JsonObject, meta_file: Path, calibration: str | Path | None, unit: LidarUnit
) -> tuple[np.ndarray, LaserIntrinsics | None, Path, str]:
    """Each laser's factory vertical angle (rad): from the calibration file when given (a ROS velodyne YAML
    or an OS-1's metadata JSON; ``lidar.calibration`` names one in the folder), else meta.json's
    ``vertical_deg``, else the model's datasheet (HDL-32E, VLP-32C, VLP-16, Puck Hi-Res: every unit alike). Returns the
    calibration read (None without one), and the file and field the angles came from."""
    if calibration is None and isinstance(lidar.get("calibration"), str):
        calibration = meta_file.parent / lidar["calibration"]
    if calibration is not None:
        from sensact.io.velodyne_calibration import read_calibration

        factory = read_calibration(calibration)
        field = "vert_correction" if unit.velodyne else "beam_altitude_angles"
        return factory.vertical_rad, factory, Path(calibration), field
    if "vertical_deg" not in lidar and unit.vertical_deg is not None:
        return np.radians(np.asarray(unit.vertical_deg)), None, meta_file, "lidar.vertical_deg"
    try:
        vertical_rad = np.radians(np.asarray(lidar["vertical_deg"], dtype=float).reshape(-1))
    except (KeyError, TypeError, ValueError):
        fix = (
            f"add the {unit.lasers} factory vertical angles, or pass the factory calibration file "
            "(sensact learn car LOG --factory-calibration FILE.yaml)."
            if unit.velodyne
            else "pass the OS-1's metadata JSON (sensact learn car LOG --factory-calibration metadata.json), "
            'or name it in meta.json ("lidar": {"calibration": "metadata.json"}).'
        )
        raise LogFormatError(
            "no numeric lidar.vertical_deg (the factory's vertical angle of each laser, in degrees).",
            file=meta_file,
            field="lidar.vertical_deg",
            fix=fix,
        ) from None
    return vertical_rad, None, meta_file, "lidar.vertical_deg"


def _refuse_another_learners_folder(meta: JsonObject, folder: Path) -> None:
    """A log folder written for EM or for chapter 3 named as such, with the command that learns it."""
    if "action" in meta and "sensor" in meta:
        what, how = "a 1-D log folder", f"`sensact learn bootstrap {folder}` (chapter 3) or `sensact learn em {folder}`"
    elif "geometry" in meta:
        what, how = f"a log folder for EM (geometry: {meta['geometry']})", f"`sensact learn em {folder}`"
    else:
        return
    raise LogFormatError(
        f"this is {what}, not a car log: meta.json has no lidar section.",
        file=folder / "meta.json",
        field="lidar",
        fix=f"learn it with {how}; `sensact learn car` reads a car log folder ({CAR_LOG_DOCS}).",
    )


def _refuse_controls_off_the_scans(path: Path, t: np.ndarray, controls: np.ndarray, scan_s: float) -> None:
    """The controls explain the scans' motion only on the scans' clock: at least two rows, in time order,
    every control given, and most of them within the capture (a bogus pcap clock, a NaN time origin or
    times in ms put them elsewhere, and the dynamics would come out exactly zero)."""
    if t.size < 2:
        raise LogFormatError(
            f"{t.size} row: the dynamics need the controls over time.", file=path, field="t_s", fix="give every row."
        )
    refuse_unordered(path, t, strict=True)
    empty = np.flatnonzero(~np.all(np.isfinite(controls), axis=1))
    if empty.size:
        raise LogFormatError(
            f"row {empty[0] + 2} has an empty control.",
            file=path,
            field="throttle, brake, steering",
            fix="give every row its throttle, brake and steering.",
        )
    refuse_apart(path, t, (t >= -1.0) & (t <= scan_s + 1.0), 0.0, scan_s, "the lidar capture, from its first firing")


def read_car_log(folder: str | Path, calibration: str | Path | None = None) -> CarLog:
    """A car log folder. ``calibration``: a ROS velodyne calibration file (the factory's) whose vertical
    angles replace ``lidar.vertical_deg``; its horizontal ones are never read. ``lidar.firing_hz`` and
    ``lidar.rpm`` may be left out: the packets' own clock gives them."""
    folder = Path(folder)
    if folder.is_file():
        raise LogFormatError(
            "learn car reads a car log folder, not a single file.",
            file=folder,
            fix=f"put it in a folder with meta.json, and actions.csv if you have the controls ({CAR_LOG_DOCS}).",
        )
    meta = read_meta(folder, example="`sensact simulate car --out DIR`")
    meta_file = folder / "meta.json"
    lidar = meta.get("lidar")
    if not isinstance(lidar, dict):
        _refuse_another_learners_folder(meta, folder)
        raise LogFormatError(
            "meta.json has no lidar section.",
            file=meta_file,
            field="lidar",
            fix='add "lidar": {"file": "velodyne.pcap"} and the factory vertical angles (vertical_deg, or '
            f"--factory-calibration); {CAR_LOG_DOCS}.",
        )
    t0 = _lidar_number(lidar, "time_origin_s", meta_file) or 0.0
    # the capture before the angles: no angles fix a capture of another lidar
    pcap = folder / str(lidar.get("file", "velodyne.pcap"))
    port = _lidar_number(lidar, "port", meta_file)
    capture = _read_capture(pcap, None if port is None else int(port))
    unit, times, repeated = capture.unit, capture.times_s, capture.repeated
    vertical_rad, factory, vertical_file, vertical_field = _vertical_angles(lidar, meta_file, calibration, unit)
    slots = slots_from_clock(capture.timestamp_us)
    P = len(times)
    if slots[-1] + 1 > max_slots(P):  # the empty firings of dropped packets are held: bounded first
        raise LogFormatError(
            f"the lidar's own clock spans {int(slots[-1]) + 1} packet periods, but {P} packets came: "
            "over half would be dropped ones.",
            file=pcap,
            fix="capture the lidar again (a clock that jumps, or a capture of several runs joined, is not one drive).",
        )
    n = unit.firings_per_packet
    spin = spin_from_clock(capture.timestamp_us, capture.rotation[:, 0], n)
    held = capture.distance_m
    need = (int(slots[-1]) + 1) * n
    if need > len(held):  # more dropped packets than the file's size left room for: one copy, rarely
        held = np.zeros((need, held.shape[1]), dtype=np.float32)
        held[: P * n] = capture.distance_m[: P * n]
    rot_deg, dist = firings_in_place(capture.rotation, held, slots)
    if len(vertical_rad) != dist.shape[1]:
        raise LogFormatError(
            f"{len(vertical_rad)} vertical angles for the {unit.name}'s {dist.shape[1]} lasers.",
            file=vertical_file,
            field=vertical_field,
            fix="give one vertical angle per laser id.",
        )
    notes: list[str] = []
    if unit.dual:
        notes.append("dual-return packets: each firing's last return read")
    if factory is None and "vertical_deg" not in lidar:
        notes.append(f"vertical angles from the {unit.name} datasheet's (meta.json gives no lidar.vertical_deg)")
    warnings: list[str] = []
    if repeated:
        notes.append(f"{repeated} packets repeated byte for byte (a mirrored port sends some twice): each read once")
    dropped = int(slots[-1]) + 1 - P
    if dropped > 0:
        gaps = int(np.count_nonzero(np.diff(slots) > 1))
        notes.append(
            f"{dropped} dropped packets in {gaps} gaps (by the sensor's clock): their firings are left empty, "
            "so that each firing keeps its time"
        )
    stated_hz, stated_rpm = _lidar_number(lidar, "firing_hz", meta_file), _lidar_number(lidar, "rpm", meta_file)
    firing_hz = _spin_value(stated_hz, spin and spin.firing_hz, "firing_hz", "Hz", notes, warnings)
    rpm = _spin_value(stated_rpm, spin and spin.rpm, "rpm", "rpm", notes, warnings)
    if firing_hz is None or rpm is None or firing_hz <= 0 or rpm <= 0:
        raise LogFormatError(
            "the packets are too few to measure the firing rate and rpm, and meta.json gives no positive ones.",
            file=meta_file,
            field="lidar.firing_hz",
            fix="add lidar.firing_hz and lidar.rpm.",
        )
    first = times[0] if len(times) else t0
    action_times = actions = None
    if (folder / "actions.csv").is_file():
        path = folder / "actions.csv"
        acts = read_numeric_csv(path, ["t_s", "throttle", "brake", "steering"], what="actions.csv")
        action_times = acts["t_s"] - (first - t0)
        actions = np.column_stack([acts["throttle"], acts["brake"], acts["steering"]])
        _refuse_controls_off_the_scans(path, action_times, actions, dist.shape[0] / firing_hz)
    else:
        notes.append("no actions.csv: the laser angles and C from the scans alone (the dynamics need the controls)")
    gt = None
    if (folder / "groundtruth.csv").is_file():
        gt = read_numeric_csv(folder / "groundtruth.csv", ["t_s", "x_m", "y_m", "theta_rad"], what="groundtruth.csv")
        refuse_unordered(folder / "groundtruth.csv", gt["t_s"], strict=True)
    return CarLog(
        np.radians(-rot_deg),
        dist,
        np.asarray(vertical_rad, dtype=float),
        firing_hz,
        # theta_r is counterclockwise (eq. 2.35) and the packets count clockwise; a capture too short to
        # show the direction is taken to turn as every Velodyne does
        (1.0 if spin is not None and not spin.clockwise else -1.0) * rpm / 60.0 * 2 * np.pi,
        action_times,
        actions,
        meta,
        gt,
        tuple(notes),
        tuple(warnings),
        factory,
        unit.name,
        np.asarray(unit.delay_s, dtype=float),
    )
