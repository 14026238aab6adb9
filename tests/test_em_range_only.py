"""A robot whose sensor reads ranges alone (UWB anchors, sonar beacons): `simulate diffdrive --set
sensor=radio`, EM without bearings (learn/em/searches/facing.py), and its scores and figures without a bearing."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import assert_written
from sensact.app import read_settings_file
from sensact.cli import app
from sensact.core.angles import wrap_angle
from sensact.evaluate.landmark_truth import path_offset, score_against_truth
from sensact.experiments.real import bar_checks
from sensact.io.landmark_folder import read_landmark_log
from sensact.learn.em import EMConfig, fit_em, initial_model
from sensact.learn.em.estep import e_step, log_likelihood
from sensact.learn.em.searches.facing import drives_backward, turned_model, turned_posteriors
from sensact.presets import range_only_config
from sensact.records import to_json
from sensact.sim.diffdrive import COMMAND_NAMES, DiffDriveConfig, simulate_diffdrive

runner = CliRunner()


def true_model(run, config: EMConfig):
    """The simulated robot's own action model and range line, from EM's starting model's families."""
    data = run.log()
    start = initial_model(data, config)
    action = start.action.with_coefficients(run.config.action_coefficients())
    ch = start.sensor.channels[0]
    line = ch.function.__class__((run.config.range_offset_mm, run.config.range_gain, 0.0, 0.0))
    sensor = start.sensor.with_fits([(line, run.config.range_sd_mm, ch.bearing_terms)], start.sensor.sigma_bearing_rad)
    return data, start.replace(action=action, sensor=sensor)


def test_a_range_only_model_turned_by_pi_reads_the_same_and_a_camera_model_does_not():
    """Exact invariant (searches/facing.py): without bearings, the robot facing the other way and driving
    backward has the same likelihood, and its posteriors are the first's turned; with bearings the
    heading is seen, and the two differ by thousands of log-units."""
    radio = simulate_diffdrive(DiffDriveConfig(seconds=60, seed=2, sensor="radio"))
    data, model = true_model(radio, range_only_config(COMMAND_NAMES, (0.0, 0.0, 0.0)))
    assert model.sensor.sigma_bearing_rad is None and not np.isfinite(data.obs_bearing_rad).any()
    turned = turned_model(model)
    assert turned.action.coefficients[1, 1] == -model.action.coefficients[1, 1]
    assert abs(turned.prior_mean[2]) == pytest.approx(np.pi)
    ll, ll_turned = log_likelihood(model, data), log_likelihood(turned, data)
    assert np.isfinite(ll) and ll_turned == pytest.approx(ll, rel=1e-9)
    assert not drives_backward(model, data) and drives_backward(turned, data)
    post, post_turned = e_step(model, data), e_step(turned, data)
    expect = turned_posteriors(post)
    np.testing.assert_allclose(post_turned.mean_gamma[:, :2], expect.mean_gamma[:, :2], atol=1e-6)
    np.testing.assert_allclose(wrap_angle(post_turned.mean_gamma[:, 2] - expect.mean_gamma[:, 2]), 0.0, atol=1e-9)
    np.testing.assert_allclose(post_turned.disp_mean, expect.disp_mean, atol=1e-6)
    np.testing.assert_allclose(post_turned.disp_cov, expect.disp_cov, atol=1e-9)

    camera = simulate_diffdrive(DiffDriveConfig(seconds=60, seed=2))
    cdata, cmodel = true_model(camera, range_only_config(COMMAND_NAMES, (0.0, 0.0, 0.0)))
    assert cmodel.sensor.sigma_bearing_rad is not None  # the camera's log has bearings: the model reads them
    fits = [(c.function, c.sigma, c.bearing_terms) for c in cmodel.sensor.channels]
    cmodel = cmodel.replace(sensor=cmodel.sensor.with_fits(fits, camera.config.bearing_sd_rad))
    assert log_likelihood(turned_model(cmodel), cdata) < log_likelihood(cmodel, cdata) - 1000.0
    assert not drives_backward(turned_model(cmodel), cdata)  # a camera's model is never turned


