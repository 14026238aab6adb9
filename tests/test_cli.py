"""The sensact command: help for every command, end-to-end runs, and one-line errors."""

from __future__ import annotations

import json
import re
import shutil

import pytest
import typer
from typer.testing import CliRunner

import sensact
from conftest import assert_written
from sensact.cli import app
from sensact.cli.base import one_line_paragraphs
from sensact.evaluate.bars import counts, verdict_line
from sensact.experiments import em1d, field2d, track1d
from sensact.experiments.field2d import bar_misses
from turtlebot_robot import write_turtlebot_csv

runner = CliRunner()


def _command_paths(command, path=()):
    """Every command and group under ``command``, as the words that name it."""
    yield path, command
    for name, sub in getattr(command, "commands", {}).items():
        yield from _command_paths(sub, (*path, name))


COMMANDS = list(_command_paths(typer.main.get_command(app)))


@pytest.mark.parametrize("path", [list(p) for p, _ in COMMANDS], ids=[" ".join(p) or "sensact" for p, _ in COMMANDS])
def test_every_command_has_help(path):
    res = runner.invoke(app, [*path, "--help"])
    assert res.exit_code == 0, res.output
    assert "Usage" in res.output


def test_every_commands_help_is_one_line_a_paragraph():
    # typer's rich help keeps a docstring's single line breaks (in a group's command list, and in every
    # paragraph after the first), so text that wraps in the source would break mid-sentence at 80 columns
    assert len(COMMANDS) >= 14
    for path, command in COMMANDS:
        paragraphs = (command.short_help or command.help or "").split("\n\n")
        assert paragraphs[0].strip(), path
        for p in paragraphs:
            assert p.startswith("\b") or "\n" not in p.strip(), (path, p)


def test_the_command_reference_is_generated_from_the_help_and_current():
    """docs/cli-reference.md is what `python -m sensact.cli.reference` writes from the CLI's own help, with a
    section per command that runs something; a stale page fails here."""
    from pathlib import Path

    from sensact.cli.reference import leaf_commands, render

    page = Path(__file__).resolve().parents[1] / "docs" / "cli-reference.md"
    assert page.read_text() == render(), "stale: run `python -m sensact.cli.reference > docs/cli-reference.md`"
    leaves = [" ".join(p) for p, _ in leaf_commands()]
    assert len(leaves) >= 17 and all(f"## `sensact {name}`" in page.read_text() for name in leaves)
    assert {"convert bag", "export", "learn em"} <= set(leaves)


def test_one_line_paragraphs_joins_lines_and_keeps_paragraphs_and_kept_blocks():
    doc = """Summary that
    wraps.

    Body line one
       and two.

    \b
    kept
    lines"""
    assert one_line_paragraphs(doc) == "Summary that wraps.\n\nBody line one and two.\n\n\b\nkept\nlines"
    assert one_line_paragraphs(None) is None


def test_simulate_then_learn(tmp_path):
    log = tmp_path / "log"
    res = runner.invoke(
        app,
        [
            "simulate",
            "track1d",
            "--seconds",
            "60",
            "--seed",
            "2",
            "--out",
            str(log),
            "--set",
            "observation_noise_px=1.0",
        ],
    )
    assert res.exit_code == 0, res.output
    meta = json.loads((log / "meta.json").read_text())
    assert meta["simulator"]["config"]["observation_noise_px"] == 1.0
    res = runner.invoke(app, ["learn", "bootstrap", str(log), "--a0", "sign", "--out", str(tmp_path / "m.json")])
    assert res.exit_code == 0, res.output
    assert "S(o) =" in res.output and "vs truth" in res.output
    out = json.loads((tmp_path / "m.json").read_text())
    assert out["status"] == "ok" and out["config"]["a0"] == "sign"
    assert out["sensor"]["kind"] == "polynomial1d" and len(out["action"]["coef"]) == 5
    assert out["evaluation"]["sensor_rms"] > 0
    assert (tmp_path / "m.history.npz").is_file()
    assert (tmp_path / "m.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and "m.png" in res.output
    assert (tmp_path / "m.png").stat().st_size > 30_000  # three panels of points and curves


def test_learn_em_bad_setting_is_one_line_naming_it(tmp_path):
    """A bad --set or --preset on a log EM can read: one line naming the field (the settings rest on the log's
    own settings file, so they are read after the log)."""
    log = tmp_path / "log"
    assert runner.invoke(app, ["simulate", "field2d", "--seconds", "20", "--out", str(log)]).exit_code == 0
    for args, needle in (
        (["--set", "patience=0"], "patience"),
        (["--preset", "mars_rover"], "no preset 'mars_rover'"),
        (["--preset", "track_1d"], "preset track_1d is for a 1-D robot"),
    ):
        res = runner.invoke(app, ["learn", "em", str(log), *args])
        assert res.exit_code == 2 and needle in res.output and "Traceback" not in res.output, res.output


@pytest.mark.parametrize(
    "args,needle",
    [
        (["learn", "bootstrap", "/nonexistent/log"], "not a log folder"),
        (["learn", "bootstrap", ".", "--a0", "cubic"], "--a0"),
        (["simulate", "track1d", "--out", "x", "--set", "gamma=0.5"], "unknown field 'gamma'"),
        (["reproduce", "nothing"], "unknown experiment"),
        (["reproduce", "real", "--data", "/nonexistent", "--set", "seconds=3"], "seconds is not an EM setting"),
        (["reproduce", "real", "--data", "/nonexistent", "--set", "motion_noise=wobbly"], "motion_noise.kind must be"),
        (["simulate", "field2d", "--out", "x", "--setting", "mars"], "unknown setting"),
        (["learn", "em", "/nonexistent/log"], "not a log folder: not found"),
        *(
            (["simulate", sim, "--out", "x", "--seconds", "0"], "--seconds: seconds")
            for sim in ("track1d", "field2d", "diffdrive", "car")
        ),
    ],
)
def test_bad_input_is_one_line_without_traceback(args, needle):
    res = runner.invoke(app, args)
    assert res.exit_code == 2
    assert needle in res.output
    assert "Traceback" not in res.output


@pytest.mark.parametrize(
    "meta,command,fix",
    [
        ({"geometry": "planar"}, "bootstrap", "learn it with `sensact learn em {d}`; `sensact learn bootstrap` reads"),
        ({"geometry": "track"}, "bootstrap", "or write it again with `sensact convert track`"),
        ({"geometry": "planar"}, "car", "a log folder for EM (geometry: planar), not a car log"),
        ({"action": {"column": "c"}, "sensor": {"column": "o"}}, "car", "`sensact learn bootstrap {d}` (chapter 3)"),
        ({"platform": "car", "lidar": {"file": "velodyne.pcap"}}, "em", "learn it with `sensact learn car {d}`"),
        ({"platform": "car", "lidar": {"file": "velodyne.pcap"}}, "bootstrap", "learn it with `sensact learn car {d}`"),
    ],
)
def test_a_folder_for_another_learner_names_the_command_that_learns_it(tmp_path, meta, command, fix):
    """Each learner reads only its own kind of folder; given another's, it says which command reads that one."""
    folder = tmp_path / "log"
    folder.mkdir()
    (folder / "meta.json").write_text(json.dumps({"format": "sensact-log", "version": 1, **meta}))
    res = runner.invoke(app, ["learn", command, str(folder)])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert fix.format(d=folder) in " ".join(res.output.split()), res.output


def test_a_path_the_system_refuses_is_one_line(tmp_path):
    """An --out under a file (or any path the system refuses) names the path and the fix, like bad input."""
    blocker = tmp_path / "results"
    blocker.write_text("not a folder")
    for args in (["simulate", "track1d", "--seconds", "5"], ["reproduce", "track1d", "--trials", "1"]):
        res = runner.invoke(app, [*args, "--out", str(blocker / "sub")])
        flat = " ".join(res.output.split())
        assert res.exit_code == 2 and f"{blocker}" in flat and "a file stands where a folder is needed" in flat, flat
        assert "Traceback" not in res.output
    res = runner.invoke(app, ["--debug", "simulate", "track1d", "--seconds", "5", "--out", str(blocker / "sub")])
    assert isinstance(res.exception, OSError)  # --debug still shows what the system raised


def test_version_is_printed():
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0 and res.output.strip() == f"sensact {sensact.__version__}"


def test_debug_shows_the_traceback():
    from sensact.errors import LogFormatError

    res = runner.invoke(app, ["--debug", "learn", "bootstrap", "/nonexistent/log"])
    assert isinstance(res.exception, LogFormatError)  # raised through, where a traceback shows it
    plain = runner.invoke(app, ["learn", "bootstrap", "/nonexistent/log"])
    assert isinstance(plain.exception, SystemExit) and "Fix:" in plain.output  # one line, no traceback


def test_reproduce_track1d_writes_the_documented_shape(tmp_path):
    res = runner.invoke(app, ["reproduce", "track1d", "--trials", "2", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "track1d.json").read_text())
    assert out["experiment"] == "track1d" and set(out["rows"]) == {"linear", "sign", "constant"}
    for row in out["rows"].values():
        assert {
            "sensor_rms_mm",
            "sensor_rms_mm_std",
            "action_rms_mm_s",
            "action_rms_mm_s_std",
            "consistency",
            "converged",
            "trials",
        } <= set(row)
        assert row["trials"] == 2
    assert {"degree_selection", "thesis", "seconds"} <= set(out)
    assert out["sensact_version"] == sensact.__version__  # a result names the code that made it
    for fig in ("fig3_7_location_estimates.png", "fig3_8_learned_vs_measured.png", "fig3_9_learning_curves.png"):
        assert (tmp_path / fig).stat().st_size > 10_000
    assert "Table 3.1" in (tmp_path / "track1d.md").read_text()
    checks = track1d.scorecard(out)
    assert out["scorecard"] == [c.to_dict() for c in checks] and len(checks) == 12
    assert f"### Bars: {counts(checks)[0]} of 12 cleared" in (tmp_path / "track1d.md").read_text()
    assert f"track1d {verdict_line(checks)}" in " ".join(res.output.split())


def test_simulate_field2d_then_learn_em(tmp_path):
    log = tmp_path / "field"
    res = runner.invoke(app, ["simulate", "field2d", "--seconds", "120", "--seed", "3", "--out", str(log)])
    assert res.exit_code == 0, res.output
    assert "40 actions" in res.output
    model = tmp_path / "model.json"
    res = runner.invoke(
        app,
        ["learn", "em", str(log), "--out", str(model), "--set", "max_iterations=40", "--set", "prune_rad_per_step=0"],
    )
    assert_written(res)
    assert "f(d) =" in res.output and "vs truth" in res.output and "sigma_2" in res.output
    out = json.loads(model.read_text())
    assert out["model"]["kind"] == "em_model" and len(out["model"]["action"]["velocities"]) == 40
    assert out["summary"]["iterations"] <= 40 and out["evaluation"]["vtheta_rms_rad_s"] < 0.5
    from sensact.models.em_model import EMModel

    assert EMModel.from_dict(out["model"]).geometry.name == "planar"
    import numpy as np

    with np.load(tmp_path / "model.history.npz", allow_pickle=False) as h:
        assert h["loglik"].size == out["summary"]["iterations"] and h["velocities"].shape[1:] == (40, 3)
    # the fit's figure: the likelihood, f over the readings, the smoothed path
    assert (tmp_path / "model.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and "model.png" in res.output
    assert (tmp_path / "model.png").stat().st_size > 30_000
    # a learned Sigma_m is held first; with a ridge search the run says where the search moved (plain EM: the
    # schedule counts its iterations)
    sets = ["motion_noise=shared", "refine_from=5", "ridge_search_mm=300", "max_iterations=8", "prune_rad_per_step=0"]
    sets.append("accelerate=false")
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(model)] + [a for x in sets for a in ("--set", x)])
    assert_written(res)
    assert "ridge search at iteration 5" in res.output
    (ridge,) = json.loads(model.read_text())["summary"]["ridge"]
    assert ridge["loglik_after"] >= ridge["loglik_before"] and abs(ridge["shift_mm"]) <= 300.0


