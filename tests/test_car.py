"""Car-like robots (docs/ackermann.md): the bicycle's curvature, the VESC's numbers, the wheelbase and the lidar's mount
learned from a simulated F1TENTH car's bag through `convert bag` and `learn em`, the exports, and the refusals."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from sensact.cli import app
from sensact.core.pose_models import arc_poses
from sensact.io.car_folder import read_car_log, write_car_log
from sensact.learn.car_lidar import along_arcs, bend, learn_car_lidar, shadow_edges, steering
from sensact.sim.car import CarConfig, simulate_car

runner = CliRunner()


def _run(args, code=0):
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == code, res.output
    return res


def test_bend_is_the_tangent_and_the_hyperbolic_tangent_and_smooth_through_zero():
    x = np.linspace(-0.6, 0.6, 13)
    g = 1.2
    assert np.allclose(bend(x, 1 / g**2), g * np.tan(x / g), rtol=1e-12)
    assert np.allclose(bend(x, -1 / g**2), g * np.tanh(x / g), rtol=1e-12)
    assert np.array_equal(bend(x, 0.0), x)
    # the series and the closed form agree where they meet: no step in u for the fit to stick on
    for u in (1e-4 / 0.36 * 0.999, 1e-4 / 0.36 * 1.001):
        xx = np.array([0.6])
        exact = np.tan(xx * math.sqrt(u)) / math.sqrt(u)
        assert bend(xx, u)[0] == pytest.approx(exact[0], rel=1e-10)


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_poses_between_steps_lie_on_the_steps_arcs(direction):
    """Exact reduction: a path of 40 arcs read at 400 times is the same path driven in 400 steps (forward and in
    reverse), which a chord between steps is not."""
    coarse = arc_poses(np.full(40, 50.0 * direction), np.full(40, 0.07))
    fine = arc_poses(np.full(400, 5.0 * direction), np.full(400, 0.007))
    got = along_arcs(np.arange(41) * 0.02, coarse, np.arange(401) * 0.002)
    assert np.abs(got - fine).max() < 1e-9
    chord = np.column_stack([np.interp(np.arange(401) * 0.002, np.arange(41) * 0.02, coarse[:, c]) for c in range(3)])
    assert np.abs(chord - fine)[:, :2].max() > 0.1  # mm: what the deskew got wrong before


def test_shadow_edges_are_the_beams_beside_a_jump_in_range():
    r = np.array([1000.0, 1001, 1002, 3000, 3001, 3002, 3003, np.nan, 3004, 3005])
    assert shadow_edges(r, 1).tolist() == [False, False, True, True, False, False, True, True, True, False]


def test_a_noise_free_car_gives_back_its_numbers():
    """Seeded recovery: no noise, no delays, no lag: every number to a fraction of its bar."""
    cfg = CarConfig(
        seconds=45, seed=3, slip_sd=0.0, range_sd_mm=0.0, erpm_sd=0.0, steering_delay_s=0.0, erpm_delay_s=0.0,
        motor_lag_s=0.0,
    )  # fmt: skip
    res = learn_car_lidar(simulate_car(cfg).log())
    p = res.fit.params
    st = steering(p, res.fit.cov)
    assert p[0] == pytest.approx(cfg.speed_to_erpm_gain, rel=2e-3)
    assert p[3] == pytest.approx(cfg.steering_angle_to_servo_offset, abs=2e-4)
    assert st.product == pytest.approx(cfg.steering_angle_to_servo_gain * cfg.wheelbase_m, rel=2e-3)
    assert st.wheelbase_m == pytest.approx(cfg.wheelbase_m, rel=0.01)
    assert np.allclose(p[5:7], cfg.mount[:2], atol=1.0) and p[7] == pytest.approx(cfg.mount[2], abs=1e-3)


@pytest.fixture(scope="module")
def car_route(tmp_path_factory):
    """A simulated F1TENTH car (60 s) through the user's route: simulate --bag (ROS 1), convert bag, learn em."""
    root = tmp_path_factory.mktemp("car")
    _run(["simulate", "ackermann", "--out", root / "sim", "--seconds", "60", "--seed", "2", "--bag", root / "car.bag"])
    _run(["convert", "bag", root / "car.bag", "--out", root / "log"])
    res = _run_any(["learn", "em", root / "log", "--out", root / "model.json"])
    truth = json.loads((root / "sim" / "meta.json").read_text())["truth"]
    return root, json.loads((root / "model.json").read_text()), truth, res