@pytest.mark.parametrize("heading", [0.0, 3.0])
def test_em_learns_a_range_only_robot_facing_the_way_it_drives(heading):
    """Seeded recovery: five minutes of a robot with a radio range sensor (every landmark in reach, no
    bearings), learned from where it was put. From a start heading near the truth's, or one that faces
    it nearly backward, EM finds the robot's path and model; the backward one is reported turned by pi."""
    run = simulate_diffdrive(DiffDriveConfig(seconds=300, seed=1, sensor="radio"))
    cfg = range_only_config(COMMAND_NAMES, (0.0, 0.0, heading)).replace(max_iterations=300)
    res = fit_em(run.log(), config=cfg)
    m = res.model
    assert m.sensor.sigma_bearing_rad is None
    assert res.turned_to_face_forward == (heading == 3.0)
    assert ("turned_to_face_forward" in res.summary()) == (heading == 3.0)
    assert res.start_moved is None and "start_moved" not in res.summary()  # the start was where it was given
    truth = run.config
    assert m.action.coefficients[1, 1] == pytest.approx(truth.forward_gain, rel=0.02)
    assert m.action.coefficients[2, 2] == pytest.approx(truth.turn_gain, rel=0.02)
    assert m.sensor.channels[0].sigma == pytest.approx(truth.range_sd_mm, rel=0.25)
    poses = run.poses
    offset = path_offset(res.posteriors.mean_gamma, poses, np.ones(len(poses)))
    assert offset["median_mm"] < 30.0
    # the reported headings are the robot's own
    assert np.median(np.abs(wrap_angle(res.posteriors.mean_gamma[:, 2] - poses[:, 2]))) < 0.05


def test_localize_finds_a_range_only_robot_anywhere_on_the_map_from_its_ranges():
    """Seeded recovery (uses/place.range_start_candidates): the simulated radio robot's own model, held, on a
    run that starts 2.7 m from the origin facing 2 rad: the ranges' start search puts the chosen start
    within a grid cell and half a heading step of the truth, and the smoothed path within 30 mm of the
    recorded poses. Invariants: the candidates are pairwise a few cells or two headings apart, and the
    chosen one is the most likely over the whole log."""
    from sensact.learn.em.uses.place import RANGE_HEADINGS, localize

    run = simulate_diffdrive(DiffDriveConfig(seconds=120, seed=4, sensor="radio", start_pose=(1000.0, -2500.0, 2.0)))
    cfg = range_only_config(COMMAND_NAMES, (0.0, 0.0, 0.0))
    data, model = true_model(run, cfg)
    heard = []
    loc = localize(model, data, cfg, progress=lambda *call: heard.append(call))
    assert loc.start["how"] == "the ranges' start search"
    # the progress bar's rows each climb to their end: the grid's positions, then the candidates
    rows = list(dict.fromkeys(desc for desc, _, _ in heard))
    assert rows == ["start search: grid positions scored", "start candidates scored on the whole log"]
    assert [max(d for r, d, _ in heard if r == row) for row in rows] == [heard[0][2], len(loc.start["candidates"])]
    got, g, step = np.array(loc.start["prior_mean"]), cfg.search.start_grid_mm, 2 * np.pi / RANGE_HEADINGS
    assert np.hypot(*(got[:2] - (1000.0, -2500.0))) < g and abs(wrap_angle(got[2] - 2.0)) <= 0.5 * step + 1e-9
    offset = path_offset(loc.posteriors.mean_gamma, run.poses, np.ones(len(run.poses)))
    assert offset["median_mm"] < 30.0
    cands = [np.array(c["prior_mean"]) for c in loc.start["candidates"]]
    assert 1 < len(cands) <= cfg.search.start_candidates
    for i, a in enumerate(cands):
        for b in cands[:i]:
            assert np.hypot(*(a[:2] - b[:2])) >= 2.5 * g or abs(wrap_angle(a[2] - b[2])) > 1.5 * step
    scores = [c["loglik"] for c in loc.start["candidates"]]
    assert loc.start["chosen"] == int(np.argmax(scores)) and loc.posteriors.loglik == pytest.approx(max(scores))
    # the position given alone: every heading tried there, the one nearest the truth's kept
    loc = localize(model, data, cfg, start=np.array([1000.0, -2500.0]))
    tried = np.array([c["prior_mean"] for c in loc.start["candidates"]])
    assert loc.start["how"] == "the given position at each heading" and tried.shape == (RANGE_HEADINGS, 3)
    np.testing.assert_array_equal(tried[:, :2], [[1000.0, -2500.0]] * RANGE_HEADINGS)
    assert abs(wrap_angle(loc.model.prior_mean[2] - 2.0)) <= 0.5 * step + 1e-9
    assert path_offset(loc.posteriors.mean_gamma, run.poses, np.ones(len(run.poses)))["median_mm"] < 30.0


