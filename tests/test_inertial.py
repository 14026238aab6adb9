"""Issue 105: wheel odometry, an IMU and GNSS, calibrated from one bag with no ground truth.

The ladder: exact reductions (dead reckoning of a constant turn is an arc; the filter's Jacobians are its
models' derivatives; URDF's rpy is scipy's extrinsic xyz), an independent reference (the bias's integral's
variance by the smoother's lag covariances, against a brute-force sum of every pair), seeded recovery of a
simulated skid-steer robot (each barred number within its bar and within 3 of its own sd) through the route a
user takes (`simulate outdoor --bag`, `convert bag`, `learn em`, `export`, `evaluate log`), invariants (no
GNSS: the product of the turn gain and the gyro's scale; a robot that never moves is flagged), and bad input
refused or flagged in one line."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from sensact.app.inertial import calibrate_inertial
from sensact.cli import app
from sensact.core import inertial_smoother as ks
from sensact.core.pose_models import rpy_matrix
from sensact.errors import LogFormatError
from sensact.evaluate.bars import INERTIAL_BARS as BARS
from sensact.learn import inertial as li
from sensact.sim.inertial import InertialConfig, simulate_inertial

runner = CliRunner()


def _run(args, code=0):
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == code, res.output
    return res


def _state(rng: np.random.Generator) -> np.ndarray:
    m = np.zeros(ks.N_STATE)
    m[[ks.X, ks.Y]] = rng.normal(0, 5000, 2)
    m[ks.TH] = rng.uniform(-3, 3)
    m[[ks.CX, ks.CY, ks.CTH]] = m[[ks.X, ks.Y, ks.TH]] - rng.normal(0, [300, 300, 0.1])
    m[[ks.B, ks.CB]] = rng.normal(0, 0.01, 2)
    m[[ks.GF, ks.GT, ks.S]] = rng.uniform(0.8, 1.2, 3)
    m[[ks.LF, ks.LL]] = rng.normal(0, 400, 2)
    return m


def test_dead_reckoning_of_a_constant_turn_is_an_arc():
    """Pieces of equal travel turning at a constant rate reach the arc's end: with gains, the robot drives
    GF d along a circle turning GT a (sensact's frame: facing +y, its left is -x)."""
    n, d, a = 400, 2000.0, 1.2
    sub_d = np.full(n, d / n)
    sub_a = (np.arange(n) + 0.5) * a / n
    m = np.zeros(ks.N_STATE)
    m[ks.GF], m[ks.GT] = 1.05, 0.9
    J = np.zeros((3, ks.N_STATE))
    x, y, th = ks.odometry_move(m, sub_d, sub_a, a, J)
    L, phi = 1.05 * d, 0.9 * a
    r = L / phi
    np.testing.assert_allclose([x, y, th], [-r * (1 - math.cos(phi)), r * math.sin(phi), phi], rtol=2e-6)
    m[ks.GT] = 0.0  # no turn: a straight line
    x, y, _ = ks.odometry_move(m, sub_d, sub_a, a, J)
    assert x == 0.0 and y == pytest.approx(1.05 * d, rel=1e-12)


def test_the_filters_jacobians_are_its_models_derivatives():
    rng = np.random.default_rng(3)
    n = ks.N_STATE
    sub_d, sub_a = rng.uniform(0, 40, 12), np.cumsum(rng.normal(0, 0.02, 12))
    for _ in range(5):
        m = _state(rng)
        H2 = np.zeros((2, n))
        ks.gnss_model(m, sub_d, sub_a, sub_a[-1], H2)
        F, Q, out = np.zeros((n, n)), np.zeros((n, n)), np.zeros(n)
        q = np.full(ks.N_NOISE, 1e-3)
        ks._transition(m, 1.0, sub_d.sum(), sub_a[-1], sub_d, sub_a, q, out, F, Q)
        Hg = np.zeros(n)
        ks.gyro_model(m, 1.0, Hg)
        for j in range(n):
            step = 1e-6 * max(1.0, abs(m[j]))
            mp, mm = m.copy(), m.copy()
            mp[j] += step
            mm[j] -= step
            hp = np.array(ks.gnss_model(mp, sub_d, sub_a, sub_a[-1], np.zeros((2, n))))
            hm = np.array(ks.gnss_model(mm, sub_d, sub_a, sub_a[-1], np.zeros((2, n))))
            np.testing.assert_allclose(H2[:, j], (hp - hm) / (2 * step), rtol=1e-5, atol=1e-6)
            op, om = np.zeros(n), np.zeros(n)
            ks._transition(mp, 1.0, sub_d.sum(), sub_a[-1], sub_d, sub_a, q, op, np.zeros((n, n)), np.zeros((n, n)))
            ks._transition(mm, 1.0, sub_d.sum(), sub_a[-1], sub_d, sub_a, q, om, np.zeros((n, n)), np.zeros((n, n)))
            np.testing.assert_allclose(F[:, j], (op - om) / (2 * step), rtol=1e-5, atol=1e-6)
            gp = ks.gyro_model(mp, 1.0, np.zeros(n))
            gm = ks.gyro_model(mm, 1.0, np.zeros(n))
            assert Hg[j] == pytest.approx((gp - gm) / (2 * step), rel=1e-5, abs=1e-8)


def test_urdf_rpy_is_extrinsic_xyz_and_gravity_gives_roll_and_pitch_back():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(5)
    for _ in range(20):
        rpy = rng.uniform(-3, 3, 3) * [1, 0.45, 1]
        R = rpy_matrix(*rpy)
        np.testing.assert_allclose(R, Rotation.from_euler("xyz", rpy).as_matrix(), atol=1e-12)
        roll, pitch = li.tilt_rpy(R[2] * 9.8)  # what an accelerometer at rest reads: base z in its axes
        assert roll == pytest.approx(rpy[0], abs=1e-9) and pitch == pytest.approx(rpy[1], abs=1e-9)


def test_the_bias_integrals_variance_is_the_sum_of_every_pair():
    """``run_smoother``'s variance of sum_k b_k dt_k, by the recursion through the lag covariances, against
    sum_ij dt_i dt_j Cov(b_i, b_j) with Cov(x_i, x_j) = J_i ... J_j-1 P_j computed here in numpy."""
    rng = np.random.default_rng(2)
    T = 25
    steps = li.Steps(
        t=np.arange(T + 1.0),
        dt=rng.uniform(0.5, 1.5, T),
        d=rng.uniform(0, 800, T),
        a=rng.normal(0, 0.2, T),
        gz=rng.normal(0, 0.2, T),
        sub_ptr=np.arange(T + 1, dtype=np.int64),
        sub_d=rng.uniform(0, 800, T),
        sub_a=rng.normal(0, 0.1, T),
        fix_step=np.zeros(0, dtype=np.int64),
        fix_ptr=np.zeros(1, dtype=np.int64),
        fix_sub_d=np.zeros(0),
        fix_sub_a=np.zeros(0),
        fix_dp=np.zeros(0),
        fix_ap=np.zeros(0),
        fix_xy=np.zeros((0, 2)),
        fix_row=np.zeros(0, dtype=np.int64),
    )
    steps = dataclasses.replace(steps, d=steps.sub_d)
    q = np.array([0.1, 0.1, 1e-3, 1e-8, 1e-6, 1e-5, 1e4, 10.0, 1e-4, 0.0, 0.0])
    m0 = np.zeros(ks.N_STATE)
    m0[[ks.GF, ks.GT, ks.S]] = 1.0
    P0 = li._prior(False)
    m_f, P_f, m_p, P_p, Fs, *_ = li.run_filter(steps, q, m0, P0)
    active = np.union1d(np.flatnonzero(np.diag(P0) > 0), [0, 1, 2, 3, 4, 5, 6, 7]).astype(np.int64)
    _, P_s, var_sum = ks.run_smoother(m_f, P_f, m_p, P_p, Fs, active, steps.dt)
    J = []
    for k in range(T):
        Jk = np.zeros((ks.N_STATE, ks.N_STATE))
        Pa = P_p[k + 1][np.ix_(active, active)]
        Jk[:, active] = (P_f[k] @ Fs[k].T)[:, active] @ np.linalg.inv(Pa)
        J.append(Jk)
    cov = np.zeros((T + 1, T + 1))  # Cov(b during step i-1, b during step j-1) = CB of states i, j
    for i in range(1, T + 1):
        for j in range(i, T + 1):
            M = np.eye(ks.N_STATE)
            for k in range(i, j):
                M = M @ J[k]
            cov[i, j] = cov[j, i] = (M @ P_s[j])[ks.CB, ks.CB]
    w = np.concatenate([[0.0], steps.dt])
    assert var_sum == pytest.approx(w @ cov @ w, rel=1e-8)


@pytest.fixture(scope="module")
def husky():
    """A 300-s skid-steer robot, upside-down IMU turned about two axes, RTK fixes with outliers and a
    misreported covariance, /tf_static's IMU wrong; learned once for the tests below."""
    cfg = InertialConfig(seconds=300, seed=11, tf_imu="wrong", gain_turn=0.83, gain_forward=1.025)
    run = simulate_inertial(cfg)
    return cfg, run, calibrate_inertial(run.log_)


def test_learns_the_simulated_robot_within_the_bars_and_its_own_error_bars(husky):
    cfg, _, cal = husky
    assert cal.health.ok, cal.health.flags
    ev = cal.evaluation()
    for key, bar in BARS.items():
        assert abs(ev[key]["error"]) < bar, (key, ev[key])
        assert abs(ev[key]["error_sd"]) < 3, (key, ev[key])
    sigma = cal.value("gnss.sigma_mm") / (1000 * cfg.gnss_sigma_m)
    assert 1 / 1.5 < sigma < 1.5
    assert cal.value("gnss.covariance_ratio") == pytest.approx(cfg.gnss_reported_factor, rel=0.1)
    assert cal.value("gnss.outlier_share") == pytest.approx(cfg.gnss_outliers, abs=0.02)


def test_its_json_holds_every_key_the_issue_names(husky, tmp_path):
    _, _, cal = husky
    from sensact.app.inertial import save_inertial

    out = tmp_path / "model.json"
    save_inertial(cal, out, report=True)
    doc = json.loads(out.read_text())
    keys = ["odometry.gain_forward", "odometry.gain_turn", "imu.gyro.bias_rad_s", "imu.gyro.bias_walk_rad_s_sqrt_s",
            "imu.gyro.scale", "imu.gyro.noise_rad_s_sqrt_hz", "imu.time_offset_s", "imu.mount.roll_rad",
            "imu.mount.pitch_rad", "imu.mount.yaw_rad", "gnss.lever_arm.forward_mm", "gnss.lever_arm.left_mm",
            "gnss.sigma_mm", "gnss.covariance_ratio", "gnss.heading_offset_rad"]  # fmt: skip
    for key in keys:
        node = doc
        *parents, leaf = key.split(".")
        for p in parents:
            node = node[p]
        assert isinstance(node[leaf], float) and math.isfinite(node[leaf]), key
        assert isinstance(node[leaf + "_sd"], float) and node[leaf + "_sd"] > 0, key
    with np.load(tmp_path / "model_bias.npz", allow_pickle=False) as z:
        assert z["bias_rad_s"].shape == z["t_s"].shape == z["bias_sd_rad_s"].shape
        assert np.mean(z["bias_rad_s"]) == pytest.approx(cal.value("imu.gyro.bias_rad_s"), abs=1e-3)
    assert (tmp_path / "report.html").stat().st_size > 10_000  # its three figures inlined


def test_exports_load_as_their_consumers_read_them(husky, tmp_path):
    _, _, cal = husky
    from sensact.app.export import export_model
    from sensact.app.inertial import save_inertial

    model = tmp_path / "model.json"
    save_inertial(cal, model, report=False)

    def finite(node):
        if isinstance(node, dict):
            return all(finite(v) for v in node.values())
        if isinstance(node, list):
            return all(finite(v) for v in node)
        return not isinstance(node, float) or math.isfinite(node)

    for fmt, node in (("diff-drive-controller", "diff_drive_controller"), ("robot-localization", "ekf_filter_node"),
                      ("navsat-transform", "navsat_transform")):  # fmt: skip
        out = tmp_path / f"{fmt}.yaml"
        export_model(model, fmt, out)
        doc = yaml.safe_load(out.read_text())
        params = doc[node]["ros__parameters"]
        assert finite(params)
        if fmt == "diff-drive-controller":
            gf, gt = cal.value("odometry.gain_forward"), cal.value("odometry.gain_turn")
            assert params["wheel_separation_multiplier"] == pytest.approx(gf / gt)
            assert len(params["twist_covariance_diagonal"]) == 6
        if fmt == "robot-localization":
            assert len(params["process_noise_covariance"]) == 225 and len(params["odom0_config"]) == 15
            assert params["imu0_config"][11] is True
        if fmt == "navsat-transform":
            assert params["magnetic_declination_radians"] == 0.0
            assert params["yaw_offset"] == pytest.approx(cal.value("gnss.heading_offset_rad"))
    export_model(model, "urdf", tmp_path / "joints.urdf")
    robot = ET.parse(tmp_path / "joints.urdf").getroot()
    assert robot.tag == "robot"
    joints = {j.get("name"): j.find("origin") for j in robot.findall("joint")}
    rpy = [float(v) for v in joints["imu_link_joint"].get("rpy").split()]
    np.testing.assert_allclose(rpy, [cal.value(f"imu.mount.{k}_rad") for k in ("roll", "pitch", "yaw")], atol=1e-6)
    xyz = [float(v) for v in joints["gps_link_joint"].get("xyz").split()]
    assert xyz[0] == pytest.approx(cal.value("gnss.lever_arm.forward_mm") / 1000, abs=1e-6)
    export_model(model, "kalibr", tmp_path / "imu.yaml")
    kalibr = yaml.safe_load((tmp_path / "imu.yaml").read_text())
    assert kalibr["gyroscope_noise_density"] == pytest.approx(cal.value("imu.gyro.noise_rad_s_sqrt_hz"))
    assert finite(kalibr)


def test_without_gnss_the_turn_gain_carries_the_gyros_scale(husky):
    cfg, run, _ = husky
    log = dataclasses.replace(
        run.log_, gnss_t=np.zeros(0), gnss_enu_m=np.zeros((0, 3)), gnss_var_reported_m2=np.zeros((0, 2))
    )
    cal = calibrate_inertial(log)
    assert cal.health.ok, cal.health.flags
    assert cal.value("odometry.gain_forward") is None and cal.value("gnss.lever_arm.forward_mm") is None
    product = cal.value("odometry.gain_turn") * cal.value("imu.gyro.scale")
    assert product == pytest.approx(cfg.gain_turn * cfg.gyro_scale, rel=0.01)
    assert cal.result.estimates["imu.gyro.scale"].sd is None  # held at 1: not learned


def test_a_robot_that_never_moves_is_flagged():
    cfg = InertialConfig(seconds=60, speed_m_s=0.0, turn_rad_s=0.0, seed=2)
    cal = calibrate_inertial(simulate_inertial(cfg).log_)
    assert [f.code for f in cal.health.flags] == ["no_motion"]


def test_a_stuck_gyro_is_refused():
    run = simulate_inertial(InertialConfig(seconds=60, seed=3))
    log = dataclasses.replace(run.log_, gyro_rad_s=np.zeros_like(run.log_.gyro_rad_s) + 0.01)
    with pytest.raises(LogFormatError, match="does not turn with the robot"):
        calibrate_inertial(log)


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
def test_bag_to_model_through_the_cli(tmp_path, fmt):
    """simulate outdoor --bag, convert bag, learn em, evaluate log: the route a user takes."""
    pytest.importorskip("rosbags")
    bag = tmp_path / ("run.bag" if fmt == "ros1" else "run")
    _run(["simulate", "outdoor", "--out", tmp_path / "sim", "--seconds", 120, "--bag", bag, "--bag-format", "mcap"])
    _run(["convert", "bag", bag, "--out", tmp_path / "log"])
    sim = json.loads((tmp_path / "sim" / "meta.json").read_text())
    meta = json.loads((tmp_path / "log" / "meta.json").read_text())
    assert meta["kind"] == "imu_gnss" and meta["topics"]["gnss"] == "/gps/fix"
    np.testing.assert_allclose(meta["tf_static"]["imu"]["rpy_rad"], sim["tf_static"]["imu"]["rpy_rad"], atol=1e-9)
    from sensact.io.inertial_folder import read_inertial_log

    a, b = read_inertial_log(tmp_path / "sim"), read_inertial_log(tmp_path / "log")
    np.testing.assert_allclose(b.imu_t - b.imu_t[0], a.imu_t - a.imu_t[0], atol=1e-8)
    np.testing.assert_array_equal(b.gyro_rad_s, a.gyro_rad_s)
    np.testing.assert_allclose(b.odom_omega_rad_s, a.odom_omega_rad_s, rtol=0, atol=0)
    # WGS 84 and back, about the first fix: the same local frame up to its origin, to a tenth of a millimetre
    d = (b.gnss_enu_m - b.gnss_enu_m[0]) - (a.gnss_enu_m - a.gnss_enu_m[0])
    assert np.abs(d[:, :2]).max() < 1e-4
    _run(["learn", "em", tmp_path / "log", "--out", tmp_path / "model.json"])
    doc = json.loads((tmp_path / "model.json").read_text())
    assert doc["kind"] == "imu_gnss" and doc["health"]["ok"]
    res = _run(["evaluate", "log", tmp_path / "sim", "--model", tmp_path / "model.json", "--out", tmp_path / "ev.json"])
    ev = json.loads((tmp_path / "ev.json").read_text())
    for sensor in ("gyro", "gnss"):
        assert 0.8 <= ev["consistency"][sensor]["coverage90"] <= 0.97, res.output


def test_next_run_consistency_is_honest(husky, tmp_path):
    """A model learned on one run, scored on another seed's: the filter's innovations fall in the model's
    90 % intervals about 90 % of the time."""
    from sensact.app.inertial import evaluate_inertial, save_inertial

    cfg, _, cal = husky
    model = tmp_path / "model.json"
    save_inertial(cal, model, report=False)
    other = simulate_inertial(dataclasses.replace(cfg, seed=99, tf_imu="none")).log_
    ev = evaluate_inertial(other, json.loads(model.read_text()), model)
    for sensor in ("gyro", "gnss"):
        assert 0.85 <= ev["consistency"][sensor]["coverage90"] <= 0.95, ev


def _bag_with(tmp_path, edit) -> object:
    """A 60-s simulated bag whose messages ``edit`` changes (messages: (topic, type, ns, msg) rows)."""
    from sensact.io import rosbag_write as rw

    run = simulate_inertial(InertialConfig(seconds=60, seed=4))
    captured = {}
    real = rw.write_bag

    def capture(path, fmt, messages, m, empty=()):
        captured["m"] = m
        return real(path, fmt, edit(messages, m), m, empty)

    rw.write_bag = capture
    try:
        return rw.write_inertial_bag(tmp_path / "bad.bag", "ros1", run)
    finally:
        rw.write_bag = real


def test_bad_bags_are_refused_or_flagged_in_one_line(tmp_path):
    pytest.importorskip("rosbags")

    def nan_covariance(msgs, m):
        for topic, _, _, msg in msgs:
            if topic == "/imu/data":
                msg.angular_velocity_covariance[:] = np.nan
        return msgs

    bag = _bag_with(tmp_path, nan_covariance)
    res = _run(["convert", "bag", bag, "--out", tmp_path / "a"])
    assert "NaN angular velocity covariance: ignored" in res.output

    def no_fix(msgs, m):
        for topic, _, _, msg in msgs:
            if topic == "/gps/fix":
                msg.status.status = -1
        return msgs

    # a receiver that never had a fix (a Jackal indoors): left out and said so; named with --gnss, refused
    no_fix_bag = _bag_with(tmp_path / "b", no_fix)
    res = _run(["convert", "bag", no_fix_bag, "--out", tmp_path / "b_out"])
    assert "fixes (status >= 0)" in res.output and "learned without GNSS" in " ".join(res.output.split())
    assert not (tmp_path / "b_out" / "gnss.csv").exists()
    assert "gnss" not in json.loads((tmp_path / "b_out" / "meta.json").read_text())["topics"]
    res = _run(["convert", "bag", no_fix_bag, "--gnss", "/gps/fix", "--out", tmp_path / "b_named"], code=2)
    assert "fixes (status >= 0)" in res.output and "Traceback" not in res.output

    def some_no_fix(msgs, m):
        fixes = [msg for topic, _, _, msg in msgs if topic == "/gps/fix"]
        for msg in fixes[::7]:
            msg.status.status = -1
        return msgs

    res = _run(["convert", "bag", _bag_with(tmp_path / "c", some_no_fix), "--out", tmp_path / "c_out"])
    assert "have no fix (status -1 or NaN): dropped" in res.output

    def datum_jump(msgs, m):
        fixes = [msg for topic, _, _, msg in msgs if topic == "/gps/fix"]
        for msg in fixes[len(fixes) // 2 :]:
            msg.latitude += 0.01  # a kilometre north, and it stays
        return msgs

    res = _run(["convert", "bag", _bag_with(tmp_path / "d", datum_jump), "--out", tmp_path / "d_out"], code=2)
    assert "leap" in res.output and "datum" in res.output


def test_a_log_that_never_moves_exits_3(tmp_path):
    _run(["simulate", "outdoor", "--out", tmp_path / "still", "--seconds", 40, "--set", "speed_m_s=0", "--set",
          "turn_rad_s=0"])  # fmt: skip
    res = _run(["learn", "em", tmp_path / "still", "--out", tmp_path / "m.json"], code=3)
    assert "no_motion" in res.output


def test_the_door_knows_the_kind_and_refuses_em_options(tmp_path):
    from sensact.app.log_kinds import kind_of

    _run(["simulate", "outdoor", "--out", tmp_path / "run", "--seconds", 30])
    assert kind_of(tmp_path / "run").name == "imu_gnss"
    res = _run(["learn", "em", tmp_path / "run", "--preset", "thesis_aibo", "--out", tmp_path / "m.json"], code=2)
    assert "--preset is for EM's landmark logs" in res.output


def test_a_folder_with_an_empty_cell_is_refused(tmp_path):
    _run(["simulate", "outdoor", "--out", tmp_path / "run", "--seconds", 30])
    imu = tmp_path / "run" / "imu.csv"
    lines = imu.read_text().splitlines()
    cells = lines[5].split(",")
    cells[2] = ""
    lines[5] = ",".join(cells)
    imu.write_text("\n".join(lines) + "\n")
    res = _run(["learn", "em", tmp_path / "run", "--out", tmp_path / "m.json"], code=2)
    assert "imu.csv" in res.output and "row 6" in res.output


def test_a_husky_bag_s_fused_topics_are_passed_over_for_the_sensors_own():
    """robot_localization's /odometry/filtered, navsat_transform's /odometry/gps and /gps/filtered share the
    sensors' types: the roles go to the wheels', the IMU's and the receiver's own topics; two wheel-odometry
    topics nothing tells apart are refused, naming both."""
    from pathlib import Path

    from sensact.io.rosbag import Topic
    from sensact.io.rosbag_inertial import inertial_roles

    odom, imu, fix = "nav_msgs/Odometry", "sensor_msgs/Imu", "sensor_msgs/NavSatFix"
    husky = [
        Topic("/husky_velocity_controller/odom", odom, 10),
        Topic("/odometry/filtered", odom, 10),
        Topic("/odometry/gps", odom, 10),
        Topic("/imu/data", imu, 10),
        Topic("/imu/data_raw", imu, 10),
        Topic("/navsat/fix", fix, 10),
        Topic("/gps/filtered", fix, 10),
    ]
    roles = inertial_roles(Path("husky.bag"), husky, {})
    assert (roles.odom, roles.imu, roles.gnss) == ("/husky_velocity_controller/odom", "/imu/data_raw", "/navsat/fix")
    assert inertial_roles(Path("h.bag"), husky, {"odom": "/odometry/filtered"}).odom == "/odometry/filtered"
    with pytest.raises(LogFormatError, match="/a/odom, /b/odom"):
        inertial_roles(Path("two.bag"), [Topic("/a/odom", odom, 10), Topic("/b/odom", odom, 10), husky[3]], {})


def test_an_imu_whose_driver_took_gravity_out_is_levelled_by_its_orientation(tmp_path):
    """Roll and pitch come from gravity; a driver that publishes accelerations without it (or in g) and no
    orientation is refused in one line with the fix; with the orientation it reports (read from the bag's
    sensor_msgs/Imu, kept in imu.csv), the mount is learned within the bar."""
    truth = InertialConfig().imu_rpy_rad
    for sets, said in [
        (["accel=no_gravity"], "the driver took gravity out"),
        (["accel=g"], "gravity in g, not m/s^2"),
        (["accel=no_gravity", "imu_orientation=true"], None),
    ]:
        name = "_".join(sets).replace("=", "-")
        flags = [a for s in sets for a in ("--set", s)]
        bag, out = tmp_path / f"{name}.bag", tmp_path / name
        _run(["simulate", "outdoor", "--out", tmp_path / f"sim_{name}", "--seconds", 150, "--bag", bag, *flags])
        _run(["convert", "bag", bag, "--out", out])
        if said is not None:
            res = _run(["learn", "em", out, "--no-report"], code=2)
            text = " ".join(res.output.split())
            assert said in text and "Fix:" in text and "Traceback" not in text
            continue
        assert "orientation_w" in (out / "imu.csv").read_text().splitlines()[0]
        _run(["learn", "em", out, "--out", tmp_path / "m.json", "--no-report"])
        mount = json.loads((tmp_path / "m.json").read_text())["imu"]["mount"]
        got = [mount[k] for k in ("roll_rad", "pitch_rad", "yaw_rad")]
        assert np.abs(np.angle(np.exp(1j * (np.array(got) - truth)))).max() < BARS["imu.mount.roll_rad"]


def test_the_halves_agree_and_the_first_holds_on_the_second(husky):
    """`learn em --halves`'s check without ground truth: each half learned alone gives the robot's constants
    within 3 combined sd of the other's, and the first half's model scored on the second is honest; the
    heading offset, the odometry frame's at each half's start, is the run's, not held to agreeing."""
    from sensact.app.inertial import halves_inertial

    _, _, cal = husky
    doc = halves_inertial(cal)
    assert doc["agree_within_3sd"], (doc["worst"], doc["differ_sd"])
    held = {k: z for k, z in doc["differ_sd"].items() if k not in doc["run_keys"]}
    assert "odometry.gain_turn" in held and "imu.mount.yaw_rad" in held and "gnss.lever_arm.left_mm" in held
    assert all(abs(z) <= 3 for z in held.values())
    cons = doc["first_on_second"]["consistency"]
    assert 0.8 <= cons["gyro"]["coverage90"] <= 0.97 and 0.8 <= cons["gnss"]["coverage90"] <= 0.97
    assert doc["cut_s"] == pytest.approx(150, abs=1)


@pytest.mark.slow
def test_halves_through_the_cli_are_written_into_the_model(tmp_path):
    _run(["simulate", "outdoor", "--out", tmp_path / "run", "--seconds", 90])
    _run(["learn", "em", tmp_path / "run", "--out", tmp_path / "m.json", "--no-report", "--halves"])
    doc = json.loads((tmp_path / "m.json").read_text())
    assert set(doc["halves"]) >= {"first_half", "second_half", "differ_sd", "agree_within_3sd", "first_on_second"}
    assert doc["halves"]["first_half"]["odometry.gain_turn"]["sd"] > 0


@pytest.mark.parametrize("every, code", [(250, 0), (20, 2)])
def test_a_stamp_repeated_now_and_then_is_dropped_and_often_is_refused(tmp_path, every, code):
    """A driver that repeats an IMU stamp now and then (a serial link's hiccup): those messages are dropped and
    counted; one that does it every 20th message has a clock to fix, refused naming the message."""

    def repeat_stamps(msgs, m):
        imu = [msg for topic, _, _, msg in msgs if topic == "/imu/data"]
        for prev, msg in list(itertools.pairwise(imu))[::every]:
            msg.header.stamp = prev.header.stamp
        return msgs

    res = _run(["convert", "bag", _bag_with(tmp_path, repeat_stamps), "--out", tmp_path / "o"], code=code)
    text = " ".join(res.output.split())
    if code == 0:
        assert "repeat or precede an earlier stamp: dropped" in text
        learned = runner.invoke(app, ["learn", "em", str(tmp_path / "o"), "--no-report"])
        assert learned.exit_code in (0, 3), learned.output  # a minute's log may be flagged; never refused
    else:
        assert "stamp is not after" in text and "--receive-times" in text


def test_a_folder_of_unix_times_learns_what_the_same_from_zero_learns(tmp_path):
    """Every table 1.7e9 s later (a robot's own CSVs in Unix time): read exactly from the odometry's first
    whole second, the same model comes out."""
    from decimal import Decimal

    _run(["simulate", "outdoor", "--out", tmp_path / "zero", "--seconds", 60, "--set", "gnss_hz=0"])
    epoch = tmp_path / "epoch"
    epoch.mkdir()
    for f in (tmp_path / "zero").iterdir():
        text = f.read_text()
        if f.suffix == ".csv":
            head, *rows = text.splitlines()
            rows = [f"{Decimal(r.split(',', 1)[0]) + 1_700_000_000},{r.split(',', 1)[1]}" for r in rows]
            text = "\n".join([head, *rows]) + "\n"
        (epoch / f.name).write_text(text)
    docs = []
    for name in ("zero", "epoch"):
        res = runner.invoke(app, ["learn", "em", str(tmp_path / name), "--out", str(tmp_path / f"{name}.json"),
                                  "--no-report"])  # fmt: skip
        assert res.exit_code in (0, 3), res.output
        docs.append(json.loads((tmp_path / f"{name}.json").read_text()))
    for part in ("odometry", "imu"):
        assert json.dumps(docs[0][part], sort_keys=True) == json.dumps(docs[1][part], sort_keys=True)
