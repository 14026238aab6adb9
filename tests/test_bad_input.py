"""Issue 74: how a command ends (exit codes 0, 2, 3, 70, 130; SIGTERM as Ctrl-C), what it may write over,
the fit health flags, and the bounds checked before allocation."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fuzz_corpus import sensact_argv
from sensact.cli import app
from sensact.errors import EXIT_BAD_INPUT, EXIT_FLAGGED, EXIT_INTERNAL, EXIT_INTERRUPTED, SensactError

runner = CliRunner()


@pytest.fixture(scope="module")
def planar_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("planar") / "log"
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(out), "--seconds", "60"])
    assert res.exit_code == 0, res.output
    return out


def test_an_unexpected_exception_is_one_line_and_exit_70(monkeypatch, tmp_path):
    import sensact.sim.track1d as track1d

    def broken(cfg):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(track1d, "simulate_track", broken)
    res = runner.invoke(app, ["simulate", "track1d", "--out", str(tmp_path / "t")])
    assert res.exit_code == EXIT_INTERNAL
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("internal error: ZeroDivisionError: a bug")
    assert "--debug" in lines[0] and "Traceback" not in res.output


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (["--seconds", "nan"], "--seconds"),
        (["--seconds", "1e12"], "--seconds"),
        (["--seed", "-1"], "--seed"),
    ],
)
def test_simulate_refuses_a_bogus_length_or_seed_before_allocating(tmp_path, args, field):
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(tmp_path / "s"), *args])
    assert res.exit_code == EXIT_BAD_INPUT and field in res.output
    assert not (tmp_path / "s").exists()


def test_out_refuses_a_device_a_folder_and_the_figures_name(planar_log, tmp_path):
    for out in ("/dev/null", str(tmp_path), str(tmp_path / "model.png")):
        res = runner.invoke(app, ["learn", "em", str(planar_log), "--out", out])
        assert res.exit_code == EXIT_BAD_INPUT, (out, res.output)
        assert "--out" in res.output
    assert Path("/dev/null").is_char_device() and list(tmp_path.iterdir()) == []


def test_an_atomic_write_never_replaces_a_device_or_another_output_of_the_run(tmp_path):
    from sensact.io.atomic import one_run, write_bytes, write_json

    with pytest.raises(SensactError, match="not a regular file"):
        write_json("/dev/null", {"a": 1})
    with one_run():
        write_json(tmp_path / "m.json", {"a": 1})
        write_json(tmp_path / "m.json", {"a": 2})  # the same output again (a model with its error bars)
        with pytest.raises(SensactError, match="wrote another of its outputs here"):
            write_bytes(tmp_path / "m.json", b"\x89PNG")
    assert json.loads((tmp_path / "m.json").read_text()) == {"a": 2}
    write_bytes(tmp_path / "m.json", b"x")  # outside a command, a library caller decides
    assert list(tmp_path.glob("*.tmp")) == []


@pytest.mark.slow
def test_sigterm_ends_em_as_ctrl_c_does_with_the_best_model_written_and_no_temporary_file(planar_log, tmp_path):
    out = tmp_path / "m.json"
    never_done = ("--set", "max_iterations=100000", "--set", "patience=100000")
    proc = subprocess.Popen(
        sensact_argv("learn", "em", str(planar_log), "--out", str(out), "--no-report", *never_done),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    time.sleep(25)  # the kernels compiled and EM under way (before it, SIGTERM ends the command all the same)
    assert proc.poll() is None
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == EXIT_INTERRUPTED, stderr.decode()[-2000:]
    assert b"Traceback" not in stderr
    assert list(tmp_path.glob("*.tmp")) == [] and list(tmp_path.glob(".*.tmp")) == []
    if out.exists():  # interrupted in EM: the best model so far, whole
        doc = json.loads(out.read_text())
        assert doc["summary"]["stop_reason"] == "interrupted"
        assert doc["health"]["ok"] is False and "interrupted" in [f["code"] for f in doc["health"]["flags"]]


def _copy_with_readings(log: Path, dest: Path, readings) -> Path:
    shutil.copytree(log, dest)
    lines = (dest / "observations.csv").read_text().splitlines()
    col = lines[0].split(",").index("range_mm")
    rows = []
    for i, line in enumerate(lines[1:]):
        cells = line.split(",")
        cells[col] = repr(float(readings(i)))
        rows.append(",".join(cells))
    (dest / "observations.csv").write_text("\n".join([lines[0], *rows]) + "\n")
    return dest


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["constant", "noise"])
def test_a_degenerate_fit_is_written_flagged_and_exits_3(planar_log, tmp_path, kind):
    rng = np.random.default_rng(5)
    readings = (lambda i: 3000.0) if kind == "constant" else (lambda i: rng.uniform(1000, 6000))
    log = _copy_with_readings(planar_log, tmp_path / kind, readings)
    out = tmp_path / "m.json"
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(out), "--no-report"])
    assert res.exit_code == EXIT_FLAGGED, res.output
    health = json.loads(out.read_text())["health"]
    assert health["ok"] is False
    codes = {f["code"] for f in health["flags"]}
    if kind == "constant":
        assert "reading_constant" in codes
    else:
        assert codes & {"reading_explains_nothing", "gain_sign_flips"}


@pytest.fixture(scope="module")
def healthy_model(planar_log: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("healthy") / "m.json"
    res = runner.invoke(app, ["learn", "em", str(planar_log), "--out", str(out), "--no-report"])
    assert res.exit_code == 0, res.output
    return out


def test_a_healthy_fit_has_no_flags(healthy_model):
    assert json.loads(healthy_model.read_text())["health"] == {"ok": True, "flags": []}


@pytest.mark.parametrize("command", ["localize", "monitor"])
def test_what_a_flagged_model_gives_is_flagged_too(planar_log, healthy_model, tmp_path, command):
    doc = json.loads(healthy_model.read_text())
    for name, health, code in (
        ("ok.json", doc["health"], 0),
        ("flagged.json", {"ok": False, "flags": [{"code": "sigma_collapsed", "message": "range_mm's sigma."}]}, 3),
    ):
        shutil.copy(healthy_model.with_suffix(".path.npz"), (tmp_path / name).with_suffix(".path.npz"))
        (tmp_path / name).write_text(json.dumps(doc | {"health": health}))
        out = tmp_path / f"{command}_{name}"
        res = runner.invoke(app, [command, str(planar_log), "--model", str(tmp_path / name), "--out", str(out)])
        assert res.exit_code == code, res.output
        got = json.loads(out.read_text())["health"]
        if code:
            assert [f["code"] for f in got["flags"]] == ["model_flagged"] and "sigma_collapsed" in res.output
        else:
            assert got == {"ok": True, "flags": []}


def test_a_model_that_is_not_a_model_is_refused(healthy_model):
    from sensact.app.logs import read_em_model

    tmp_path = healthy_model.parent
    good = json.loads(healthy_model.read_text())
    bad = {
        "prior_cov": [[1, 2, 0], [2, 1, 0], [0, 0, 1]],
        "prior_mean": [float("nan"), 0, 0],
    }
    for key, value in bad.items():
        doc = json.loads(json.dumps(good))
        doc["model"][key] = value
        (tmp_path / "bad.json").write_text(json.dumps(doc))
        with pytest.raises(SensactError):
            read_em_model(tmp_path / "bad.json")
    doc = json.loads(json.dumps(good))
    doc["model"]["action"]["delay_steps"] = 10**9
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(SensactError, match="delay_steps"):
        read_em_model(tmp_path / "bad.json")


def test_delayed_commands_never_allocate_more_than_the_log():
    from sensact.models.linear_action import delayed

    c = np.arange(5.0)[:, None]
    assert delayed(c, 2).ravel().tolist() == [0, 0, 0, 1, 2]
    assert delayed(c, 10**12).ravel().tolist() == [0, 0, 0, 0, 0]


def test_a_wrong_option_is_one_line_with_exit_2(monkeypatch, capsys):
    """click's usage errors (a wrong type, an unknown option, a missing argument) end as every bad input does."""
    from sensact.cli import main

    for argv, where in (
        (["reproduce", "track1d", "--trials", "abc"], "sensact reproduce"),
        (["learn", "em", "--bogus", "1"], "sensact learn em"),
        (["learn", "em"], "sensact learn em"),
    ):
        monkeypatch.setattr("sys.argv", ["python -m sensact", *argv])
        with pytest.raises(SystemExit) as end:
            main()
        err = capsys.readouterr().err
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert end.value.code == EXIT_BAD_INPUT and len(lines) == 1, err
        assert lines[0].startswith("error: ") and lines[0].endswith(f"Fix: see `{where} --help`."), lines[0]


