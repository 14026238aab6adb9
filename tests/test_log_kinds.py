"""One door per log kind (``app/log_kinds.py``): every kind of log is opened and learned through the same
registry, so that ``calibrate(open_log(DIR))`` writes what `sensact learn em DIR --out` writes, whatever
the kind; options a kind does not take are refused in one line before any work."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from sensact.app import KINDS, calibrate, open_log, save_calibration
from sensact.app.log_kinds import kind_of, landmark_log, refuse_options
from sensact.cli import app
from sensact.errors import ConfigError, LogFormatError
from turtlebot_robot import write_turtlebot_csv

runner = CliRunner()
SHORT = ("max_iterations=4", "start_search_s=null", "turn_restarts=0")  # a few EM iterations: equality is the test
TIMING = ("seconds", "elapsed", "wall", "cpu_s")


def _simulate(*args: str) -> None:
    res = runner.invoke(app, ["simulate", *args])
    assert res.exit_code == 0, res.output


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> dict[str, tuple[Path, tuple[str, ...]]]:
    """A short log of every kind, and the settings `learn em` is given on it (none for a lidar2d log)."""
    root = tmp_path_factory.mktemp("kinds")
    _simulate("diffdrive", "--out", str(root / "planar"), "--seconds", "30")
    _simulate("diffdrive", "--out", str(root / "radio"), "--seconds", "30", "--set", "sensor=radio")
    _simulate("track1d", "--out", str(root / "track"), "--seconds", "40")
    _simulate("diffdrive", "--out", str(root / "lidar"), "--seconds", "60", "--set", "sensor=lidar2d", "--seed", "7")
    _simulate("outdoor", "--out", str(root / "outdoor"), "--seconds", "120")
    _simulate("ackermann", "--out", str(root / "car"), "--seconds", "20")
    write_turtlebot_csv(root / "robot.csv", with_range=True)
    return {
        "planar": (root / "planar", SHORT),
        "radio": (root / "radio", SHORT),
        "track": (root / "track", SHORT),
        "turtlebot": (root / "robot.csv", SHORT),
        "lidar2d": (root / "lidar", ()),
        "outdoor": (root / "outdoor", ()),
        "car": (root / "car", ()),
    }


def _without_timings(x):
    if isinstance(x, dict):
        return {k: _without_timings(v) for k, v in x.items() if not any(t in k.lower() for t in TIMING)}
    if isinstance(x, list):
        return [_without_timings(v) for v in x]
    return x


def test_each_kind_is_recognized(logs):
    names = {case: kind_of(path).name for case, (path, _) in logs.items()}
    assert names == {
        "planar": "landmarks",
        "radio": "landmarks",
        "track": "landmarks",
        "turtlebot": "turtlebot_csv",
        "lidar2d": "lidar2d",
        "outdoor": "imu_gnss",
        "car": "car",
    }
    assert [k.name for k in KINDS] == ["lidar2d", "car", "intervals", "imu_gnss", "turtlebot_csv", "landmarks"]


@pytest.mark.parametrize("case", ["planar", "radio", "track", "turtlebot", "lidar2d", "outdoor", "car"])
def test_calibrate_open_log_is_learn_em(logs, case, tmp_path):
    """The library's two calls write the command's model, value for value but timings."""
    path, sets = logs[case]
    mine = save_calibration(calibrate(open_log(path), sets=sets), tmp_path / "py.json", report=False).written[0]
    flags = [arg for s in sets for arg in ("--set", s)]
    res = runner.invoke(app, ["learn", "em", str(path), "--out", str(tmp_path / "cli.json"), "--no-report", *flags])
    assert res.exit_code in (0, 3), res.output  # 3: written, flagged (a few iterations do not converge)
    a, b = (_without_timings(json.loads((tmp_path / n).read_text())) for n in ("py.json", "cli.json"))
    assert a.pop("log", None) == b.pop("log", None)
    assert a == b
    assert mine == tmp_path / "py.json"


def test_options_a_kind_does_not_take_are_refused_before_any_work(logs):
    lidar, _ = logs["lidar2d"]
    with pytest.raises(ConfigError, match=r"--preset is for EM's landmark logs; .* is a wheels-and-2-D-lidar log"):
        refuse_options(lidar, {"--preset": "aibo_field", "--halves": False})
    refuse_options(lidar, {"--preset": None, "--set": [], "--halves": False})  # none given: nothing to refuse
    refuse_options(logs["planar"][0], {"--preset": "aibo_field", "--halves": True})
    with pytest.raises(ConfigError, match="--set is for EM's landmark logs"):
        calibrate(open_log(lidar), sets=["patience=3"])
    res = runner.invoke(app, ["learn", "em", str(lidar), "--uncertainty", "information"])
    assert res.exit_code == 2 and "--uncertainty is for EM's landmark logs" in " ".join(res.output.split())


def test_a_command_that_reads_landmark_logs_names_the_one_that_reads_this(logs):
    lidar, _ = logs["lidar2d"]
    with pytest.raises(LogFormatError, match=r"fleet learn reads landmark logs .* learn it with `sensact learn em"):
        landmark_log(lidar, "fleet learn")
    assert landmark_log(logs["planar"][0], "fleet learn").data.geometry.has_heading


def test_a_path_no_kind_reads_is_one_line_naming_every_kind(tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(LogFormatError) as err:
        open_log(tmp_path / "notes.txt")
    assert all(k.what in str(err.value) for k in KINDS)


@pytest.mark.parametrize("command", [["localize"], ["monitor"], ["evaluate", "log"]])
def test_the_commands_that_read_landmark_logs_refuse_another_kind_in_one_line(logs, tmp_path, command):
    lidar, _ = logs["lidar2d"]
    model = tmp_path / "m.json"
    model.write_text("{}")
    res = runner.invoke(app, [*command, str(lidar), "--model", str(model)])
    line = " ".join(res.output.split())
    assert res.exit_code == 2 and "reads landmark logs (EM's), and this is a wheels-and-2-D-lidar log" in line
    assert f"learn it with `sensact learn em {lidar}`" in line and "Traceback" not in res.output
