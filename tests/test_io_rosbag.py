"""``sensact convert bag``: bags written by rosbags' writers from timed tables convert to the log folders the
same tables give through ``convert csv`` and ``convert track``, and learn the same models bit for bit; a
bad bag gets one line."""

from __future__ import annotations

import json
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import CAPPED, DATA, assert_written, require, write_csv
from sensact.cli import app
from sensact.io.rosbag_write import FORMATS, Msgs, recording_of, write_bag, write_map_csv, write_robot_bag
from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

pytest.importorskip("rosbags", reason="the ros extra (pip install 'sensact[ros]') reads bags")
runner = CliRunner()
SHORT = ("thesis.max_iterations=40", "search.start_candidates=2")  # the same run either way: a short one will do
T0_NS = 1_700_000_000 * 10**9  # a wall clock's epoch time, as a real bag's


def _seconds(ns):
    """Whole nanoseconds as the nearest float of seconds (what a CSV of 9-place decimal times reads as)."""
    return np.array([float(Fraction(int(n), 10**9)) for n in ns])


def _ok(args, allowed=CAPPED):
    res = runner.invoke(app, [str(a) for a in args])
    assert_written(res, allowed)
    return res


def _learned(folder, out, *sets):
    """The model ``learn em`` writes, less the time it took and the folder's name."""
    # the two routes are compared, flags and all: a flag is the same on both
    _ok(["learn", "em", folder, "--out", out, *(a for s in sets for a in ("--set", s))], allowed=None)
    doc = json.loads(out.read_text())
    del doc["summary"]["seconds"], doc["log"]
    return doc


@pytest.fixture(scope="module")
def diffdrive_source(tmp_path_factory):
    """A simulated differential drive (two minutes, the camera 220 mm ahead) as a ROS robot records it
    (``recording_of``), and the timed CSVs of the same numbers: a tag's range and bearing are its
    position's in the ground plane (the optical frame's z forward, x right), times whole nanoseconds."""
    run = simulate_diffdrive(DiffDriveConfig(seconds=120.0, seed=3, mounted_at=(220.0, 0.0, 0.0)))
    rec = recording_of(run)
    folder = tmp_path_factory.mktemp("bag_source")
    x, z = rec.tag_xyz_optical_m[:, 0], rec.tag_xyz_optical_m[:, 2]
    csv = {
        "commands": write_csv(
            folder / "commands.csv", {"t_s": _seconds(rec.cmd_ns), "v_m_s": rec.v_m_s, "omega_rad_s": rec.omega_rad_s}
        ),
        "sightings": write_csv(
            folder / "sightings.csv",
            {
                "t_s": _seconds(rec.tag_ns),
                "landmark_id": rec.tag_id,
                "range_m": np.hypot(z, -x),
                "bearing_rad": np.arctan2(-x, z),
            },
        ),
        "landmarks": write_map_csv(folder / "map.csv", rec.map_xy_m),
    }
    return csv, rec


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_bag_converts_to_the_tables_it_was_made_from(diffdrive_source, tmp_path, fmt):
    """Each format, no mapping given: the roles are found, the camera placed by /tf_static, and the
    commands and sightings read back as the CSVs' numbers exactly; truth to rounding of its quaternion."""
    csv, rec = diffdrive_source
    bag = write_robot_bag(tmp_path / "run", fmt, rec)
    out = tmp_path / "log"
    _ok(["convert", "bag", bag, "--landmarks", csv["landmarks"], "--out", out])
    from sensact.io.csvtable import read_numeric_csv

    for name in ("commands", "sightings"):
        _same_rows(read_numeric_csv(out / "bag_tables" / f"{name}.csv"), read_numeric_csv(csv[name]))
    truth = read_numeric_csv(out / "bag_tables" / "truth.csv")
    np.testing.assert_array_equal(truth["x_m"], rec.truth_xy_m[:, 0])
    wrapped = np.angle(np.exp(1j * (truth["theta_rad"] - rec.truth_yaw_rad)))
    assert np.abs(wrapped).max() < 1e-12
    meta = json.loads((out / "meta.json").read_text())
    assert meta["source"]["roles"] == {
        "commands": "/cmd_vel",
        "sightings": "/tf",
        "truth": "/mocap/pose",
    }
    mount = meta["source"]["tf_static_mount"]
    assert mount["x_m"] == pytest.approx(0.22) and mount["y_m"] == pytest.approx(0.0, abs=1e-12)
    assert mount["yaw_rad_applied"] == pytest.approx(0.0, abs=1e-12)


def test_ros1_apriltag_detections_read_as_the_tf_sightings(diffdrive_source, tmp_path):
    """ROS 1's apriltag_ros/AprilTagDetectionArray, its definition read from the bag, gives the sightings
    the transforms on /tf give."""
    csv, rec = diffdrive_source
    bag = write_robot_bag(tmp_path / "run", "ros1", rec, detections=True)
    out = tmp_path / "log"
    _ok(["convert", "bag", bag, "--landmarks", csv["landmarks"], "--out", out])
    from sensact.io.csvtable import read_numeric_csv

    _same_rows(read_numeric_csv(out / "bag_tables" / "sightings.csv"), read_numeric_csv(csv["sightings"]))


def _same_rows(got, want):
    """The same columns and the same rows, bit for bit, in any order (a bag is in the order recorded)."""
    assert list(got) == list(want)
    rows = [np.column_stack([t[k] for k in t]) for t in (got, want)]
    rows = [r[np.lexsort(r.T[::-1])] for r in rows]
    np.testing.assert_array_equal(rows[0], rows[1])