def test_a_late_row_is_refused_by_chapter_3_before_allocating(tmp_path):
    rows = ["time,range,velocity_command,sonar1"] + [f"{0.1 * k:.1f},1.0,0.1,1.0" for k in range(50)]
    (tmp_path / "tb.csv").write_text("\n".join([*rows, "1e9,1.0,0.1,1.0"]) + "\n")
    res = runner.invoke(app, ["learn", "bootstrap", str(tmp_path / "tb.csv"), "--no-report"])
    # the gap before it is named (issue 95), before the steps it would take are counted
    assert res.exit_code == EXIT_BAD_INPUT and "before row 51" in res.output, res.output
    (tmp_path / "tb.csv").write_text("\n".join([rows[0], *(f"{1e3 * k:.1f},1.0,0.1,1.0" for k in range(60))]) + "\n")
    res = runner.invoke(app, ["learn", "bootstrap", str(tmp_path / "tb.csv"), "--no-report"])
    assert res.exit_code == EXIT_BAD_INPUT and "a Turtlebot logs about ten rows a second" in res.output, res.output


def test_reproduce_bounds_its_trials():
    res = runner.invoke(app, ["reproduce", "track1d", "--trials", "1000000000"])
    assert res.exit_code == EXIT_BAD_INPUT and "SENSACT_MAX_TRIALS" in res.output, res.output


