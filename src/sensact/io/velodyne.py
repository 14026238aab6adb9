"""Velodyne UDP packet captures (pcap or pcapng): decode HDL-64E, HDL-32E, VLP-32C and VLP-16 data packets, and
write HDL-64E packets the way the sensor does (sec. 2.5.2).

A data packet is a 1206-byte UDP payload on port 2368: 12 blocks of 100 bytes, each a 2-byte block id
(0xEEFF upper, 0xDDFF lower on the HDL-64E), a 2-byte rotation in 0.01° and 32 returns of a uint16
distance in 2 mm units and a uint8 intensity; then a 4-byte timestamp (µs past the hour) and two status
bytes (on the HDL-32E and VLP-16: return mode and product id, 0x21 and 0x22). Multi-byte values are
little-endian. Position packets (port 8308, 512 bytes) and anything else are skipped.

dpkt frames the capture's records (classic pcap in either byte order and resolution, or pcapng, whose
first interface's link type is taken for every packet); the Ethernet, IPv4 and UDP headers are then
checked and the payloads read as one numpy structured array, vectorized.
"""

from __future__ import annotations

import dataclasses
import struct
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import dpkt
import numpy as np

from sensact.errors import LogFormatError
from sensact.io.atomic import write_bytes
from sensact.models.spinning_lidar import UNITS, VELODYNE_PAYLOAD_BYTES, VELODYNE_PORT

PAYLOAD_BYTES = VELODYNE_PAYLOAD_BYTES
DATA_PORT = VELODYNE_PORT
UPPER, LOWER = 0xEEFF, 0xDDFF
PRODUCT_IDS = {unit.product_id: name for name, unit in UNITS.items() if unit.product_id is not None}
DUAL_RETURN = 0x39  # the return-mode byte when every firing fills two blocks (strongest and last)
DISTANCE_UNIT_M = 0.002
HDL64_FIRINGS_PER_PACKET = 6

BLOCK = np.dtype([("id", "<u2"), ("rotation", "<u2"), ("distance", "<u2", 32), ("intensity", "u1", 32)])
_RETURN = np.dtype([("distance", "<u2"), ("intensity", "u1")])
_BLOCK_RAW = np.dtype([("id", "<u2"), ("rotation", "<u2"), ("returns", _RETURN, 32)])
PACKET = np.dtype([("blocks", _BLOCK_RAW, 12), ("timestamp_us", "<u4"), ("status_type", "u1"), ("status_value", "u1")])
assert PACKET.itemsize == PAYLOAD_BYTES


@dataclass(frozen=True, eq=False)
class VelodyneReturns:
    """One row per return (including empty ones, ``distance_m == 0``), in packet order."""

    model: str
    time_s: np.ndarray  # capture time of the packet plus the firing's offset within it
    laser: np.ndarray  # laser id as the calibration file numbers it
    rotation_deg: np.ndarray  # theta_r, the unit's reported rotation
    distance_m: np.ndarray  # 0 where nothing was hit
    intensity: np.ndarray
    firing: np.ndarray  # index of the firing (all lasers fired together) across the file
    n_packets: int
    n_skipped: int  # records that were not data packets (position packets, other ports)

    @property
    def valid(self) -> np.ndarray:
        return self.distance_m > 0


MAX_RECORD_BYTES = 262_144  # libpcap's largest snapshot length: a longer record is corrupt
PCAPNG_MAGIC = 0x0A0D0D0A
_LINK_HEADER_BYTES = {1: 14, 0: 4, 101: 0, 113: 16}  # Ethernet, BSD loopback, raw IP, Linux cooked