def test_reproduce_em1d_and_field2d_write_the_documented_keys(tmp_path):
    res = runner.invoke(
        app,
        [
            "reproduce",
            "em1d",
            "--out",
            str(tmp_path),
            "--set",
            "seconds=240",
            "--set",
            "change_at_s=120",
            "--set",
            "max_iterations=60",
        ],
    )
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "em1d.json").read_text())
    keys = {"sensor_rms_px", "sensor_rms_pct", "action_rms_mm_s", "action_rms_pct", "scale_ratio", "iterations"}
    assert keys <= set(out["ours"]) and keys <= set(out["thesis"])
    for k in ("change_before_on_before", "change_after_on_after", "change_before_on_after", "change_after_on_before"):
        assert {"action_rms_mm_s", "scale_ratio"} <= set(out["ours"][k])
    assert (tmp_path / "fig4_6_em1d_learned.png").stat().st_size > 10_000
    assert out["scorecard"] == [c.to_dict() for c in em1d.scorecard(out)]
    assert f"em1d {verdict_line(em1d.scorecard(out))}" in " ".join(res.output.split())
    assert (tmp_path / "fig4_7_em1d_relearned.png").stat().st_size > 10_000
    res = runner.invoke(
        app,
        [
            "reproduce",
            "field2d",
            "--trials",
            "1",
            "--out",
            str(tmp_path),
            "--set",
            "seconds=60",
            "--set",
            "max_iterations=20",
        ],
    )
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "field2d.json").read_text())
    keys = {
        "vx_rms_mm_s",
        "vy_rms_mm_s",
        "vtheta_rms_rad_s",
        "sigma1_learned",
        "sigma1_true",
        "sigma2_learned",
        "sigma2_true",
        "iterations",
        "loglik_start",
        "loglik_best",
        "seconds",
    }
    assert keys <= set(out["ours"]) and keys - {"loglik_best"} <= set(out["thesis"])
    assert out["config"]["simulator"]["seconds"] == 60 and out["config"]["learner"]["thesis"]["max_iterations"] == 20
    assert out["config"]["learner"]["thesis"]["prune_rad_per_step"] == 0.0  # the simulation default survives --set
    for fig in ("fig4_4_field2d_learning.png", "fig4_5_field2d_sensor.png", "fig4_2_real_robot_learning.png"):
        assert (tmp_path / fig).stat().st_size > 10_000
    assert "real-robot setting" in (tmp_path / "field2d.md").read_text()
    page = (tmp_path / "index.html").read_text()  # both runs' tables and figures on one page
    assert "index.html" in res.output and 'id="em1d"' in page and 'id="field2d"' in page
    assert all(f'src="{f.name}"' in page for f in tmp_path.glob("fig4_*.png"))
    # a minute of walking and 20 iterations miss bars; the command names each miss, as the JSON does
    o = out["ours"]
    assert o["misses"] == bar_misses(out["per_trial"][0]) and o["misses"]
    assert o["clears_bars_every_trial"] is False and o["clears_bars_mean"] is (not bar_misses(o))
    checks = field2d.scorecard(out)
    assert out["scorecard"] == [c.to_dict() for c in checks] and any(c.cleared is False for c in checks)
    flat = " ".join(res.output.split())
    assert f"field2d {verdict_line(checks)}" in flat, res.output
    assert "em1d bars:" in flat.split("every experiment in")[1]  # the folder's earlier run, summed up at the end
    assert "Bars: " in (tmp_path / "field2d.md").read_text() and 'class="missed"' in page


def test_field2d_bar_misses_name_each_bar_a_trial_misses():
    ok = {"vx_rms_mm_s": 23.06, "vy_rms_mm_s": 18.34, "vtheta_rms_rad_s": 0.086}  # at a bar is within it
    ok |= {"sigma1_error_pct": 5.0, "sigma2_error_pct": 0.0, "seed": 2}
    assert bar_misses(ok) == []
    bad = ok | {"vx_rms_mm_s": 23.53, "sigma2_error_pct": 5.5}
    assert bar_misses(bad) == [
        "seed 2: v_x RMS 23.53 mm/s (bar ≤ 23.06 mm/s)",
        "seed 2: sigma_2 error 5.5 % (bar ≤ 5.0 %)",
    ]
    mean = {k: v for k, v in bad.items() if k != "seed"} | {"vtheta_rms_rad_s": 0.09}
    assert bar_misses(mean)[1] == "mean: v_theta RMS 0.090 rad/s (bar ≤ 0.086 rad/s)"