def test_export_checks_the_path_and_the_calibration_it_writes(healthy_model, tmp_path):
    from sensact.io.velodyne_calibration import calibration_yaml
    from sensact.models.laser_intrinsics import LaserIntrinsics

    model = tmp_path / "m.json"
    shutil.copy(healthy_model, model)
    with np.load(healthy_model.with_suffix(".path.npz")) as z:
        arrays = {k: z[k] for k in z.files}
    tum = ["export", str(model), "--format", "tum", "--out", str(tmp_path / "m.tum")]
    for key, broken, words in (
        ("mean", lambda a: np.where(np.arange(a.shape[0])[:, None] == 3, np.nan, a), "not finite"),
        ("time_s", lambda a: a[::-1].copy(), "do not rise"),
        ("mean", lambda a: a[:-1], "times for poses"),
    ):
        np.savez(model.with_suffix(".path.npz"), **(arrays | {key: broken(arrays[key])}))
        res = runner.invoke(app, tum)
        assert res.exit_code == EXIT_BAD_INPUT and words in res.output, res.output
    np.savez(model.with_suffix(".path.npz"), **arrays)
    assert runner.invoke(app, tum).exit_code == 0
    import yaml

    cal = yaml.safe_load(calibration_yaml(LaserIntrinsics(np.zeros(4), np.full(4, 0.01), 0.002, ())))
    car = tmp_path / "car.json"
    velodyne = ["export", str(car), "--format", "velodyne", "--out", str(tmp_path / "v.yaml")]
    car.write_text(json.dumps({"velodyne_calibration": cal}))
    assert runner.invoke(app, velodyne).exit_code == 0
    assert yaml.safe_load((tmp_path / "v.yaml").read_text()) == cal  # what learn car wrote, as it wrote it
    cal["num_lasers"] = 10**8
    car.write_text(json.dumps({"velodyne_calibration": cal}))
    res = runner.invoke(app, velodyne)
    assert res.exit_code == EXIT_BAD_INPUT and "num_lasers" in res.output, res.output