def test_only_a_range_only_start_given_and_moved_past_three_sds_counts_as_moved():
    """Exact reduction (searches/given_start.py): the distance is returned only past three of the prior's position
    sd, on a planar log read without bearings whose start was given; a camera's or a searched start never."""
    from sensact.learn.em.searches.given_start import start_moved_mm

    radio = simulate_diffdrive(DiffDriveConfig(seconds=20, seed=2, sensor="radio")).log()
    camera = simulate_diffdrive(DiffDriveConfig(seconds=20, seed=2)).log()
    cfg = range_only_config(COMMAND_NAMES, (100.0, -200.0, 0.5))  # start_prior_sd 300 mm
    start = initial_model(radio, cfg)
    at = start.replace(prior_mean=start.prior_mean + np.array([540.0, 720.0, 2.0]))  # 900 mm: not past
    past = start.replace(prior_mean=start.prior_mean + np.array([540.0, 721.0, 0.0]))
    assert start_moved_mm(start, at, radio, cfg) is None
    assert start_moved_mm(start, past, radio, cfg) == pytest.approx(np.hypot(540.0, 721.0))
    assert start_moved_mm(start, past, radio, cfg.replace(start_search_s=30.0)) is None
    cam_start = initial_model(camera, cfg)
    assert cam_start.sensor.sigma_bearing_rad is not None
    assert start_moved_mm(cam_start, cam_start.replace(prior_mean=past.prior_mean), camera, cfg) is None


@pytest.mark.slow
def test_a_range_only_start_metres_off_runs_again_from_where_em_moved_it():
    """Seeded recovery (searches/given_start.py): from a start 3.2 m off, EM finds the path with a wrong turn
    model (the heading noise carries the turns; the turn gain -1.12) and moves the start to within
    150 mm of the true one; EM again from there finds the model, which is kept as the more likely."""
    run = simulate_diffdrive(DiffDriveConfig(seconds=300, seed=1, sensor="radio"))
    cfg = range_only_config(COMMAND_NAMES, (-1000.0, 3000.0, 0.0)).replace(max_iterations=300)
    heard = []
    res = fit_em(run.log(), config=cfg, on_start_moved=lambda mm, mean: heard.append((mm, mean)))
    moved = res.start_moved
    assert len(heard) == 1 and heard[0][0] == moved.moved_mm and moved.moved_mm > 3 * 300.0
    assert np.hypot(*moved.learned[:2]) < 300.0 and moved.given == (-1000.0, 3000.0, 0.0)
    assert moved.kept == "again" and moved.loglik[1] > moved.loglik[0] + 100.0
    assert res.summary()["start_moved"] == to_json(moved)
    m, truth = res.model, run.config
    assert m.action.coefficients[2, 2] == pytest.approx(truth.turn_gain, rel=0.02)
    assert m.action.coefficients[1, 1] == pytest.approx(truth.forward_gain, rel=0.02)
    offset = path_offset(res.posteriors.mean_gamma, run.poses, np.ones(len(run.poses)))
    assert offset["median_mm"] < 30.0