class _CheckedReads:
    """The capture file as dpkt reads it, record by record: a read that asks for more than any record
    holds, or that the file ends inside, is refused here, before dpkt allocates or hands on a cut record."""

    def __init__(self, handle: Any, path: Path) -> None:
        self._handle = handle
        self._path = path
        self.position = 0

    def read(self, n: int = -1) -> bytes:
        if n > MAX_RECORD_BYTES + 64:
            raise LogFormatError(
                f"corrupt: a record at byte {self.position} claims {n} bytes (no capture holds a record over "
                f"{MAX_RECORD_BYTES}).",
                file=self._path,
                fix="re-capture, or cut the file before that record.",
            )
        data = self._handle.read(n)
        if 0 < len(data) < n:
            raise LogFormatError(
                f"truncated or corrupt: a record at byte {self.position} runs past the end of the file "
                f"({self.position + len(data)} bytes).",
                file=self._path,
                fix="re-capture, or cut the file at the last complete packet.",
            )
        self.position += len(data)
        return data


CHUNK_RECORDS = 4096  # records framed, checked and gathered at a time: memory stays bounded by a chunk


@dataclass(frozen=True, eq=False)
class _Frames:
    """A chunk of a capture's records laid end to end in ``buf``."""

    buf: np.ndarray  # uint8
    start: np.ndarray  # each record's first byte in buf
    length: np.ndarray
    time_s: np.ndarray  # capture time


def _capture_chunks(path: Path, records: int = CHUNK_RECORDS) -> Iterator[tuple[int, _Frames]]:
    """The records of a pcap or pcapng capture, framed by dpkt, ``records`` at a time: ``(link type, frames)``."""
    if not path.is_file():
        raise LogFormatError("pcap file not found.", file=path, fix="check the path.")
    if path.stat().st_size == 0:
        raise LogFormatError("empty file.", file=path, fix="give a pcap or pcapng capture of the lidar's packets.")
    with path.open("rb") as handle:
        head = handle.read(4)
        handle.seek(0)
        magic = int.from_bytes(head.ljust(4, b"\0"), "little")
        reads = _CheckedReads(handle, path)
        try:
            reader = (dpkt.pcapng.Reader if magic == PCAPNG_MAGIC else dpkt.pcap.Reader)(reads)
        except (ValueError, dpkt.UnpackError, struct.error) as exc:
            raise LogFormatError(
                f"not a pcap or pcapng capture ({exc}).",
                file=path,
                fix="give a libpcap (.pcap) or pcapng (.pcapng) capture, as tcpdump or Wireshark writes it.",
            ) from None
        link = int(reader.datalink())
        frames: list[bytes] = []
        times: list[float] = []
        done = 0
        records_read = iter(reader)
        while True:
            try:
                for stamp, frame in records_read:
                    times.append(float(stamp))  # a nanosecond pcap's stamps are Decimals
                    frames.append(frame)
                    if len(frames) == records:
                        break
            except (ValueError, dpkt.UnpackError, struct.error) as exc:
                raise LogFormatError(
                    f"truncated or corrupt: record {done + len(frames)} near byte {reads.position} does not read "
                    f"({exc}).",
                    file=path,
                    fix="re-capture, or cut the file at the last complete packet.",
                ) from None
            if frames:
                lens = np.fromiter(map(len, frames), dtype=np.int64, count=len(frames))
                starts = np.concatenate([[0], np.cumsum(lens)[:-1]]).astype(np.int64)
                buf = np.frombuffer(b"".join(frames), dtype=np.uint8)
                yield link, _Frames(buf, starts, lens, np.array(times, dtype=float))
            if len(frames) < records:
                return
            done += len(frames)
            frames, times = [], []