def _run_any(args):
    return runner.invoke(app, [str(a) for a in args])


def test_the_bag_route_learns_the_vesc_numbers_and_the_mount_within_the_bars(car_route):
    root, doc, truth, res = car_route
    assert res.exit_code in (0, 3), res.output
    v, c, m = doc["vesc"], doc["car"], doc["lidar"]["mount"]
    tv, tm = truth["vesc"], truth["lidar"]["mount"]
    assert doc["kind"] == "car"
    gain = v["speed_to_erpm_gain"]
    assert abs(gain / tv["speed_to_erpm_gain"] - 1) <= 0.01
    assert abs(gain - tv["speed_to_erpm_gain"]) <= 3 * v["speed_to_erpm_gain_sd"]
    product = tv["steering_angle_to_servo_gain"] * truth["car"]["wheelbase_mm"] / 1000
    assert abs(c["steering_gain_times_wheelbase_m"] / product - 1) <= 0.02
    for k, bar in (("forward_mm", 10.0), ("left_mm", 10.0), ("yaw_rad", math.radians(0.5))):
        assert abs(m[k] - tm[k]) <= bar and abs(m[k] - tm[k]) <= 3 * m[k + "_sd"], (k, m[k], tm[k])
    # straight ahead by the log's own yaml (from /drive against the servo), through the learned numbers
    ahead = c["straight_ahead"]
    assert ahead["yaml_servo_offset"] == pytest.approx(truth["yaml"]["steering_angle_to_servo_offset"], abs=1e-3)
    true_deg = math.degrees(
        (truth["yaml"]["steering_angle_to_servo_offset"] - tv["steering_angle_to_servo_offset"])
        / tv["steering_angle_to_servo_gain"]
    )
    assert abs(ahead["wheel_angle_deg"] - true_deg) <= 0.3
    assert c["steering_delay_s"] == pytest.approx(truth["car"]["steering_delay_s"], abs=0.01)
    flags = {f["code"] for f in doc["health"]["flags"]}
    if "wheelbase_not_identified" not in flags:  # else flagged, exit 3: the bar allows it
        assert abs(c["wheelbase_mm"] / truth["car"]["wheelbase_mm"] - 1) <= 0.02
    assert (res.exit_code == 3) == bool(flags)
    for png in ("model_scans.png", "model_steering.png", "model_residuals.png", "report.html"):
        assert (root / png).stat().st_size > 5000


def test_the_yaml_the_log_was_driven_with_is_read_off_drive_and_odom(car_route):
    """Before and after: /drive against the servo gives the old servo numbers, /odom against the ERPM the old speed
    numbers, /odom's turn rate the wheelbase vesc_to_odom used (the simulator's own)."""
    _, doc, truth, _ = car_route
    old, yaml_ = doc["car"]["yaml_before"], truth["yaml"]
    for k in ("speed_to_erpm_gain", "steering_angle_to_servo_gain"):
        assert old[k] == pytest.approx(yaml_[k], rel=2e-3), k
    assert old["steering_angle_to_servo_offset"] == pytest.approx(yaml_["steering_angle_to_servo_offset"], abs=1e-3)
    assert old["speed_to_erpm_offset"] == pytest.approx(yaml_["speed_to_erpm_offset"], abs=20.0)
    assert old["wheelbase_mm"] == pytest.approx(truth["car"]["wheelbase_mm"], rel=0.01)


def test_a_car_bag_is_not_taken_for_a_differential_drive(car_route):
    root, *_ = car_route
    meta = json.loads((root / "log" / "meta.json").read_text())
    assert meta["kind"] == "car"
    assert meta["urdf"]["lidar_mount"]["forward_mm"] == pytest.approx(270.0)  # /tf_static's, kept to compare


