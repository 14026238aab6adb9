"""The packets of each spinning lidar in ``sensact.models.spinning_lidar``, as chapter 5 reads them: each
firing's rotation (clockwise, 0.01°, as the packets count) and one distance per laser; and written, for the
simulator, the way the units send them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.io.velodyne import LOWER, PACKET, PAYLOAD_BYTES, UPPER, _model_of, encode_hdl64e, firings_in_place
from sensact.models.spinning_lidar import (
    OUSTER_COLUMNS_PER_PACKET,
    OUSTER_ENCODER_COUNTS,
    OUSTER_VALID,
    UNITS,
    LidarUnit,
)


def ouster_column(beams: int) -> np.dtype:
    pixel = np.dtype(
        [("range", "<u4"), ("reflectivity", "<u2"), ("signal", "<u2"), ("noise", "<u2"), ("unused", "<u2")]
    )
    return np.dtype(
        [
            ("timestamp_ns", "<u8"),
            ("measurement_id", "<u2"),
            ("frame_id", "<u2"),
            ("encoder", "<u4"),
            ("pixels", pixel, beams),
            ("status", "<u4"),
        ]
    )


def velodyne_unit(packets: np.ndarray) -> LidarUnit:
    """The Velodyne whose packets these are (``PACKET`` records; ``sensact.io.velodyne._model_of``)."""
    return UNITS[_model_of(packets)]


@dataclass(frozen=True, eq=False)
class PacketFields:
    """What chapter 5 reads of P packets."""

    stamp_us: np.ndarray  # (P,) the unit's own clock, µs (a Velodyne's past the hour, wrapping)
    rotation: np.ndarray  # (P, firings per packet) clockwise, 0.01°
    distance: np.ndarray  # (P * firings per packet, lasers) in the unit's distance steps
    damaged: dict[str, np.ndarray]  # (P,) flags of packets no such unit sends, by what is wrong


def velodyne_fields(unit: LidarUnit, payloads: np.ndarray) -> PacketFields:
    """An HDL-32E's, VLP-32C's, VLP-16's or HDL-64E's payloads (P, 1206) as firings."""
    pk = np.ascontiguousarray(payloads).view(PACKET).reshape(-1)
    P = len(pk)
    blocks = pk["blocks"]
    ids, rot = blocks["id"], blocks["rotation"].astype(np.int64)
    dist = blocks["returns"]["distance"]
    if unit.name == "HDL-64E":
        damaged = {
            "block ids": ~(np.all(ids[:, 0::2] == UPPER, axis=1) & np.all(ids[:, 1::2] == LOWER, axis=1)),
            "rotations": ~(np.all(rot < 36000, axis=1) & np.all(rot[:, 0::2] == rot[:, 1::2], axis=1)),
        }
        # an upper block and the lower block after it are one firing of lasers 0-31 and 32-63
        return PacketFields(
            pk["timestamp_us"].astype(np.int64), rot[:, 0::2].astype(float), dist.reshape(P * 6, 64), damaged
        )
    damaged = {"block ids": ~np.all(ids == UPPER, axis=1), "rotations": ~np.all(rot < 36000, axis=1)}
    if unit.dual:  # a firing's two blocks share a rotation: its last return read, in the first
        damaged["rotations"] |= ~np.all(rot[:, 0::2] == rot[:, 1::2], axis=1)
        rot, dist = rot[:, 0::2], dist[:, 0::2]
    B = rot.shape[1]
    if unit.firings_per_packet <= B:  # one firing a block
        return PacketFields(pk["timestamp_us"].astype(np.int64), rot.astype(float), dist.reshape(P * B, 32), damaged)
    # the VLP-16's second firing of a block is halfway round to the next block (the last block's step is
    # its predecessor's), as ROS's driver interpolates it
    step = np.mod(np.diff(rot, axis=1), 36000)
    step = np.concatenate([step, step[:, -1:]], axis=1)
    both = np.empty((P, 2 * B))
    both[:, 0::2] = rot
    both[:, 1::2] = np.mod(rot + 0.5 * step, 36000)
    return PacketFields(pk["timestamp_us"].astype(np.int64), both, dist.reshape(P * 2 * B, 16), damaged)


def ouster_fields(unit: LidarUnit, payloads: np.ndarray) -> PacketFields:
    """An OS-1's legacy lidar packets (P, 16 columns) as firings: a column is a firing; a column whose
    status is not valid holds no returns."""
    cols = np.ascontiguousarray(payloads).view(ouster_column(unit.lasers)).reshape(len(payloads), -1)
    P = len(cols)
    enc = cols["encoder"].astype(np.int64)
    dist = (cols["pixels"]["range"] & 0xFFFFF).reshape(P * OUSTER_COLUMNS_PER_PACKET, unit.lasers)
    dist[(cols["status"] != OUSTER_VALID).reshape(-1)] = 0
    damaged = {"encoder counts": ~np.all(enc < OUSTER_ENCODER_COUNTS, axis=1)}
    stamp = (cols["timestamp_ns"][:, 0] // 1000).astype(np.int64)
    return PacketFields(stamp, enc * (36000.0 / OUSTER_ENCODER_COUNTS), dist, damaged)


def packet_fields(unit: LidarUnit, payloads: np.ndarray) -> PacketFields:
    return velodyne_fields(unit, payloads) if unit.velodyne else ouster_fields(unit, payloads)


def firings(unit: LidarUnit, payloads: np.ndarray, slots: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A unit's payloads as ``(rotation_deg (F,), distance_m (F, lasers) float32)``, one row per firing: the
    compact form the learners read (``read_car_log`` builds it a chunk at a time). ``slots``
    (``slots_from_clock``): see ``firings_in_place``."""
    fields = packet_fields(unit, payloads)
    P, n = fields.rotation.shape
    rows = P if slots is None or P == 0 else int(slots[-1]) + 1
    out = np.zeros((rows * n, unit.lasers), dtype=np.float32)
    np.multiply(fields.distance, np.float32(unit.distance_unit_m), out=out[: P * n], casting="unsafe")
    return firings_in_place(fields.rotation, out, slots)