def _udp_fields(path: Path, link: int, f: _Frames) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Which records of a chunk are whole IPv4 UDP datagrams: ``(ok, payload start, destination port,
    payload bytes)``, vectorized over the records."""
    link_header = _LINK_HEADER_BYTES.get(link)
    if link_header is None:
        raise LogFormatError(f"unsupported link type {link}.", file=path, fix="capture on Ethernet (link type 1).")
    # a chunk of records captured with (almost) no bytes: a buffer every header index below can read (lens rule)
    buf, offs, lens = (f.buf if f.buf.size >= 64 else np.zeros(64, np.uint8)), f.start, f.length
    last = buf.size - 1
    ip = offs + link_header
    ok = lens >= link_header + 28
    if link == 1:
        ok &= (buf[np.minimum(offs + 12, last)] == 0x08) & (buf[np.minimum(offs + 13, last)] == 0x00)
    ipc = np.clip(ip, 0, max(buf.size - 28, 0))
    ihl = (buf[ipc] & 0x0F).astype(np.int64) * 4
    ok &= ((buf[ipc] >> 4) == 4) & (buf[ipc + 9] == 17)
    udp = np.clip(ip + ihl, 0, max(buf.size - 8, 0))
    dport = buf[udp + 2].astype(np.int64) * 256 + buf[udp + 3]
    size = buf[udp + 4].astype(np.int64) * 256 + buf[udp + 5] - 8
    ok &= lens >= (udp - offs) + 8 + np.maximum(size, 0)  # the whole payload was captured
    return ok, udp + 8, dport, size


def iter_payloads(
    path: str | Path, port: int = DATA_PORT, size: int = PAYLOAD_BYTES, records: int = CHUNK_RECORDS
) -> Iterator[tuple[np.ndarray, np.ndarray, int]]:
    """The capture's UDP payloads of ``size`` bytes to ``port``, a chunk at a time: ``(capture_time_s,
    payloads (n, size) uint8, records skipped)``. Never more than a chunk of the capture is held."""
    path = Path(path)
    for link, f in _capture_chunks(path, records):
        ok, start, dport, got = _udp_fields(path, link, f)
        ok &= (dport == port) & (got == size)
        # rows of a sliding view: no index array as large as the payloads themselves
        payloads = (
            np.lib.stride_tricks.sliding_window_view(f.buf, size)[start[ok]]
            if ok.any()
            else np.zeros((0, size), np.uint8)
        )
        yield f.time_s[ok], payloads, int((~ok).sum())


def read_pcap_payloads(path: str | Path, port: int = DATA_PORT) -> tuple[np.ndarray, np.ndarray, int]:
    """``(capture_time_s, payloads (P, 1206) uint8, n_skipped)`` of the Velodyne data packets in a pcap."""
    times, payloads, skipped = [np.zeros(0)], [np.zeros((0, PAYLOAD_BYTES), np.uint8)], 0
    for t, p, n in iter_payloads(path, port):
        times.append(t)
        payloads.append(p)
        skipped += n
    return np.concatenate(times), np.concatenate(payloads), skipped


def udp_traffic(path: str | Path, most: int = 3) -> str:
    """The capture's commonest UDP streams, for an error that found none it could read: "UDP to port
    7502 (12608-byte payloads) x 1280, ..." or "no UDP packets"."""
    path = Path(path)
    counts: Counter[tuple[int, int]] = Counter()
    for link, f in _capture_chunks(path):
        ok, _, dport, size = _udp_fields(path, link, f)
        counts.update(zip(dport[ok].tolist(), size[ok].tolist(), strict=True))
    if not counts:
        return "no UDP packets"
    ranked = sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))[:most]
    return ", ".join(f"UDP to port {port} ({size}-byte payloads) x {n}" for (port, size), n in ranked)


def _model_of(packets: np.ndarray) -> str:
    """HDL-64E if any block is a lower block; otherwise the packet period on the unit's own clock tells the
    HDL-32E (12 firings of 46.08 µs: 0.55 ms), the VLP-32C (12 of 55.296 µs: 0.66 ms) and the VLP-16 (24 of
    55.296 µs: 1.33 ms) apart; in dual-return mode a firing fills two blocks. Some VLP-16 firmware reports
    the HDL-32E product id, so the id byte alone is not trusted."""
    if np.any(packets["blocks"]["id"] == LOWER):
        return "HDL-64E"
    ts = packets["timestamp_us"].astype(np.int64)
    steps = np.diff(ts)
    steps = steps[(steps > 0) & (steps < 10_000)]
    if steps.size:
        block_us = float(np.median(steps)) * (2 if np.any(packets["status_type"] == DUAL_RETURN) else 1) / 12.0
        if block_us > 80.0:  # two firings a block: a VLP-16 (110.6 µs), or its Hi-Res twin by its product id
            return "Puck Hi-Res" if _product(packets) == UNITS["Puck Hi-Res"].product_id else "VLP-16"
        return "VLP-32C" if block_us > 50.0 else "HDL-32E"  # 55.3 µs and 46.1 µs a block
    return PRODUCT_IDS.get(_product(packets), "HDL-32E")