def test_ros1_and_mcap_bags_of_one_run_convert_to_the_same_log(tmp_path):
    """The bag's own message definitions (a ROS 1 connection header, an MCAP schema) read alike."""
    from sensact.io.rosbag_write import write_car_bag

    run = simulate_car(CarConfig(seconds=15, seed=2))
    logs = []
    for fmt in ("ros1", "mcap"):
        bag = write_car_bag(tmp_path / f"bag_{fmt}", fmt, run)
        _run(["convert", "bag", bag, "--out", tmp_path / fmt])
        logs.append(read_car_log(tmp_path / fmt))
    a, b = logs
    for field in ("scan_t", "erpm_t", "erpm", "servo_t", "servo", "drive_t", "drive"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert np.array_equal(a.ranges_mm, b.ranges_mm, equal_nan=True)
    assert np.allclose(a.erpm, run.erpm) and np.allclose(a.servo, run.servo)


def test_export_vesc_loads_as_yaml_with_the_four_keys_finite(car_route):
    root, doc, *_ = car_route
    out = root / "model.vesc.yaml"
    res = _run_any(["export", root / "model.json", "--format", "vesc", "--out", out, "--force"])
    assert res.exit_code in (0, 3), res.output
    loaded = yaml.safe_load(out.read_text())
    for k in ("speed_to_erpm_gain", "speed_to_erpm_offset", "steering_angle_to_servo_gain",
              "steering_angle_to_servo_offset", "wheelbase"):  # fmt: skip
        assert math.isfinite(loaded[k]), k
    assert loaded["speed_to_erpm_gain"] == pytest.approx(doc["vesc"]["speed_to_erpm_gain"], rel=1e-6)
    urdf = root / "model.urdf.xacro"
    _run_any(["export", root / "model.json", "--format", "urdf", "--out", urdf, "--force"])
    assert f'xyz="{doc["lidar"]["mount"]["forward_mm"] / 1000:.6f}' in urdf.read_text()


def test_gentle_curves_flag_the_wheelbase_or_still_get_it_and_the_product_holds(tmp_path):
    """On a track three times larger only the steering gain times the wheelbase shows."""
    run = simulate_car(CarConfig(seconds=45, seed=1, scale=3.0))
    write_car_log(tmp_path / "log", run.log(str(tmp_path / "log")))
    res = _run_any(["learn", "em", tmp_path / "log", "--out", tmp_path / "m.json"])
    doc = json.loads((tmp_path / "m.json").read_text())
    cfg = run.config
    flags = {f["code"] for f in doc["health"]["flags"]}
    if "wheelbase_not_identified" in flags:
        assert res.exit_code == 3
    else:
        assert abs(doc["car"]["wheelbase_mm"] / (cfg.wheelbase_m * 1000) - 1) <= 0.02
    product = cfg.steering_angle_to_servo_gain * cfg.wheelbase_m
    assert abs(doc["car"]["steering_gain_times_wheelbase_m"] / product - 1) <= 0.02


@pytest.fixture(scope="module")
def short_car(tmp_path_factory):
    root = tmp_path_factory.mktemp("short_car")
    run = simulate_car(CarConfig(seconds=30, seed=4))
    return write_car_log(root / "log", run.log(str(root / "log")))


def test_a_servo_that_never_moves_is_refused_in_one_line(short_car, tmp_path):
    log = tmp_path / "log"
    shutil.copytree(short_car, log)
    rows = (log / "servo.csv").read_text().splitlines()
    (log / "servo.csv").write_text("\n".join([rows[0]] + [r.split(",")[0] + ",0.5" for r in rows[1:]]) + "\n")
    res = _run(["learn", "em", log], code=2)
    assert "the servo's command never moves" in " ".join(res.output.split())
    assert len(res.output.strip().splitlines()) == 2  # the log's description, then the one line


def test_a_car_that_never_steers_is_refused(short_car, tmp_path):
    """The first seconds run down the first straight corridor: no turn to learn the steering from."""
    log = read_car_log(short_car)
    keep = log.scan_t < 6.0
    from dataclasses import replace

    straight = replace(log, scan_t=log.scan_t[keep], ranges_mm=log.ranges_mm[keep], truth=None)
    write_car_log(tmp_path / "log", straight)
    res = _run(["learn", "em", tmp_path / "log"], code=2)
    assert "the car never steered" in " ".join(res.output.split())


def test_erpm_of_the_other_sign_is_flagged_and_still_learned(tmp_path):
    cfg = CarConfig(seconds=20, seed=4, speed_to_erpm_gain=-4614.0, yaml_speed_gain=-4380.0)
    write_car_log(tmp_path / "log", simulate_car(cfg).log(str(tmp_path / "log")))
    _run(["learn", "em", tmp_path / "log", "--out", tmp_path / "m.json"], code=3)
    doc = json.loads((tmp_path / "m.json").read_text())
    assert "erpm_sign_reversed" in {f["code"] for f in doc["health"]["flags"]}
    assert doc["vesc"]["speed_to_erpm_gain"] == pytest.approx(-4614.0, rel=0.01)


def test_a_car_bag_without_a_servo_topic_is_refused_naming_it(tmp_path):
    from sensact.errors import LogFormatError
    from sensact.io.rosbag import Topic
    from sensact.io.rosbag_car import car_roles, is_car_bag

    topics = [
        Topic("/scan", "sensor_msgs/LaserScan", 10),
        Topic("/sensors/core", "vesc_msgs/VescStateStamped", 10),
        Topic("/drive", "ackermann_msgs/AckermannDriveStamped", 10),
    ]
    assert is_car_bag(topics)
    with pytest.raises(LogFormatError, match="servo_position_command"):
        car_roles(tmp_path / "x.bag", topics, {})
    topics.append(Topic("/sensors/servo_position_command", "std_msgs/Float64", 10))
    roles = car_roles(tmp_path / "x.bag", topics, {})
    assert (roles.scan, roles.vesc, roles.servo, roles.drive) == (
        "/scan", "/sensors/core", "/sensors/servo_position_command", "/drive"
    )  # fmt: skip


def test_a_full_f1tenth_stack_gets_its_roles_without_naming_them(tmp_path):
    """Two servo topics (the command and the driver's echo), the mux's inputs and output, a particle filter's odometry
    beside vesc_to_odom's: the ones the VESC driver used, or none for an optional role nothing decides."""
    from sensact.io.rosbag import Topic
    from sensact.io.rosbag_car import car_roles

    topics = [
        Topic("/scan", "sensor_msgs/LaserScan", 10),
        Topic("/vesc/sensors/core", "vesc_msgs/VescStateStamped", 10),
        Topic("/vesc/commands/servo/position", "std_msgs/Float64", 10),
        Topic("/vesc/sensors/servo_position_command", "std_msgs/Float64", 10),
        Topic("/vesc/high_level/ackermann_cmd_mux/input/nav_0", "ackermann_msgs/AckermannDriveStamped", 10),
        Topic("/vesc/low_level/ackermann_cmd", "ackermann_msgs/AckermannDriveStamped", 10),
        Topic("/vesc/odom", "nav_msgs/Odometry", 10),
        Topic("/pf/pose/odom", "nav_msgs/Odometry", 10),
    ]
    roles = car_roles(tmp_path / "x.bag", topics, {})
    assert (roles.servo, roles.drive, roles.odom) == (
        "/vesc/sensors/servo_position_command", "/vesc/low_level/ackermann_cmd", "/vesc/odom"
    )  # fmt: skip
    two = [t for t in topics if "ackermann" not in t.name and "odom" not in t.name]
    two += [
        Topic("/a", "ackermann_msgs/AckermannDriveStamped", 5),
        Topic("/b", "ackermann_msgs/AckermannDriveStamped", 5),
    ]
    assert car_roles(tmp_path / "x.bag", two, {}).drive is None
