"""Chapter 5: ray casting, the simulator's pcap, the laser-angle learner, ICP and Algorithm 3."""

from __future__ import annotations

import dataclasses
import json
import shutil

import dpkt
import numpy as np
import pytest

from conftest import rewrite_capture
from sensact.app.velodyne_car import learn_angles_from_log, learn_from_log, simulate_car_log
from sensact.core.raycast import BOX, CYLINDER, _hit_box, _hit_cylinder, build_grid, cast_firings
from sensact.errors import LogFormatError
from sensact.io.velodyne import PACKET, UPPER, encode_hdl64e, read_pcap_payloads, write_pcap
from sensact.io.velodyne_calibration import write_calibration
from sensact.io.velodyne_car_folder import read_car_log
from sensact.learn.scan_odometry import OdometryConfig, angle_median, icp, invert, offset_from_motion
from sensact.learn.spinning_lidar_intrinsics import learn_relative_angles, masked_ncc
from sensact.learn.velodyne_car_dynamics import CarLearningConfig, regression_actions
from sensact.models.laser_intrinsics import LaserIntrinsics
from sensact.models.velodyne_car_dynamics import CarDynamics, fit_car_dynamics
from sensact.sim.velodyne_car import CarConfig, nominal_intrinsics


def test_grid_ray_casting_equals_brute_force():
    rng = np.random.default_rng(0)
    kinds, params = [], []
    for _ in range(150):
        x, y = rng.uniform(-100, 100, 2)
        if rng.random() < 0.5:
            kinds.append(BOX)
            params.append((x, y, x + rng.uniform(2, 20), y + rng.uniform(2, 20), rng.uniform(1, 15)))
        else:
            kinds.append(CYLINDER)
            params.append((x, y, rng.uniform(0.1, 1.0), rng.uniform(1, 8), 0.0))
    kind, params = np.array(kinds), np.array(params)
    origin, cell, shape, start, items = build_grid(kind, params, 7.0)
    intr = nominal_intrinsics()
    F = 300
    poses = np.column_stack([rng.uniform(-50, 50, F), rng.uniform(-50, 50, F), rng.uniform(-3, 3, F)])
    rot = rng.uniform(0, 2 * np.pi, F)
    out = np.zeros((F, 64))
    cast_firings(
        poses,
        2.0,
        rot,
        intr.vertical_rad,
        intr.horizontal_rad,
        1.5,
        120.0,
        kind,
        params,
        origin,
        cell,
        shape[0],
        shape[1],
        start,
        items,
        out,
    )
    for f in range(0, F, 7):
        c, s = np.cos(poses[f, 2]), np.sin(poses[f, 2])
        for lid in range(0, 64, 5):
            a = intr.horizontal_rad[lid] + rot[f] + 1.5
            cv = np.cos(intr.vertical_rad[lid])
            ex, ey, ez = cv * np.cos(a), cv * np.sin(a), np.sin(intr.vertical_rad[lid])
            d = (c * ex - s * ey, s * ex + c * ey, ez)
            best = -2.0 / d[2] if d[2] < 0 else 120.0
            for k in range(len(kind)):
                fn = _hit_box if kind[k] == BOX else _hit_cylinder
                best = min(best, fn(poses[f, 0], poses[f, 1], 2.0, *d, params[k]))
            assert out[f, lid] == pytest.approx(best if best < 120.0 else 0.0, abs=1e-9)


def test_masked_ncc_equals_the_direct_sum():
    rng = np.random.default_rng(1)
    n = 600
    base = np.cumsum(rng.normal(size=n + 40))
    a = base[20 : 20 + n] + 10
    b = base[27 : 27 + n] + 10 + rng.normal(size=n) * 0.1
    a[rng.random(n) < 0.1] = 0
    b[rng.random(n) < 0.1] = 0
    K = masked_ncc(a, b, 15)
    direct = np.full(31, np.nan)
    for i, k in enumerate(range(-15, 16)):
        idx = np.arange(max(0, k), min(n, n + k))
        x, y = a[idx], b[idx - k]
        ok = (x > 0) & (y > 0)
        direct[i] = np.corrcoef(x[ok], y[ok])[0, 1]
    np.testing.assert_allclose(K, direct, atol=1e-9)
    assert np.nanargmax(K) - 15 == 7  # a[i] = b[i - 7]: the peak is at k = 7


