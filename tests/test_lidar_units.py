"""Chapter 5 on every spinning lidar sensact decodes: HDL-64E, HDL-32E, VLP-32C, VLP-16 and Ouster OS-1."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import yaml

from conftest import require
from sensact.app.logs import data_root
from sensact.app.velodyne_car import learn_angles_from_log, simulate_car_log
from sensact.io.logfolder import LOG_FORMAT, LOG_VERSION
from sensact.io.spinning_lidar_packets import encode_packets, packet_fields
from sensact.io.velodyne import decode_packets
from sensact.io.velodyne_calibration import read_calibration
from sensact.io.velodyne_car_folder import read_car_log
from sensact.learn.spinning_lidar_intrinsics import learn_relative_angles
from sensact.learn.velodyne_car_dynamics import laser_angles
from sensact.models.spinning_lidar import UNITS, ouster_unit
from sensact.sim.velodyne_car import CarConfig

VELO = data_root() / "velodyne"
SHORT = {"seconds": 12.0, "seed": 3, "turn_times_s": (6.0,), "stop_times_s": (30.0,)}


@pytest.fixture(scope="module", params=list(UNITS))
def unit_drive(request, tmp_path_factory):
    cfg = CarConfig(lidar=request.param, **SHORT)
    folder = tmp_path_factory.mktemp(request.param) / "log"
    return simulate_car_log(cfg, folder), read_car_log(folder), folder


def test_each_unit_is_read_as_its_firings(unit_drive):
    run, log, _ = unit_drive
    unit = run.config.unit
    assert log.model == unit.name and log.distance_m.shape[1] == run.intrinsics.n_lasers
    # the firing rate and the spin from the packets' own clock
    assert log.firing_hz == pytest.approx(unit.firing_hz, rel=1e-3)
    assert log.omega_rad_s == pytest.approx(-20 * np.pi, rel=1e-3)
    assert log.distance_m.shape[0] == int(12.0 * unit.firing_hz) // unit.firings_per_packet * unit.firings_per_packet
    step = np.angle(np.exp(1j * np.diff(log.rotation_rad)))  # 0.01° steps in the packets: the mean
    np.testing.assert_allclose(np.mean(step), log.omega_rad_s / log.firing_hz, rtol=1e-3)
    valid = log.distance_m > 0
    assert 0.5 < valid.mean() < 0.999


def test_each_unit_recovers_its_horizontal_laser_angles(unit_drive):
    """Sec. 5.1 with each laser's firing delay taken out: the true theta_l (zero on every laser of an HDL-32E
    and a VLP-16, whose delays alone spread where they point) up to the common offset, within 0.25°."""
    run, log, _ = unit_drive
    rel = learn_relative_angles(log.distance_m, log.vertical_rad, log.firing_hz, log.omega_rad_s)
    err = laser_angles(rel.relative_rad, 0.0, log.omega_rad_s, log.delay_s) - run.true_laser_angles_rad
    err -= np.angle(np.mean(np.exp(1j * err)))
    assert np.degrees(np.sqrt(np.mean(err**2))) < 0.25


def test_the_angles_from_the_scans_alone_on_each_unit(unit_drive):
    """Secs. 5.1-5.2 (the common offset from the scan matching's motion) on each unit: every laser's angle on
    the car, theta_l + theta_b, within 1.2° on a 12-s drive, whose few fast intervals give C roughly (up to
    1° off, the Puck Hi-Res's); on the 200-s drive every unit is within 0.2° (``benchmarks/lidar_units.py``)."""
    run, log, _ = unit_drive
    res = learn_angles_from_log(log)
    err = np.degrees(np.angle(np.exp(1j * (res.laser_angles_rad - run.true_laser_angles_rad))))
    assert np.sqrt(np.mean(err**2)) < 1.2


def test_an_independent_decoder_reads_each_simulated_velodyne(unit_drive):
    """velodyne-decoder (test-only) reads the simulator's packets of each Velodyne (the HDL-64E by its true
    calibration file): the same returns, and, but on the HDL-64E, whose file corrects each laser's
    distances, at the same ranges (the VLP-32C's in 4 mm steps; it measures from the unit's centre, up to
    9 mm from the lasers' own origins). No such decoder reads an OS-1 here."""
    vd = pytest.importorskip("velodyne_decoder")
    run, log, folder = unit_drive
    if not run.config.unit.velodyne:
        pytest.skip("velodyne-decoder reads Velodynes only")
    models = {"HDL-32E": vd.Model.HDL32E, "VLP-32C": vd.Model.VLP32C, "VLP-16": vd.Model.VLP16}
    models["Puck Hi-Res"] = vd.Model.PuckHiRes
    if run.config.lidar == "HDL-64E":
        conf = vd.Config(
            model=vd.Model.HDL64E_S1, calibration=vd.Calibration.read(str(folder / "calibration_true.yaml"))
        )
    else:
        conf = vd.Config(model=models[run.config.lidar])
    ranges = []
    for _, points in vd.read_pcap(str(folder / "velodyne.pcap"), conf, as_pcl_structs=True):
        ranges.append(np.sqrt(points["x"] ** 2 + points["y"] ** 2 + points["z"] ** 2))
    theirs = np.sort(np.concatenate(ranges))
    ours = np.sort(log.distance_m[log.distance_m > 0])
    assert theirs.size == pytest.approx(ours.size, rel=0.002)  # it drops a scan's last packets
    if run.config.lidar == "HDL-64E":
        return
    q = np.linspace(0, 1, 101)
    np.testing.assert_allclose(np.quantile(theirs, q), np.quantile(ours, q), atol=0.012)


@pytest.mark.parametrize("model", list(UNITS))
def test_packets_round_trip(model):
    """Each unit's packets as the simulator writes them read back as the same firings, and the per-return
    decoder (``read_velodyne_pcap``'s) tells the Velodyne by its packet period and reads the same distances."""
    unit = UNITS[model]
    n = unit.firings_per_packet
    rng = np.random.default_rng(0)
    rot = np.mod(np.arange(4 * n) * 0.2, 360.0)
    dist = np.round(rng.uniform(0.5, 100.0, (4 * n, unit.lasers)) / unit.distance_unit_m) * unit.distance_unit_m
    pay = encode_packets(unit, rot, dist, 10.0 + np.arange(4) * n * unit.firing_s)
    fields = packet_fields(unit, pay)
    np.testing.assert_allclose(fields.distance * unit.distance_unit_m, dist, atol=1e-9)
    np.testing.assert_allclose(fields.rotation.reshape(-1) / 100.0, rot, atol=0.006)
    assert not any(flag.any() for flag in fields.damaged.values())
    if unit.velodyne:
        returns = decode_packets(10.0 + np.arange(4) * n * unit.firing_s, pay)
        assert returns.model == model
        order = np.lexsort((returns.laser, returns.firing))
        np.testing.assert_allclose(returns.distance_m[order].reshape(dist.shape), dist, atol=1e-9)


def test_the_datasheet_angles_are_the_ros_drivers():
    """The HDL-32E's and VLP-16's built-in vertical angles, which read_car_log uses when a log gives none,
    match ROS's calibration files; the Puck Hi-Res's and the VLP-32C's match velodyne-decoder's."""
    for model, name in (("HDL-32E", "32db.yaml"), ("VLP-16", "VLP16db.yaml")):
        cal = read_calibration(require(VELO / "calibration" / name))
        np.testing.assert_allclose(UNITS[model].vertical_deg, np.degrees(cal.vertical_rad), atol=0.01)
        np.testing.assert_allclose(UNITS[model].rot_correction_deg, np.degrees(cal.horizontal_rad), atol=1e-9)
    vd = pytest.importorskip("velodyne_decoder")
    for model, theirs in (("Puck Hi-Res", vd.Model.PuckHiRes), ("VLP-32C", vd.Model.VLP32C)):
        doc = yaml.safe_load(vd.Calibration.default_calibs[theirs].to_string())
        lasers = sorted(doc["lasers"], key=lambda row: row["laser_id"])
        np.testing.assert_allclose(
            UNITS[model].vertical_deg, [np.degrees(r["vert_correction"]) for r in lasers], atol=0.01
        )
        np.testing.assert_allclose(
            UNITS[model].rot_correction_deg, [np.degrees(r["rot_correction"]) for r in lasers], atol=0.01
        )
        assert UNITS[model].distance_unit_m == pytest.approx(doc["distance_resolution"])


def _car_folder(tmp_path, pcap, **lidar):
    folder = tmp_path / pcap.stem
    folder.mkdir()
    shutil.copy(pcap, folder / pcap.name)
    meta = {"format": LOG_FORMAT, "version": LOG_VERSION, "platform": "car", "lidar": {"file": pcap.name, **lidar}}
    (folder / "meta.json").write_text(json.dumps(meta))
    return folder


@pytest.mark.realdata
@pytest.mark.parametrize(
    ("name", "model", "lasers", "rpm"),
    [("hdl32_example.pcap", "HDL-32E", 32, 703.3), ("velodyne_vlp16.pcap", "VLP-16", 16, 599.3)],
)
def test_real_velodyne_captures_read_as_firings(tmp_path, name, model, lasers, rpm):
    log = read_car_log(_car_folder(tmp_path, require(VELO / name)))
    assert log.model == model and log.distance_m.shape[1] == lasers
    assert abs(log.omega_rad_s) * 60 / (2 * np.pi) == pytest.approx(rpm, rel=0.01)
    assert log.firing_hz == pytest.approx(UNITS[model].firing_hz, rel=0.01)
    np.testing.assert_allclose(log.vertical_rad, np.radians(UNITS[model].vertical_deg))
    assert 0.3 < (log.distance_m > 0).mean() and log.distance_m.max() < 130.0


@pytest.mark.realdata
def test_a_real_ouster_capture_reads_as_columns(tmp_path):
    """The OS-1-64's capture with its metadata: a column every 1/1024 of a turn at 10 Hz, its encoder's
    rotation stepping 360°/1024 a column, its beams' altitudes from the JSON."""
    meta = require(VELO / "ouster_example.json")
    folder = _car_folder(tmp_path, require(VELO / "ouster_example.pcap"), calibration="metadata.json")
    shutil.copy(meta, folder / "metadata.json")
    log = read_car_log(folder)
    assert log.model == "OS-1" and log.distance_m.shape == (100 * 16, 64)
    assert log.firing_hz == pytest.approx(10240.0, rel=0.01)
    assert abs(log.omega_rad_s) == pytest.approx(20 * np.pi, rel=0.01)
    step = np.degrees(np.angle(np.exp(1j * np.diff(log.rotation_rad))))
    np.testing.assert_allclose(step, -360.0 / 1024, atol=1e-6)
    np.testing.assert_allclose(np.degrees(log.vertical_rad), json.loads(meta.read_text())["beam_altitude_angles"])
    assert log.factory is not None and log.factory.distance_resolution_m == 0.001
    assert 0.2 < (log.distance_m > 0).mean() and 1.0 < np.median(log.distance_m[log.distance_m > 0]) < 60.0


def test_an_ouster_needs_its_metadata_for_the_altitudes(tmp_path):
    unit = ouster_unit(16, 512)
    pay = encode_packets(unit, np.zeros(16 * 8), np.ones((16 * 8, 16)), np.arange(8) * 16 * unit.firing_s)
    from sensact.errors import LogFormatError
    from sensact.io.velodyne import write_pcap

    write_pcap(tmp_path / "os.pcap", pay, 1.0 + np.arange(8) * 0.0016, port=unit.port)
    folder = _car_folder(tmp_path, tmp_path / "os.pcap")
    with pytest.raises(LogFormatError) as err:
        read_car_log(folder)
    assert err.value.field == "lidar.vertical_deg" and "metadata" in (err.value.fix or "")


def test_a_velodyne_whose_lasers_are_laid_out_otherwise_is_named(tmp_path):
    from sensact.errors import LogFormatError
    from sensact.io.velodyne import PACKET, write_pcap

    unit = UNITS["HDL-32E"]
    n, P = unit.firings_per_packet, 20
    start = 100.0 + np.arange(P) * n * unit.firing_s
    pay = encode_packets(unit, np.zeros(P * n), np.ones((P * n, 32)), start)
    pay.view(PACKET).reshape(-1)["status_value"] = 0xA1  # a VLS-128's product id
    write_pcap(tmp_path / "vls.pcap", pay, start)
    with pytest.raises(LogFormatError, match="VLS-128 packets") as err:
        read_car_log(_car_folder(tmp_path, tmp_path / "vls.pcap"))
    assert err.value.field == "lidar.file"


def test_a_unit_sending_to_another_port_is_read_where_meta_json_says(tmp_path):
    from sensact.errors import LogFormatError
    from sensact.io.velodyne import write_pcap

    unit = UNITS["VLP-16"]
    n, P = unit.firings_per_packet, 40
    rot = np.mod(np.arange(P * n) * 0.2, 360.0)
    start = 100.0 + np.arange(P) * n * unit.firing_s
    write_pcap(tmp_path / "vlp.pcap", encode_packets(unit, rot, np.full((P * n, 16), 5.0), start), start, port=2369)
    with pytest.raises(LogFormatError, match="to port 2368") as err:
        read_car_log(_car_folder(tmp_path, tmp_path / "vlp.pcap"))
    assert "UDP to port 2369 (1206-byte payloads) x 40" in str(err.value) and "lidar.port" in (err.value.fix or "")
    other = tmp_path / "other"
    other.mkdir()
    log = read_car_log(_car_folder(other, tmp_path / "vlp.pcap", port=2369))
    assert log.model == "VLP-16" and log.distance_m.shape == (P * n, 16) and np.all(log.distance_m == 5.0)


@pytest.mark.parametrize("model", ["HDL-32E", "VLP-32C", "VLP-16", "Puck Hi-Res"])
def test_a_dual_return_capture_reads_as_its_last_returns(tmp_path, model):
    """The same firings sent in dual-return mode (each block twice: the last return, then the strongest, here
    alike; packets twice as often) read as the single-return capture does."""
    from sensact.io.velodyne import PACKET, write_pcap

    unit = UNITS[model]
    n, P = unit.firings_per_packet, 40
    rng = np.random.default_rng(2)
    rot = np.mod(np.arange(P * n) * 0.2, 360.0)
    dist = np.round(rng.uniform(1.0, 90.0, (P * n, unit.lasers)) / unit.distance_unit_m) * unit.distance_unit_m
    start = 100.0 + np.arange(P) * n * unit.firing_s
    single = encode_packets(unit, rot, dist, start)
    pk = single.view(PACKET).reshape(-1)
    dual = np.repeat(pk, 2)
    half = n * unit.firing_s / 2  # six blocks' time
    for k in range(2):  # the first six blocks of a packet, then the last six, each block twice
        dual[k::2]["blocks"] = np.repeat(pk["blocks"][:, 6 * k : 6 * k + 6], 2, axis=1)
        dual[k::2]["timestamp_us"] = np.rint(np.mod(start + k * half, 3600.0) * 1e6).astype(np.uint32)
    dual["status_type"] = 0x39
    times = np.repeat(start, 2) + np.tile([0.0, half], P)
    write_pcap(tmp_path / "single.pcap", single, start)
    write_pcap(tmp_path / "dual.pcap", dual.view(np.uint8).reshape(-1, 1206), times)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    one = read_car_log(_car_folder(tmp_path / "a", tmp_path / "single.pcap"))
    two = read_car_log(_car_folder(tmp_path / "b", tmp_path / "dual.pcap"))
    assert two.model == model and "dual-return packets: each firing's last return read" in two.notes
    np.testing.assert_array_equal(two.distance_m, one.distance_m)
    np.testing.assert_allclose(np.angle(np.exp(1j * (two.rotation_rad - one.rotation_rad))), 0.0, atol=2e-4)
    assert two.firing_hz == pytest.approx(one.firing_hz, rel=1e-3)


def test_a_calibration_of_another_unit_is_refused_before_simulating(tmp_path):
    from sensact.errors import ConfigError
    from sensact.io.velodyne_calibration import write_calibration
    from sensact.models.laser_intrinsics import LaserIntrinsics

    write_calibration(tmp_path / "vlp16.yaml", LaserIntrinsics(np.zeros(16), np.zeros(16)))
    with pytest.raises(ConfigError, match="16 lasers, but lidar is HDL-64E") as err:
        simulate_car_log(CarConfig(seconds=1.0, calibration_yaml=str(tmp_path / "vlp16.yaml")), tmp_path / "log")
    assert err.value.field == "calibration_yaml" and "VLP-16" in (err.value.fix or "")
    assert not (tmp_path / "log").exists()