def _product(packets: np.ndarray) -> int:
    """The commonest product id byte (a Velodyne's last status byte)."""
    return int(np.bincount(packets["status_value"]).argmax()) if len(packets) else 0


def clock_steps_us(timestamp_us: np.ndarray) -> np.ndarray:
    """Steps of the sensor's clock between packets (µs past the hour, so a step back by most of an hour
    is the wrap)."""
    step = np.diff(np.asarray(timestamp_us).astype(np.int64))
    step[step < -1_800_000_000] += 3_600_000_000
    return step


def slots_from_clock(timestamp_us: np.ndarray) -> np.ndarray:
    """Each packet's place in time, in packet periods from the first, by the sensor's clock: a dropped
    packet leaves its slot empty. A step of less than a period (a repeated or reordered packet) takes the
    next slot, so a capture without drops gets 0, 1, 2, ..."""
    step = clock_steps_us(timestamp_us)
    if not np.any(step > 0):
        return np.arange(len(timestamp_us))
    periods = np.maximum(np.rint(step / float(np.median(step[step > 0]))), 1).astype(np.int64)
    return np.concatenate([[0], np.cumsum(periods)])


def packet_slots(payloads: np.ndarray) -> np.ndarray:
    """``slots_from_clock`` of the payloads' own clock."""
    return slots_from_clock(np.ascontiguousarray(payloads).view(PACKET).reshape(-1)["timestamp_us"])


FIRINGS_PER_PACKET = {name: unit.firings_per_packet for name, unit in UNITS.items() if unit.velodyne}
SPIN_GAP_PACKETS = 5  # packets further apart than this many periods are a gap, not a step of the spin


@dataclass(frozen=True)
class Spin:
    """How fast a unit fired and turned, as its own packets say."""

    firing_hz: float  # firings (every laser once) per second
    rpm: float
    clockwise: bool  # seen from above, as every Velodyne turns: the rotation field counts up


def velodyne_model(payloads: np.ndarray) -> str:
    """HDL-64E, HDL-32E or VLP-16, from the packets themselves (see ``_model_of``)."""
    return _model_of(np.ascontiguousarray(payloads).view(PACKET).reshape(-1))


def measure_spin(payloads: np.ndarray, model: str | None = None) -> Spin | None:
    """``spin_from_clock`` of the payloads' own clock and first blocks' rotations."""
    packets = np.ascontiguousarray(payloads).view(PACKET).reshape(-1)
    if len(packets) < 3:
        return None
    firings = FIRINGS_PER_PACKET[model or _model_of(packets)]
    return spin_from_clock(packets["timestamp_us"], packets["blocks"]["rotation"][:, 0], firings)


def spin_from_clock(timestamp_us: np.ndarray, first_rotation: np.ndarray, firings_per_packet: int) -> Spin | None:
    """The firing rate and the spin rate from the packets' own clock (µs past the hour), not the host's
    capture times, which carry its jitter: the usual packet period, over the whole capture, with each
    step counted as the whole number of periods it spans (dropped packets), holds a model's fixed number
    of firings; the first block's clockwise rotation (0.01°, ``first_rotation``) over the steps that are
    not gaps gives the spin. None for fewer than three packets or a clock that never advances. (An OS-1's
    clock, in ns, is given here in µs, and its encoder in 0.01°.)"""
    if len(timestamp_us) < 3:
        return None
    step = clock_steps_us(timestamp_us)
    if not np.any(step > 0):
        return None
    usual = float(np.median(step[step > 0]))
    periods = np.rint(np.maximum(step, 0) / usual)
    packet_s = float(step[periods > 0].sum()) * 1e-6 / float(periods.sum())
    turn = np.mod(np.diff(np.asarray(first_rotation).astype(float) / 100.0), 360.0)
    near = (step > 0) & (periods <= SPIN_GAP_PACKETS)
    clockwise = bool(np.median(turn[near]) < 180.0) if near.any() else True
    if not clockwise:
        turn = 360.0 - turn
    deg_s = float(turn[near].sum()) / (float(step[near].sum()) * 1e-6)
    return Spin(firings_per_packet / packet_s, deg_s / 6.0, clockwise)


