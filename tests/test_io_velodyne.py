"""Velodyne pcap and calibration IO on real captures and calibrations (../shared/data/velodyne)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from conftest import DATA, require, rewrite_capture
from sensact.errors import LogFormatError
from sensact.io.spinning_lidar_packets import firings
from sensact.io.velodyne import (
    LOWER,
    PACKET,
    UPPER,
    decode_packets,
    encode_hdl64e,
    measure_spin,
    packet_slots,
    pcap_bytes,
    read_pcap_payloads,
    read_velodyne_pcap,
    udp_traffic,
    write_pcap,
)
from sensact.io.velodyne_calibration import calibration_yaml, read_calibration, write_calibration
from sensact.models.spinning_lidar import UNITS

VELO = DATA / "velodyne"


@pytest.mark.parametrize(
    "name,model,packets,skipped",
    [
        ("hdl32_example.pcap", "HDL-32E", 876, 100),
        ("velodyne_vlp32.pcap", "HDL-32E", 91, 9),
        ("velodyne_vlp16.pcap", "VLP-16", 84, 16),
        ("velodyne_example.pcap", "VLP-16", 84, 0),
    ],
)
def test_real_captures_decode(name, model, packets, skipped):
    r = read_velodyne_pcap(require(VELO / name))
    assert (r.model, r.n_packets, r.n_skipped) == (model, packets, skipped)
    assert r.distance_m.size == packets * 384
    _, payloads, _ = read_pcap_payloads(VELO / name)
    ids = payloads.view(PACKET).reshape(-1)["blocks"]["id"]
    assert np.all(ids == UPPER)  # 32E and VLP-16 use upper blocks only
    v = r.valid
    assert v.mean() > 0.5 and np.percentile(r.distance_m[v], 99) < 130.0 and r.distance_m[v].min() > 0.5
    # the rotation advances by small steps within a revolution and wraps once per revolution
    rot = r.rotation_deg[r.laser == 0]
    step = np.mod(np.diff(rot), 360.0)
    assert np.all(step < 2.0) and np.median(step) > 0
    assert np.all(np.diff(r.time_s[::32]) >= -1e-9)


def test_an_independent_decoder_agrees():
    """velodyne-decoder (a C++ decoder, test-only) finds the same returns in a VLP-16 capture."""
    vd = pytest.importorskip("velodyne_decoder")
    path = require(VELO / "velodyne_example.pcap")
    pts = np.concatenate([p for _, p in vd.read_pcap(str(path), vd.Config(model=vd.Model.VLP16), as_pcl_structs=True)])
    r = read_velodyne_pcap(path)
    v = r.valid
    assert v.sum() == len(pts)
    cal = read_calibration(require(VELO / "calibration" / "VLP16db.yaml"))
    ring_of_laser = np.argsort(cal.vertical_order())  # their ring = rank of the vertical angle
    ours = np.bincount(ring_of_laser[r.laser[v]], minlength=16)
    np.testing.assert_array_equal(ours, np.bincount(pts["ring"], minlength=16))
    theirs = np.sort(np.sqrt(pts["x"] ** 2 + pts["y"] ** 2 + pts["z"] ** 2))
    np.testing.assert_allclose(np.sort(r.distance_m[v]), theirs, atol=0.01)


def test_hdl64e_write_then_read_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    F = 60
    rot = np.mod(np.arange(F) * 0.4615, 360.0)
    dist = np.round(rng.uniform(0, 120, (F, 64)) / 0.002) * 0.002
    dist[rng.random((F, 64)) < 0.1] = 0.0
    inten = rng.integers(0, 256, (F, 64))
    payloads = encode_hdl64e(rot, dist, inten, np.arange(F // 6) * 769)
    ids = payloads.view(PACKET).reshape(-1)["blocks"]["id"]
    assert np.all(ids[:, 0::2] == UPPER) and np.all(ids[:, 1::2] == LOWER)
    path = write_pcap(tmp_path / "v.pcap", payloads, 1000.0 + np.arange(F // 6) / 1300.0)
    r = read_velodyne_pcap(path)
    assert r.model == "HDL-64E" and r.n_packets == F // 6 and r.n_skipped == 0
    back = np.zeros((F, 64))
    back[r.firing, r.laser] = r.distance_m
    np.testing.assert_allclose(back, dist, atol=1e-9)
    rot_back = np.zeros(F)
    rot_back[r.firing] = r.rotation_deg
    np.testing.assert_allclose(rot_back, np.round(rot * 100) / 100, atol=1e-9)
    assert np.allclose(np.diff(r.time_s[r.laser == 0]), 1 / 7800.0, atol=1e-3)


def _big_endian(data: bytes) -> bytes:
    """A little-endian classic pcap with its global and record headers byte-swapped, as a big-endian
    host's libpcap writes it (the frames themselves are network bytes either way)."""
    import struct

    out = [struct.pack(">IHHiIII", *struct.unpack_from("<IHHiIII", data, 0))]
    at = 24
    while at < len(data):
        head = struct.unpack_from("<IIII", data, at)
        out += [struct.pack(">IIII", *head), data[at + 16 : at + 16 + head[2]]]
        at += 16 + head[2]
    return b"".join(out)