@pytest.fixture(scope="module")
def short_drive_folder(tmp_path_factory):
    cfg = CarConfig(seconds=30.0, seed=3, turn_times_s=(12.0,), stop_times_s=(24.0,))
    folder = tmp_path_factory.mktemp("car") / "log"
    return simulate_car_log(cfg, folder), folder


@pytest.fixture(scope="module")
def short_drive(short_drive_folder):
    run, folder = short_drive_folder
    return run, read_car_log(folder)


def test_simulated_pcap_decodes_as_an_hdl64e(short_drive):
    _, log = short_drive

    assert log.meta["lidar"]["file"] == "velodyne.pcap"
    assert log.distance_m.shape == ((30 * 7800) // 6 * 6, 64)
    valid = log.distance_m > 0
    assert 0.5 < valid.mean() < 0.999 and log.distance_m[valid].max() <= 120.0
    # the rotation moves by omega / f per firing, clockwise as every Velodyne turns (theta_r falls)
    assert log.omega_rad_s == pytest.approx(-20 * np.pi, rel=1e-4)
    step = np.angle(np.exp(1j * np.diff(log.rotation_rad)))
    np.testing.assert_allclose(step, -20 * np.pi / 7800, atol=2e-4)
    assert log.actions.shape[1] == 3 and log.groundtruth is not None


def test_reading_a_capture_holds_little_beyond_the_distances(short_drive_folder, tmp_path):
    """The capture streams through a chunk at a time: reading it costs about the float32 distances the
    learner reads, not the payloads (the whole 200-s drive took 3.2 GB to read before, 0.6 GB now)."""
    import platform
    import subprocess
    import sys

    if platform.system() != "Linux":
        pytest.skip("reads the resident memory from /proc")
    _, folder = short_drive_folder
    script = (
        "import sys, threading, time\n"
        "from sensact.io.velodyne_car_folder import read_car_log\n"
        "def rss():\n"
        "    return int(open('/proc/self/status').read().split('VmRSS:')[1].split()[0]) * 1024\n"
        "before, peak, reading = rss(), [0], [True]\n"
        "def sample():\n"
        "    while reading[0]:\n"
        "        peak[0] = max(peak[0], rss())\n"
        "        time.sleep(0.002)\n"
        "watch = threading.Thread(target=sample)\n"
        "watch.start()\n"
        "log = read_car_log(sys.argv[1])\n"
        "reading[0] = False\n"
        "watch.join()\n"
        "print(log.distance_m.nbytes, max(peak[0], rss()) - before)\n"
    )
    done = subprocess.run([sys.executable, "-c", script, str(folder)], capture_output=True, text=True, check=True)
    distances, grew = map(int, done.stdout.split())
    assert distances == 30 * 7800 * 64 * 4
    assert grew < 1.5 * distances + 40 * 2**20, (grew, distances)
    print(f"read grew {grew / 2**20:.0f} MiB for {distances / 2**20:.0f} MiB of distances")


def test_a_users_car_folder_needs_no_rates_and_takes_the_factory_calibration(short_drive_folder, short_drive, tmp_path):
    """A folder of one's own: the capture where it lies, the pedal log, and the factory calibration file;
    the firing rate and rpm come from the packets' clock and match what the simulator states."""
    _, sim = short_drive_folder
    _, log = short_drive
    assert not log.notes and not log.warnings  # the simulator's stated rates agree with its packets
    lidar = {
        "file": str(sim / "velodyne.pcap"),
        "time_origin_s": json.loads((sim / "meta.json").read_text())["lidar"]["time_origin_s"],
    }
    own = tmp_path / "own"
    own.mkdir()
    shutil.copy(sim / "actions.csv", own)

    def write_meta(**extra):
        meta = {"format": "sensact-log", "version": 1, "platform": "car", "lidar": {**lidar, **extra}}
        (own / "meta.json").write_text(json.dumps(meta))

    write_meta()
    with pytest.raises(LogFormatError, match="--factory-calibration"):
        read_car_log(own)
    (own / "actions.csv").rename(own / "later.csv")
    lidar_only = read_car_log(own, calibration=sim / "calibration_true.yaml")
    assert lidar_only.actions is None and lidar_only.action_times_s is None
    assert lidar_only.notes[-1].startswith("no actions.csv: the laser angles and C from the scans alone")
    (own / "later.csv").rename(own / "actions.csv")
    mine = read_car_log(own, calibration=sim / "calibration_true.yaml")
    assert mine.firing_hz == pytest.approx(log.firing_hz, rel=1e-5)
    assert mine.omega_rad_s == pytest.approx(log.omega_rad_s, rel=1e-4)
    np.testing.assert_array_equal(mine.distance_m, log.distance_m)
    np.testing.assert_allclose(mine.vertical_rad, log.vertical_rad, atol=1e-12)
    assert log.factory is None and mine.factory is not None  # kept for the export: the file is read once
    np.testing.assert_allclose(mine.action_times_s, log.action_times_s, atol=1e-9)
    assert [n.split()[0] for n in mine.notes] == ["firing_hz", "rpm"] and not mine.warnings
    # the same capture saved as pcapng, as Wireshark saves it
    rewrite_capture(sim / "velodyne.pcap", own / "velodyne.pcapng", dpkt.pcapng.Writer)
    write_meta(file="velodyne.pcapng")
    np.testing.assert_array_equal(
        read_car_log(own, calibration=sim / "calibration_true.yaml").distance_m, log.distance_m
    )
    write_meta()
    assert all("measured from the packets' clock" in n for n in mine.notes)
    # a stated rate wins, but one the packets contradict is said
    write_meta(rpm=300)
    wrong = read_car_log(own, calibration=sim / "calibration_true.yaml")
    assert wrong.omega_rad_s == pytest.approx(-10 * np.pi)
    assert len(wrong.warnings) == 1 and "rpm is 300 rpm but the packets show 600" in wrong.warnings[0]
    # a capture that lost packets on the way: their firings stay in place, empty
    times, payloads, _ = read_pcap_payloads(sim / "velodyne.pcap")
    keep = np.ones(len(payloads), dtype=bool)
    keep[[1000, 2000, 2001, 2002]] = False
    write_pcap(own / "lossy.pcap", payloads[keep], times[keep])
    write_meta(file="lossy.pcap", vertical_deg=np.degrees(log.vertical_rad).tolist())
    lossy = read_car_log(own)
    lost = np.repeat(~keep, 6)
    assert lossy.distance_m.shape == log.distance_m.shape and not lossy.distance_m[lost].any()
    np.testing.assert_array_equal(lossy.distance_m[~lost], log.distance_m[~lost])
    np.testing.assert_allclose(np.angle(np.exp(1j * (lossy.rotation_rad - log.rotation_rad))), 0, atol=2e-4)
    assert lossy.notes[0].startswith("4 dropped packets in 2 gaps")
    # a gap longer than the file's size leaves room for (3 % of the drive): placed the same way
    keep[5000:6200] = False
    write_pcap(own / "lossy.pcap", payloads[keep], times[keep])
    gappy = read_car_log(own)
    lost = np.repeat(~keep, 6)
    assert gappy.distance_m.shape == log.distance_m.shape and not gappy.distance_m[lost].any()
    np.testing.assert_array_equal(gappy.distance_m[~lost], log.distance_m[~lost])
    assert gappy.notes[0].startswith("1204 dropped packets in 3 gaps")
    # a calibration for another unit, the capture itself given as the log, and a capture of another model
    write_calibration(tmp_path / "vlp16.yaml", LaserIntrinsics(np.zeros(16), np.zeros(16)))
    with pytest.raises(LogFormatError, match="16 vertical angles for the HDL-64E's 64 lasers") as err:
        read_car_log(own, calibration=tmp_path / "vlp16.yaml")
    assert "vlp16.yaml" in str(err.value)
    with pytest.raises(LogFormatError, match="not a single file"):
        read_car_log(sim / "velodyne.pcap")
    payloads = encode_hdl64e(np.zeros(60), np.ones((60, 64)), np.zeros((60, 64)), np.arange(10) * 553)
    # upper blocks only, every 553 µs, as an HDL-32E sends them
    payloads.view(PACKET).reshape(-1)["blocks"]["id"] = UPPER
    write_pcap(own / "other.pcap", payloads, np.arange(10) * 553e-6)
    write_meta(file="other.pcap", vertical_deg=[0.0] * 64)
    with pytest.raises(LogFormatError, match="64 vertical angles for the HDL-32E's 32 lasers") as err:
        read_car_log(own)  # read as the 32-laser unit it is (tests/test_lidar_units.py learns from each)
    assert "meta.json" in str(err.value)


@pytest.fixture(scope="module")
def counterclockwise_drive(tmp_path_factory):
    """The short drive with a unit that turns the other way (no Velodyne does): the learners must not
    assume a direction."""
    cfg = CarConfig(seconds=30.0, seed=3, turn_times_s=(12.0,), stop_times_s=(24.0,), clockwise=False)
    folder = tmp_path_factory.mktemp("car_ccw") / "log"
    return simulate_car_log(cfg, folder), read_car_log(folder)


@pytest.mark.parametrize("drive", ["short_drive", "counterclockwise_drive"])
def test_relative_angles_recover_the_true_differences(drive, request):
    run, log = request.getfixturevalue(drive)
    assert np.sign(log.omega_rad_s) == (-1.0 if run.config.clockwise else 1.0)
    res = learn_relative_angles(log.distance_m, log.vertical_rad, log.firing_hz, log.omega_rad_s)
    err = res.relative_rad - run.true_laser_angles_rad
    err -= err.mean()
    assert np.degrees(np.sqrt(np.mean(err**2))) < 0.3


def test_both_matchers_follow_the_true_motion(short_drive):
    """Every interval's speed and turn rate from scan matching against the truth's, with the true laser
    angles: KISS-ICP (every revolution, deskewed, against a local map) follows the truth closer than
    Algorithm 2 (0.037 against 0.133 m/s RMS in speed), and the true motion as its guess (as the learned
    dynamics seed it in Algorithm 3) leaves it as close."""
    pytest.importorskip("kiss_icp")
    from sensact.evaluate.velodyne_car import truth_motion
    from sensact.learn.scan_odometry import scan_odometry

    _, log = short_drive
    angles = np.asarray(log.meta["truth"]["laser_angles_rad"])
    gt = log.groundtruth
    poses = np.column_stack([gt["x_m"], gt["y_m"], gt["theta_rad"]])
    errors = {}
    runs = (("algorithm2", None), ("kiss_icp", None), ("kiss_icp seeded", "truth"))
    for name, seed in runs:
        cfg = dataclasses.replace(CarLearningConfig(), matcher=name.split()[0]).odometry
        per_rev = round(2 * np.pi / abs(log.omega_rad_s) * log.firing_hz)
        starts = np.arange(0, len(log.rotation_rad) - per_rev + 1, round(cfg.dt_s * log.firing_hz))
        mid = (starts + per_rev / 2) / log.firing_hz
        v, w, _ = truth_motion(gt["t_s"], poses, mid[:-1], cfg.dt_s)
        guess = None
        if seed:  # the true motion as the dynamics would predict it: forward is +y in the car's frame
            guess = np.column_stack([np.zeros_like(v), v * cfg.dt_s, w * cfg.dt_s])
        odo = scan_odometry(
            log.rotation_rad, log.distance_m, log.vertical_rad, angles, log.firing_hz, log.omega_rad_s, guess, cfg
        )
        speed = np.hypot(odo.motion[:, 0], odo.motion[:, 1]) / cfg.dt_s
        errors[name] = (
            float(np.sqrt(np.mean((speed - np.abs(v)) ** 2))),
            float(np.sqrt(np.mean((odo.motion[:, 2] / cfg.dt_s - w) ** 2))),
        )
    for name in ("kiss_icp", "kiss_icp seeded"):
        assert errors[name][0] < 0.05 and errors[name][1] < 0.01, errors
    assert errors["kiss_icp"][0] < 0.5 * errors["algorithm2"][0], errors
    assert errors["kiss_icp"][0] < 0.05 and errors["kiss_icp"][1] < 0.01, errors
    assert errors["kiss_icp"][0] < errors["algorithm2"][0], errors


def test_the_kiss_matcher_without_kiss_icp_says_which_extra(monkeypatch):
    import sys

    from sensact.errors import ConfigError
    from sensact.learn.scan_odometry import OdometryConfig, scan_odometry

    for name in ("kiss_icp", "kiss_icp.config", "kiss_icp.kiss_icp"):
        monkeypatch.setitem(sys.modules, name, None)  # as if not installed: importing it fails
    cfg = OdometryConfig(matcher="kiss_icp")
    with pytest.raises(ConfigError, match=r"matcher: the kiss_icp matcher needs KISS-ICP.*sensact\[kiss\]"):
        scan_odometry(np.zeros(800), np.ones((800, 2)), np.zeros(2), np.zeros(2), 7800.0, 20 * np.pi, config=cfg)


def test_icp_recovers_a_known_motion():
    """Walls in three directions and a round kiosk, densely sampled: ICP finds the transform to the
    sampling's resolution."""
    from scipy.spatial import cKDTree

    u = np.linspace(-30, 30, 3000)
    ang = np.linspace(0, 2 * np.pi, 600)
    pts = np.concatenate(
        [
            np.column_stack([u, np.full(u.size, 12.0)]),
            np.column_stack([np.full(u.size, -15.0), u]),
            np.column_stack([u, 0.6 * u - 20.0]),
            np.column_stack([5 + 3 * np.cos(ang), -4 + 3 * np.sin(ang)]),
        ]
    )
    T = np.array([0.8, 2.5, 0.04])
    c, s = np.cos(T[2]), np.sin(T[2])
    moved = pts @ np.array([[c, s], [-s, c]]) + T[:2]
    est, _, _ = icp(pts[::3], cKDTree(moved), moved, np.zeros(3), OdometryConfig())
    np.testing.assert_allclose(est, T, atol=0.02)
    np.testing.assert_allclose(invert(invert(T)), T)


def test_angle_median_and_offset():
    a = np.array([3.1, -3.1, 3.05, 0.2])
    assert abs(angle_median(a)) > 3.0  # the wrap-around cluster wins
    motion = np.array([[np.cos(1.2), np.sin(1.2), 0.0]] * 5 + [[0.01, 0.0, 0.0]])
    assert offset_from_motion(motion * 2.0, 0.5) == pytest.approx(np.pi / 2 - 1.2)
    # a drive that never reaches the speed says so, with the setting to lower (not a bare ValueError)
    from sensact.errors import LogFormatError

    with pytest.raises(LogFormatError, match=r"min_speed_m_s: .*the fastest: 0\.02 m/s"):
        offset_from_motion(motion[-1:], 0.5)


def test_factory_comparison_takes_out_one_mount_yaw():
    from sensact.evaluate.velodyne_car import factory_comparison

    factory = np.radians(np.linspace(-8.0, 10.0, 64))
    yaw = np.radians(179.0)  # the learned angles wrap past pi: the comparison must not see a 360° jump
    fc = factory_comparison(factory + yaw, factory)
    assert fc["mount_yaw_deg"] == pytest.approx(179.0, abs=1e-9) and fc["rms_deg"] < 1e-9
    e = np.radians(0.2) * np.where(np.arange(64) % 2 == 0, 1.0, -1.0)  # disagreements that cancel in pairs
    fc = factory_comparison(factory + yaw + e, factory)
    assert fc["mount_yaw_deg"] == pytest.approx(179.0, abs=1e-9)
    assert fc["rms_deg"] == pytest.approx(0.2, rel=1e-9) and fc["max_deg"] == pytest.approx(0.2, rel=1e-9)


def test_regression_recovers_the_coefficients_exactly():
    rng = np.random.default_rng(3)
    true = CarDynamics(0.1, 3.5, -0.4, -0.5, 0.002, 0.11)
    K = 300
    act = np.column_stack([rng.uniform(0, 1, K), rng.uniform(0, 1, K), rng.uniform(-1, 1, K)])
    v = rng.uniform(0, 7, K)
    fit = fit_car_dynamics(v, true.accel(v, act[:, 0], act[:, 1]), true.omega(v, act[:, 2]), act)
    np.testing.assert_allclose(fit.as_array(), true.as_array(), atol=1e-10)
    assert CarDynamics.from_dict(fit.to_dict()) == fit


def test_regression_actions_align_with_the_acceleration():
    t = np.arange(0, 10, 0.05)
    acts = np.column_stack([t, 2 * t, 3 * t])
    out = regression_actions(t, acts, np.array([0.0, 0.5, 1.0]), 0.5)
    np.testing.assert_allclose(out[:, 0], [0.475, 0.975, 1.475])  # throttle over [t + dt/2, t + 3dt/2)
    np.testing.assert_allclose(out[:, 2], 3 * np.array([0.225, 0.725, 1.225]))  # steering over [t, t + dt)


@pytest.mark.slow
def test_algorithm_3_on_a_short_drive(short_drive):
    run, log = short_drive
    res = learn_from_log(log, CarLearningConfig())
    # from the scans alone: exactly Algorithm 3's first pass (identity guesses), which needs no controls
    scans_only = learn_angles_from_log(log, CarLearningConfig())
    assert scans_only.offset_rad == res.history[0]["C_rad"]
    np.testing.assert_array_equal(scans_only.intrinsics.relative_rad, res.intrinsics.relative_rad)
    with pytest.raises(ValueError, match="needs the log's actions"):
        learn_from_log(dataclasses.replace(log, actions=None), CarLearningConfig())
    from sensact.evaluate.velodyne_car import laser_angle_error

    assert laser_angle_error(res.laser_angles_rad, run.true_laser_angles_rad)["laser_angle_rms_deg"] < 0.3
    assert 1 <= res.iterations < 10 and res.converged  # 3 iterations on this drive
    once = learn_from_log(log, dataclasses.replace(CarLearningConfig(), max_iterations=1))
    assert once.iterations == 1 and not once.converged  # stopped by max_iterations, and says so
    true = run.config.true_coefficients()
    assert res.model.C10 == pytest.approx(true["C10"], rel=0.3)
    assert res.model.C6 > 0 and res.model.C8 < 0


def test_a_standard_decoder_reads_the_simulated_pcap(short_drive_folder, short_drive):
    """velodyne-decoder (test-only), reading the simulator's HDL-64E pcap with its true calibration,
    finds every return that sensact's reader finds."""
    vd = pytest.importorskip("velodyne_decoder")
    _, log = short_drive
    pcap = short_drive_folder[1] / "velodyne.pcap"
    conf = vd.Config(
        model=vd.Model.HDL64E_S1, calibration=vd.Calibration.read(str(pcap.parent / "calibration_true.yaml"))
    )
    n = sum(len(p) for _, p in vd.read_pcap(str(pcap), conf, as_pcl_structs=True))
    assert n == int((log.distance_m > 0).sum())


def test_learn_car_takes_kiss_icp_where_installed_else_the_thesis_matcher(monkeypatch):
    import importlib.util

    from sensact.cli.learn.velodyne_car import best_matcher
    from sensact.learn.velodyne_car_dynamics import CarLearningConfig

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None if name == "kiss_icp" else real(name))
    assert best_matcher() == "algorithm2" == CarLearningConfig().matcher  # reproduce car: the thesis's
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: object() if name == "kiss_icp" else real(name))
    assert best_matcher() == "kiss_icp"