@pytest.mark.slow
def test_a_range_only_start_metres_and_radians_off_races_its_heading_where_em_moved_it():
    """Seeded recovery (searches/given_start.py, fit.headings_at): the given start 3.2 m off and its heading 2 rad
    off (a UWB robot's log, whose start nobody wrote down). EM moves the start near the true position;
    the ranges cannot tell the heading, so EM races eight headings there and goes on from the winner,
    which finds the robot's model, kept as the more likely."""
    run = simulate_diffdrive(DiffDriveConfig(seconds=300, seed=1, sensor="radio"))
    cfg = range_only_config(COMMAND_NAMES, (-1000.0, 3000.0, 2.0)).replace(max_iterations=600)
    res = fit_em(run.log(), config=cfg)
    moved = res.start_moved
    assert moved.kept == "again" and len(moved.heading_race.headings_rad) == 8
    assert abs(wrap_angle(res.model.prior_mean[2] - run.poses[0, 2])) < 0.2
    m, truth = res.model, run.config
    assert m.action.coefficients[2, 2] == pytest.approx(truth.turn_gain, rel=0.03)
    offset = path_offset(res.posteriors.mean_gamma, run.poses, np.ones(len(run.poses)))
    assert offset["median_mm"] < 60.0


@pytest.mark.slow
def test_simulate_a_radio_robot_then_learn_and_score_it_without_a_bearing(tmp_path):
    """`simulate diffdrive --set sensor=radio` writes a log without bearings and settings that start where
    the robot was put; `learn em --out` scores it with no bearing row, bar or figure (a traceback before)."""
    log, model = tmp_path / "radio", tmp_path / "m.json"
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(log), "--seconds", "60", "--set", "sensor=radio"])
    assert res.exit_code == 0, res.output
    lf = read_landmark_log(log)
    assert not np.isfinite(lf.data.obs_bearing_rad).any()
    assert "bearing_rad" not in (log / "observations.csv").read_text().splitlines()[0]
    assert lf.meta["truth"]["bearing_sigma_rad"] is None and lf.meta["truth"]["range_bearing_terms"] == []
    assert read_settings_file(log / "em_config.yaml") == range_only_config(COMMAND_NAMES, (0.0, 0.0, 0.0))
    assert "start_prior_mean: [0.0, 0.0, 0.0]" in (log / "em_config.yaml").read_text()
    args = ["learn", "em", str(log), "--config", str(log / "em_config.yaml"), "--set", "max_iterations=30"]
    res = runner.invoke(app, [*args, "--out", str(model)])
    assert_written(res)
    assert "Traceback" not in res.output and "bearing" not in res.output.split("against ground truth")[1]
    ev = json.loads(model.read_text())["evaluation"]
    assert ev["bearing"] is None and ev["sensor_mount"]["fitted_to_truth"] is None  # no bearings to fit it by
    assert set(ev["sensor_mount"]["learned"]) == {"forward_mm", "left_mm", "yaw_rad"}
    assert ev["bars"] == bar_checks(ev) and "bearing_sigma" not in ev["bars"] and len(ev["bars"]) == 6
    assert "bearing_sigma_rad" not in ev["simulated"]
    against_truth = ["m_actions.png", "m_heading_noise.png", "m_range.png"]  # no bearing figure
    report = ["m_commands.png", "m_path.png", "m_residuals.png"]  # the report's own
    assert sorted(p.name for p in tmp_path.glob("m_*.png")) == sorted(against_truth + report)
    # the library's score agrees, and a camera's model on this log has no bearing to be scored on either
    learned = json.loads(model.read_text())["model"]
    assert learned["sensor"]["sigma_bearing_rad"] is None
    poses, valid = lf.truth_poses()
    from sensact.models.em_model import EMModel

    sc = score_against_truth(EMModel.from_dict(learned), lf.data, poses, valid)
    assert sc["bearing"] is None and set(bar_checks(sc)) == set(ev["bars"]) - {"path_median"}  # no path given
    # `evaluate log` and `evaluate fleet` score it too (the fleet cell without a bearing ratio)
    res = runner.invoke(app, ["evaluate", "log", str(log), "--model", str(model), "--out", str(tmp_path / "e.json")])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["evaluate", "fleet", str(log), "--model", str(model), "--out", str(tmp_path / "f.json")])
    assert res.exit_code == 0, res.output
    assert "no bearing" in res.output and (tmp_path / "f.png").stat().st_size > 10_000
    # `localize` searches for the start by the ranges, or follows the robot from a given one
    for extra in ([], ["--start", "0,0,0"]):
        res = runner.invoke(
            app, ["localize", str(log), "--model", str(model), *extra, "--out", str(tmp_path / "l.json")]
        )
        assert_written(res)  # a model capped at 30 iterations: flagged, and so is its path
        loc = json.loads((tmp_path / "l.json").read_text())
        assert loc["start"]["how"] == ("given" if extra else "the ranges' start search")
        assert loc["truth"]["path"]["median_mm"] < 2 * ev["path"]["median_mm"] + 50.0
    res = runner.invoke(app, ["localize", str(log), "--model", str(model), "--start", "1000"])
    assert res.exit_code == 2 and "give --start X_MM,Y_MM,HEADING_RAD or X_MM,Y_MM" in " ".join(res.output.split())
    # a camera's model on it: refused when its range reads through bearing terms; run when it does not, with its
    # per-sighting likelihood said to be unlike the one learned on ranges and bearings
    doc = json.loads(model.read_text())
    doc["model"]["sensor"].update(sigma_bearing_rad=0.006, bearing_robust="student_t", bearing_robust_param=4.0)
    for terms in ([0.0, 0.08], []):
        doc["model"]["sensor"]["channels"][0]["bearing_terms"] = terms
        (tmp_path / "cam.json").write_text(json.dumps(doc))
        res = runner.invoke(app, ["localize", str(log), "--model", str(tmp_path / "cam.json")])
        said = " ".join(res.output.split())
        if terms:
            assert res.exit_code == 2 and "range_mm reads through its bearing terms and the log has no bearings" in said
        else:
            assert_written(res)
            assert "where each sighting read a bearing too: not comparable" in said