def test_a_static_transform_tree_that_loops_is_refused(tmp_path):
    from sensact.io.rosbag import _camera_pose

    eye, zero = np.eye(3), np.zeros(3)
    assert _camera_pose(tmp_path, {"cam": ("base_link", eye, np.ones(3))}, "cam")[2]
    with pytest.raises(SensactError, match="form a loop"):
        _camera_pose(tmp_path, {"cam": ("link", eye, zero), "link": ("cam", eye, zero)}, "cam")


def test_one_damaged_stamp_is_told_from_a_gap_of_dropped_packets():
    from sensact.io.velodyne_car_folder import _isolated_jumps

    t = np.arange(10.0) * 0.001  # a packet a millisecond
    gap = t.copy()
    gap[5:] += 100.0  # packets dropped: one step forward, never back
    assert not _isolated_jumps(gap, 1.0).any()
    one = t.copy()
    one[4] += 1e6  # one stamp damaged: away from both neighbours, which agree
    assert _isolated_jumps(one, 1.0).tolist() == [k == 4 for k in range(10)]
    last = t.copy()
    last[-1] -= 5e5
    assert _isolated_jumps(last, 1.0).tolist() == [k == 9 for k in range(10)]


def test_a_scan_match_further_than_the_lidar_sees_is_flagged():
    from sensact.learn.velodyne_car_dynamics import car_health

    angles = np.radians(np.linspace(-5.0, 5.0, 64))
    motion = np.column_stack([np.full(10, 2.0), np.zeros(10), np.zeros(10)])  # 2 m a revolution
    assert car_health(None, angles, motion, 120.0).ok
    motion[3, 0] = 4e17  # the matched motion of a failed ICP
    flags = car_health(None, angles, motion, 120.0).flags
    assert [f.code for f in flags] == ["scan_matching_failed"] and "1 of 10" in flags[0].message
    motion[5, 1] = np.nan
    assert "2 of 10" in car_health(None, angles, motion, 120.0).flags[0].message


@pytest.mark.parametrize(
    "args,field",
    [
        (["learn", "em", "{log}", "--uncertainty", "1000000000", "--out", "{tmp}/u.json"], "--uncertainty"),
        (["fleet", "learn", "{log}", "--uncertainty", "1000000000", "--out", "{tmp}/f"], "--uncertainty"),
        (["fleet", "learn", "{log}", "--scheduler", "not an address", "--out", "{tmp}/f"], "--scheduler"),
        (["monitor", "{log}", "--model", "{model}", "--bin-s", "1e-9"], "bin_s"),
    ],
)
def test_a_count_or_an_address_that_cannot_run_is_one_line_before_any_work(
    planar_log, healthy_model, tmp_path, args, field
):
    """Issue 95: --uncertainty beyond the limit (before EM runs), a scheduler that is no address, and
    monitor bins a billion to the second end in one line, exit 2, nothing written."""
    argv = [a.format(log=planar_log, tmp=tmp_path, model=healthy_model) for a in args]
    res = runner.invoke(app, argv)
    assert res.exit_code == EXIT_BAD_INPUT, res.output
    assert f"error: {field}:" in res.output and "internal error" not in res.output
    assert not (tmp_path / "u.json").exists() and not (tmp_path / "f" / "fleet.json").exists()