@pytest.mark.slow
def test_simulate_car_then_learn_car_with_ros_export(tmp_path):
    log = tmp_path / "car"
    res = runner.invoke(
        app,
        [
            "simulate",
            "car",
            "--seconds",
            "20",
            "--seed",
            "4",
            "--out",
            str(log),
            "--set",
            "turn_times_s=[8]",
            "--set",
            "stop_times_s=[15]",
        ],
    )
    assert res.exit_code == 0, res.output
    assert (log / "velodyne.pcap").stat().st_size > 10_000_000
    import dataclasses

    import numpy as np

    from sensact.io.velodyne_calibration import read_calibration, write_calibration

    # as a user's folder: no rates and no vertical angles in meta.json, the factory's calibration file
    # (here the true one, with a distance correction per laser) beside it
    meta = json.loads((log / "meta.json").read_text())
    for name in ("vertical_deg", "firing_hz", "rpm"):
        del meta["lidar"][name]
    (log / "meta.json").write_text(json.dumps(meta))
    factory = read_calibration(log / "calibration_true.yaml")
    extra = tuple({"laser_id": i, "dist_correction": 0.01 * i} for i in range(factory.n_lasers))
    write_calibration(tmp_path / "factory.yaml", dataclasses.replace(factory, extra=extra))
    out, yml = tmp_path / "car.json", tmp_path / "learned.yaml"
    res = runner.invoke(
        app,
        [
            *("learn", "car", str(log), "--out", str(out), "--calibration-yaml", str(yml)),
            *("--factory-calibration", str(tmp_path / "factory.yaml")),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "omega =" in res.output and "vs truth: laser angles" in res.output
    assert "firing_hz 7800 Hz, measured from the packets' clock" in res.output
    assert "rpm 600 rpm, measured" in res.output and "warning" not in res.output
    model = json.loads(out.read_text())
    assert len(model["laser_angles_deg"]) == 64 and model["car_dynamics"]["kind"] == "car_dynamics"
    assert model["evaluation"]["laser_angle_rms_deg"] < 1.0  # 20 s: C rests on a few fast intervals
    from sensact.cli.learn.velodyne_car import best_matcher

    # the best matcher it has, said in one line: KISS-ICP with the kiss extra (the test extra has it)
    assert model["config"]["matcher"] == best_matcher()
    assert ("scan matcher: KISS-ICP" in res.output) == (best_matcher() == "kiss_icp")
    cal = read_calibration(yml)
    np.testing.assert_allclose(np.degrees(cal.horizontal_rad) + 90.0, model["laser_angles_deg"], atol=1e-9)
    np.testing.assert_allclose(cal.vertical_rad, factory.vertical_rad, atol=1e-12)
    assert [e["dist_correction"] for e in cal.extra] == [0.01 * i for i in range(64)]
    page = (tmp_path / "car.report.html").read_text()  # the page a browser opens (tests/test_report_page.py)
    assert "Algorithm 3 on" in page and page.count('src="data:image/png;base64,') == 1
    # `sensact export --format velodyne` writes the same calibration from the model alone
    exp = runner.invoke(app, ["export", str(out), "--format", "velodyne", "--out", str(tmp_path / "exported.yaml")])
    assert exp.exit_code == 0, exp.output
    exported = read_calibration(tmp_path / "exported.yaml")
    np.testing.assert_array_equal(exported.horizontal_rad, cal.horizontal_rad)
    np.testing.assert_array_equal(exported.vertical_rad, cal.vertical_rad)
    assert exported.extra == cal.extra
    # the factory file holds the true theta_l: about its mount yaw it differs by the relative angles' error
    fc = model["factory_comparison"]
    assert "vs the factory calibration's horizontal angles" in res.output
    assert fc["mount_yaw_deg"] == pytest.approx(meta["truth"]["mount_yaw_deg"], abs=1.0)
    assert fc["rms_deg"] <= model["evaluation"]["laser_angle_rms_deg"] + 1e-3
    png = out.with_suffix(".png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 50_000 and "car.png" in res.output
    # without the controls: the laser angles and C from the scans alone (Algorithm 3's first pass)
    (log / "actions.csv").unlink()
    res = runner.invoke(app, ["learn", "car", str(log), "--out", str(out), "--factory-calibration", str(yml)])
    assert res.exit_code == 0, res.output
    assert "no actions.csv" in res.output and "laser angles from the scans alone" in res.output
    assert "omega =" not in res.output
    alone = json.loads(out.read_text())
    assert alone["car_dynamics"] is None and alone["iterations"] == 0
    assert alone["evaluation"]["laser_angle_rms_deg"] < 1.0
    assert alone["offset_C_deg"] == pytest.approx(model["history"][0]["C_rad"] * 180 / np.pi, abs=1e-9)
    # the "factory" here is Algorithm 3's export (C_final - 90° on the same relative angles), so the scans
    # alone differ from it by one constant, 90° + C_first - C_final, and not at all about it
    fc = alone["factory_comparison"]
    assert fc["rms_deg"] < 1e-6 and fc["mount_yaw_deg"] == pytest.approx(
        90.0 + alone["offset_C_deg"] - model["offset_C_deg"], abs=1e-6
    )
    res = runner.invoke(app, ["learn", "car", str(tmp_path)])
    assert res.exit_code == 2 and "meta.json" in res.output


def test_a_track_velocity_is_told_toward_or_away_from_what_the_robot_ranges_to():
    """Sec. 4.4.3's track state is the distance to the beacon: a positive velocity shortens it."""
    from sensact.cli.scores import describe_track_velocity
    from sensact.models.linear_action import LinearActionModel

    toward = LinearActionModel("affine", 1, [[0.0], [0.5]], ("v_cmd_mm_s",), ("v_mm_s",))
    assert "moves toward it at 0.5 mm/s per unit of v_cmd_mm_s" in describe_track_velocity(toward)
    away = LinearActionModel("affine", 1, [[3.0], [-0.92]], ("u",), ("v_mm_s",))
    assert "moves away from it at 0.92 mm/s per unit of u" in describe_track_velocity(away)
    curved = LinearActionModel("polynomial", 2, [[0.0], [0.5], [0.1]], ("u",), ("v_mm_s",))
    assert describe_track_velocity(curved).endswith("a negative v_mm_s takes the robot away from it")


@pytest.mark.slow
def test_learn_em_on_a_turtlebot_csv_recovers_the_gain_and_sonar(tmp_path):
    csv = tmp_path / "robot.csv"
    write_turtlebot_csv(csv, with_range=True)
    model = tmp_path / "m.json"
    res = runner.invoke(app, ["learn", "em", str(csv), "--out", str(model)])
    assert_written(res)
    assert "Turtlebot CSV" in res.output and "continuous commands (v_cmd_mm_s)" in res.output
    out = json.loads(model.read_text())
    channels = out["model"]["sensor"]["channels"]
    assert [c["name"] for c in channels] == ["sonar1", "raw_ir1", "raw_ir2", "raw_ir3", "raw_ir4"]
    ev = out["evaluation"]
    # seeds 7, 8, 9 gave gain 0.25-0.36 % off, sonar1 0.53-1.35 % of its span, the delay exact
    assert ev["gain_error_pct"] < 1.0, ev["gain_error_pct"]
    assert ev["sensors"]["sonar1"]["rms_pct_of_span"] < 2.0
    assert ev["delay_s"] == pytest.approx(0.12, abs=0.01)
    assert (tmp_path / "m.png").stat().st_size > 30_000  # a panel per channel and the smoothed state
    assert (tmp_path / "m_against_range.png").stat().st_size > 30_000  # and against the range column
    assert "m_against_range.png" in res.output
    # the smoothed distance per step, written beside the model, is the one scored: after the state map
    # it is the range column within the map's RMS, which on this robot is a few mm
    import numpy as np

    from sensact.io.turtlebot import read_turtlebot_landmark_log

    _, truth_mm = read_turtlebot_landmark_log(csv)
    with np.load(tmp_path / "m.path.npz", allow_pickle=False) as path:
        assert list(path["state"]) == ["distance"] and path["mean"].shape == (truth_mm.size, 1)
        smap = ev["state_map"]
        rms = np.std(smap["scale"] * path["mean"][:, 0] + smap["offset_mm"] - truth_mm)
        assert rms == pytest.approx(smap["rms_mm"], rel=1e-9) and rms < 10.0, rms
        assert 0.0 < np.median(path["sd"]) < 10.0
    assert "stopped: converged" in res.output and "raise the cap" not in res.output
    # the seeded robot's range grows with its command: sec. 4.4.3's velocity, toward the wall, is negative,
    # and the output says which way the robot goes, with the gain's own digits
    coef = out["model"]["action"]["coefficients"][1][0]
    said = " ".join(res.output.split())
    assert coef < 0 and f"this robot moves away from it at {-coef:.4g} mm/s per unit of v_cmd_mm_s" in said, said
    # --set overrides the Turtlebot's settings; without a range column there is nothing to score, and the
    # figure the first run drew against its range column is removed, so that it cannot pass for this fit
    write_turtlebot_csv(csv, with_range=False)
    res = runner.invoke(app, ["learn", "em", str(csv), "--out", str(model), "--set", "max_iterations=5"])
    assert_written(res)
    assert "no range column" in res.output
    out = json.loads(model.read_text())
    assert out["evaluation"] is None and out["summary"]["iterations"] <= 5
    assert not (tmp_path / "m_against_range.png").exists()
    said = " ".join(res.output.split())
    assert "removed what an earlier run at this --out drew against a truth this log does not have: " in said
    assert "m_against_range.png" in said and (tmp_path / "m.png").exists()
    # stopped at the cap, not by patience: the user is told the likelihood was still rising, and how to go on
    said = " ".join(res.output.split())
    assert "EM reached max_iterations (5) before 50 iterations passed without a new best" in said
    ll = out["summary"]["loglik_best"] - out["summary"]["loglik_start"]
    assert "in the last 2 iterations" in said and "--set max_iterations=10" in said and ll > 0
    # a range column with an empty cell is not scored, and says so
    write_turtlebot_csv(csv, with_range=True)
    lines = csv.read_text().splitlines()
    cells = lines[10].split(",")
    cells[2] = ""  # the range cell (index, time, range, ...)
    lines[10] = ",".join(cells)
    csv.write_text("\n".join(lines) + "\n")
    res = runner.invoke(app, ["learn", "em", str(csv), "--set", "max_iterations=2"])
    assert_written(res, ("not_converged", "reading_explains_nothing", "residuals_correlated"))  # f not learned yet
    assert "empty steps: not scored" in res.output
    # after five iterations raw_ir2's window holds too few of the range column's distances: said, not "nan"
    write_turtlebot_csv(csv, with_range=True)
    res = runner.invoke(app, ["learn", "em", str(csv), "--set", "max_iterations=5"])
    said = " ".join(res.output.split())
    assert_written(res)
    assert "raw_ir2: not scored (readings in fewer than two 100-mm bins" in said, res.output
    assert "nan" not in said and "raw_ir1: " in said and "% of its" in said


def test_the_turtlebot_figure_draws_the_scored_models_of_a_known_robot(tmp_path):
    """The figure's curves are the score's: the learned velocity line has the scored gain as its slope
    (an exact reduction) and, on the seeded robot (gain 0.9), lies on its true response; the sensor
    panel's medians are sonar1's readings of the recorded range; one panel per channel and the action."""
    import numpy as np

    from sensact.evaluate.turtlebot_em import learned_velocity_mm_s, sensor_bins, state_map
    from sensact.experiments.turtlebot_em import run_turtlebot_em
    from sensact.report.figures_turtlebot_em import figure_turtlebot_em

    csv = tmp_path / "robot.csv"
    write_turtlebot_csv(csv, with_range=True, drop=("raw_ir1", "raw_ir2", "raw_ir3"))
    summary, run = run_turtlebot_em(csv)
    score = summary["score"]
    a, b = state_map(run.result.posteriors.mean_gamma[:, 0], run.truth_mm)
    assert (a, b) == (score["state_map"]["scale"], score["state_map"]["offset_mm"])
    v0, v1 = learned_velocity_mm_s(run.result, np.array([0.0, 1.0]), a)
    assert v1 - v0 == pytest.approx(score["gain_learned"], rel=1e-12)
    assert learned_velocity_mm_s(run.result, np.array([300.0]), a)[0] == pytest.approx(0.9 * 300.0, rel=0.01)
    sonar = run.result.model.sensor.channels[0]
    readings = run.data.obs_readings[:, run.data.reading_names.index("sonar1")]
    centers, medians, errs = sensor_bins(sonar, readings, run.truth_mm[run.data.obs_step], a, b)
    assert centers.size == score["sensors"]["sonar1"]["bins"] and centers.size > 10
    # sonar1 reads the distance (5 % outliers, which the median ignores): each bin's median lies within
    # the bin, whose distances need not centre on its middle (the robot turns back at either end)
    assert np.max(np.abs(medians - centers)) < 50.0, np.abs(medians - centers).max()
    assert np.sqrt(np.mean(errs**2)) == pytest.approx(score["sensors"]["sonar1"]["rms_mm"])
    path = figure_turtlebot_em(run, score, tmp_path / "f.png", "seeded robot")
    assert path.stat().st_size > 30_000


@pytest.mark.slow
def test_localize_follows_another_run_of_a_turtlebot_with_the_model_learned_on_one(tmp_path):
    """`sensact localize`: a model learned on one seeded run, held, places the robot in another run; its
    start comes from the first readings through the learned f, so that one outlier cannot set it; the
    same run scored as `learn em` scored it gives the same path; bad input is one line."""
    import numpy as np

    first, second, model = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "m.json"
    write_turtlebot_csv(first, with_range=True, seed=7)
    write_turtlebot_csv(second, with_range=True, seed=8)
    assert runner.invoke(app, ["learn", "em", str(first), "--out", str(model)]).exit_code == 0
    res = runner.invoke(app, ["localize", str(second), "--model", str(model), "--out", str(tmp_path / "l.json")])
    assert_written(res)
    loc = json.loads((tmp_path / "l.json").read_text())
    assert loc["start"]["how"] == "the first readings through the learned f"
    assert (
        abs(
            loc["start"]["prior_mean"][0] * loc["truth"]["state_map"]["scale"]
            + loc["truth"]["state_map"]["offset_mm"]
            - 400.0
        )
        < 30.0
    )  # the seeded robot starts 400 mm from the wall
    assert loc["truth"]["state_map"]["rms_mm"] < 10.0 and loc["filter_ok"]
    # the map fitted on the first run, carried over, is nearly as good as the second run's own best map
    carried = json.loads(model.read_text())["evaluation"]["state_map"]
    with np.load(tmp_path / "l.path.npz", allow_pickle=False) as path:
        x = path["mean"][:, 0]
    from sensact.io.turtlebot import read_turtlebot_landmark_log

    _, truth_mm = read_turtlebot_landmark_log(second, json.loads(model.read_text())["dt_s"])
    rms = np.sqrt(np.mean((carried["scale"] * x + carried["offset_mm"] - truth_mm) ** 2))
    assert loc["truth"]["rms_mm_learned_map"] == pytest.approx(rms, rel=1e-9)
    assert loc["truth"]["state_map"]["rms_mm"] <= rms < 2 * loc["truth"]["state_map"]["rms_mm"] + 5.0, rms
    assert loc["loglik_per_sighting"] > loc["loglik_per_sighting_learned"] - 0.5, loc  # the model holds there
    said = " ".join(res.output.split())
    assert "smoothed distance against the range column" in said and "l.path.npz" in said
    assert (tmp_path / "l.png").stat().st_size > 30_000
    # on the log it was learned from, from the start EM learned, the path is the one `learn em` wrote
    start = json.loads(model.read_text())["model"]["prior_mean"][0]
    res = runner.invoke(
        app, ["localize", str(first), "--model", str(model), "--start", str(start), "--out", str(tmp_path / "s.json")]
    )
    assert res.exit_code == 0, res.output
    assert f"start: ({start:.4g}), given" in " ".join(res.output.split())
    with np.load(tmp_path / "s.path.npz", allow_pickle=False) as a, np.load(tmp_path / "m.path.npz") as b:
        assert np.sqrt(np.mean((a["mean"] - b["mean"]) ** 2)) < 1.0
    # a start that is not one number, and a model for other readings, are one line each
    res = runner.invoke(app, ["localize", str(second), "--model", str(model), "--start", "1,2"])
    assert res.exit_code == 2 and "--start '1,2' is not 1 number" in " ".join(res.output.split())
    write_turtlebot_csv(second, with_range=True, seed=8, drop=("raw_ir4",))
    res = runner.invoke(app, ["localize", str(second), "--model", str(model)])
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and "the log has no reading raw_ir4" in said and "cannot be run on" in said, said


@pytest.mark.slow
def test_evaluate_log_scores_a_turtlebot_model_on_another_run_against_its_range(tmp_path):
    """`evaluate log` on a Turtlebot CSV: a model learned on one seeded run holds on another run of the same
    robot (gain and sonar1 scored as `learn em` scores them), and shows a robot that now drives at 0.72 of
    its command (a new floor) as the gain's error; on the log it was learned from it gives `learn em`'s own
    evaluation; a CSV without the range column is one line."""
    first, model = tmp_path / "a.csv", tmp_path / "m.json"
    write_turtlebot_csv(first, with_range=True, seed=7)
    assert runner.invoke(app, ["learn", "em", str(first), "--out", str(model)]).exit_code == 0
    learned = json.loads(model.read_text())["evaluation"]
    scores = {}
    for name, seed, gain in (("same", 8, 0.9), ("slower", 8, 0.72), ("itself", 7, 0.9)):
        csv = first if name == "itself" else tmp_path / f"{name}.csv"
        if name != "itself":
            write_turtlebot_csv(csv, with_range=True, seed=seed, gain=gain)
        out = tmp_path / f"{name}.json"
        res = runner.invoke(app, ["evaluate", "log", str(csv), "--model", str(model), "--out", str(out)])
        assert res.exit_code == 0, res.output
        assert "vs range (optimal scale and offset): action gain" in " ".join(res.output.split())
        assert out.with_name(f"{name}_against_range.png").stat().st_size > 30_000
        scores[name] = json.loads(out.read_text())["evaluation"]
    same, slower, itself = scores["same"], scores["slower"], scores["itself"]
    assert same["gain_true"] == pytest.approx(0.9, rel=0.03) and same["gain_error_pct"] < 3.0, same
    assert same["sensors"]["sonar1"]["rms_pct_of_span"] < 3.0, same["sensors"]["sonar1"]
    # the held model still reads the distance, so the path (and the map onto the range) holds, and the gain
    # it carries is 0.9 / 0.72 - 1 = 25 % more than the robot now drives
    assert slower["gain_true"] == pytest.approx(0.72, rel=0.03)
    assert slower["gain_error_pct"] == pytest.approx(25.0, abs=5.0), slower
    assert slower["sensors"]["sonar1"]["rms_pct_of_span"] < 3.0
    # the robot placed on its own log by the E-step alone, from the start it finds, as EM placed it
    assert itself["gain_learned"] == pytest.approx(learned["gain_learned"], rel=1e-3)
    for channel, s in learned["sensors"].items():
        assert itself["sensors"][channel]["rms_pct_of_span"] == pytest.approx(s["rms_pct_of_span"], abs=0.01)
    bare = tmp_path / "bare.csv"
    write_turtlebot_csv(bare, with_range=False, seed=8)
    res = runner.invoke(app, ["evaluate", "log", str(bare), "--model", str(model)])
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and "bare.csv: range: there is no range column to score against" in said, said
    rows = (tmp_path / "same.csv").read_text().splitlines()
    cells = rows[5].split(",")
    cells[rows[0].split(",").index("range")] = ""
    (tmp_path / "gap.csv").write_text("\n".join([*rows[:5], ",".join(cells), *rows[6:]]) + "\n")
    res = runner.invoke(app, ["evaluate", "log", str(tmp_path / "gap.csv"), "--model", str(model)])
    said = " ".join(res.output.split())
    # one empty cell leaves the steps read from it empty
    assert res.exit_code == 2 and re.search(r"range: the range column has \d+ empty steps to score against", said), said


@pytest.mark.slow
def test_evaluate_fleet_scores_turtlebot_models_on_each_others_runs_against_their_range(tmp_path):
    """`evaluate fleet` on Turtlebot CSVs: two robots (gains 0.9 and 0.72, on a floor each), each model
    learned on its own run; every model placed on every run and scored against its range column as
    `evaluate log` scores it (the same numbers), the other robot's gain off by what the gains say, a run
    without a range column placed but not scored. The second run's clock steps 0.1 % longer, as two real
    runs' median steps differ, so each model reads each run onto its own step."""
    runs = {"a": (7, 0.9), "b": (9, 0.72)}
    for name, (seed, gain) in runs.items():
        write_turtlebot_csv(tmp_path / f"{name}.csv", with_range=True, seed=seed, gain=gain)
    rows = (tmp_path / "b.csv").read_text().splitlines()
    stretched = [",".join([c[0], f"{1.001 * float(c[1]):.6f}", *c[2:]]) for c in (r.split(",") for r in rows[1:])]
    (tmp_path / "b.csv").write_text("\n".join([rows[0], *stretched]) + "\n")
    for name in runs:
        model = tmp_path / f"m{name}.json"
        assert runner.invoke(app, ["learn", "em", str(tmp_path / f"{name}.csv"), "--out", str(model)]).exit_code == 0
    write_turtlebot_csv(tmp_path / "bare.csv", with_range=False, seed=8)
    out = tmp_path / "fleet.json"
    csvs = [str(tmp_path / f"{g}.csv") for g in ("a", "b", "bare")]
    models = ["--model", str(tmp_path / "ma.json"), "--model", str(tmp_path / "mb.json")]
    res = runner.invoke(app, ["evaluate", "fleet", *csvs, *models, "--out", str(out)])
    said = " ".join(res.output.split())
    assert res.exit_code == 0, res.output
    assert "not scored against the range: bare (there is no range column)" in said
    assert "not scored against ground truth" not in said  # a CSV is scored against its range instead
    fleet = json.loads(out.read_text())
    assert fleet["own"] == {"ma": "a", "mb": "b"} and fleet["logs"] == ["a", "b", "bare"]
    rng = fleet["range"]
    assert rng["logs"] == ["a", "b"] and rng["no_range"] == {"bare": "there is no range column"}
    cells = rng["cells"]
    for m, g in (("ma", "a"), ("mb", "b")):  # each robot's own model clears both bars on its run
        assert cells[m][g]["bars"] == {"gain": True, "sensor": True}, cells[m][g]
    # a 0.9 model on a 0.72 robot carries 0.9 / 0.72 - 1 = 25 % too much gain, the other 1 - 0.72 / 0.9 = 20 %
    assert cells["ma"]["b"]["gain_error_pct"] == pytest.approx(25.0, abs=5.0) and not cells["ma"]["b"]["bars"]["gain"]
    assert cells["mb"]["a"]["gain_error_pct"] == pytest.approx(20.0, abs=5.0) and not cells["mb"]["a"]["bars"]["gain"]
    # one kind of sensor: a's model reads b's run as well as its own; b's own fit is the weaker (2.1 % on b)
    assert cells["ma"]["b"]["bars"]["sensor"] and cells["mb"]["a"]["best_sensor_pct"] < 5.0, cells["mb"]["a"]
    assert rng["summary"]["own"]["clear_gain_bar"] == 2 and rng["summary"]["other"]["clear_gain_bar"] == 0
    lk = fleet["likelihood"]
    assert lk["summary"]["own_most_likely"] == 2, lk["summary"]
    assert all(lk["cells"][m]["bare"]["per_sighting"] is not None for m in ("ma", "mb"))
    assert out.with_suffix(".png").stat().st_size > 30_000
    # a pair is what `evaluate log` gives for that model on that run: b's model reads a's run onto its own
    # step, not onto the first model's
    single = tmp_path / "mb_on_a.json"
    res = runner.invoke(app, ["evaluate", "log", csvs[0], "--model", str(tmp_path / "mb.json"), "--out", str(single)])
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "mb.json").read_text())["dt_s"] == pytest.approx(0.06006, rel=1e-4)
    ev = json.loads(single.read_text())
    assert cells["mb"]["a"]["gain_error_pct"] == pytest.approx(ev["evaluation"]["gain_error_pct"], rel=1e-9)
    assert lk["cells"]["mb"]["a"]["per_sighting"] == pytest.approx(ev["loglik_per_sighting"], rel=1e-9)
    for channel, pct in cells["mb"]["a"]["sensors_pct_of_span"].items():
        alone = ev["evaluation"]["sensors"][channel]["rms_pct_of_span"]  # null where a sensor is not scored
        assert (pct is None and alone is None) or pct == pytest.approx(alone, rel=1e-9), (channel, pct, alone)


def _as_track_folder(csv, folder):
    """The run of a Turtlebot CSV as a 1-D robot's own track log folder: the same steps, command and
    readings, the recorded distance as groundtruth.csv's distance_mm, and the Turtlebot's settings as its
    em_config.yaml (what a user with other column names writes by hand: docs/em-real.md, section 1)."""
    from sensact.config import config_to_yaml
    from sensact.io.landmark_folder import write_landmark_log
    from sensact.io.turtlebot import read_turtlebot_landmark_log
    from sensact.presets import turtlebot_em_config

    data, truth_mm = read_turtlebot_landmark_log(csv)
    write_landmark_log(folder, data, groundtruth={"distance_mm": truth_mm})
    (folder / "em_config.yaml").write_text(config_to_yaml(turtlebot_em_config(data.reading_names), "# 1-D robot\n"))
    return folder


@pytest.mark.slow
def test_a_track_folders_recorded_distance_is_scored_as_a_turtlebot_csvs_range(tmp_path):
    """A 1-D robot's own track folder (continuous commands, groundtruth.csv's distance_mm) is scored
    against its recorded distance by `learn em`, `evaluate log`, `evaluate fleet` and `localize` exactly
    as the same run written as a Turtlebot CSV is against its range column (an exact reduction: the same
    log, the same settings)."""
    runs = {}
    for name, seed in (("a", 7), ("b", 8)):
        csv = tmp_path / f"{name}.csv"
        write_turtlebot_csv(csv, with_range=True, seed=seed)
        runs[name] = (csv, _as_track_folder(csv, tmp_path / f"{name}_folder"))
    learned = {}
    for kind in (0, 1):  # the CSV, then the folder
        model = tmp_path / f"m{kind}.json"
        res = runner.invoke(app, ["learn", "em", str(runs["a"][kind]), "--out", str(model)])
        assert_written(res)
        learned[kind] = json.loads(model.read_text())
        against = ("range", "the recorded distance")[kind]  # what the score line names
        assert f"vs {against} (optimal scale and offset): action gain" in " ".join(res.output.split())
        assert (tmp_path / f"m{kind}_against_range.png").stat().st_size > 30_000
    assert learned[1]["model"] == learned[0]["model"] and learned[1]["evaluation"] == learned[0]["evaluation"]
    assert learned[1]["evaluation"]["gain_error_pct"] < 1.0  # the seeded robot's gain, 0.9
    scored, placed = {}, {}
    for kind in (0, 1):
        log, model = str(runs["b"][kind]), str(tmp_path / f"m{kind}.json")
        out = tmp_path / f"e{kind}.json"
        res = runner.invoke(app, ["evaluate", "log", log, "--model", model, "--out", str(out)])
        against = ("range", "the recorded distance")[kind]
        assert res.exit_code == 0 and f"vs {against} (optimal" in " ".join(res.output.split()), res.output
        scored[kind] = json.loads(out.read_text())["evaluation"]
        out = tmp_path / f"l{kind}.json"
        assert runner.invoke(app, ["localize", log, "--model", model, "--out", str(out)]).exit_code == 0
        placed[kind] = json.loads(out.read_text())["truth"]
    assert scored[1] == scored[0] and scored[1]["sensors"]["sonar1"]["rms_pct_of_span"] < 2.0
    # a recorded distance with an empty cell is named in one line, by its file and column
    truth = runs["b"][1] / "groundtruth.csv"
    kept = truth.read_text()
    rows = kept.splitlines()
    truth.write_text("\n".join([*rows[:100], rows[100].split(",")[0] + ",", *rows[101:]]) + "\n")
    res = runner.invoke(app, ["evaluate", "log", str(runs["b"][1]), "--model", str(tmp_path / "m1.json")])
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and "groundtruth.csv: distance_mm: groundtruth.csv's distance_mm is empty at" in said, (
        said
    )
    truth.write_text(kept)
    assert placed[1] == placed[0] and placed[1]["state_map"]["rms_mm"] < 10.0
    out = tmp_path / "fleet.json"
    logs = [str(runs[n][1]) for n in ("a", "b")]
    res = runner.invoke(app, ["evaluate", "fleet", *logs, "--model", str(tmp_path / "m1.json"), "--out", str(out)])
    assert res.exit_code == 0, res.output
    cells = json.loads(out.read_text())["range"]["cells"]["m1"]
    # a pair is `evaluate log`'s score of that model on that run (the robot placed with the model held)
    assert cells["b_folder"]["gain_error_pct"] == pytest.approx(scored[1]["gain_error_pct"], rel=1e-9)
    assert cells["a_folder"]["bars"] == {"gain": True, "sensor": True}, cells["a_folder"]
    # a track folder without the recorded distance learns the same model and is not scored
    (runs["a"][1] / "groundtruth.csv").unlink()
    res = runner.invoke(app, ["learn", "em", str(runs["a"][1]), "--out", str(tmp_path / "bare.json")])
    assert res.exit_code == 0 and "(optimal scale and offset)" not in " ".join(res.output.split()), res.output
    bare = json.loads((tmp_path / "bare.json").read_text())
    assert bare["model"] == learned[1]["model"] and bare["evaluation"] is None


@pytest.mark.slow
def test_learn_em_starts_from_a_model_learned_on_another_robot_of_its_kind(tmp_path):
    """`learn em --start-from`: robot b (gain 0.72) learned from robot a's model (gain 0.9) learns b's own
    gain, with a's settings read back whole from a's model.json; started from a's model on a's own run, EM
    stays at a's fit (an exact reduction up to EM's last steps); a family the settings change and a model
    for other readings are one line each."""
    import numpy as np

    for name, seed, gain in (("a", 7, 0.9), ("b", 9, 0.72)):
        write_turtlebot_csv(tmp_path / f"{name}.csv", with_range=True, seed=seed, gain=gain)
    ma, mb = tmp_path / "ma.json", tmp_path / "mb.json"
    res = runner.invoke(app, ["learn", "em", str(tmp_path / "a.csv"), "--out", str(ma), "--halves"])
    assert_written(res)
    # --halves: each half learned on from a's model; a's gain does not change during its run
    halves = json.loads(ma.read_text())["halves"]
    assert [h["steps"] for h in halves["fits"]] == [[0, 1249], [1249, 2499]]
    cmp = halves["comparison"]  # measured: 2.02 mm/s; sigma ratios 1.00-1.08
    assert cmp["velocity"]["first_vs_second"]["velocity_mm_s"] < 5.0
    assert set(cmp["f"]["spans"]) == {"sonar1", "raw_ir1", "raw_ir3", "raw_ir4"}  # raw_ir2 read nothing in its window
    assert "raw_ir2 sigma" not in cmp["noise"]["halves_ratio"] and max(cmp["noise"]["halves_ratio"].values()) < 1.2
    said = " ".join(res.output.split())
    assert "the log's halves, each learned on from the whole log's model" in said
    assert said.index(f"wrote {ma},") < said.index("--halves:") < said.index(f"wrote {ma} again, with the halves")
    halves_png = tmp_path / "ma_halves.png"  # a panel for the velocity, each read channel and the noise
    assert f"wrote {halves_png}" in said and halves_png.stat().st_size > 30_000
    res = runner.invoke(app, ["learn", "em", str(tmp_path / "b.csv"), "--start-from", str(ma), "--out", str(mb)])
    assert_written(res)
    said = " ".join(res.output.split())
    assert f"starting from {ma} (learned on {tmp_path / 'a.csv'}): its settings, parameters" in said
    assert "start: (" in said and "from the first readings through the learned f" in said
    a, b = json.loads(ma.read_text()), json.loads(mb.read_text())
    assert b["start_from"]["model"] == str(ma) and b["start_from"]["placed"]["how"].startswith("the first readings")
    # a's settings, windows at infinity included, and EM run from a learned start
    warm = a["summary"]["config"]
    warm["search"]["warm_start"] = True
    assert b["summary"]["config"] == warm
    # b's own gain, not a's. Measured: learned cold, b's gain is 0.40 % off and sonar1 2.67 % of its span
    # (log-likelihood -2188.3); from a's model 0.39 % and 0.77 % (-1903.7, 52 iterations against 198)
    assert b["evaluation"]["gain_error_pct"] < 1.0, b["evaluation"]
    assert b["evaluation"]["sensors"]["sonar1"]["rms_pct_of_span"] < 1.5
    # from a's own model on a's own run EM starts where it ended: the same fit (never written over the model
    # it starts from; without --halves, over an earlier run's files whose halves figure goes: it would pass
    # for this fit's)
    again, again_png = tmp_path / "again.json", tmp_path / "again_halves.png"
    shutil.copy(ma, again)
    shutil.copy(halves_png, again_png)
    res = runner.invoke(app, ["learn", "em", str(tmp_path / "a.csv"), "--start-from", str(ma), "--out", str(ma)])
    assert res.exit_code == 2 and "--out and --start-from are both" in " ".join(res.output.split())
    res = runner.invoke(app, ["learn", "em", str(tmp_path / "a.csv"), "--start-from", str(ma), "--out", str(again)])
    assert_written(res)
    assert not again_png.exists() and f"removed {again_png}, an earlier run's --halves figure" in " ".join(
        res.output.split()
    )
    c = json.loads(again.read_text())
    assert c["summary"]["loglik_best"] == pytest.approx(a["summary"]["loglik_best"], abs=2.0)
    assert c["evaluation"]["gain_learned"] == pytest.approx(a["evaluation"]["gain_learned"], rel=2e-3)
    assert np.allclose(c["model"]["prior_mean"], a["model"]["prior_mean"], atol=5.0)
    # a family the settings change, and a model for readings the log lacks, are one line each
    res = runner.invoke(
        app, ["learn", "em", str(tmp_path / "b.csv"), "--start-from", str(ma), "--set", "action_basis=polynomial"]
    )
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and "the start model has action.basis 'affine' and the settings 'polynomial'" in said
    assert "without --start-from" in said and "Traceback" not in said, said
    write_turtlebot_csv(tmp_path / "c.csv", with_range=True, seed=8, drop=("raw_ir4",))
    res = runner.invoke(app, ["learn", "em", str(tmp_path / "c.csv"), "--start-from", str(ma)])
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and "the log has no reading raw_ir4" in said and "EM cannot start from it on" in said


def test_track_start_candidates_invert_each_learned_f_inside_its_window():
    """The real roots of ``f(x) = o`` inside the window, with the sd the channel's sigma gives there."""
    import numpy as np

    from sensact.learn.em.uses.place import TRACK_MIN_SD, track_start_candidates
    from sensact.logs.landmark_log import LandmarkLog
    from sensact.models.em_model import EMModel
    from sensact.models.landmark_sensor import LandmarkSensor, ReadingChannel
    from sensact.models.linear_action import LinearActionModel
    from sensact.models.polynomial import Polynomial1D

    line = ReadingChannel("a", Polynomial1D((1.0, 2.0)), 4.0)  # f = 1 + 2x
    bowl = ReadingChannel("b", Polynomial1D((0.0, 0.0, 1.0)), 1.0, 0.0, 10.0)  # f = x^2, only 0..10 valid
    sensor = LandmarkSensor((line, bowl))
    action = LinearActionModel.zero("affine", 1, ("c",), ("v",))
    model = EMModel("track", action, sensor, np.zeros(1), np.eye(1), np.ones((1, 1)))
    data = LandmarkLog(
        "track", 0.1, np.full(3, -1), np.zeros((0, 1)), ("c",), np.array([0]), np.array([0]),
        np.array([[5.0, 9.0]]), np.array([np.nan]), np.zeros((1, 2)), ("wall",), "", ("a", "b"), np.zeros((3, 1)),
    )  # fmt: skip
    got = track_start_candidates(model, data)
    # a: x = 2 (sd 4 / 2); b: x = 3 (sd 1 / 6, at least TRACK_MIN_SD), its root -3 is outside the window
    assert [(round(x, 9), sd) for x, sd in got] == [(2.0, 2.0), (3.0, TRACK_MIN_SD)]


def test_learn_em_on_a_turtlebot_csv_learns_the_sensors_it_has(tmp_path):
    csv = tmp_path / "robot.csv"
    write_turtlebot_csv(csv, with_range=True, drop=("raw_ir1", "raw_ir2"))
    model = tmp_path / "m.json"
    res = runner.invoke(app, ["learn", "em", str(csv), "--out", str(model), "--set", "max_iterations=3"])
    assert_written(res)
    assert "Channels sonar1, raw_ir3, raw_ir4 (raw_ir1, raw_ir2 not in the file)." in " ".join(res.output.split())
    channels = json.loads(model.read_text())["model"]["sensor"]["channels"]
    assert [c["name"] for c in channels] == ["sonar1", "raw_ir3", "raw_ir4"]
    assert channels[1]["valid_min"] == 100.0 and channels[2]["valid_max"] == 5000.0  # their datasheet windows
    # chapter 3's reproduction runs the default sensors the file has
    folder = tmp_path / "data" / "turtlebot1d"
    folder.mkdir(parents=True)
    write_turtlebot_csv(folder / "training1.csv", with_range=True, drop=("raw_ir3",))
    res = runner.invoke(app, ["reproduce", "turtlebot", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "r")])
    assert res.exit_code == 0 and "has no column raw_ir3: run without them" in " ".join(res.output.split())
    out = json.loads((tmp_path / "r" / "turtlebot.json").read_text())
    assert list(out["rows"]) == ["sonar1", "sonar2", "raw_ir4"] and out["skipped_sensors"] == ["raw_ir3"]
    # without the sonar, nothing says what unit the state is in
    write_turtlebot_csv(csv, with_range=True, drop=("sonar1",))
    res = runner.invoke(app, ["learn", "em", str(csv)])
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and "robot.csv: sonar1: EM on a Turtlebot CSV needs the sonar1 column" in said


