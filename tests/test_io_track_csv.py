"""`sensact convert track`: a 1-D robot's own CSV as a track log folder with its EM settings."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from conftest import assert_written, require
from sensact.cli import app
from sensact.errors import LogFormatError
from sensact.io.csvtable import read_numeric_csv
from sensact.io.track_csv import read_track_csv
from sensact.io.turtlebot import read_turtlebot_landmark_log
from turtlebot_robot import write_turtlebot_csv

runner = CliRunner()
# the Turtlebot's columns under a user's names (its readings and range in m, its command in m/s)
AS_USERS = {
    "time": "t_s",
    "velocity_command": "v_cmd_m_s",
    "sonar1": "sonar_m",
    "raw_ir3": "ir_volts",
    "raw_ir4": "ir2_volts",
    "range": "distance_m",
}


def _as_users_csv(turtlebot_csv: Path, out: Path, columns: dict[str, str] = AS_USERS) -> Path:
    """A Turtlebot CSV's columns renamed as a 1-D robot of another make would log them, rows shuffled
    (a file merged from two loggers need not be in time order)."""
    cols = read_numeric_csv(turtlebot_csv)
    names = [c for c in columns if c in cols]
    order = np.random.default_rng(0).permutation(len(cols["time"]))
    rows = [",".join(columns[c] for c in names)]
    rows += [",".join(repr(float(cols[c][k])) for c in names) for k in order]
    out.write_text("\n".join(rows) + "\n")
    return out


def test_a_turtlebot_run_under_a_users_names_reads_as_the_turtlebot_csv(tmp_path):
    """An exact reduction: the same run under a user's column names, in shuffled rows, is the same log
    (steps, held commands, readings in mm and volts, recorded distance) as the Turtlebot reader makes of it,
    but for its last row: the Turtlebot reader's grid ends a step short when (t_last - t_0) / dt rounds
    below a whole number (it puts the last row on the step before), which the clock tolerance of
    io/resample.py (shared with `convert csv`) does not."""
    csv = tmp_path / "tb.csv"
    write_turtlebot_csv(csv, with_range=True, drop=("raw_ir1", "raw_ir2", "sonar2"))
    want, want_mm = read_turtlebot_landmark_log(csv)
    got = read_track_csv(_as_users_csv(csv, tmp_path / "robot.csv"))
    d, T = got.data, want.n_steps
    assert d.geometry.name == "track" and d.command_names == ("v_cmd_mm_s",)
    assert d.reading_names == ("sonar_mm", "ir_volts", "ir2_volts") and got.distance_reading == "sonar_mm"
    assert d.dt_s == pytest.approx(want.dt_s, rel=1e-12) and d.n_steps == T + 1 == 2500
    np.testing.assert_allclose(d.step_commands[:T], want.step_commands, rtol=1e-12)
    np.testing.assert_array_equal(np.minimum(d.obs_step, T - 1), want.obs_step)
    assert d.obs_step[-1] == T  # 0.1 + 0.06 * 2499 s, the file's last row
    np.testing.assert_allclose(d.obs_readings, want.obs_readings, rtol=1e-12)
    np.testing.assert_allclose(got.truth_mm[:T], want_mm, rtol=1e-12)
    assert got.summary["kept"] == got.summary["reading_rows"] == d.obs_step.size
    assert got.sources["sonar_mm"] == "sonar_m" and got.sources["distance_mm"] == "distance_m"


def test_a_robot_logging_centimetres_reads_as_one_logging_metres(tmp_path):
    """An exact reduction: the same run with its command, sonar and distance in cm and cm/s."""
    csv = tmp_path / "tb.csv"
    write_turtlebot_csv(csv, with_range=True, drop=("raw_ir1", "raw_ir2", "sonar2"))
    metres = _as_users_csv(csv, tmp_path / "robot_m.csv")
    cols = read_numeric_csv(metres)
    in_cm = {"v_cmd_m_s": "v_cmd_cm_s", "sonar_m": "sonar_cm", "distance_m": "distance_cm"}
    rows = [",".join(in_cm.get(c, c) for c in cols)]
    rows += [
        ",".join(repr(float(cols[c][k] * (100.0 if c in in_cm else 1.0))) for c in cols)
        for k in range(len(cols["t_s"]))
    ]
    (tmp_path / "robot_cm.csv").write_text("\n".join(rows) + "\n")
    want, got = read_track_csv(metres), read_track_csv(tmp_path / "robot_cm.csv")
    assert got.data.command_names == ("v_cmd_mm_s",) and got.distance_reading == "sonar_mm"
    assert got.sources["sonar_mm"] == "sonar_cm" and got.data.n_steps == want.data.n_steps
    np.testing.assert_allclose(got.data.step_commands, want.data.step_commands, rtol=1e-12)
    np.testing.assert_allclose(got.data.obs_readings, want.data.obs_readings, rtol=1e-12)
    np.testing.assert_allclose(got.truth_mm, want.truth_mm, rtol=1e-12)


def test_convert_track_writes_a_folder_that_learn_em_learns_and_scores(tmp_path):
    """Seeded recovery through the commands: the folder `convert track` writes, with the settings it
    writes (the IR curves from flat lines, a window and a robust sonar asked for), learns the seeded
    robot's gain 0.9 and reads its distance, scored against the recorded distance."""
    csv = tmp_path / "tb.csv"
    write_turtlebot_csv(csv, with_range=True, drop=("raw_ir1", "raw_ir2", "sonar2"))
    users = _as_users_csv(csv, tmp_path / "robot.csv")
    out = tmp_path / "track"
    args = ["convert", "track", str(users), "--out", str(out), "--window", "ir_volts=100:1500", "--robust", "sonar_m"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert (out / "overview.png").stat().st_size > 30_000
    settings = yaml.safe_load((out / "em_config.yaml").read_text())
    chans = {c["name"]: c for c in settings["channels"]}
    assert [c["name"] for c in settings["channels"]] == ["sonar_mm", "ir_volts", "ir2_volts"]
    assert chans["sonar_mm"]["robust"] == "student_t" and "robust" not in chans["ir_volts"]
    assert (chans["ir_volts"]["valid_min"], chans["ir_volts"]["valid_max"]) == (100.0, 1500.0)
    assert chans["ir_volts"]["start_slope"] == 0.0 and "valid_min" not in chans["ir2_volts"]
    model = tmp_path / "m.json"
    res = runner.invoke(app, ["learn", "em", str(out), "--out", str(model)])
    assert_written(res)
    ev = json.loads(model.read_text())["evaluation"]
    assert ev["gain_error_pct"] < 1.0 and ev["sensors"]["sonar_mm"]["rms_pct_of_span"] < 2.0, ev
    assert ev["sensors"]["ir_volts"]["rms_pct_of_span"] < 3.0, ev
    # chapter 3's learner on the same folder, with the settings written beside it
    assert yaml.safe_load((out / "bootstrap_config.yaml").read_text()) == {
        "t_start_s": 60.0,
        "action_degree": 1,
        "outlier_gate": 3.0,
    }
    res = runner.invoke(app, ["learn", "bootstrap", str(out), "--out", str(tmp_path / "b.json")])
    assert res.exit_code == 0 and "bootstrap_config.yaml, written beside the log" in res.output, res.output
    assert "warning" not in res.output  # the robot reverses at 7 s, long before A_t takes over at 120 s
    doc = json.loads((tmp_path / "b.json").read_text())
    ev, slope = doc["evaluation"], doc["action"]["power_coefficients"][1]
    # the sine never holds a command to time: the gain is A's slope in mm/s through S's scale
    assert ev["sensor_rms_pct"] < 2.0 and ev["sensor_scale_b"] * slope == pytest.approx(0.9, rel=0.03), ev
    # A_t taking over before the first reversal (7 s in, at the sine's half period) is warned about
    said = " ".join(runner.invoke(app, ["learn", "bootstrap", str(out), "--set", "t_start_s=3"]).output.split())
    assert "at 2 t_start_s = 6 s into the log, and until 7.0 s the robot is commanded one way only" in said, said


def _held_still_first(users: Path, seconds: float, out: Path) -> Path:
    """The user's CSV with the robot standing still (command 0, the first readings with noise) first."""
    cols = read_numeric_csv(users)
    dt = float(np.median(np.diff(np.sort(cols["t_s"]))))
    n = round(seconds / dt)
    first = int(np.argmin(cols["t_s"]))
    rng = np.random.default_rng(5)
    idle = {c: np.full(n, v[first]) for c, v in cols.items()}
    idle["t_s"] = cols["t_s"][first] - dt * np.arange(n, 0, -1)
    idle["v_cmd_m_s"] = np.zeros(n)
    idle["sonar_m"] = idle["sonar_m"] + rng.normal(0.0, 0.005, n)
    joined = {c: np.r_[idle[c], cols[c]] for c in cols}
    rows = [",".join(joined)] + [
        ",".join(repr(float(v[k])) for v in joined.values()) for k in range(n + len(cols["t_s"]))
    ]
    out.write_text("\n".join(rows) + "\n")
    return out


def test_chapter_3s_clock_starts_when_the_robot_is_first_commanded(tmp_path):
    """Seeded recovery: the seeded robot standing still for 150 s before it drives (beyond 2 t_start_s = 120 s,
    where S had learned every reading as one place and both models stayed at zero, "status: ok") learns its
    gain and distance, and is told where the clock starts; a log never commanded is refused in one line."""
    csv = tmp_path / "tb.csv"
    write_turtlebot_csv(csv, with_range=True, drop=("raw_ir1", "raw_ir2", "sonar2"))
    users = _held_still_first(_as_users_csv(csv, tmp_path / "robot.csv"), 150.0, tmp_path / "still.csv")
    out = tmp_path / "track"
    assert runner.invoke(app, ["convert", "track", str(users), "--out", str(out), "--robust", "sonar_m"]).exit_code == 0
    res = runner.invoke(app, ["learn", "bootstrap", str(out), "--out", str(tmp_path / "b.json")])
    said = " ".join(res.output.split())
    assert res.exit_code == 0 and "the robot is first commanded 150.0 s into the log" in said, said
    assert "warning" not in said  # the clock starts at 150 s: A_t takes over at 270 s, the robot reverses at 157 s
    doc = json.loads((tmp_path / "b.json").read_text())
    ev, slope = doc["evaluation"], doc["action"]["power_coefficients"][1]
    assert ev["sensor_rms_pct"] < 2.0 and ev["sensor_scale_b"] * slope == pytest.approx(0.9, rel=0.03), ev
    # the warning counts from the first command too
    said = " ".join(runner.invoke(app, ["learn", "bootstrap", str(out), "--set", "t_start_s=3"]).output.split())
    assert "at 2 t_start_s = 6 s after the first command (156.0 s into the log), and until 157.0 s" in said, said
    # commands all zero: refused, naming the command column
    cut = tmp_path / "never.csv"
    cut.write_text("\n".join(users.read_text().splitlines()[: 150 * 16]) + "\n")
    assert runner.invoke(app, ["convert", "track", str(cut), "--out", str(tmp_path / "never")]).exit_code == 0
    res = runner.invoke(app, ["learn", "bootstrap", str(tmp_path / "never")])
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and "v_cmd_mm_s: every command is zero" in said, said


def test_chapter_3s_learner_refuses_a_converted_folder_of_two_commands(tmp_path):
    t = 0.05 * np.arange(400)
    v, w = 0.2 * np.sin(t), 0.1 * np.cos(t)
    rows = ["t_s,v_m_s,w_m_s,sonar_m"] + [f"{a},{b},{c},{1.0 + b}" for a, b, c in zip(t, v, w, strict=True)]
    (tmp_path / "two.csv").write_text("\n".join(rows) + "\n")
    out = tmp_path / "track"
    args = [
        "convert",
        "track",
        str(tmp_path / "two.csv"),
        "--out",
        str(out),
        "--command",
        "v_m_s",
        "--command",
        "w_m_s",
    ]
    res = runner.invoke(app, args)
    assert res.exit_code == 0 and not (out / "bootstrap_config.yaml").exists(), res.output
    res = runner.invoke(app, ["learn", "bootstrap", str(out)])  # chapter 3 reads one command and one sensor
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and f"learn it with `sensact learn em {out}`" in said, said


@pytest.mark.parametrize(
    ("header", "options", "field", "said"),
    [
        ("t_s,cmd,sonar_m", [], "--command", "no column is a speed"),
        ("t_s,v_m_s,w_m_s,sonar_m", [], "--command", "2 columns are speeds (v_m_s, w_m_s)"),
        ("t_s,v_m_s,ir_volts", [], "--reading", "none of the readings (ir_volts) is in a distance unit"),
        ("t_s,v_m_s,sonar_m", ["--reading", "lidar_m"], "lidar_m", "--reading lidar_m: no such column"),
        ("t_s,v_m_s,sonar_m", ["--reading", "v_m_s"], "v_m_s", "v_m_s is read as a command"),
        ("t_s,v_m_s,sonar_m", ["--window", "ir_volts=100:800"], "--window", "no such reading"),
        ("t_s,v_m_s,sonar_m", ["--window", "sonar_m=800:100"], "--window", "is not a window of distances"),
        ("t_s,v_m_s,sonar_m", ["--robust", "sonar"], "--robust", "no such reading"),
        ("time,v_m_s,sonar_m", [], "t_s", "missing column t_s"),
    ],
)
def test_a_file_convert_track_cannot_read_is_named_in_one_line(tmp_path, header, options, field, said):
    csv = tmp_path / "robot.csv"
    n = len(header.split(","))
    csv.write_text(header + "\n" + "\n".join(",".join([str(0.1 * k)] + ["0.5"] * (n - 1)) for k in range(20)) + "\n")
    res = runner.invoke(app, ["convert", "track", str(csv), "--out", str(tmp_path / "out"), *options])
    text = " ".join(res.output.split())
    assert res.exit_code == 2 and said in text and f"{field}:" in text, text
    assert "Traceback" not in text and not (tmp_path / "out").exists()


def test_commands_logged_only_when_they_change_are_held_to_the_last_row(tmp_path):
    """A command row, then readings alone: the command holds until the file's last row, and a reading
    before the first command is dropped and counted."""
    csv = tmp_path / "robot.csv"
    rows = ["t_s,v_mm_s,sonar_mm,distance_mm", "0.0,,500,", "0.1,100,510,510"]
    rows += [f"{0.1 * k:.1f},,{500 + 10 * k},{500 + 10 * k}" for k in range(2, 12)]
    csv.write_text("\n".join(rows) + "\n")
    got = read_track_csv(csv)
    assert got.data.n_steps == 11 and np.all(got.data.step_commands == 100.0)
    assert got.summary["dropped_outside_commands"] == 1 and got.summary["kept"] == 11
    np.testing.assert_allclose(got.truth_mm, 500.0 + 10.0 * np.arange(1, 12))
    assert got.data.reading_names == ("sonar_mm",) and not math.isnan(got.data.obs_readings[0, 0])
    with pytest.raises(LogFormatError, match="not a step"):
        read_track_csv(csv, dt_s=0.0)
    csv.write_text("\n".join([rows[0], rows[1], rows[2], *(r.rsplit(",", 1)[0] + "," for r in rows[3:])]) + "\n")
    with pytest.raises(LogFormatError, match="the recorded distance has 1 values"):  # one row cannot be interpolated
        read_track_csv(csv)


def test_the_real_turtlebot_under_a_users_names_clears_the_issues_bars(tmp_path, data_dir):
    """Real data: training1.csv under a user's column names, converted with the windows its overview
    shows (raw_ir4 folds back below about 600 mm) and a robust sonar, clears issue 5's Turtlebot bars."""
    users = _as_users_csv(require(data_dir / "turtlebot1d" / "training1.csv"), tmp_path / "robot.csv")
    out = tmp_path / "track"
    args = ["convert", "track", str(users), "--out", str(out), "--robust", "sonar_m"]
    args += ["--window", "ir_volts=100:800", "--window", "ir2_volts=600:"]
    assert runner.invoke(app, args).exit_code == 0
    model = tmp_path / "m.json"
    res = runner.invoke(app, ["learn", "em", str(out), "--out", str(model)])
    assert_written(res)
    ev = json.loads(model.read_text())["evaluation"]
    assert ev["gain_error_pct"] < 5.0 and ev["sensors"]["sonar_mm"]["rms_pct_of_span"] < 3.0, ev
    # chapter 3's learner beside it, as `reproduce turtlebot` reports it on the Turtlebot's own file
    res = runner.invoke(app, ["learn", "bootstrap", str(out), "--out", str(tmp_path / "b.json")])
    assert res.exit_code == 0, res.output
    ev = json.loads((tmp_path / "b.json").read_text())["evaluation"]
    assert ev["sensor_rms_pct"] < 3.0 and abs(ev["learned_gain"] / ev["true_gain"] - 1.0) < 0.05, ev