def test_a_map_in_the_wrong_unit_is_refused_before_the_start_grid_is_allocated(planar_log, tmp_path):
    """Issue 95: landmarks in mm read as metres (a room 9 km across) asked the start search for a grid of
    hundreds of millions of cells (4 GiB): one line instead, naming the unit."""
    log = tmp_path / "log"
    shutil.copytree(planar_log, log)
    meta = json.loads((log / "meta.json").read_text())
    for m in meta["landmarks"]:
        m["x_mm"], m["y_mm"] = m["x_mm"] * 1000.0, m["y_mm"] * 1000.0
    (log / "meta.json").write_text(json.dumps(meta))
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(tmp_path / "m.json")])
    assert res.exit_code == EXIT_BAD_INPUT and "search.start_grid_mm" in res.output and "unit" in res.output
    assert not (tmp_path / "m.json").exists()


def test_a_track_robot_that_never_moves_is_flagged_not_an_internal_error(tmp_path):
    """Issue 95: every command zero divided the action score by the true velocities' spread (exit 70).
    Now the fit is written, flagged (command_constant, exit 3), and its share of that spread is NaN."""
    log = tmp_path / "trk"
    assert runner.invoke(app, ["simulate", "track1d", "--out", str(log)]).exit_code == 0
    rows = (log / "actions.csv").read_text().splitlines()
    (log / "actions.csv").write_text("\n".join([rows[0]] + [f"{r.split(',')[0]},0.0" for r in rows[1:]]) + "\n")
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(tmp_path / "m.json")])
    assert res.exit_code == EXIT_FLAGGED, res.output
    doc = json.loads((tmp_path / "m.json").read_text())
    assert [f["code"] for f in doc["health"]["flags"]] == ["command_constant"]


@pytest.mark.parametrize("start", ["1e9,0", "0,-2e8,1.0"])
def test_localize_refuses_a_start_kilometres_from_the_map(planar_log, healthy_model, tmp_path, start):
    """Issue 95: `localize --start 1e9` was run with exit 0; a start over 100 m from every landmark is one line."""
    res = runner.invoke(app, ["localize", str(planar_log), "--model", str(healthy_model), "--start", start])
    assert res.exit_code == EXIT_BAD_INPUT and "error: --start:" in res.output and "in mm" in res.output


@pytest.mark.parametrize("sigma", [1e-300, 1e300])
def test_a_model_with_a_sigma_no_fit_gives_is_refused_where_it_is_read(planar_log, healthy_model, tmp_path, sigma):
    """Issue 95: a sigma of 1e-300 was monitored with exit 0 (every reading infinitely sure)."""
    doc = json.loads(healthy_model.read_text())
    doc["model"]["sensor"]["channels"][0]["sigma"] = sigma
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    res = runner.invoke(app, ["monitor", str(planar_log), "--model", str(bad)])
    assert res.exit_code == EXIT_BAD_INPUT and "channels[0].sigma" in res.output


@pytest.mark.parametrize(
    "args,field",
    [
        (["simulate", "track1d", "--set", "dt_s=0"], "--set"),
        (["simulate", "track1d", "--set", "motion_noise_mm_s=-1"], "--set"),
        (["simulate", "field2d", "--set", "false_positive_rate=2"], "--set"),
    ],
)
def test_a_simulator_setting_out_of_range_is_one_line(tmp_path, args, field):
    """Issue 95: dt_s 0 divided by zero (exit 70); a negative noise or a false-positive share of 2 ran."""
    res = runner.invoke(app, [*args, "--out", str(tmp_path / "sim")])
    assert res.exit_code == EXIT_BAD_INPUT and f"error: {field}:" in res.output, res.output
    assert not (tmp_path / "sim").exists()


@pytest.mark.parametrize("key,value", [("observations", ["x"]), ("truth", "x")])
def test_a_meta_json_part_of_the_wrong_type_is_one_line(planar_log, tmp_path, key, value):
    """Issue 95: meta.json's observations as a list, or its truth as a string, were AttributeErrors."""
    log = tmp_path / "log"
    shutil.copytree(planar_log, log)
    meta = json.loads((log / "meta.json").read_text())
    meta[key] = value
    (log / "meta.json").write_text(json.dumps(meta))
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(tmp_path / "m.json")])
    assert res.exit_code == EXIT_BAD_INPUT and f"meta.json: {key}:" in res.output.replace("\n", ""), res.output