def test_reproduce_turtlebot_runs_algorithm_1_on_every_training_log_it_finds(tmp_path):
    import shutil

    folder = tmp_path / "data" / "turtlebot1d"
    folder.mkdir(parents=True)
    write_turtlebot_csv(folder / "training1.csv", with_range=True)
    shutil.copy(folder / "training1.csv", folder / "training2.csv")  # the same log under another name
    write_turtlebot_csv(folder / "training3.csv", with_range=False)
    write_turtlebot_csv(folder / "calibration.csv", with_range=True, one_speed=True)  # not a training log
    out = tmp_path / "r"
    res = runner.invoke(app, ["reproduce", "turtlebot", "--data", str(tmp_path / "data"), "--out", str(out)])
    said = " ".join(res.output.split())
    assert res.exit_code == 0, res.output
    assert "not run: training3.csv: " in said and "range: the log has no recorded range" in said
    summary = json.loads((out / "turtlebot.json").read_text())
    assert summary["file"].endswith("training1.csv") and list(summary["more_logs"]) == ["training2"]
    assert len(summary["skipped_logs"]) == 1 and summary["skipped_logs"][0].startswith("training3.csv: ")
    again = summary["more_logs"]["training2"]
    assert again["file"].endswith("training2.csv") and again["rows"] == summary["rows"]
    tables = (out / "turtlebot.md").read_text()
    assert "Turtlebot training1.csv, Algorithm 1" in tables and "Turtlebot training2.csv, Algorithm 1" in tables
    assert "training3.csv, Algorithm 1" not in tables and "calibration.csv" not in tables
    assert (out / "turtlebot_models.png").stat().st_size > 10_000
    assert (out / "turtlebot_models_training2.png").stat().st_size > 10_000
    assert not (out / "turtlebot_models_training1.png").exists()
    # a folder whose only training log cannot be scored: one line naming the file and the field
    (folder / "training1.csv").unlink()
    (folder / "training2.csv").unlink()
    res = runner.invoke(app, ["reproduce", "turtlebot", "--data", str(tmp_path / "data"), "--out", str(out)])
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and "training3.csv: range: the log has no recorded range" in said, res.output
    assert "learn bootstrap FILE" in said and "Traceback" not in res.output
    # and one with no training log at all
    (folder / "training3.csv").unlink()
    res = runner.invoke(app, ["reproduce", "turtlebot", "--data", str(tmp_path / "data"), "--out", str(out)])
    said = " ".join(res.output.split())
    assert res.exit_code == 2 and "no Turtlebot training log (training*.csv) found" in said, res.output