def test_pcapng_nanosecond_and_big_endian_captures_read_as_the_pcap(tmp_path):
    import dpkt

    payloads = encode_hdl64e(np.arange(60) * 0.4615, np.ones((60, 64)), np.zeros((60, 64)), np.arange(10) * 769)
    src = write_pcap(tmp_path / "v.pcap", payloads, 1_600_000_000.0 + np.arange(10) / 1300.0)
    want_t, want_p, want_skip = read_pcap_payloads(src)
    rewrite_capture(src, tmp_path / "v.pcapng", dpkt.pcapng.Writer)
    rewrite_capture(src, tmp_path / "nano.pcap", lambda h: dpkt.pcap.Writer(h, nano=True))
    (tmp_path / "be.pcap").write_bytes(_big_endian(src.read_bytes()))
    for name in ("v.pcapng", "nano.pcap", "be.pcap"):
        t, p, skip = read_pcap_payloads(tmp_path / name)
        np.testing.assert_array_equal(p, want_p)
        np.testing.assert_allclose(t, want_t, atol=1e-6)
        assert skip == want_skip == 0
    assert read_velodyne_pcap(tmp_path / "v.pcapng").model == "HDL-64E"


def test_a_real_capture_reads_the_same_as_pcapng(tmp_path):
    import dpkt

    src = require(VELO / "hdl32_example.pcap")
    rewrite_capture(src, tmp_path / "hdl32.pcapng", dpkt.pcapng.Writer)
    a, b = read_velodyne_pcap(src), read_velodyne_pcap(tmp_path / "hdl32.pcapng")
    assert (b.model, b.n_packets, b.n_skipped) == ("HDL-32E", 876, 100)
    np.testing.assert_array_equal(a.distance_m, b.distance_m)
    np.testing.assert_allclose(a.time_s, b.time_s, atol=1e-6)