def test_a_start_model_whose_summary_config_is_not_an_object_is_one_line(planar_log, healthy_model, tmp_path):
    doc = json.loads(healthy_model.read_text())
    doc["summary"]["config"] = "a string"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    res = runner.invoke(
        app, ["learn", "em", str(planar_log), "--start-from", str(bad), "--out", str(tmp_path / "m.json")]
    )
    assert res.exit_code == EXIT_BAD_INPUT and "summary.config" in res.output


def _turtlebot_csv(path: Path, sonar: str = "clean", truth: str = "sorted") -> Path:
    """Two minutes of a Turtlebot-style 1-D log (back and forth at 0.15 m/s in front of a wall)."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 120.0, 0.1)
    cmd = np.where((t // 6) % 2 == 0, 0.15, -0.15)
    pos = 1.0 + np.cumsum(cmd) * 0.1
    reading = pos + rng.normal(0, 0.02, t.size) if sonar == "clean" else rng.uniform(0.2, 3.0, t.size)
    recorded = rng.permutation(pos) if truth == "shuffled" else pos
    rows = [f"{a:.2f},{x:.4f},{c:.3f},{s:.4f}" for a, x, c, s in zip(t, recorded, cmd, reading, strict=True)]
    path.write_text("\n".join(["time,range,velocity_command,sonar1", *rows]) + "\n")
    return path


@pytest.mark.parametrize("sonar, codes", [("clean", []), ("noise", ["reading_explains_nothing"])])
def test_chapter_3_flags_a_sonar_that_reads_noise_as_em_does(tmp_path, sonar, codes):
    """Issue 95: Algorithm 1 on a sonar of pure noise returned models with exit 0. Its own two estimates
    (w_a from A, w_s from S) must explain each other, as EM's f must explain the readings."""
    csv = _turtlebot_csv(tmp_path / "tb.csv", sonar=sonar)
    out = tmp_path / "b.json"
    res = runner.invoke(
        app, ["learn", "bootstrap", str(csv), "--out", str(out), "--no-report", "--set", "t_start_s=10"]
    )
    assert res.exit_code == (EXIT_FLAGGED if codes else 0), res.output
    assert [f["code"] for f in json.loads(out.read_text())["health"]["flags"]] == codes


def test_a_recorded_distance_out_of_order_is_refused_by_name(tmp_path):
    """Issue 95: a shuffled truth column was scored against as if it were the robot's path."""
    csv = _turtlebot_csv(tmp_path / "tb.csv", truth="shuffled")
    res = runner.invoke(app, ["learn", "bootstrap", str(csv), "--out", str(tmp_path / "b.json"), "--no-report"])
    assert res.exit_code == EXIT_BAD_INPUT
    assert "range" in res.output and "autocorrelation" in res.output
    assert not (tmp_path / "b.json").exists()


def test_a_fleet_never_writes_into_an_input_log(planar_log, tmp_path):
    """Issue 95: --out naming a log (or the folder that holds one of the name the results take) wrote the
    fleet's models among the log's own files."""
    other = tmp_path / "other" / "log"
    shutil.copytree(planar_log, other)
    for logs, out in (([planar_log, other], other), ([planar_log, other], other / "inside"), ([other], other.parent)):
        argv = ["fleet", "learn", *map(str, logs), "--out", str(out), "--workers", "1"]
        res = runner.invoke(app, argv)
        assert res.exit_code == EXIT_BAD_INPUT and "one of its inputs" in res.output, res.output
    assert sorted(p.name for p in other.iterdir()) == sorted(p.name for p in planar_log.iterdir())


@pytest.mark.parametrize("bins", ["0", "1", "1000000000"])
def test_bins_out_of_range_are_one_line_before_the_log_is_binned(planar_log, healthy_model, tmp_path, bins):
    argv = ["monitor", str(planar_log), "--model", str(healthy_model), "--out", str(tmp_path / "m.json")]
    res = runner.invoke(app, [*argv, "--bins", bins])
    assert res.exit_code == EXIT_BAD_INPUT and "--bins" in res.output, res.output