def test_a_file_that_is_not_text_is_one_line_naming_it(tmp_path):
    binary = tmp_path / "capture.csv"
    binary.write_bytes(b"\x00\xff\xfe\x10 not text")
    for command in ("bootstrap", "em"):
        res = runner.invoke(app, ["learn", command, str(binary)])
        said = " ".join(res.output.split())
        assert res.exit_code == 2 and "capture.csv: not a readable CSV text file" in said, res.output
        assert "Traceback" not in res.output


def test_learn_em_refuses_a_turtlebot_csv_out_of_order(tmp_path):
    csv = tmp_path / "robot.csv"
    write_turtlebot_csv(csv, with_range=True)
    lines = csv.read_text().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    csv.write_text("\n".join(lines) + "\n")
    res = runner.invoke(app, ["learn", "em", str(csv)])
    assert res.exit_code == 2 and "time must be finite and strictly increasing" in res.output
    assert "robot.csv" in res.output and "Traceback" not in res.output
    (tmp_path / "notes.txt").write_text("x")
    res = runner.invoke(app, ["learn", "em", str(tmp_path / "notes.txt")])
    assert res.exit_code == 2 and "not a log sensact reads" in res.output and "a Turtlebot CSV" in res.output
    # a .csv that is not a Turtlebot's: a log folder's own file, or a robot's records `convert csv` reads
    folder = tmp_path / "track"
    assert runner.invoke(app, ["simulate", "track1d", "--seconds", "5", "--out", str(folder)]).exit_code == 0
    (tmp_path / "commands.csv").write_text("t_s,v_m_s\n0,0.1\n1,0.1\n")
    for given, fix in (
        (folder / "actions.csv", f"give the log folder {folder}"),
        (tmp_path / "commands.csv", "convert csv"),
    ):
        res = runner.invoke(app, ["learn", "em", str(given)])
        flat = " ".join(res.output.split())
        assert res.exit_code == 2 and "missing column(s) time, velocity_command" in flat and fix in flat, res.output
        assert "read as a Turtlebot's log" in flat
    # a Turtlebot CSV without the sensor chapter 3's learner is asked for names it and what the file has
    write_turtlebot_csv(csv, with_range=True, drop=("raw_ir4",))
    res = runner.invoke(app, ["learn", "bootstrap", str(csv), "--sensor", "raw_ir4"])
    flat = " ".join(res.output.split())
    assert res.exit_code == 2 and "no raw_ir4 column; found" in flat and "raw_ir3" in flat, res.output
    # a track folder of one step: both learners name the file and the field
    one = tmp_path / "one"
    assert runner.invoke(app, ["simulate", "track1d", "--seconds", "5", "--out", str(one)]).exit_code == 0
    for name in ("actions.csv", "observations.csv"):
        (one / name).write_text("\n".join((one / name).read_text().splitlines()[:2]) + "\n")
    # and a track whose sensor never read, or a Turtlebot CSV whose sonar1 never did
    blind = tmp_path / "blind"
    assert runner.invoke(app, ["simulate", "track1d", "--seconds", "5", "--out", str(blind)]).exit_code == 0
    rows = (blind / "observations.csv").read_text().splitlines()
    (blind / "observations.csv").write_text("\n".join([rows[0], *(r.split(",")[0] + "," for r in rows[1:])]) + "\n")
    write_turtlebot_csv(csv, with_range=True)
    table = [r.split(",") for r in csv.read_text().splitlines()]
    col = table[0].index("sonar1")
    csv.write_text(
        "\n".join(",".join([*r[:col], "", *r[col + 1 :]]) if k else ",".join(r) for k, r in enumerate(table))
    )
    for learner in ("bootstrap", "em"):
        res = runner.invoke(app, ["learn", learner, str(one)])
        flat = " ".join(res.output.split())
        assert res.exit_code == 2 and "actions.csv: t_s:" in flat and "at least two rows (it has 1)" in flat, flat
        res = runner.invoke(app, ["learn", learner, str(blind)])
        flat = " ".join(res.output.split())
        assert res.exit_code == 2 and "observations.csv: height_px: no reading of height_px" in flat, flat
        res = runner.invoke(app, ["learn", learner, str(csv)])
        flat = " ".join(res.output.split())
        assert res.exit_code == 2 and "robot.csv: sonar1:" in flat and "Traceback" not in res.output, flat