@pytest.mark.slow
def test_a_truth_of_positions_alone_converts_learns_and_is_scored_without_heading(tmp_path):
    """A UWB robot's truth often has no heading: `convert csv` takes a truth.csv of t_s, x_m, y_m, and
    `learn em` scores what positions can score. The translation on each window's chord, From-Truth
    fitted to the same chords (an exact reduction: the true model's chords are the truth's but for the
    motion noise), the range against the truth's distances, the path; the rotation, the bearing and the
    sensor's pose are not scored, and the JSON says so."""
    sim = DiffDriveConfig(sensor="radio", seconds=200.0, seed=3)
    run = simulate_diffdrive(sim)
    d = run.log()
    t = np.arange(d.n_steps) * sim.dt_s
    timed = tmp_path / "timed"
    timed.mkdir()

    def write(name, header, cols):
        np.savetxt(timed / name, np.column_stack(cols), delimiter=",", header=header, comments="")

    write("commands.csv", "t_s,v_m_s,omega_rad_s", [t, d.step_commands[:, 0] / 1000, d.step_commands[:, 1]])
    write("sightings.csv", "t_s,landmark_id,range_m", [t[d.obs_step], d.obs_landmark, d.obs_readings[:, 0] / 1000])
    write("landmarks.csv", "id,x_m,y_m", [np.arange(len(d.landmarks_xy)), d.landmarks_xy / 1000])
    write("truth.csv", "t_s,x_m,y_m", [t, run.poses[:, :2] / 1000])
    files = [f"--{n}={timed / (n + '.csv')}" for n in ("commands", "sightings", "landmarks", "truth")]
    res = runner.invoke(
        app,
        ["convert", "csv", *files, "--out", str(tmp_path / "log")],
    )
    assert res.exit_code == 0, res.output
    lf = read_landmark_log(tmp_path / "log")
    assert lf.data.dt_s == pytest.approx(sim.dt_s)  # the commands' own rate
    assert np.isnan(lf.truth_poses()[0][:, 2]).all()
    out = tmp_path / "m.json"
    res = runner.invoke(app, ["learn", "em", str(tmp_path / "log"), "--out", str(out)])
    assert_written(res)
    ev = json.loads(out.read_text())["evaluation"]
    assert ev["no_heading"] and ev["bearing"] is None and ev["truth_noise"] is None
    assert ev["action"]["ratio_rotation"] is None and ev["sensor_mount"]["fitted_to_truth"] is None
    assert set(ev["bars"]) == {
        "action_translation_ratio",
        "action_translation_abs",
        "range_sigma",
        "range_function",
        "path_median",
    }
    assert all(ev["bars"].values()), ev["bars"]
    assert 0.9 < ev["action"]["ratio_translation"] < 1.3 and ev["path"]["median_mm"] < 60.0