@pytest.mark.parametrize("scale, says", [(-1.0, "below zero"), (1e-3, "times the map's extent")])
def test_a_log_whose_ranges_are_signed_or_in_metres_is_not_scored(planar_log, healthy_model, tmp_path, scale, says):
    """Issue 95: `evaluate log` scored a model learned in mm on ranges in metres, or negative, with exit 0."""
    log = tmp_path / "log"
    shutil.copytree(planar_log, log)
    rows = (log / "observations.csv").read_text().splitlines()
    col = rows[0].split(",").index("range_mm")
    cells = [r.split(",") for r in rows[1:]]
    for c in cells:
        c[col] = repr(float(c[col]) * scale)
    (log / "observations.csv").write_text("\n".join([rows[0], *(",".join(c) for c in cells)]) + "\n")
    res = runner.invoke(
        app, ["evaluate", "log", str(log), "--model", str(healthy_model), "--out", str(tmp_path / "e.json")]
    )
    assert res.exit_code == EXIT_BAD_INPUT and says in res.output and "range_mm" in res.output, res.output
    assert not (tmp_path / "e.json").exists()


@pytest.mark.parametrize("seed, code", [(3, "mount_not_identified"), (4, "turn_sign_flipped")])
def test_a_short_range_only_log_that_em_mirrors_is_flagged(tmp_path, seed, code):
    """Issue 94, item 4: 30 s of a range-only robot on wheel speeds, its start unknown. Seed 3 comes out with
    the sensor 1.24 m from the axle on a path of 0.39 m, seed 4 with an axle of -1.69 m; both ended exit 0."""
    log = tmp_path / "log"
    argv = ["simulate", "diffdrive", "--out", str(log), "--seconds", "30", "--seed", str(seed)]
    assert runner.invoke(app, [*argv, "--set", "sensor=radio", "--set", "wheel_axle_mm=230"]).exit_code == 0
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(tmp_path / "m.json"), "--no-report"])
    assert res.exit_code == EXIT_FLAGGED, res.output
    assert code in [f["code"] for f in json.loads((tmp_path / "m.json").read_text())["health"]["flags"]]


def test_correlated_residuals_are_flagged_beyond_half(planar_log, healthy_model):
    """Issue 94, item 4: a channel's residuals with lag-1 autocorrelation beyond +-0.5 (a 1-D log whose range
    errors alternate gave a sigma ten times too small, flagged only as not converged)."""
    from sensact.app import calibrate, open_log
    from sensact.learn.em.checks.fit_health import em_health

    cal = calibrate(open_log(planar_log), sets=["max_iterations=3"])
    result, data = cal.result, cal.log.data

    def codes(r: float | None) -> list[str]:
        return [f.code for f in em_health(result, data, {"range_mm": r}).flags if f.code == "residuals_correlated"]

    assert codes(-0.53) == codes(0.6) == ["residuals_correlated"]
    assert codes(0.45) == codes(-0.3) == codes(None) == []


def test_a_model_turning_against_omega_is_flagged(planar_log):
    """Issue 94, item 4, on (v, omega) commands: the model's own turn rate over the log falls as omega rises."""
    from dataclasses import replace

    from sensact.app import calibrate, open_log
    from sensact.learn.em.checks.fit_health import em_health

    cal = calibrate(open_log(planar_log), sets=["max_iterations=3"])
    result, data, action = cal.result, cal.log.data, cal.model.action
    beta = action.coefficients.copy()
    beta[1 + action.command_names.index("omega_rad_s"), action.velocity_names.index("v_theta_rad_s")] *= -1.0
    flipped = replace(result, model=result.model.replace(action=action.with_coefficients(beta)))

    def codes(r) -> list[str]:
        return [f.code for f in em_health(r, data).flags if f.code == "turn_sign_flipped"]

    assert codes(result) == [] and codes(flipped) == ["turn_sign_flipped"]