def test_learning_from_a_bag_gives_the_model_learned_from_its_csvs(diffdrive_source, tmp_path):
    """The bag route and the CSV route learn the same model, bit for bit (an MCAP bag; the formats' tables
    are checked equal above)."""
    csv, rec = diffdrive_source
    bag = write_robot_bag(tmp_path / "run", "mcap", rec)
    _ok(["convert", "bag", bag, "--landmarks", csv["landmarks"], "--out", tmp_path / "from_bag"])
    truth = write_csv(
        tmp_path / "truth.csv",
        {k: v for k, v in zip(("t_s", "x_m", "y_m", "theta_rad"), _truth_columns(tmp_path / "from_bag"), strict=True)},
    )
    _ok(
        [
            "convert", "csv", "--commands", csv["commands"], "--sightings", csv["sightings"],
            "--landmarks", csv["landmarks"], "--truth", truth, "--out", tmp_path / "from_csv",
        ]
    )  # fmt: skip
    a = _learned(tmp_path / "from_bag", tmp_path / "a.json", *SHORT)
    assert a == _learned(tmp_path / "from_csv", tmp_path / "b.json", *SHORT)


def _truth_columns(log):
    from sensact.io.csvtable import read_numeric_csv

    t = read_numeric_csv(log / "bag_tables" / "truth.csv")
    return t["t_s"], t["x_m"], t["y_m"], t["theta_rad"]