def decode_packets(times_s: np.ndarray, payloads: np.ndarray, model: str = "auto", firing_rate_hz: float | None = None):
    """Per-return arrays from raw payloads. ``firing_rate_hz`` spaces the firings inside a packet in time
    (default: the unit's own, ``sensact.models.spinning_lidar.UNITS``; the HDL-64E's is the thesis's 7800 Hz)."""
    packets = np.ascontiguousarray(payloads).view(PACKET).reshape(-1)
    bad = ~np.isin(packets["blocks"]["id"], (UPPER, LOWER))
    if bad.any():
        p, b = np.argwhere(bad)[0]
        raise LogFormatError(
            f"packet {p}, block {b}: block id {packets['blocks']['id'][p, b]:#06x} is neither 0xEEFF nor 0xDDFF.",
            field="block id",
            fix="the capture is corrupt or not from a Velodyne; check the port and the file.",
        )
    if model == "auto":
        model = _model_of(packets)
    if model not in FIRINGS_PER_PACKET:
        raise LogFormatError(
            f"unknown model {model!r}.", field="model", fix="use " + ", ".join(FIRINGS_PER_PACKET) + " or auto."
        )
    unit = UNITS[model]
    period = 1.0 / firing_rate_hz if firing_rate_hz else unit.firing_s
    P = len(packets)
    # packet times on the sensor's clock (µs past the hour, unwrapped), anchored at the first capture time:
    # capture times carry the host's jitter
    step = clock_steps_us(packets["timestamp_us"])
    times_s = float(times_s[0]) + np.concatenate([[0], np.cumsum(step)]) * 1e-6 if P else np.zeros(0)
    blocks = packets["blocks"]
    dist = blocks["returns"]["distance"].astype(float) * unit.distance_unit_m  # (P, 12, 32)
    inten = blocks["returns"]["intensity"]
    rot = blocks["rotation"].astype(float) / 100.0  # (P, 12)
    if model == "HDL-64E":
        lower = blocks["id"] == LOWER
        laser = np.where(lower[..., None], 32, 0) + np.arange(32)[None, None, :]
        # an upper block and the lower block after it fire together: firing = packet * 6 + block // 2
        fire_in_packet = np.broadcast_to(np.arange(12)[None, :] // 2, (P, 12))
        firing = np.arange(P)[:, None] * 6 + fire_in_packet
        t = times_s[:, None] + fire_in_packet * period
        shape = (P, 12, 32)
        t = np.broadcast_to(t[..., None], shape)
        firing = np.broadcast_to(firing[..., None], shape)
        rot3 = np.broadcast_to(rot[..., None], shape)
    elif unit.lasers == 32:  # one firing a block
        laser = np.broadcast_to(np.arange(32)[None, None, :], (P, 12, 32))
        firing = np.broadcast_to((np.arange(P)[:, None] * 12 + np.arange(12)[None, :])[..., None], (P, 12, 32))
        t = np.broadcast_to((times_s[:, None] + np.arange(12)[None, :] * period)[..., None], (P, 12, 32))
        rot3 = np.broadcast_to(rot[..., None], (P, 12, 32))
    else:  # 16 lasers, two firings a block
        laser = np.broadcast_to((np.arange(32) % 16)[None, None, :], (P, 12, 32))
        seq = np.arange(12)[:, None] * 2 + (np.arange(32) // 16)[None, :]  # (12, 32) firing sequence
        firing = np.arange(P)[:, None, None] * 24 + seq[None]
        t = times_s[:, None, None] + seq[None] * period
        # the second sequence's rotation is halfway to the next block's
        step = np.diff(rot, axis=1, append=rot[:, -1:] + (rot[:, -1:] - rot[:, -2:-1]))
        step = np.mod(step, 360.0)
        rot3 = np.mod(rot[..., None] + (np.arange(32) // 16)[None, None, :] * 0.5 * step[..., None], 360.0)
    return VelodyneReturns(
        model,
        np.asarray(t, dtype=float).reshape(-1),
        np.asarray(laser, dtype=np.int16).reshape(-1),
        np.asarray(rot3, dtype=float).reshape(-1),
        dist.reshape(-1),
        np.asarray(inten).reshape(-1),
        np.asarray(firing, dtype=np.int64).reshape(-1),
        P,
        0,
    )


def read_velodyne_pcap(path: str | Path, *, model: str = "auto", port: int = DATA_PORT) -> VelodyneReturns:
    """Decode every data packet of a Velodyne pcap into per-return arrays."""
    times, payloads, skipped = read_pcap_payloads(path, port)
    if len(payloads) == 0:
        raise LogFormatError(
            f"no Velodyne data packets (1206-byte UDP payloads on port {port}); it holds {udp_traffic(path)}.",
            file=path,
            fix="check the port (--port) or the capture.",
        )
    try:
        out = decode_packets(times, payloads, model)
    except LogFormatError as exc:
        raise LogFormatError(exc.problem, file=path, field=exc.field, fix=exc.fix) from None
    return dataclasses.replace(out, n_skipped=skipped)


# ------------------------------------------------------------------ writing


def encode_hdl64e(
    rotation_deg: np.ndarray, distance_m: np.ndarray, intensity: np.ndarray, timestamp_us: np.ndarray
) -> np.ndarray:
    """HDL-64E payloads from ``F`` firings (a multiple of 6): rotation (F,), distances and intensities
    (F, 64) indexed by laser id, and one timestamp per packet (F // 6,). Returns (F // 6, 1206) uint8."""
    F = len(rotation_deg)
    if F % HDL64_FIRINGS_PER_PACKET:
        raise ValueError("the number of firings must be a multiple of 6")
    P = F // HDL64_FIRINGS_PER_PACKET
    pk = np.zeros(P, dtype=PACKET)
    rot = np.mod(np.rint(np.asarray(rotation_deg) * 100.0), 36000).astype(np.uint16).reshape(P, 6)
    d = np.clip(np.rint(np.asarray(distance_m) / DISTANCE_UNIT_M), 0, 65535).astype(np.uint16).reshape(P, 6, 64)
    it = np.asarray(intensity, dtype=np.uint8).reshape(P, 6, 64)
    blocks = pk["blocks"]
    blocks["id"][:, 0::2] = UPPER
    blocks["id"][:, 1::2] = LOWER
    blocks["rotation"][:, 0::2] = rot
    blocks["rotation"][:, 1::2] = rot
    blocks["returns"]["distance"][:, 0::2] = d[:, :, :32]
    blocks["returns"]["distance"][:, 1::2] = d[:, :, 32:]
    blocks["returns"]["intensity"][:, 0::2] = it[:, :, :32]
    blocks["returns"]["intensity"][:, 1::2] = it[:, :, 32:]
    pk["timestamp_us"] = np.asarray(timestamp_us, dtype=np.uint32)
    return pk.view(np.uint8).reshape(P, PAYLOAD_BYTES)


def firings_in_place(
    rotation: np.ndarray, distance_m: np.ndarray, slots: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(rotation_deg (F,), distance_m (F, lasers))`` of P packets of n firings: ``rotation`` (P, n) in 0.01°
    and ``distance_m`` whose first P * n rows hold their firings in the order they came. ``slots``
    (``slots_from_clock``) puts each packet's firings at its place in time, moved within ``distance_m``
    (which needs the F rows): the firings of dropped packets have no returns and a rotation interpolated
    between their neighbours', so that a firing's index stays its time times the firing rate, which the
    learners assume."""
    P, n = rotation.shape
    rot = rotation.reshape(-1).astype(float) / 100.0
    if slots is None or P == 0 or int(slots[-1]) == P - 1:
        return rot, distance_m[: P * n]
    F = (int(slots[-1]) + 1) * n
    if distance_m.shape[0] < F:
        raise ValueError(f"{distance_m.shape[0]} rows for {F} firings")
    slots = np.asarray(slots, dtype=np.int64)
    block = 1 << 12
    # from the last packet back: a packet only moves later, so none is overwritten before it moves
    for end in range(P, 0, -block):
        start = max(end - block, 0)
        src = (np.arange(start, end)[:, None] * n + np.arange(n)).reshape(-1)
        dst = (slots[start:end, None] * n + np.arange(n)).reshape(-1)
        moved = src != dst
        if not moved.any():
            break  # slots equal indices from here back, as they do before the first drop
        distance_m[dst[moved]] = distance_m[src[moved]]
        distance_m[np.setdiff1d(src[moved], dst, assume_unique=True)] = 0.0
    at = (slots[:, None] * n + np.arange(n)).reshape(-1)
    turned = np.unwrap(rot, period=360.0)
    return np.mod(np.interp(np.arange(F), at, turned), 360.0), distance_m[:F]


def _ip_checksum(header: np.ndarray) -> np.ndarray:
    """RFC 791 checksums of (P, 20) IPv4 headers whose checksum field is zero."""
    words = header[:, 0::2].astype(np.uint32) * 256 + header[:, 1::2]
    s = words.sum(axis=1)
    while np.any(s >> 16):
        s = (s & 0xFFFF) + (s >> 16)
    return (~s) & 0xFFFF


PCAP_HEADER = np.array([0xA1B2C3D4, 2 | (4 << 16), 0, 0, 65535, 1], dtype="<u4").tobytes()  # v2.4, Ethernet


def pcap_records(payloads: np.ndarray, capture_time_s: np.ndarray, port: int = DATA_PORT) -> bytes:
    """The pcap records (no global header) of UDP packets from 192.168.3.43 to ``port``."""
    payloads = np.ascontiguousarray(payloads, dtype=np.uint8)
    P, n = payloads.shape
    frame = 42 + n
    rec = np.zeros((P, 16 + frame), np.uint8)
    t = np.asarray(capture_time_s, dtype=float)
    sec = np.floor(t).astype(np.uint32)
    usec = np.minimum(np.rint((t - sec) * 1e6), 999999).astype(np.uint32)
    rec[:, 0:16] = (
        np.column_stack([sec, usec, np.full(P, frame, np.uint32), np.full(P, frame, np.uint32)])
        .astype("<u4")
        .view(np.uint8)
    )
    eth = rec[:, 16:30]
    eth[:, 0:6] = 0xFF
    eth[:, 6:12] = (0x60, 0x76, 0x88, 0x00, 0x00, 0x00)
    eth[:, 12:14] = (0x08, 0x00)
    ip = rec[:, 30:50]
    total = 20 + 8 + n
    ip[:, 0], ip[:, 2], ip[:, 3] = 0x45, total >> 8, total & 0xFF
    ip[:, 8], ip[:, 9] = 64, 17
    ip[:, 12:16] = (192, 168, 3, 43)
    ip[:, 16:20] = (255, 255, 255, 255)
    cs = _ip_checksum(ip)
    ip[:, 10], ip[:, 11] = cs >> 8, cs & 0xFF
    udp = rec[:, 50:58]
    udp[:, 0], udp[:, 1] = 0x01, 0xBB  # source port 443, as the sensor uses
    udp[:, 2], udp[:, 3] = port >> 8, port & 0xFF
    udp[:, 4], udp[:, 5] = (n + 8) >> 8, (n + 8) & 0xFF
    rec[:, 58:] = payloads
    return rec.tobytes()


def pcap_bytes(payloads: np.ndarray, capture_time_s: np.ndarray, port: int = DATA_PORT) -> bytes:
    """A classic pcap file's bytes holding the payloads."""
    return PCAP_HEADER + pcap_records(payloads, capture_time_s, port)


def write_pcap(path: str | Path, payloads: np.ndarray, capture_time_s: np.ndarray, port: int = DATA_PORT) -> Path:
    """Write payloads as a pcap file, atomically."""
    return write_bytes(path, pcap_bytes(payloads, capture_time_s, port))