# ------------------------------------------------------------------ writing (the simulator's packets)


def encode_packets(
    unit: LidarUnit, rotation_cw_deg: np.ndarray, distance_m: np.ndarray, start_s: np.ndarray
) -> np.ndarray:
    """Payloads (P, bytes) of ``F`` firings (a multiple of the unit's firings per packet): each firing's
    clockwise rotation (F,), distances (F, lasers) by laser id, and each packet's start on the unit's clock
    (P,), seconds (a Velodyne stamps µs past the hour, an OS-1 ns)."""
    n = unit.firings_per_packet
    F = len(rotation_cw_deg)
    if F % n:
        raise ValueError(f"the number of firings must be a multiple of {n}")
    P = F // n
    steps = np.clip(
        np.rint(np.asarray(distance_m) / unit.distance_unit_m), 0, 2**16 - 1 if unit.velodyne else 2**20 - 1
    )
    inten = np.where(steps > 0, 40 + (np.arange(unit.lasers) % 7) * 20, 0)
    stamp_us = np.rint(np.mod(np.asarray(start_s), 3600.0) * 1e6).astype(np.uint32)
    if unit.name == "HDL-64E":
        return encode_hdl64e(rotation_cw_deg, distance_m, inten, stamp_us)
    if not unit.velodyne:
        cols = np.zeros((P, n), dtype=ouster_column(unit.lasers))
        f = np.arange(F)
        per_turn = unit.columns or 1024
        cols["timestamp_ns"] = np.rint(
            (np.asarray(start_s)[:, None] + np.arange(n)[None, :] * unit.firing_s) * 1e9
        ).astype(np.uint64)
        cols["measurement_id"] = (f % per_turn).reshape(P, n)
        cols["frame_id"] = ((f // per_turn) % 65536).reshape(P, n)
        cols["encoder"] = np.mod(
            np.rint(np.asarray(rotation_cw_deg) / 360.0 * OUSTER_ENCODER_COUNTS), OUSTER_ENCODER_COUNTS
        ).reshape(P, n)
        cols["pixels"]["range"] = steps.reshape(P, n, unit.lasers)
        cols["pixels"]["reflectivity"] = inten.reshape(P, n, unit.lasers)
        cols["status"] = OUSTER_VALID
        return cols.view(np.uint8).reshape(P, unit.payload_bytes)
    pk = np.zeros(P, dtype=PACKET)
    rot = np.mod(np.rint(np.asarray(rotation_cw_deg) * 100.0), 36000).astype(np.uint16).reshape(P, n)
    blocks = pk["blocks"]
    d = steps.astype(np.uint16)
    blocks["id"] = UPPER
    blocks["rotation"] = rot[:, 0::2] if unit.lasers == 16 else rot  # a 16-laser block: the first of two firings
    blocks["returns"]["distance"] = d.reshape(P, 12, 32)
    blocks["returns"]["intensity"] = inten.reshape(P, 12, 32)
    pk["status_type"] = 0x37  # strongest return
    pk["status_value"] = unit.product_id or 0
    pk["timestamp_us"] = stamp_us
    return pk.view(np.uint8).reshape(P, PAYLOAD_BYTES)
