"""The held-out malformed-input corpus's remainder (issue 107): each input refused in one line naming the file,
the field and the fix, or learned with its doubt said; never an internal error or garbage with exit 0."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sensact.cli import app
from sensact.errors import LogFormatError

runner = CliRunner()


def _run(args, code):
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code in ((code,) if isinstance(code, int) else code), res.output
    assert "Traceback" not in res.output and "internal error" not in res.output
    return " ".join(res.output.split())


@pytest.fixture(scope="module")
def track(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("track")
    _run(["simulate", "track1d", "--out", root / "log", "--seconds", "40"], 0)
    return root / "log"


def test_a_track_truth_of_strings_leaves_the_fit_unscored(track, tmp_path):
    log = tmp_path / "log"
    log.mkdir()
    for f in track.iterdir():
        (log / f.name).write_bytes(f.read_bytes())
    meta = json.loads((log / "meta.json").read_text())
    meta["truth"]["sensor"]["k_px_mm"] = "40200"
    meta["truth"]["action"]["v_mm_s"][3] = "fast"
    (log / "meta.json").write_text(json.dumps(meta))
    text = _run(["learn", "em", log, "--set", "max_iterations=3", "--no-report", "--out", tmp_path / "m.json"], (0, 3))
    assert "not a simulated track's models" in text and "not scored" in text


def test_pixel_heights_all_below_zero_are_refused(track, tmp_path):
    log = tmp_path / "log"
    log.mkdir()
    for f in track.iterdir():
        (log / f.name).write_bytes(f.read_bytes())
    head, *rows = (log / "observations.csv").read_text().splitlines()
    flipped = [f"{r.split(',')[0]},{-abs(float(r.split(',')[1]))}" if r.split(",")[1] else r for r in rows]
    (log / "observations.csv").write_text("\n".join([head, *flipped]) + "\n")
    text = _run(["learn", "em", log, "--no-report"], 2)
    assert "height_px" in text and "a height in pixels is not negative" in text and "Fix:" in text


def _mrclam(folder: Path, odometry: str, bearing: float) -> Path:
    folder.mkdir()
    (folder / "Robot1_Odometry.dat").write_text(odometry)
    rows = "\n".join(f"{1.0 + 0.1 * k} 11 {1.5 + 0.01 * k} {bearing}" for k in range(30))
    (folder / "Robot1_Measurement.dat").write_text(rows + "\n")
    (folder / "Robot1_Groundtruth.dat").write_text("\n".join(f"{1.0 + 0.1 * k} 0 0 0" for k in range(30)) + "\n")
    (folder / "Barcodes.dat").write_text("1 5\n6 11\n")
    (folder / "Landmark_Groundtruth.dat").write_text("6 1.0 2.0 0.01 0.01\n")
    return folder


@pytest.mark.parametrize(
    "speed, bearing, said",
    [
        (1e300, 0.1, "v is 1e+300 m/s: beyond any ground robot's"),
        (0.1, 25.0, "they are degrees"),
    ],
)
def test_mrclam_speeds_beyond_any_robot_and_bearings_in_degrees_are_refused(tmp_path, speed, bearing, said):
    odometry = "\n".join(f"{1.0 + 0.02 * k} {speed} 0.05" for k in range(200)) + "\n"
    folder = _mrclam(tmp_path / "MRCLAM_Dataset9", odometry, bearing)
    text = _run(["convert", "mrclam", folder, "--robot", "1", "--out", tmp_path / "out"], 2)
    assert said in text and "Fix:" in text
    assert not (tmp_path / "out").exists()


def test_a_car_log_s_rpm_beyond_any_lidar_is_refused(tmp_path):
    from sensact.io.velodyne_car_folder import _lidar_number

    with pytest.raises(LogFormatError, match=r"lidar.rpm is 1000000000000.0, not a number in \[1, 6000\]"):
        _lidar_number({"rpm": 1e12}, "rpm", tmp_path / "meta.json")
    assert _lidar_number({"rpm": 600.0}, "rpm", tmp_path / "meta.json") == 600.0
    assert np.isfinite(_lidar_number({"firing_hz": 20_000.0}, "firing_hz", tmp_path / "meta.json"))