def test_a_fit_stopped_at_the_cap_says_how_fast_it_was_climbing():
    import numpy as np

    from sensact.cli.learn.em import _still_climbing

    # the best of 240 iterations rose by 50 in the last 50 (patience); the race's 60 count toward the cap
    said = _still_climbing(np.arange(240.0), 239, 300, 50, 60)
    assert "max_iterations (300, the start race's 60 included) before 50 iterations" in said
    assert "rose by 50.0 in the last 50 iterations" in said and "--set max_iterations=600" in said
    # a best before the window is no rise; a run shorter than patience is judged on its second half
    assert "rose by 0.0 in the last 2 iterations" in _still_climbing(np.array([0.0, 5.0, 1.0, 2.0]), 1, 4, 50, 0)
    assert "race" not in _still_climbing(np.array([0.0, 5.0, 1.0, 2.0]), 1, 4, 50, 0)
    assert "too few iterations" in _still_climbing(np.array([3.0]), 0, 1, 50, 0)


def test_a_progress_description_that_changes_while_counting_keeps_its_row():
    """EM's progress line carries the current log-likelihood, so its description changes every
    iteration; it must move one row of the bar, not add a row per iteration (as it did in a terminal).
    A count that starts again (the next trial) or another total is a new row; a known description
    goes back to its row."""
    from sensact.cli.base import ProgressRows

    class Bar:
        def __init__(self):
            self.rows, self.updates = [], []

        def add_task(self, desc, total):
            self.rows.append(desc)
            return len(self.rows) - 1

        def update(self, task, description, completed, total):
            self.updates.append((task, description, completed, total))

    bar = Bar()
    rows = ProgressRows(bar)
    for it in range(4):
        rows(f"EM: log-likelihood {-100.0 + it:.1f}", it + 1, None)
    assert len(bar.rows) == 1 and bar.updates[-1] == (0, "EM: log-likelihood -97.0", 4, None)
    rows("trial 2 iteration 0", 1, None)  # the count starts again: a new row
    rows("scan matching", 3, 10)  # another total: a new row
    rows("scan matching", 4, 10)
    rows("EM: log-likelihood -97.0", 5, None)  # a known description: its own row
    assert bar.rows == ["EM: log-likelihood -100.0", "trial 2 iteration 0", "scan matching"]
    assert [u[0] for u in bar.updates[4:]] == [1, 2, 2, 0]
    # jobs running at once, each naming itself before ": ", keep a row each however their calls interleave
    bar = Bar()
    rows = ProgressRows(bar)
    rows("diffdrive seed0: start race", 1, 6)
    rows("diffdrive seed1: start race", 1, 6)
    rows("diffdrive seed0: EM iteration 3, log-likelihood -5.0", 4, 80)  # EM's projected total
    rows("diffdrive seed1: EM iteration 1, log-likelihood -9.0", 2, 90)
    rows("diffdrive seed0: EM iteration 4, log-likelihood -4.0", 5, 81)
    assert bar.rows == ["diffdrive seed0: start race", "diffdrive seed1: start race"]
    assert [u[0] for u in bar.updates] == [0, 1, 0, 1, 0]
    # a count with no end after one with an end gets a row of its own: rich would keep the old total (322/11)
    rows("diffdrive seed1: EM iteration 2, no end known", 3, None)
    assert bar.rows[-1] == "diffdrive seed1: EM iteration 2, no end known" and bar.updates[-1][0] == 2