def test_the_spin_is_measured_from_the_packets_own_clock():
    """A written HDL-64E capture at a known firing rate and rpm, with dropped packets, jittered capture
    times and the sensor clock wrapping at the hour: both come back to the clock's microsecond."""
    hz, rpm = 7800.0, 900.0  # a packet every 769.23 µs: the clock rounds each to a whole µs
    F = 6 * 3000
    t = np.arange(F) / hz
    rot = np.mod(t * rpm * 6.0, 360.0)
    stamp = np.rint(np.mod(3599.5 + t[::6], 3600.0) * 1e6)
    payloads = encode_hdl64e(rot, np.ones((F, 64)), np.zeros((F, 64)), stamp)
    keep = np.ones(F // 6, dtype=bool)
    keep[[5, 6, 7, 900, 2000]] = False  # a three-packet drop and two single ones
    spin = measure_spin(payloads[keep])
    assert spin.firing_hz == pytest.approx(hz, rel=2e-6)
    assert spin.rpm == pytest.approx(rpm, rel=1e-4)  # the rotation field is in 0.01°
    assert measure_spin(payloads[:2]) is None
    frozen = payloads.copy().view(PACKET).reshape(-1)
    frozen["timestamp_us"] = 7
    assert measure_spin(frozen.view(np.uint8).reshape(-1, 1206)) is None


@pytest.mark.parametrize(
    "name,period_us", [("hdl32_example.pcap", 46.08), ("velodyne_vlp32.pcap", 46.08), ("velodyne_vlp16.pcap", 55.296)]
)
def test_real_captures_fire_at_their_datasheets_rate(name, period_us):
    """The datasheets' firing periods (HDL-32E 46.08 µs; VLP-16 55.296 µs per sequence of 16), read
    from real packets; the spin agrees with the rotation's steps between a packet's blocks."""
    _, payloads, _ = read_pcap_payloads(require(VELO / name))
    spin = measure_spin(payloads)
    assert spin.firing_hz == pytest.approx(1e6 / period_us, rel=1e-3)
    blocks = payloads.view(PACKET).reshape(-1)["blocks"]
    within = np.mod(np.diff(blocks["rotation"].astype(float) / 100.0, axis=1), 360.0)
    firings_per_block = 2 if name == "velodyne_vlp16.pcap" else 1
    rpm_within = within.mean() / (firings_per_block * period_us * 1e-6) / 6.0
    assert spin.rpm == pytest.approx(rpm_within, rel=0.02)
    assert 300.0 <= spin.rpm <= 1200.0  # the units' settable range


def test_dropped_packets_leave_their_firings_empty_in_place():
    """A firing's index is its time (the learners assume it): a capture missing packets reads as the whole
    capture with those firings empty and their rotations interpolated."""
    rng = np.random.default_rng(1)
    F = 6 * 40
    rot = np.mod(360.0 - np.arange(F) * 0.4615, 360.0)  # clockwise in theta_r, the field counting down here
    dist = np.round(rng.uniform(1, 100, (F, 64)) / 0.002) * 0.002
    stamp = np.rint(np.mod(3599.99 + np.arange(F // 6) * 6 / 7800.0, 3600.0) * 1e6)  # across the hour
    payloads = encode_hdl64e(rot, dist, np.zeros((F, 64)), stamp)
    np.testing.assert_array_equal(packet_slots(payloads), np.arange(F // 6))
    whole_rot, whole = firings(UNITS["HDL-64E"], payloads, packet_slots(payloads))
    keep = np.ones(F // 6, dtype=bool)
    keep[[3, 17, 18, 19, 39]] = False  # the last one too: the capture ends early, nothing to place after it
    slots = packet_slots(payloads[keep])
    np.testing.assert_array_equal(slots, np.flatnonzero(keep))
    got_rot, got = firings(UNITS["HDL-64E"], payloads[keep], slots)
    kept = np.repeat(keep[:39], 6)
    assert got.shape == (39 * 6, 64)
    np.testing.assert_array_equal(got[kept], whole[: 39 * 6][kept])
    assert not got[~kept].any()
    np.testing.assert_allclose(got_rot, whole_rot[: 39 * 6], atol=0.01)  # the rotation field is in 0.01°


def test_bad_files_are_rejected_clearly(tmp_path):
    with pytest.raises(LogFormatError, match="not found"):
        read_velodyne_pcap(tmp_path / "none.pcap")
    (tmp_path / "junk.pcap").write_bytes(b"\x0a\x0d\x0d\x0a" + bytes(60))
    with pytest.raises(LogFormatError, match="not a pcap or pcapng capture"):
        read_velodyne_pcap(tmp_path / "junk.pcap")
    (tmp_path / "text.pcap").write_bytes(b"time,x\n" * 10)
    with pytest.raises(LogFormatError, match="not a pcap or pcapng capture"):
        read_velodyne_pcap(tmp_path / "text.pcap")
    payloads = encode_hdl64e(np.zeros(6), np.ones((6, 64)), np.zeros((6, 64)), [0])
    data = pcap_bytes(payloads, [0.0])
    (tmp_path / "cut.pcap").write_bytes(data[:-100])
    with pytest.raises(LogFormatError, match="truncated or corrupt"):
        read_velodyne_pcap(tmp_path / "cut.pcap")
    (tmp_path / "cut_header.pcap").write_bytes(data[:30])  # inside the first record's header
    with pytest.raises(LogFormatError, match="truncated or corrupt"):
        read_velodyne_pcap(tmp_path / "cut_header.pcap")
    huge = bytearray(data)
    huge[32:36] = (2**31).to_bytes(4, "little")  # the first record claims 2 GB
    (tmp_path / "huge.pcap").write_bytes(bytes(huge))
    with pytest.raises(LogFormatError, match="claims 2147483648 bytes"):
        read_velodyne_pcap(tmp_path / "huge.pcap")
    bad = payloads.copy()
    bad[0, 0:2] = 0
    with pytest.raises(LogFormatError, match="block id"):
        decode_packets(np.zeros(1), bad)
    (tmp_path / "empty.pcap").write_bytes(data[:24])
    with pytest.raises(LogFormatError, match=r"no Velodyne data packets.*it holds no UDP packets"):
        read_velodyne_pcap(tmp_path / "empty.pcap")
    # another lidar's capture: the error names the streams it does hold, commonest first
    other = pcap_bytes(np.zeros((5, 100), np.uint8), np.arange(5.0), port=7502)
    imu = pcap_bytes(np.zeros((2, 48), np.uint8), np.arange(2.0), port=7503)
    (tmp_path / "other.pcap").write_bytes(other + imu[24:])
    said = "UDP to port 7502 (100-byte payloads) x 5, UDP to port 7503 (48-byte payloads) x 2"
    assert udp_traffic(tmp_path / "other.pcap") == said
    with pytest.raises(LogFormatError, match=re.escape(said)):
        read_velodyne_pcap(tmp_path / "other.pcap")


def test_an_ouster_capture_is_named_by_its_traffic():
    said = udp_traffic(require(VELO / "ouster_example.pcap"))
    assert said == "UDP to port 7502 (12608-byte payloads) x 100"  # the OS-1-64's lidar port and packet size
    assert udp_traffic(require(VELO / "hdl32_example.pcap")).startswith("UDP to port 2368 (1206-byte payloads) x 876")


def test_calibration_yaml_round_trip(tmp_path):
    cal = read_calibration(require(VELO / "calibration" / "64e_utexas.yaml"))
    h = np.degrees(cal.horizontal_rad)
    v = np.degrees(cal.vertical_rad)
    assert cal.n_lasers == 64
    assert h.min() == pytest.approx(-8.0, abs=0.01) and h.max() == pytest.approx(10.0, abs=0.01)  # the 18° range
    assert v.min() == pytest.approx(-24.7, abs=0.05) and v.max() == pytest.approx(2.0, abs=0.05)
    learned = cal.with_horizontal(cal.horizontal_rad + 0.01)
    back = read_calibration(write_calibration(tmp_path / "out.yaml", learned))
    np.testing.assert_allclose(back.horizontal_rad, cal.horizontal_rad + 0.01)
    np.testing.assert_array_equal(back.vertical_rad, cal.vertical_rad)
    assert back.extra[5]["dist_correction"] == cal.extra[5]["dist_correction"]
    assert "rot_correction" in calibration_yaml(cal)
    (tmp_path / "bad.yaml").write_text("lasers:\n- {laser_id: 0}\n")
    with pytest.raises(LogFormatError, match=r"lasers\[0\]"):
        read_calibration(tmp_path / "bad.yaml")


def test_calibration_angles_in_the_wrong_unit_are_refused(tmp_path):
    """Issue 95: a ROS calibration whose angles are degrees (read as radians), or Ouster metadata whose
    azimuths are 1e6 degrees, was learned from with exit 0."""
    import json

    vlp = (
        "lasers:\n"
        + "".join(
            f"- {{laser_id: {i}, rot_correction: 0.0, vert_correction: {v}}}\n" for i, v in enumerate(range(-15, 17, 2))
        )
        + "num_lasers: 16\n"
    )
    (tmp_path / "vlp16_deg.yaml").write_text(vlp)
    with pytest.raises(LogFormatError, match="another unit") as err:
        read_calibration(tmp_path / "vlp16_deg.yaml")
    assert err.value.field == "vert_correction"
    meta = {"beam_altitude_angles": [0.0] * 16, "beam_azimuth_angles": [1e6] * 16}
    (tmp_path / "os1.json").write_text(json.dumps(meta))
    with pytest.raises(LogFormatError, match="another unit") as err:
        read_calibration(tmp_path / "os1.json")
    assert err.value.field == "beam_azimuth_angles"