def test_a_bag_with_two_command_sources_lists_its_topics_and_writes_nothing(tmp_path):
    """... until a mapping names the one that drives the robot."""
    m = Msgs("mcap")
    msgs = []
    for k in range(20):
        t = T0_NS + k * 10**8
        msgs += [
            ("/cmd_vel", "geometry_msgs/msg/Twist", t, m.twist(0.0, 0.0)),
            ("/teleop/cmd_vel", "geometry_msgs/msg/Twist", t + 1, m.twist(0.1 if k < 10 else -0.1, 0.0)),
            ("/sonar", "sensor_msgs/msg/Range", t + 2, m.range(t, 1.0 + 0.01 * k)),
        ]
    bag = write_bag(tmp_path / "two", "mcap", msgs, m)
    res = runner.invoke(app, ["convert", "bag", str(bag), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2
    text = " ".join(res.output.split())
    assert "commands: one of /cmd_vel, /teleop/cmd_vel" in text and "--commands TOPIC" in text
    assert "/teleop/cmd_vel geometry_msgs/Twist (20 messages)" in text
    assert not (tmp_path / "o").exists()
    (tmp_path / "roles.yaml").write_text("commands: /teleop/cmd_vel\nreadings: /sonar\n")
    res = runner.invoke(
        app, ["convert", "bag", str(bag), "--mapping", str(tmp_path / "roles.yaml"), "--out", str(tmp_path / "o")]
    )
    meta = json.loads((tmp_path / "o" / "meta.json").read_text())
    assert meta["source"]["roles"] == {"commands": "/teleop/cmd_vel", "readings": ["/sonar"]}


@pytest.mark.parametrize(
    "case, words",
    [
        ("not_a_bag", "reading it record by record failed too (no connection record"),
        ("no_such_topic", "no topic /nope (truth); the bag has"),
        ("wrong_type", "/cmd_vel is a geometry_msgs/Twist, which sensact cannot read as truth"),
        ("backwards", "/sonar's clock goes backwards"),
        ("two_clocks", "/truth's stamps are 3600 s later against the recording clock than /sonar's"),
        ("empty", "/empty (truth) has no messages"),
        ("nan_twist", "/cmd_vel: message 6's twist is not a finite number (1 such messages)"),
        ("inf_pose", "/truth: message 3's pose is not a finite number"),
        ("zero_quaternion", "/truth: message 1's orientation (0, 0, 0, 0) is not a unit quaternion"),
        ("no_range_in_span", "/sonar: 1 of its 20 ranges lie within their message's [min_range, max_range]"),
    ],
)
def test_a_bad_bag_gets_one_line(tmp_path, case, words):
    m = Msgs("sqlite3")
    t = T0_NS
    v = [float("nan") if case == "nan_twist" and k == 5 else 0.1 for k in range(20)]
    msgs = [("/cmd_vel", "geometry_msgs/msg/Twist", t + k * 10**8, m.twist(v[k], 0.0)) for k in range(20)]
    stamps = [t + k * 10**8 for k in range(20)]
    if case in ("inf_pose", "zero_quaternion"):  # a motion capture that lost the robot, or never set w
        poses = [m.pose_stamped(t + k * 10**8, 0.1 * k, 0.0, 0.0) for k in range(5)]
        poses[2].pose.position.x = float("inf") if case == "inf_pose" else 0.2
        poses[0].pose.orientation.w = 0.0 if case == "zero_quaternion" else 1.0
        msgs += [("/truth", "geometry_msgs/msg/PoseStamped", t + k * 10**8 + 2, p) for k, p in enumerate(poses)]
    if case == "backwards":
        stamps[10] = t
    if case == "two_clocks":  # two stamped topics an hour apart: no shift puts both on the commands' clock
        msgs += [
            ("/truth", "geometry_msgs/msg/PoseStamped", t + k, m.pose_stamped(t + k + 3600 * 10**9, 0, 0, 0))
            for k in range(5)
        ]
    ranges = [1.0 if case != "no_range_in_span" or k == 0 else 9.0 for k in range(20)]  # 9 m: beyond max_range
    msgs += [
        ("/sonar", "sensor_msgs/msg/Range", t + k * 10**8 + 1, m.range(s, ranges[k])) for k, s in enumerate(stamps)
    ]
    bag = write_bag(tmp_path / "b", "sqlite3", msgs, m, empty=(("/empty", "geometry_msgs/msg/PoseStamped"),))
    args = ["convert", "bag", str(bag), "--out", str(tmp_path / "o")]
    if case == "not_a_bag":
        (tmp_path / "x.bag").write_bytes(b"#ROSBAG V2.0\nnot really")
        args[2] = str(tmp_path / "x.bag")
    if case == "no_such_topic":
        args += ["--truth", "/nope"]
    if case == "wrong_type":
        args += ["--truth", "/cmd_vel"]
    if case == "empty":
        args += ["--truth", "/empty"]
    if case in ("two_clocks", "inf_pose", "zero_quaternion"):
        args += ["--truth", "/truth"]
    res = runner.invoke(app, args)
    text = " ".join(res.output.split())
    assert res.exit_code == 2 and words in text and "Traceback" not in text, text


@pytest.mark.realdata
@pytest.mark.parametrize("fmt", FORMATS)
def test_turtlebot_bag_learns_the_model_its_track_csv_learns(tmp_path, fmt):
    """The real Turtlebot log as a 1-D robot's bag (Twist commands, two sonars as sensor_msgs/Range, the
    recorded distance as a motion-capture pose facing a wall at the origin) converts, in each format, to
    the track CSV it was made from, and learns the same EM model, bit for bit (learned from one format:
    the tables are the same)."""
    from sensact.io.csvtable import read_numeric_csv

    log = read_numeric_csv(require(DATA / "turtlebot1d" / "training1.csv"))
    n = 1500  # the first minutes: enough to learn from, quick to run
    t_ns = T0_NS + np.round(log["time"][:n] * 1e9).astype(np.int64)
    sonar1 = np.float32(log["sonar1"][:n])
    sonar2 = np.float32(log["sonar2"][:n])
    shortest = lambda a: a.astype(str).astype(float)  # noqa: E731  (what a float32 field says)
    v = log["velocity_command"][:n]
    dist = log["range"][:n]
    track = {
        "t_s": np.tile(_seconds(t_ns), 4),
        "v_m_s": np.r_[v, np.full(3 * n, np.nan)],
        "sonar1_m": np.r_[np.full(n, np.nan), shortest(sonar1), np.full(2 * n, np.nan)],
        "sonar2_m": np.r_[np.full(2 * n, np.nan), shortest(sonar2), np.full(n, np.nan)],
        "distance_m": np.r_[np.full(3 * n, np.nan), np.hypot(0.0 - (-dist), 0.0)],
    }
    src = write_csv(tmp_path / "track.csv", track)
    write_csv(tmp_path / "map.csv", {"id": [0], "x_m": [0.0], "y_m": [0.0]})
    m = Msgs(fmt)
    msgs = []
    for k in range(n):
        t = int(t_ns[k])
        msgs += [
            ("/cmd_vel", "geometry_msgs/msg/Twist", t, m.twist(v[k], 0.0)),
            ("/sonar1", "sensor_msgs/msg/Range", t + 1, m.range(t, sonar1[k], 0.0, 10.0)),
            ("/sonar2", "sensor_msgs/msg/Range", t + 2, m.range(t, sonar2[k], 0.0, 10.0)),
            ("/mocap/pose", "geometry_msgs/msg/PoseStamped", t + 3, m.pose_stamped(t, -dist[k], 0.0, 0.0)),
        ]
    bag = write_bag(tmp_path / "tb", fmt, msgs, m)
    _ok(["convert", "bag", bag, "--landmarks", tmp_path / "map.csv", "--out", tmp_path / "from_bag"])
    got, want = read_numeric_csv(tmp_path / "from_bag" / "bag_tables" / "track.csv"), read_numeric_csv(src)
    assert sorted(got) == sorted(want)
    for k in set(want) - {"t_s"}:  # each column's (time, value) rows, in any order
        pairs = [sorted(zip(t["t_s"][np.isfinite(t[k])], t[k][np.isfinite(t[k])], strict=True)) for t in (got, want)]
        assert pairs[0] == pairs[1], k
    if fmt != "mcap":
        return
    _ok(["convert", "track", src, "--out", tmp_path / "from_csv"])
    a = _learned(tmp_path / "from_bag", tmp_path / "a.json")
    b = _learned(tmp_path / "from_csv", tmp_path / "b.json")
    assert a == b
    assert a["evaluation"]  # scored against the distance the pose gives


def test_of_several_poses_the_motion_capture_one_is_the_truth(tmp_path):
    m = Msgs("mcap")
    msgs = []
    for k in range(30):
        t = T0_NS + k * 10**8
        msgs += [
            ("/cmd_vel", "geometry_msgs/msg/Twist", t, m.twist(0.1 if k < 15 else -0.1, 0.0)),
            ("/sonar", "sensor_msgs/msg/Range", t + 1, m.range(t, 1.0 + 0.01 * k)),
            ("/goal_pose", "geometry_msgs/msg/PoseStamped", t + 2, m.pose_stamped(t, 5.0, 0.0, 0.0)),
            ("/vicon/robot/pose", "geometry_msgs/msg/PoseStamped", t + 3, m.pose_stamped(t, 0.01 * k, 0.0, 0.0)),
        ]
    bag = write_bag(tmp_path / "b", "mcap", msgs, m)
    write_csv(tmp_path / "map.csv", {"id": [0], "x_m": [2.0], "y_m": [0.0]})
    _ok(["convert", "bag", bag, "--landmarks", tmp_path / "map.csv", "--out", tmp_path / "o"])
    meta = json.loads((tmp_path / "o" / "meta.json").read_text())
    assert meta["source"]["roles"] == {"commands": "/cmd_vel", "readings": ["/sonar"], "truth": "/vicon/robot/pose"}
    from sensact.io.csvtable import read_numeric_csv

    track = read_numeric_csv(tmp_path / "o" / "bag_tables" / "track.csv")
    d = track["distance_m"][np.isfinite(track["distance_m"])]
    np.testing.assert_allclose(d, 2.0 - 0.01 * np.arange(30))  # the distance to the map's one landmark


def _decimal_ns(path, column=0):
    """A .dat file's times as whole nanoseconds, read from their decimal text (a float64 holds an epoch
    time only to 256 ns)."""
    rows = [line.split() for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]
    return np.array([int(Decimal(r[column]) * 10**9) for r in rows], dtype=np.int64)


@pytest.fixture(scope="module")
def mrclam_source(tmp_path_factory):
    """MRCLAM Dataset 6's robot 1, its first five minutes, as a ROS robot with a tag camera records it:
    odometry as /cmd_vel at its own times, each barcode sighting as the tag's position in the camera's
    optical frame (other robots' barcodes as tags the map lacks), Vicon as motion capture; and the timed
    CSVs of the same numbers."""
    from sensact.io.rosbag_write import RobotRecording

    folder = require(DATA / "mrclam" / "MRCLAM_Dataset6")
    load = lambda n: np.loadtxt(folder / n, comments="#")  # noqa: E731
    odo, meas, gt = load("Robot1_Odometry.dat"), load("Robot1_Measurement.dat"), load("Robot1_Groundtruth.dat")
    odo_ns, meas_ns, gt_ns = (
        _decimal_ns(folder / f"Robot1_{n}.dat") for n in ("Odometry", "Measurement", "Groundtruth")
    )
    end = odo_ns[0] + 300 * 10**9
    o, s, g = odo_ns < end, (meas_ns < end) & (meas_ns >= odo_ns[0]), gt_ns < end
    subject = {int(b): int(k) for k, b in load("Barcodes.dat")}
    tag = np.array([subject.get(int(b), 99) for b in meas[s, 1]])
    r, b = meas[s, 2], meas[s, 3]
    rec = RobotRecording(
        cmd_ns=odo_ns[o],
        v_m_s=odo[o, 1],
        omega_rad_s=odo[o, 2],
        tag_ns=meas_ns[s],
        tag_id=tag,
        tag_xyz_optical_m=np.column_stack([-r * np.sin(b), np.full(r.size, 0.2), r * np.cos(b)]),
        truth_ns=gt_ns[g],
        truth_xy_m=gt[g, 1:3],
        truth_yaw_rad=gt[g, 3],
    )
    marks = load("Landmark_Groundtruth.dat")
    out = tmp_path_factory.mktemp("mrclam_bag")
    x, z = rec.tag_xyz_optical_m[:, 0], rec.tag_xyz_optical_m[:, 2]
    csv = {
        "commands": write_csv(out / "commands.csv", {"t_s": odo[o, 0], "v_m_s": odo[o, 1], "omega_rad_s": odo[o, 2]}),
        "sightings": write_csv(
            out / "sightings.csv",
            {"t_s": meas[s, 0], "landmark_id": tag, "range_m": np.hypot(z, -x), "bearing_rad": np.arctan2(-x, z)},
        ),
        "landmarks": write_csv(out / "map.csv", {"id": marks[:, 0], "x_m": marks[:, 1], "y_m": marks[:, 2]}),
    }
    return csv, rec


@pytest.mark.realdata
@pytest.mark.parametrize("fmt", FORMATS)
def test_an_mrclam_bag_converts_to_the_csvs_it_was_made_from(mrclam_source, tmp_path, fmt):
    """Real times (epoch seconds to the millisecond) and real sightings: each format's tables are the CSVs'
    numbers, bit for bit."""
    from sensact.io.csvtable import read_numeric_csv

    csv, rec = mrclam_source
    bag = write_robot_bag(tmp_path / "run", fmt, rec)
    _ok(["convert", "bag", bag, "--landmarks", csv["landmarks"], "--out", tmp_path / "log"])
    for name in ("commands", "sightings"):
        _same_rows(read_numeric_csv(tmp_path / "log" / "bag_tables" / f"{name}.csv"), read_numeric_csv(csv[name]))


@pytest.mark.slow
@pytest.mark.realdata
def test_an_mrclam_bag_learns_the_model_its_csvs_learn(mrclam_source, tmp_path):
    csv, rec = mrclam_source
    bag = write_robot_bag(tmp_path / "run", "sqlite3", rec)
    _ok(["convert", "bag", bag, "--landmarks", csv["landmarks"], "--out", tmp_path / "from_bag"])
    truth = tmp_path / "from_bag" / "bag_tables" / "truth.csv"
    args = ["--commands", csv["commands"], "--sightings", csv["sightings"], "--landmarks", csv["landmarks"]]
    _ok(["convert", "csv", *args, "--truth", truth, "--out", tmp_path / "from_csv"])
    a = _learned(tmp_path / "from_bag", tmp_path / "a.json", *SHORT)
    assert a == _learned(tmp_path / "from_csv", tmp_path / "b.json", *SHORT)


def test_stamps_on_another_clock_than_the_recording_move_the_twists_onto_it(tmp_path):
    """Sim-time stamps recorded on the wall's clock: the Twists (no stamp) are moved onto the stamps' clock,
    so that each reading keeps its command, and the move is said."""
    from sensact.io.csvtable import read_numeric_csv

    m = Msgs("ros1")
    wall, sim = T0_NS, 1000 * 10**9
    msgs = []
    for k in range(40):
        msgs += [
            ("/cmd_vel", "geometry_msgs/msg/Twist", wall + k * 10**8, m.twist(0.1 if k < 20 else -0.1, 0.0)),
            ("/sonar", "sensor_msgs/msg/Range", wall + k * 10**8 + 5_000_000, m.range(sim + k * 10**8, 1.0)),
        ]
    bag = write_bag(tmp_path / "b", "ros1", msgs, m)
    res = _ok(["convert", "bag", bag, "--out", tmp_path / "o"])
    assert "its times are moved onto the stamps' clock" in " ".join(res.output.split())
    t = read_numeric_csv(tmp_path / "o" / "bag_tables" / "track.csv")
    cmd = t["t_s"][np.isfinite(t["v_m_s"])]
    reading = t["t_s"][np.isfinite(t["sonar_m"])]
    # each reading 5 ms after its command: the Twists take the sonar's lag from stamp to recording as their own
    np.testing.assert_allclose(reading - cmd, 0.005, atol=1e-6)


def test_wheel_odometry_is_the_command_where_no_twist_is_and_chapter_3_learns_the_folder(tmp_path):
    """A robot that logs its wheel odometry (nav_msgs/Odometry) and no /cmd_vel: the odometry's twist is the
    command; a motion-capture Odometry is the truth when named; `learn bootstrap` reads the 1-D folder."""
    m = Msgs("sqlite3")
    msgs = []
    rng = np.random.default_rng(0)
    x = 0.0
    for k in range(1200):  # two minutes at 10 Hz, back and forth before a wall at 3 m
        t = T0_NS + k * 10**8
        v = 0.2 if (k // 150) % 2 == 0 else -0.2
        x += 0.9 * v * 0.1
        msgs += [
            ("/odom", "nav_msgs/msg/Odometry", t, m.odometry(t, v, 0.0)),
            ("/sonar", "sensor_msgs/msg/Range", t + 1, m.range(t, 3.0 - x + rng.normal(0, 0.01), 0.02, 6.0)),
            ("/mocap/odom", "nav_msgs/msg/Odometry", t + 2, m.odometry(t, 0.0, 0.0)),
        ]
    bag = write_bag(tmp_path / "b", "sqlite3", msgs, m)
    res = runner.invoke(app, ["convert", "bag", str(bag), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "commands: one of /mocap/odom, /odom" in " ".join(res.output.split())
    _ok(["convert", "bag", bag, "--commands", "/odom", "--truth", "/mocap/odom", "--out", tmp_path / "o"])
    meta = json.loads((tmp_path / "o" / "meta.json").read_text())
    assert meta["source"]["roles"] == {"commands": "/odom", "readings": ["/sonar"], "truth": "/mocap/odom"}
    assert (tmp_path / "o" / "bootstrap_config.yaml").is_file()
    _ok(["learn", "bootstrap", tmp_path / "o", "--out", tmp_path / "b.json"])
    assert json.loads((tmp_path / "b.json").read_text())["status"] == "ok"


def test_a_message_that_does_not_read_is_one_line_naming_its_topic_and_number(tmp_path):
    """A bag whose index opens but whose messages are damaged (rosbags, struct or an assertion raises)."""
    import struct
    from types import SimpleNamespace

    from sensact.errors import SensactError
    from sensact.io.rosbag import _messages

    class Damaged:
        def __init__(self):
            self.connections = [SimpleNamespace(topic="/cmd_vel", msgtype="geometry_msgs/msg/Twist", msgcount=3)]
            self.paths = [tmp_path / "robot.bag"]

        def messages(self, connections):
            yield connections[0], 1, b"ok"
            raise struct.error("unpack requires a buffer of 8 bytes")

        def deserialize(self, raw, msgtype):
            return raw

    got = []
    with pytest.raises(SensactError) as err:
        got.extend(_messages(Damaged(), "/cmd_vel"))
    assert got == [(1, b"ok")]
    text = str(err.value)
    assert "/cmd_vel: message 2 cannot be read (error: unpack requires" in text and "robot.bag" in text
    assert "\n" not in text


def _field(name: str, value: bytes) -> bytes:
    body = name.encode() + b"=" + value
    return len(body).to_bytes(4, "little") + body


def _record(fields: bytes, data: bytes = b"") -> bytes:
    return len(fields).to_bytes(4, "little") + fields + len(data).to_bytes(4, "little") + data


def _as_format_1_2(bag, dest):
    """``bag`` (format 2.0) written again in format 1.2, as ROS recorded before 2010: message definitions and
    messages named by topic, an index of the old style (none here: rosbag's 1.2 reader scans as this one)."""
    from rosbags.rosbag1 import Reader

    with Reader(bag) as r:
        conns = {c.id: c for c in r.connections}
        out = [b"#ROSBAG V1.2\n", _record(_field("op", b"\x03") + _field("index_pos", bytes(8)), bytes(4000))]
        for c in conns.values():
            kind = c.msgtype.replace("/msg/", "/").encode()
            out.append(
                _record(
                    _field("op", b"\x01")
                    + _field("topic", c.topic.encode())
                    + _field("md5", c.digest.encode())
                    + _field("type", kind)
                    + _field("def", c.msgdef.data.encode())
                )
            )
        for c, t, raw in r.messages():
            time = (t // 10**9).to_bytes(4, "little") + (t % 10**9).to_bytes(4, "little")
            fields = _field("op", b"\x02") + _field("topic", c.topic.encode()) + _field("time", time)
            out.append(_record(fields, raw))
    dest.write_bytes(b"".join(out))
    return dest


def _unindexed(bag, dest):
    """``bag`` as a recording never closed leaves it: its header's index position zero (`rosbag reindex`'s case)."""
    data = bytearray(bag.read_bytes())
    at = data.index(b"index_pos=") + len(b"index_pos=")
    data[at : at + 8] = bytes(8)
    dest.write_bytes(bytes(data))
    return dest


@pytest.mark.parametrize("variant", [_as_format_1_2, _unindexed])
def test_a_ros1_bag_rosbags_refuses_is_read_record_by_record(diffdrive_source, tmp_path, variant):
    """A whole ROS 1 bag of format 1.2, or one with no index, converts to the tables its indexed 2.0 original
    converts to (rosbags' own reader refuses both)."""
    from rosbags.highlevel import AnyReader

    from sensact.io.csvtable import read_numeric_csv

    csv, rec = diffdrive_source
    bag = write_robot_bag(tmp_path / "run", "ros1", rec)
    old = variant(bag, tmp_path / "old.bag")
    with pytest.raises(Exception):  # noqa: B017 (whatever rosbags raises, it refuses)
        AnyReader([old]).open()
    for source, out in ((bag, tmp_path / "new"), (old, tmp_path / "old")):
        res = _ok(["convert", "bag", source, "--landmarks", csv["landmarks"], "--out", out])
    assert "the bag is read record by record" in " ".join(res.output.split())
    for name in ("commands", "sightings", "truth"):
        _same_rows(
            read_numeric_csv(tmp_path / "old" / "bag_tables" / f"{name}.csv"),
            read_numeric_csv(tmp_path / "new" / "bag_tables" / f"{name}.csv"),
        )


NUMERIC = {
    "bool": np.bool_,
    "int8": np.int8,
    "uint8": np.uint8,
    "byte": np.uint8,
    "char": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}
FIDUCIALS = {  # ROS's fiducial_msgs, as aruco_detect publishes them
    "fiducial_msgs/msg/FiducialTransform": "int32 fiducial_id\ngeometry_msgs/Transform transform\n"
    "float64 image_error\nfloat64 object_error\nfloat64 fiducial_area",
    "fiducial_msgs/msg/FiducialTransformArray": "std_msgs/Header header\nint32 image_seq\n"
    "FiducialTransform[] transforms",
}


def _blank(ts, name):
    """A message of type ``name`` with every field zero or empty, from the typestore's definitions."""

    def value(kind, detail):
        if kind == 1:
            return "" if detail[0] == "string" else False if detail[0] == "bool" else 0
        if kind == 2:
            return _blank(ts, detail)
        (sub_kind, sub_detail), length = detail
        n = length if kind == 3 else 0
        if sub_kind == 1 and sub_detail[0] in NUMERIC:
            return np.zeros(n, dtype=NUMERIC[sub_detail[0]])
        return [value(sub_kind, sub_detail) for _ in range(n)]

    _, fields = ts.fielddefs[name]
    return ts.types[name](**{f: value(int(k), d) for f, (k, d) in fields})


def _robot_bag(path, topics, empty=()):
    """A sqlite3 bag of ten blank messages on each (topic, type), and ``empty`` (topic, type) recorded with none:
    what a real robot's recording holds."""
    from rosbags.typesys import get_types_from_msg

    m = Msgs("sqlite3")
    for name, text in FIDUCIALS.items():
        m.ts.register(get_types_from_msg(text, name))
    msgs = [(t, kind, T0_NS + k * 10**8, _blank(m.ts, kind)) for t, kind in topics for k in range(10)]
    return write_bag(path, "sqlite3", msgs, m, empty=empty)


ODOM, IMU = ("/odom", "nav_msgs/msg/Odometry"), ("/imu/data", "sensor_msgs/msg/Imu")
CMD, GPS = ("/cmd_vel", "geometry_msgs/msg/Twist"), ("/gps/fix", "sensor_msgs/msg/NavSatFix")
SCAN, JOINTS = ("/scan", "sensor_msgs/msg/LaserScan"), ("/joint_states", "sensor_msgs/msg/JointState")
FIDS, TF = ("/fiducial_transforms", "fiducial_msgs/msg/FiducialTransformArray"), ("/tf", "tf2_msgs/msg/TFMessage")
IMAGE = ("/camera/image_raw", "sensor_msgs/msg/Image")


@pytest.mark.parametrize(
    "topics, missing, planned",
    [
        ([CMD, JOINTS, ODOM], "readings or sightings", True),
        ([CMD, FIDS, TF], "readings or sightings", False),
        ([CMD, IMAGE], "readings or sightings", False),
    ],
)
def test_a_bag_with_no_type_sensact_reads_names_what_it_found_and_what_it_reads(tmp_path, topics, missing, planned):
    """No naming can fix these (the six kinds of robot bag the first-contact issue tried): one line that
    lists the types found, the types sensact reads for each role, and what would add the rest."""
    bag = _robot_bag(tmp_path / "robot", topics)
    res = runner.invoke(app, ["convert", "bag", str(bag), "--out", str(tmp_path / "o")])
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    text = " ".join(res.output.split())
    assert res.exit_code == 2 and "Traceback" not in text, text
    assert f"no topic of a type sensact reads plays the {missing}" in text
    for _, kind in topics:
        assert kind.replace("/msg/", "/") in text
    assert "commands from geometry_msgs/Twist" in text and "readings from sensor_msgs/Range" in text
    assert ("read with a 2-D lidar's sensor_msgs/LaserScan" in text) == planned
    assert lines[0].startswith("error:") and "Fix:" in text and "cannot tell" not in text
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "topics, said",
    [
        ([ODOM, IMU], "stamp is not after"),  # blank messages carry no stamps: it reached them
        ([ODOM, IMU, GPS], "stamp is not after"),
        ([IMU, GPS], "it has no nav_msgs/Odometry topic"),
    ],
)
def test_a_bag_with_an_imu_goes_the_inertial_route(tmp_path, topics, said):
    """An IMU's bag is an outdoor robot's (docs/inertial.md): the inertial reader opens it and reaches its
    messages, or names the wheel odometry it lacks, in one line with the fix."""
    bag = _robot_bag(tmp_path / "robot", topics)
    res = runner.invoke(app, ["convert", "bag", str(bag), "--out", str(tmp_path / "o")])
    text = " ".join(res.output.split())
    assert res.exit_code == 2 and "Traceback" not in text, text
    assert said in text and "Fix:" in text
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("named", [[], ["--scan", "/scan"]])
def test_an_empty_scan_is_named_as_empty_and_every_route_is_named(tmp_path, named):
    """A TurtleBot3's bag with its lidar off: /scan recorded with no message. The cause comes first (not "LaserScan
    is not read", not "the index lists 0"), and the refusal names every route and what it needs."""
    bag = _robot_bag(tmp_path / "robot", [CMD, JOINTS, ODOM], empty=[SCAN])
    res = runner.invoke(app, ["convert", "bag", str(bag), *named, "--out", str(tmp_path / "o")])
    text = " ".join(res.output.split())
    assert res.exit_code == 2 and "Traceback" not in text, text
    assert "/scan has no messages" in text
    assert "is not read by sensact" not in text and "index lists" not in text
    if not named:
        assert "wheels and a 2-D lidar (sensor_msgs/LaserScan" in text and "an IMU and GNSS" in text
    assert not (tmp_path / "o").exists()


def test_odometry_given_as_commands_or_odom_drives_the_lidar_route(tmp_path):
    """`--commands /odom` takes an Odometry, as `convert bag --help` says, and of /odom and robot_localization's
    /odometry/filtered the wheels' is taken, or the one --odom names."""
    from sensact.io.rosbag import Topic
    from sensact.io.rosbag_lidar2d import lidar_roles

    topics = [Topic(n, t.replace("/msg/", "/"), 10) for n, t in (SCAN, ODOM, ("/odometry/filtered", ODOM[1]))]
    assert lidar_roles(tmp_path, topics, {}).odom == "/odom"
    assert lidar_roles(tmp_path, topics, {"commands": "/odom"}).odom == "/odom"
    assert lidar_roles(tmp_path, topics, {"odom": "/odometry/filtered"}).odom == "/odometry/filtered"
    res = runner.invoke(app, ["convert", "bag", "--help"])
    assert "--odom" in res.output


def test_a_bag_with_a_laser_scan_goes_the_lidar_route_and_an_empty_scan_is_one_line(tmp_path):
    bag = _robot_bag(tmp_path / "robot", [CMD, SCAN, JOINTS, ODOM])
    res = runner.invoke(app, ["convert", "bag", str(bag), "--out", str(tmp_path / "o")])
    text = " ".join(res.output.split())
    assert res.exit_code == 2 and "/scan: 0 beams" in text and "is not a 2-D lidar's scan" in text, text
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "role, topic, kind", [("--sightings", *FIDS), ("--truth", *GPS), ("--commands", *IMU), ("--readings", *SCAN)]
)
def test_a_named_topic_of_the_wrong_type_is_refused_naming_both_types(tmp_path, role, topic, kind):
    bag = _robot_bag(tmp_path / "robot", [CMD, FIDS, GPS, IMU, SCAN])
    res = runner.invoke(app, ["convert", "bag", str(bag), role, topic, "--out", str(tmp_path / "o")])
    text = " ".join(res.output.split())
    assert res.exit_code == 2, text
    short = kind.replace("/msg/", "/")
    assert f"{topic} is a {short}, which sensact cannot read as {role[2:]}" in text
    assert "give a topic of type" in text  # the types the role takes


def test_a_bag_whose_definitions_do_not_parse_is_read_with_the_standard_ones(diffdrive_source, tmp_path):
    """A ROS 2 bag whose recorded message definitions rosbags cannot parse (a recorder's quirk) converts
    with ROS 2 Humble's, to the tables the same bag converts to, and says so."""
    import sqlite3

    from sensact.io.csvtable import read_numeric_csv

    csv, rec = diffdrive_source
    bag = write_robot_bag(tmp_path / "run", "sqlite3", rec)
    _ok(["convert", "bag", bag, "--landmarks", csv["landmarks"], "--out", tmp_path / "good"])
    with sqlite3.connect(next(bag.glob("*.db3"))) as con:
        con.execute("update message_definitions set encoded_message_definition = 'not a definition !!'")
    res = _ok(["convert", "bag", bag, "--landmarks", csv["landmarks"], "--out", tmp_path / "std"])
    assert "ROS's standard definitions are used" in " ".join(res.output.split())
    for name in ("commands", "sightings", "truth"):
        _same_rows(
            read_numeric_csv(tmp_path / "std" / "bag_tables" / f"{name}.csv"),
            read_numeric_csv(tmp_path / "good" / "bag_tables" / f"{name}.csv"),
        )


def test_a_bag_without_a_map_converts_with_its_tags_positions_to_learn(diffdrive_source, tmp_path):
    """Issue 92: tag sightings need no map. Without --landmarks every tag is a landmark EM learns (null
    positions), the same sightings kept; --survey keeps the map for scoring only."""
    csv, rec = diffdrive_source
    bag = write_robot_bag(tmp_path / "run", "ros1", rec)
    out = tmp_path / "log"
    _ok(["convert", "bag", bag, "--survey", csv["landmarks"], "--out", out])
    meta = json.loads((out / "meta.json").read_text())
    assert meta["landmarks"] and all(m["x_mm"] is None and m["y_mm"] is None for m in meta["landmarks"])
    seen = {str(int(i)) for i in np.unique(rec.tag_id)}
    assert {m["name"] for m in meta["landmarks"]} == seen
    survey = {meta["landmarks"][s["id"]]["name"]: (s["x_mm"], s["y_mm"]) for s in meta["survey"]}
    for j, (x, y) in enumerate(rec.map_xy_m):
        if str(j) in survey:
            assert survey[str(j)] == pytest.approx((1000.0 * x, 1000.0 * y))


def test_a_conversion_that_fails_after_reading_leaves_nothing_behind(diffdrive_source, tmp_path):
    """Issue 95: the bag's tables are written, then the conversion refuses them (every command stamped
    alike): nothing it wrote is left, and a folder that was there keeps what it had."""
    import dataclasses

    _, rec = diffdrive_source
    bad = dataclasses.replace(rec, cmd_ns=np.full_like(rec.cmd_ns, rec.cmd_ns[0]))
    bag = write_robot_bag(tmp_path / "run", "ros1", bad)
    res = runner.invoke(app, ["convert", "bag", str(bag), "--out", str(tmp_path / "new")])
    assert res.exit_code == 2 and "same time" in res.output
    assert not (tmp_path / "new").exists()
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "em_config.yaml").write_text("preset: differential_drive_camera\n")
    res = runner.invoke(app, ["convert", "bag", str(bag), "--out", str(kept)])
    assert res.exit_code == 2
    assert sorted(p.name for p in kept.rglob("*")) == ["em_config.yaml"]
    assert (kept / "em_config.yaml").read_text() == "preset: differential_drive_camera\n"


@pytest.mark.parametrize(
    "text", ["commands: [[/cmd_vel]]\n", "readings: [[/a, /b]]\n", "truth: {a: 1}\n", "commands: ''\n"]
)
def test_a_mapping_whose_role_is_not_a_topic_name_is_one_line(tmp_path, text):
    """Issue 95: a nested list or a map for a role was a TypeError (exit 70)."""
    (tmp_path / "map.yaml").write_text(text)
    res = runner.invoke(app, ["convert", "bag", str(tmp_path / "none.bag"), "--mapping", str(tmp_path / "map.yaml")])
    assert res.exit_code == 2 and "is not a topic's name" in res.output, res.output


def test_tags_at_or_behind_the_camera_are_dropped_or_the_frame_refused(diffdrive_source, tmp_path):
    """Issue 95: a camera sees nothing behind it. A few such detections are dropped and said; most of them
    mean the positions are not in an optical frame, refused in one line."""
    import dataclasses

    _, rec = diffdrive_source
    few = rec.tag_xyz_optical_m.copy()
    few[:3, 2] = -few[:3, 2]
    bag = write_robot_bag(tmp_path / "few", "ros1", dataclasses.replace(rec, tag_xyz_optical_m=few))
    res = runner.invoke(app, ["convert", "bag", str(bag), "--out", str(tmp_path / "few_log")])
    assert res.exit_code == 0, res.output
    assert "3 tag detections at or behind the camera" in res.output.replace("\n", " ")
    from sensact.io.csvtable import read_numeric_csv

    assert len(read_numeric_csv(tmp_path / "few_log" / "bag_tables" / "sightings.csv")["t_s"]) == len(few) - 3
    most = rec.tag_xyz_optical_m * np.array([1.0, 1.0, -1.0])
    bag = write_robot_bag(tmp_path / "most", "ros1", dataclasses.replace(rec, tag_xyz_optical_m=most))
    res = runner.invoke(app, ["convert", "bag", str(bag), "--out", str(tmp_path / "most_log")])
    assert res.exit_code == 2 and "behind the camera" in res.output and not (tmp_path / "most_log").exists()


def test_a_conversion_its_own_reader_would_refuse_is_refused_and_leaves_nothing(
    diffdrive_source, tmp_path, monkeypatch
):
    """convert writes only what `learn em` reads: the folder is read back before the conversion ends, and a
    refusal there (here forced) is convert's own, in one line, with nothing left behind."""
    import sensact.app
    from sensact.errors import LogFormatError

    csv, rec = diffdrive_source
    bag = write_robot_bag(tmp_path / "run", "sqlite3", rec)

    def refuse(path, **_):
        raise LogFormatError("2 of 9 rows repeat an earlier row exactly.", file=path, fix="drop them.")

    monkeypatch.setattr(sensact.app, "open_log", refuse)
    res = runner.invoke(
        app, ["convert", "bag", str(bag), "--landmarks", str(csv["landmarks"]), "--out", str(tmp_path / "o")]
    )
    text = " ".join(res.output.split())
    assert res.exit_code == 2 and "would not be read: 2 of 9 rows repeat" in text, text
    assert not (tmp_path / "o").exists()


def test_ranges_that_are_nan_or_infinite_are_no_readings_and_the_log_learns(tmp_path):
    """REP 117: a Range of NaN or +-inf holds no distance. Two sonars stamped alike, every third message of
    each empty: convert once wrote those as rows with nothing in them, which repeated each other, and its own
    reader refused the folder. They are no rows; the folder learns."""
    m = Msgs("ros1")
    msgs, x = [], 0.0
    rng = np.random.default_rng(1)
    for k in range(300):
        t = T0_NS + k * 10**8
        v = 0.2 if (k // 75) % 2 == 0 else -0.2
        x += 0.9 * v * 0.1
        r = 3.0 - x + rng.normal(0, 0.01) if k % 3 else (np.nan if k % 2 else np.inf)
        msgs += [
            ("/cmd_vel", "geometry_msgs/msg/Twist", t, m.twist(v, 0.0)),
            ("/sonar", "sensor_msgs/msg/Range", t + 1, m.range(t, r, 0.02, 6.0)),
            ("/sonar2", "sensor_msgs/msg/Range", t + 2, m.range(t, r + 0.1, 0.02, 6.0)),
        ]
    bag = write_bag(tmp_path / "b", "ros1", msgs, m)
    _ok(["convert", "bag", bag, "--out", tmp_path / "o"])
    rows = np.genfromtxt(tmp_path / "o" / "bag_tables" / "track.csv", delimiter=",", names=True)
    assert np.isfinite(rows["sonar_m"]).sum() == np.isfinite(rows["sonar2_m"]).sum() == 200
    assert rows.size == 300 + 2 * 200  # the commands' rows, and a row per reading: none empty
    _ok(
        [
            "learn",
            "em",
            tmp_path / "o",
            "--out",
            tmp_path / "m.json",
            "--no-report",
            "--set",
            "thesis.max_iterations=40",
        ]
    )
    channels = json.loads((tmp_path / "m.json").read_text())["model"]["sensor"]["channels"]
    assert [c["name"] for c in channels] == ["sonar_mm", "sonar2_mm"]