def test_a_log_at_one_speed_is_warned_about_and_ems_gain_not_scored(tmp_path):
    """A gain is a slope of velocity on command: a log that holds one command (97 % of its steps here)
    gives one point of it, so `learn` says so and EM's gain (an affine slope over 1-s windows) is not
    scored; chapter 3's gain (through the origin, at the timed commands) is, but not its action RMS,
    since A's own optimal scale fits any model to one timed command. `reproduce real` on such a log
    divided by the span of one timed velocity, and on a log that holds no command it fitted a
    polynomial to no points."""
    from sensact.experiments.turtlebot import run_turtlebot
    from sensact.report.figures1d import figure_real
    from sensact.report.tables import turtlebot_tables

    csv = tmp_path / "one_speed.csv"
    write_turtlebot_csv(csv, with_range=True, one_speed=True)
    model = tmp_path / "m.json"
    res = runner.invoke(app, ["learn", "em", str(csv), "--out", str(model), "--set", "max_iterations=5"])
    said = " ".join(res.output.split())
    assert_written(res, ("not_converged", "gain_sign_flips", "reading_explains_nothing"))  # one speed: degenerate
    assert "spends 97 % of its steps at one command (v_cmd_mm_s 10)" in said
    assert "action gain" in said and "(not scored: 97 % of the steps at one command)" in said
    ev = json.loads(model.read_text())["evaluation"]
    assert ev["gain_error_pct"] is None and ev["one_command_share"] == pytest.approx(0.967, abs=0.001)
    res = runner.invoke(app, ["learn", "bootstrap", str(csv)])
    said = " ".join(res.output.split())
    assert res.exit_code == 0 and "at one command (command 0.01 m/s)" in said, res.output
    assert "action RMS not scored, gain " in said  # one timed velocity: a gain through S's scale, no RMS
    row = run_turtlebot(csv, ("sonar1",))[0]["rows"]["sonar1"]
    assert row["commands_timed"] == 1 and row["action_rms_pct"] is None and row["gain_error_pct"] >= 0.0
    assert 0.7 < row["true_gain"] < 1.1  # 0.9, timed at 0.01 m/s under a 2-mm random walk per step: 0.82
    # the sine of the other tests is never held, and is not warned about: EM's gain (a regression on
    # 1-s windows) is scored, chapter 3's (timed over held commands) has nothing to time and says so
    write_turtlebot_csv(csv, with_range=True)
    res = runner.invoke(app, ["learn", "em", str(csv), "--set", "max_iterations=2"])
    assert_written(res, ("not_converged", "reading_explains_nothing", "residuals_correlated"))  # f not learned yet
    assert "at one command" not in res.output and "% off" in res.output
    summary, runs = run_turtlebot(csv, ("sonar1",))
    row = summary["rows"]["sonar1"]
    assert row["commands_timed"] == 0 and row["gain_error_pct"] is None and row["action_rms_m_s"] is None
    (_, _, rows) = turtlebot_tables(summary)[0]
    assert rows[0][3:6] == ["-", "not scored: no command held for 2 s", "-"]
    assert figure_real(runs, tmp_path / "models.png").stat().st_size > 10_000


def test_an_error_line_keeps_its_own_brackets():
    """A message's brackets (an extra's name, a list) are printed, not read as rich markup."""
    import typer as _typer

    from sensact.cli.base import friendly
    from sensact.errors import LogFormatError

    mini = _typer.Typer()

    @mini.command()
    @friendly
    def fail() -> None:
        raise LogFormatError("needs [fwd, left, yaw].", file="x.bag", fix="pip install 'sensact[ros]'")

    res = runner.invoke(mini, [])
    assert res.exit_code == 2
    text = " ".join(res.output.split())
    assert "pip install 'sensact[ros]'" in text and "needs [fwd, left, yaw]." in text


def test_help_keeps_its_brackets():
    """Help is plain text: rich markup took "[fleet]" for a style and printed `pip install 'sensact'`."""
    for args in (["fleet", "learn", "--help"], ["evaluate", "fleet", "--help"]):
        res = runner.invoke(app, args)
        assert res.exit_code == 0
        assert "pip install 'sensact[fleet]'" in " ".join(res.output.split())
