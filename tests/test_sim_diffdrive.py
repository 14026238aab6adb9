"""The simulated differential drive (sim/diffdrive.py) and EM on it with MRCLAM's settings
(experiments/diffdrive.py, `sensact simulate diffdrive`, `sensact reproduce diffdrive`)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import sensact
from conftest import assert_written
from sensact.app import read_settings_file
from sensact.cli import app
from sensact.core.angles import wrap_angle
from sensact.core.pose_models import apply_displacement, landmark_bearing, landmark_distance
from sensact.evaluate.bars import verdict_line
from sensact.evaluate.simulated_robot import score_against_simulated
from sensact.experiments import diffdrive
from sensact.experiments.real import bar_checks, evaluate_mrclam
from sensact.io.csvtable import read_numeric_csv
from sensact.io.landmark_folder import read_landmark_log
from sensact.learn.em import fit_em
from sensact.learn.em.checks.lost_signs import describe_held_sideways, held_sideways_noise
from sensact.models.em_model import EMModel
from sensact.models.linear_action import LinearActionModel
from sensact.presets import mrclam_config, planar_config
from sensact.sim.diffdrive import DiffDriveConfig, from_wheel_coefficients, ring_of_landmarks, simulate_diffdrive

runner = CliRunner()
QUIET = dict(sideways_sd_mm=0.0, forward_sd_mm=0.0, heading_sd_rad=0.0, range_sd_mm=1e-12, bearing_sd_rad=1e-12)


@pytest.mark.parametrize(("sidestep", "seed", "curve"), [(0.0, 2, 0.0), (60.0, 4, 0.0), (0.0, 3, 0.0003)])
def test_the_truth_it_writes_is_the_robot_it_drives(sidestep, seed, curve):
    """Exact reduction: without noise or lag, the affine model of ``truth()`` at its delay, dead-reckoned
    from the logged commands, is the simulated path, and each sighting reads ``range_reading``; for a
    differential drive, one that curves when driving straight (a wheel mismatch) and a robot that
    side-steps (``v_left`` to its left, a negative ``v_x``)."""
    side = {"sidestep_mm_s": sidestep, "sideways_bias_mm_s": 4.0} if sidestep else {}  # a drift to the left
    cfg = DiffDriveConfig(
        seconds=120, seed=seed, lag_s=0.0, misread_rate=0.0, straight_turn_rad_per_mm=curve, **side, **QUIET
    )
    run = simulate_diffdrive(cfg)
    t = cfg.truth()
    names, logged = run.logged_commands()
    assert tuple(t["command_names"]) == names == cfg.command_names
    model = LinearActionModel(
        "affine",
        1,
        np.array(t["action_coefficients"]),
        names,
        ("vx", "vy", "vt"),
        delay_steps=t["delay_steps"],
    )
    assert t["delay_steps"] == 6
    assert (np.abs(run.side_commands).max() > 10.0) == (sidestep > 0)  # it side-steps within these 120 s
    v = model.step_features(logged) @ model.coefficients
    w = run.poses[0]
    for k in range(len(run.commands) - 1):
        w = apply_displacement(w, v[k] * cfg.dt_s)[0]
        np.testing.assert_allclose(w[:2], run.poses[k + 1, :2], atol=1e-6)
        assert abs(wrap_angle(w[2] - run.poses[k + 1, 2])) < 1e-9
    lm = np.asarray(cfg.landmarks_xy_mm)[run.obs_landmark]
    d = landmark_distance(run.poses[run.obs_step], lm)
    b = landmark_bearing(run.poses[run.obs_step], lm)
    np.testing.assert_allclose(run.obs_bearing_rad, b, atol=1e-9)
    np.testing.assert_allclose(run.obs_range_mm, cfg.range_reading(d, b), atol=1e-6)


def test_it_drives_like_an_mrclam_robot():
    """Invariants: the robot stays in the room, never backs up or side-steps on command, turns no faster
    than its limit, waits and turns in place, and sees only what is in front of it and in range."""
    cfg = DiffDriveConfig(seconds=300, seed=5)
    run = simulate_diffdrive(cfg)
    v, w = run.commands.T
    assert v.min() == 0.0 and v.max() <= cfg.speed_mm_s and np.abs(w).max() <= cfg.turn_rate_rad_s
    assert 0.05 < np.mean(v == 0) < 0.6 and np.mean((v == 0) & (w != 0)) > 0.01  # waits, turns in place
    assert np.abs(run.poses[:, 0]).max() < 0.5 * cfg.room_width_mm
    assert np.abs(run.poses[:, 1]).max() < 0.5 * cfg.room_length_mm
    ok = ~run.obs_misread
    lm = np.asarray(cfg.landmarks_xy_mm)[run.obs_landmark[ok]]
    d = landmark_distance(run.poses[run.obs_step[ok]], lm)
    b = landmark_bearing(run.poses[run.obs_step[ok]], lm)
    assert d.min() >= cfg.min_range_mm and d.max() <= cfg.max_range_mm
    assert np.abs(b).max() <= np.deg2rad(cfg.fov_deg) / 2
    assert 0 < run.obs_misread.sum() < 0.05 * run.obs_step.size
    frames = np.unique(run.obs_step)
    assert np.all(frames % round(cfg.frame_period_s / cfg.dt_s) == 0)
    assert len(ring_of_landmarks(4000, 9000, 5)) == 14


def test_a_robot_that_side_steps_walks_at_some_waypoints_without_turning():
    """Invariants of ``sidestep_mm_s`` (a legged robot's commands): at some waypoints it walks straight at
    the waypoint, forward (or back) and sideways on the ellipse of its two top speeds, never turning; at
    the others it turns and drives as a differential drive does. The robot's own sideways travel follows
    the sideways command at its gain. Without the option nothing moves sideways on command."""
    cfg = DiffDriveConfig(seconds=300, seed=2, sidestep_mm_s=60.0, sideways_sd_mm=0.0, lag_s=0.0)
    run = simulate_diffdrive(cfg)
    names, logged = run.logged_commands()
    assert names == ("v_mm_s", "v_left_mm_s", "omega_rad_s") and logged.shape == (len(run.poses), 3)
    v, w = run.commands.T
    crab = run.side_commands != 0
    assert 0.1 < crab.mean() < 0.9 and np.mean(w != 0) > 0.1  # both kinds of waypoint
    assert np.all(w[crab] == 0) and np.abs(run.side_commands).max() <= cfg.sidestep_mm_s
    np.testing.assert_allclose(
        (v[crab] / cfg.speed_mm_s) ** 2 + (run.side_commands[crab] / cfg.sidestep_mm_s) ** 2, 1.0
    )
    assert v[crab].min() < 0  # a waypoint behind it is walked to backwards
    # the true sideways travel per step, in the robot frame (x to its right: sec. 2.5.1), against the command
    step = np.diff(run.poses[:, :2], axis=0)
    th = run.poses[:-1, 2]
    right = (np.cos(th) * step[:, 0] + np.sin(th) * step[:, 1]) / cfg.dt_s
    late = np.r_[np.zeros(cfg.delay_steps), run.side_commands[: -cfg.delay_steps - 1]]
    gain = -np.polyfit(late, right, 1)[0]
    assert gain == pytest.approx(cfg.sideways_gain, rel=1e-6)
    plain = simulate_diffdrive(DiffDriveConfig(seconds=60, seed=2))
    assert plain.logged_commands()[0] == ("v_mm_s", "omega_rad_s") and not plain.side_commands.any()
    assert np.array(DiffDriveConfig().truth()["action_coefficients"]).shape == (3, 3)


def test_a_camera_yaw_drift_is_shared_and_slow():
    """The optional left-out effect: with little white bearing noise, the residual about the true pose
    is the drift, with its stationary sd and nearly the same from frame to frame (0.24 s of a 5-s time
    constant); off by default."""
    cfg = DiffDriveConfig(seconds=600, seed=3, bearing_sd_rad=1e-6, misread_rate=0.0, bearing_drift_sd_rad=0.01)
    run = simulate_diffdrive(cfg)
    lm = np.asarray(cfg.landmarks_xy_mm)[run.obs_landmark]
    r = wrap_angle(run.obs_bearing_rad - landmark_bearing(run.poses[run.obs_step], lm))
    steps, first = np.unique(run.obs_step, return_index=True)
    per_frame = r[first]
    assert 0.006 < per_frame.std() < 0.014
    near = np.diff(steps) == round(cfg.frame_period_s / cfg.dt_s)
    assert np.corrcoef(per_frame[:-1][near], per_frame[1:][near])[0, 1] > 0.9
    same = np.repeat(per_frame, np.diff(np.append(first, r.size)))
    np.testing.assert_allclose(r, same, atol=1e-5)  # every sighting of a frame shares it
    assert DiffDriveConfig().bearing_drift_sd_rad == 0.0


def test_wheel_speeds_log_the_same_robot_on_other_commands(tmp_path):
    """Exact reduction: with ``wheel_axle_mm`` the log holds the wheel speeds of the same drive
    ((l + r) / 2 = v, (r - l) / B = omega); an affine model on them, rewritten on (v, omega), predicts the
    same velocities; the simulated model's own velocities, fitted on the wheels by least squares (an
    independent route), score its true gains exactly; and `simulate diffdrive` writes MRCLAM's settings
    less the forward-from-v restriction, saying why."""
    from sensact.learn.em.initial import initial_model
    from sensact.models.linear_action import command_features

    axle = 235.0
    base = simulate_diffdrive(DiffDriveConfig(seconds=60, seed=4))
    run = simulate_diffdrive(DiffDriveConfig(seconds=60, seed=4, wheel_axle_mm=axle))
    d, vw = run.log(), base.commands
    assert d.command_names == ("left_mm_s", "right_mm_s") and base.log().command_names == ("v_mm_s", "omega_rad_s")
    np.testing.assert_array_equal(run.poses, base.poses)
    np.testing.assert_array_equal(run.obs_bearing_rad, base.obs_bearing_rad)
    np.testing.assert_allclose(d.step_commands.mean(axis=1), vw[:, 0], atol=1e-12)
    np.testing.assert_allclose((d.step_commands[:, 1] - d.step_commands[:, 0]) / axle, vw[:, 1], atol=1e-15)
    beta_w = np.random.default_rng(0).normal(size=(3, 3))
    np.testing.assert_allclose(
        command_features("affine", 1, d.step_commands) @ beta_w,
        command_features("affine", 1, vw) @ from_wheel_coefficients(beta_w, axle),
        rtol=1e-10,
        atol=1e-9,
    )
    truth = run.config.truth()
    assert truth["wheel_axle_mm"] == axle
    true_velocities = command_features("affine", 1, vw) @ np.asarray(truth["action_coefficients"])
    on_wheels = np.linalg.lstsq(command_features("affine", 1, d.step_commands), true_velocities, rcond=None)[0]
    log_dir = tmp_path / "w"
    res = runner.invoke(
        app,
        [
            "simulate",
            "diffdrive",
            "--out",
            str(log_dir),
            "--seconds",
            "60",
            "--seed",
            "4",
            "--set",
            "wheel_axle_mm=235",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "commands left_mm_s, right_mm_s" in " ".join(res.output.split())
    text = (log_dir / "em_config.yaml").read_text()
    assert "wheels' mean" in text
    cfg = read_settings_file(log_dir / "em_config.yaml")
    assert cfg.action.inputs == ("v_y_mm_s:(left_mm_s+right_mm_s)",)  # the forward speed from the wheels' sum
    assert cfg.action.zero_mean == ("v_x_mm_s",) and cfg.action.basis == "affine"
    model = initial_model(d, cfg)
    model = replace(model, action=replace(model.action, coefficients=on_wheels, delay_steps=truth["delay_steps"]))
    s = score_against_simulated(model, truth, run.config.dt_s)
    assert s["forward_gain"][0] == pytest.approx(s["forward_gain"][1], abs=1e-9)
    assert s["turn_gain"][0] == pytest.approx(s["turn_gain"][1], abs=1e-9)
    assert s["forward_bias_mm_s"][0] == pytest.approx(s["forward_bias_mm_s"][1], abs=1e-6)


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="wheel_axle_mm"):
        DiffDriveConfig(wheel_axle_mm=-1.0)
    with pytest.raises(ValueError, match="margin_mm"):
        DiffDriveConfig(room_width_mm=1000.0)
    with pytest.raises(ValueError, match="min_range_mm"):
        DiffDriveConfig(min_range_mm=8000.0)
    with pytest.raises(ValueError, match="wheel_axle_mm"):
        DiffDriveConfig(sidestep_mm_s=60.0, wheel_axle_mm=235.0)
    with pytest.raises(ValueError, match="crab_share"):
        DiffDriveConfig(sidestep_mm_s=60.0, crab_share=1.5)


def test_em_with_mrclams_settings_recovers_the_simulated_robot():
    """Seeded recovery, the whole issue-5 learner (start search and race, ridge and delay searches,
    learned Sigma_m, Student-t readings) on five minutes of a robot its model families describe: every
    MRCLAM bar clears, and the learned model is the simulated one."""
    exp = diffdrive.DiffDriveExperiment(trials=1, seed=1, simulator=DiffDriveConfig(seconds=300))
    out, art = diffdrive.run_diffdrive(exp)
    checks = diffdrive.scorecard(out)
    assert len(checks) == 7 and all(c.cleared for c in checks), verdict_line(checks)
    s = out["seeds"]["seed1"]["simulated"]
    assert s["forward_gain"][0] == pytest.approx(s["forward_gain"][1], rel=0.03)
    assert s["turn_gain"][0] == pytest.approx(s["turn_gain"][1], rel=0.03)
    assert abs(s["delay_steps"][0] - s["delay_with_lag_steps"]) <= 1.5  # a lag of tau reads as tau more delay
    # the smoothed heading's uncertainty counts into the bearing's expected residual (docs/em-real.md)
    assert 0.9 < s["bearing_sigma_ratio"] < 1.3
    # a Student-t scale (nu 4) on Gaussian noise is below its sd
    assert 0.75 < s["range_sigma_ratio"] < 1.0
    _, res = art["robots"]["seed1"]
    assert s == score_against_simulated(res.model, replace(exp.simulator, seed=1).truth(), exp.simulator.dt_s)
    assert held_sideways_noise(res.model, "shared") is None  # a differential drive held to no sideways mean is right


@pytest.mark.slow
def test_em_learns_a_robot_that_side_steps_with_every_velocity_free():
    """Seeded recovery on a robot the differential drive's settings do not describe: a legged robot's
    (v, v_left, omega). The settings for any other commands (``planar_config``) free the sideways mean
    and the inputs; the whole learner then clears every bar and recovers all three gains."""
    names = ("v_mm_s", "v_left_mm_s", "omega_rad_s")
    learner = planar_config(names)
    assert learner.action.zero_mean == () and learner.action.inputs == ()
    assert (
        learner.replace(action_zero_mean=mrclam_config().action.zero_mean, action_inputs=mrclam_config().action.inputs)
        == mrclam_config()
    )
    assert planar_config(("v_mm_s", "omega_rad_s")) == mrclam_config()
    sim = DiffDriveConfig(seconds=300, sidestep_mm_s=60.0)
    # with no learner given, the experiment learns with the settings `simulate diffdrive` writes
    assert diffdrive.DiffDriveExperiment(simulator=sim).learner_config == learner
    assert diffdrive.DiffDriveExperiment().learner_config == mrclam_config()
    out, art = diffdrive.run_diffdrive(diffdrive.DiffDriveExperiment(trials=1, seed=2, simulator=sim))
    checks = diffdrive.scorecard(out)
    assert len(checks) == 7 and all(c.cleared for c in checks), verdict_line(checks)
    s = out["seeds"]["seed2"]["simulated"]
    for gain in ("forward_gain", "turn_gain", "sideways_gain"):
        assert s[gain][0] == pytest.approx(s[gain][1], rel=0.03), gain
    assert s["sideways_gain"][1] == sim.sideways_gain
    assert out["seeds"]["seed2"]["score"]["path"]["median_mm"] < 100.0
    robot, res = art["robots"]["seed2"]
    assert held_sideways_noise(res.model, "shared") is None
    # held to a differential drive's zero sideways mean, the same robot still clears the action bars (From-Truth
    # is fitted in that family too), but its side-steps become sideways motion noise, which learn em points out
    held = fit_em(robot.data, None, mrclam_config())
    sc = evaluate_mrclam(robot, held)
    assert sc["bars"]["action_translation_ratio"] and sc["bars"]["action_rotation_ratio"]
    assert (
        sc["action"]["learned"]["translation_rms_mm_s"]
        > 2 * out["seeds"]["seed2"]["score"]["action"]["learned"]["translation_rms_mm_s"]
    )
    note = held_sideways_noise(held.model, "shared")
    assert held_sideways_noise(held.model, "fixed") is None  # Sigma_m not learned: the config's own sds
    assert note is not None and note["ratio"] > 2.0 and "drop v_x_mm_s" in describe_held_sideways(note)


@pytest.mark.slow
def test_simulate_diffdrive_then_learn_em_scores_against_the_simulation(tmp_path):
    from sensact.config import config_from_dict
    from sensact.learn.em import EMConfig

    log, model = tmp_path / "dd", tmp_path / "m.json"
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(log), "--seconds", "90", "--seed", "3"])
    assert res.exit_code == 0, res.output
    assert f"sensact learn em {log}` (settings: {log / 'em_config.yaml'})" in " ".join(res.output.split())
    lf = read_landmark_log(log)
    assert lf.data.is_continuous and lf.meta["truth"]["kind"] == "diffdrive" and lf.truth_poses() is not None
    other = tmp_path / "other.yaml"  # a config of the user's without the action basis: the thesis's table
    other.write_text("max_iterations: 5\n")
    res = runner.invoke(app, ["learn", "em", str(log), "--config", str(other)])
    flat = " ".join(res.output.split())
    assert res.exit_code != 0 and "action.basis" in flat and f"--config {log / 'em_config.yaml'}" in flat
    assert "Traceback" not in res.output
    # without --config, the settings written beside the log are the ones --set overrides
    sets = ["--set", "max_iterations=40", "--set", "start_candidates=2"]
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(model), *sets])
    assert_written(res)
    doc = json.loads(model.read_text())
    beside = read_settings_file(log / "em_config.yaml")
    assert config_from_dict(EMConfig, doc["summary"]["config"]) == beside.replace(max_iterations=40, start_candidates=2)
    assert f"settings: {log / 'em_config.yaml'}, written beside the log" in " ".join(res.output.split())
    assert "is its unit right" not in " ".join(res.output.split())  # see the next test
    ev = doc["evaluation"]
    flat = " ".join(res.output.split())
    learned = EMModel.from_dict(doc["model"])
    assert ev["simulated"] == score_against_simulated(learned, lf.meta["truth"], lf.data.dt_s)
    assert "vs the simulated model (learned / true)" in " ".join(res.output.split())
    assert ev["bars"] == bar_checks(ev) and len(ev["bars"]) == 7
    assert (tmp_path / "m_bearing.png").stat().st_size > 10_000
    # `evaluate log`: the same model on the same log scores exactly as learn em did (an exact reduction) ...
    res = runner.invoke(app, ["evaluate", "log", str(log), "--model", str(model), "--out", str(tmp_path / "e.json")])
    assert res.exit_code == 0, res.output
    # (learn em also scores its smoothed path, which `evaluate log` does not re-run the E-step for)
    assert ev["path"]["median_mm"] < 300.0 and "smoothed path off the recorded poses" in flat
    # the smoothed path itself, written beside the model, is the one scored: the same median distance
    with np.load(tmp_path / "m.path.npz", allow_pickle=False) as path:
        assert list(path["state"]) == ["x_mm", "y_mm", "theta_rad"] and "m.path.npz" in flat
        assert path["mean"].shape == (lf.data.n_steps, 3) and path["sd"].shape == (lf.data.n_steps, 3)
        assert path["time_s"][-1] == pytest.approx((lf.data.n_steps - 1) * lf.data.dt_s)
        assert (path["sd"] > 0).all()
        poses, valid = lf.truth_poses()
        off = np.hypot(*(path["mean"][valid, :2] - poses[valid, :2]).T)
        assert float(np.median(off)) == pytest.approx(ev["path"]["median_raw_mm"], rel=1e-9)
    scored = json.loads((tmp_path / "e.json").read_text())
    assert scored.pop("sensact_version") == doc["sensact_version"] == sensact.__version__  # each file names its code
    assert scored.pop("sensact_output") == "evaluation"  # and what it is
    assert next(iter(doc)) == "sensact_version"
    # learn em also scores its path (a bar) and its pruning, which `evaluate log` has no fit for
    unscored = {k: v for k, v in ev.items() if k not in ("path", "pruned_fraction")}
    assert scored == unscored | {"bars": {k: v for k, v in ev["bars"].items() if k != "path_median"}}
    assert (tmp_path / "e_actions.png").stat().st_size > 10_000
    # ... and on another run of the robot it scores against that run's truth, with From-Truth fitted there
    other = tmp_path / "dd4"
    assert (
        runner.invoke(app, ["simulate", "diffdrive", "--out", str(other), "--seconds", "90", "--seed", "4"]).exit_code
        == 0
    )
    res = runner.invoke(app, ["evaluate", "log", str(other), "--model", str(model), "--out", str(tmp_path / "o.json")])
    assert res.exit_code == 0, res.output
    ev4 = json.loads((tmp_path / "o.json").read_text())
    assert ev4["simulated"] == ev["simulated"]  # the model against the robot: the same robot, the same numbers
    assert ev4["action"] != ev["action"] and ev4["bars"] == bar_checks(ev4)
    # `localize`: the model, held, finds where that other run started and follows it (no learning)
    res = runner.invoke(app, ["localize", str(other), "--model", str(model), "--out", str(tmp_path / "l.json")])
    assert_written(res)  # a model capped at 40 iterations: flagged, and so is its path
    loc = json.loads((tmp_path / "l.json").read_text())
    poses4, valid4 = read_landmark_log(other).truth_poses()
    assert loc["start"]["how"] == "the start search's candidates" and len(loc["start"]["candidates"]) > 1
    start = np.array(loc["start"]["prior_mean"])  # a cell of the search's 500-mm grid
    assert np.hypot(*(start[:2] - poses4[0, :2])) < 500.0, start
    assert loc["truth"]["path"]["median_mm"] < 300.0 and loc["filter_ok"]
    # a model that holds fits the other run no worse, a sighting, than the run it was learned on (here
    # better: -5.34 against -5.98); one whose range function reads 30 % long fits it far worse
    assert loc["loglik_per_sighting"] > loc["loglik_per_sighting_learned"] - 0.5, loc
    doc = json.loads(model.read_text())
    channel = doc["model"]["sensor"]["channels"][0]
    channel["function"]["coef"] = [1.3 * c for c in channel["function"]["coef"]]
    (tmp_path / "long.json").write_text(json.dumps(doc))
    res = runner.invoke(
        app, ["localize", str(other), "--model", str(tmp_path / "long.json"), "--out", str(tmp_path / "x.json")]
    )
    assert_written(res)
    wrong = json.loads((tmp_path / "x.json").read_text())
    assert wrong["loglik_per_sighting"] < loc["loglik_per_sighting"] - 1.0, wrong["loglik_per_sighting"]
    with np.load(tmp_path / "l.path.npz", allow_pickle=False) as path:
        off = np.hypot(*(path["mean"][valid4, :2] - poses4[valid4, :2]).T)
        assert float(np.median(off)) == pytest.approx(loc["truth"]["path"]["median_raw_mm"], rel=1e-9)
        assert off[0] < 300.0, off[0]  # the smoothed start, which the sightings place
    assert (tmp_path / "l.png").stat().st_size > 30_000 and "smoothed path off the recorded poses" in res.output
    assert "recorded heading" not in res.output
    # the run's recorded heading copied in as ROS has it (0 facing +x): the same path, and a warning that
    # its split into forward and right reads a heading a quarter turn off
    gt = read_numeric_csv(other / "groundtruth.csv")
    gt["theta_rad"] = gt["theta_rad"] + 0.5 * np.pi
    (other / "groundtruth.csv").write_text(
        ",".join(gt)
        + "\n"
        + "\n".join(",".join(repr(float(v)) for v in row) for row in zip(*gt.values(), strict=True))
        + "\n"
    )
    res = runner.invoke(app, ["localize", str(other), "--model", str(model)])
    flat = " ".join(res.output.split())
    assert_written(res)
    assert "write theta_rad = theta_rad - 1.57" in flat, res.output
    assert f"median {loc['truth']['path']['median_mm']:.0f} mm" in flat


def test_learn_em_says_how_many_misreads_the_gate_dropped_and_offers_joint_student_t(tmp_path):
    """A race as long as refine_from ends the held stage at the fit's first iteration, and the gate runs
    then; `learn em` says how many it dropped and suggests joint_student_t, and with it set the model
    keeps the setting and the suggestion is gone."""
    log = tmp_path / "dd"
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(log), "--seconds", "120", "--seed", "3"])
    assert res.exit_code == 0, res.output
    short = ["max_iterations=40", "start_candidates=2", "refine_from=20"]  # the race: 20 held iterations
    for joint in (False, True):
        sets = [*short, f"joint_student_t={str(joint).lower()}"]
        args = ["learn", "em", str(log), "--out", str(tmp_path / "m.json"), "--config", str(log / "em_config.yaml")]
        res = runner.invoke(app, args + [a for x in sets for a in ("--set", x)])
        assert_written(res)
        flat = " ".join(res.output.split())
        doc = json.loads((tmp_path / "m.json").read_text())
        assert doc["summary"]["n_pruned_when_freed"] == 1 and "(1 when the robust readings took over" in flat
        assert doc["model"]["sensor"]["joint_student_t"] is joint
        assert ("--set joint_student_t=true" in flat) is not joint


def test_evaluate_log_names_what_keeps_a_model_from_a_log(tmp_path):
    """A model scores only on a log it could have been learned from; anything else is one line naming the
    field and the fix, never a traceback: other commands, another step, a log with no truth, a bad file."""
    from sensact.learn.em import fit_em

    logs = {}
    for name, extra in (("vw", []), ("wheels", ["--set", "wheel_axle_mm=235"]), ("coarse", ["--set", "dt_s=0.05"])):
        logs[name] = tmp_path / name
        res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(logs[name]), "--seconds", "30", *extra])
        assert res.exit_code == 0, res.output
    lf = read_landmark_log(logs["vw"])
    cfg = read_settings_file(logs["vw"] / "em_config.yaml").replace(max_iterations=2, start_search_s=None)
    fitted = fit_em(lf.data, config=cfg).model
    model = tmp_path / "m.json"
    model.write_text(json.dumps({"model": fitted.to_dict(), "dt_s": lf.data.dt_s}))
    no_truth = tmp_path / "no_truth"
    no_truth.mkdir()
    for f in ("meta.json", "actions.csv", "observations.csv"):
        (no_truth / f).write_bytes((logs["vw"] / f).read_bytes())
    meta = json.loads((no_truth / "meta.json").read_text())
    meta.pop("truth")
    (no_truth / "meta.json").write_text(json.dumps(meta))
    (tmp_path / "bad.json").write_text("{not json")
    (tmp_path / "list.json").write_text("[1, 2]")
    cases = [
        (logs["wheels"], model, "action.command_names", "the model's commands are v_mm_s, omega_rad_s"),
        (logs["coarse"], model, "dt_s", "--dt 0.03333333333"),
        (no_truth, model, "groundtruth.csv", "has no ground truth"),
        (logs["vw"], tmp_path / "bad.json", "bad.json", "not valid JSON (line 1)"),
        (logs["vw"], tmp_path / "none.json", "none.json", "none.json not found"),
        (logs["vw"], tmp_path / "list.json", "list.json", "not a JSON object (it holds a list)"),
    ]
    for folder, m, field, words in cases:
        res = runner.invoke(app, ["evaluate", "log", str(folder), "--model", str(m)])
        flat = " ".join(res.output.split())
        assert res.exit_code == 2 and field in flat and words in flat and "Traceback" not in res.output, flat
    assert runner.invoke(app, ["evaluate", "log", str(logs["vw"]), "--model", str(model)]).exit_code == 0
    # a table of discrete actions scores only on a log whose actions are the same commands
    track = tmp_path / "track"
    assert (
        runner.invoke(app, ["simulate", "track1d", "--seconds", "60", "--seed", "1", "--out", str(track)]).exit_code
        == 0
    )
    table = tmp_path / "t.json"
    res = runner.invoke(app, ["learn", "em", str(track), "--set", "max_iterations=2", "--out", str(table)])
    assert_written(res)
    assert runner.invoke(app, ["evaluate", "log", str(track), "--model", str(table)]).exit_code == 0
    doc = json.loads(table.read_text())
    doc["model"]["action"]["commands"] = [[1.5 * c for c in row] for row in doc["model"]["action"]["commands"]]
    table.write_text(json.dumps(doc))
    res = runner.invoke(app, ["evaluate", "log", str(track), "--model", str(table)])
    flat = " ".join(res.output.split())
    assert res.exit_code == 2 and "action.commands" in flat and "other commands" in flat, flat


def test_learn_em_names_settings_and_logs_it_cannot_learn_from(tmp_path):
    """A setting that does not suit the log, or a log too short for its model, is one line naming the
    file, the field and the fix before EM runs, never a traceback; a log whose recorded poses are too
    broken up to score is still learned, and says why it was not scored."""
    dd, track = tmp_path / "dd", tmp_path / "track"
    assert runner.invoke(app, ["simulate", "diffdrive", "--seconds", "30", "--out", str(dd)]).exit_code == 0
    assert runner.invoke(app, ["simulate", "track1d", "--seconds", "20", "--out", str(track)]).exit_code == 0
    cfg = dd / "em_config.yaml"
    renamed = tmp_path / "renamed.yaml"
    renamed.write_text(cfg.read_text() + "channels: [{name: sonar9, start_intercept: 500.0, start_slope: 0.6}]\n")
    assert "sonar9" in renamed.read_text()
    short = tmp_path / "short"
    short.mkdir()
    (short / "meta.json").write_bytes((dd / "meta.json").read_bytes())
    for f in ("actions.csv", "observations.csv", "groundtruth.csv"):  # the log cut after its first 3 steps
        lines = (dd / f).read_text().splitlines()
        (short / f).write_text(
            "\n".join([lines[0], *(ln for ln in lines[1:] if float(ln.split(",")[0]) < 0.07)]) + "\n"
        )
    bad_step = tmp_path / "bad_step"
    bad_step.mkdir()
    for f in ("actions.csv", "observations.csv"):
        (bad_step / f).write_bytes((dd / f).read_bytes())
    meta = json.loads((dd / "meta.json").read_text())
    (bad_step / "meta.json").write_text(json.dumps({**meta, "dt_s": -1}))
    no_commands = tmp_path / "no_commands"
    no_commands.mkdir()
    for f in ("actions.csv", "observations.csv"):
        (no_commands / f).write_bytes((dd / f).read_bytes())
    (no_commands / "meta.json").write_text(json.dumps({**meta, "actions": {"columns": []}}))
    bad_map = tmp_path / "bad_map"
    bad_map.mkdir()
    for f in ("actions.csv", "observations.csv"):
        (bad_map / f).write_bytes((dd / f).read_bytes())
    marks = [{**m, "x_mm": "east"} for m in meta["landmarks"]]
    (bad_map / "meta.json").write_text(json.dumps({**meta, "landmarks": marks}))
    cases = [
        ([track, "--set", "ridge_search_mm=300"], "track: search.ridge_mm:", "set search.ridge_mm: null"),
        ([track, "--set", "motion_noise=turning"], "track: motion_noise.kind:", "use motion_noise.kind: shared"),
        ([track, "--set", "motion_sd_sideways_mm=3"], "track: motion_noise.sideways_mm:", "no sideways"),
        ([track, "--set", "action_basis=affine"], "track: action.basis:", "use action.basis: table"),
        ([dd, "--config", renamed], "channels[].name:", "name the log's readings: range_mm"),
        ([dd, "--config", cfg, "--set", 'action_inputs=["v_y_mm_s:w"]'], "action.inputs", "omega_rad_s"),
        ([short, "--config", cfg], "short: range_mm:", "readings of range_mm, and its model has 7 parameters"),
        ([bad_step], "meta.json: dt_s:", "must be a positive number"),
        ([no_commands, "--config", cfg], "meta.json: actions.columns:", "at least one command column"),
        ([bad_map, "--config", cfg], "meta.json: landmarks:", "landmarks: malformed (could not convert string"),
    ]
    for args, field, words in cases:
        res = runner.invoke(app, ["learn", "em", *map(str, args)])
        flat = " ".join(res.output.split())
        assert res.exit_code == 2 and field in flat and words in flat and "Traceback" not in res.output, flat
    broken = tmp_path / "broken"
    broken.mkdir()
    for f in ("meta.json", "actions.csv", "observations.csv"):
        (broken / f).write_bytes((dd / f).read_bytes())
    rows = (dd / "groundtruth.csv").read_text().splitlines()
    (broken / "groundtruth.csv").write_text(
        "\n".join([rows[0] + ",valid"] + [f"{r},{k % 2}" for k, r in enumerate(rows[1:])]) + "\n"
    )
    out = tmp_path / "m.json"
    res = runner.invoke(
        app, ["learn", "em", str(broken), "--config", str(cfg), "--set", "max_iterations=2", "--out", str(out)]
    )
    flat = " ".join(res.output.split())
    assert_written(res)
    assert "not scored against the recorded poses" in flat and "groundtruth.csv: t_s: no 30-step window" in flat
    assert json.loads(out.read_text())["evaluation"] is None
    # scoring that model there on purpose is what fails, naming the file
    res = runner.invoke(app, ["evaluate", "log", str(broken), "--model", str(out)])
    flat = " ".join(res.output.split())
    assert res.exit_code == 2 and "groundtruth.csv: t_s: no 30-step window" in flat and "not scored" not in flat, flat


def test_reproduce_diffdrive_writes_its_scorecard_and_figures(tmp_path):
    res = runner.invoke(app, ["reproduce", "diffdrive", "--trials", "0", "--out", str(tmp_path)])
    assert res.exit_code != 0 and "--trials" in res.output and not (tmp_path / "diffdrive.json").exists()
    res = runner.invoke(
        app,
        [
            "reproduce",
            "diffdrive",
            "--trials",
            "1",
            "--out",
            str(tmp_path),
            "--set",
            "seconds=90",
            "--set",
            "max_iterations=30",
            "--set",
            "start_candidates=2",
        ],
    )
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "diffdrive.json").read_text())
    assert out["config"]["simulator"]["seconds"] == 90 and out["config"]["learner"]["thesis"]["max_iterations"] == 30
    assert out["config"]["learner"]["action"]["basis"] == "affine"  # MRCLAM's settings under the --set
    assert out["scorecard"] == [c.to_dict() for c in diffdrive.scorecard(out)]
    assert f"diffdrive {verdict_line(diffdrive.scorecard(out))}" in " ".join(res.output.split())
    for kind in ("actions", "range", "heading_noise", "bearing"):
        assert (tmp_path / f"diffdrive_seed0_{kind}.png").stat().st_size > 10_000
    assert (tmp_path / "diffdrive_loglik.png").is_file()
    assert 'id="diffdrive"' in (tmp_path / "index.html").read_text()


def test_a_side_stepping_robot_from_simulate_to_learn_em_and_reproduce(tmp_path):
    """The CLI on a legged robot's commands: `simulate diffdrive --set sidestep_mm_s=60` writes the settings
    for any other commands (the sideways velocity free, and says why), `learn em` reports the sideways gain
    against the simulated one, and `reproduce diffdrive` learns with the same settings and tabulates it."""

    log, model = tmp_path / "legged", tmp_path / "m.json"
    side = ["--set", "sidestep_mm_s=60"]
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(log), "--seconds", "90", "--seed", "4", *side])
    assert res.exit_code == 0, res.output
    assert "commands v_mm_s, v_left_mm_s, omega_rad_s" in " ".join(res.output.split())
    text = (log / "em_config.yaml").read_text()
    assert read_settings_file(log / "em_config.yaml") == planar_config(("v_mm_s", "v_left_mm_s", "omega_rad_s"))
    assert "#   v_mm_s, v_left_mm_s, omega_rad_s" in text and "add action_zero_mean: [v_x_mm_s]" in text
    cfg = ["--config", str(log / "em_config.yaml"), "--set", "max_iterations=40", "--set", "start_candidates=2"]
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(model), *cfg])
    assert_written(res)
    ev = json.loads(model.read_text())["evaluation"]
    g = ev["simulated"]["sideways_gain"]
    assert g[1] == 0.85 and f"sideways gain {g[0]:.3f} / 0.850" in " ".join(res.output.split())
    out = tmp_path / "R"
    fast = ["--set", "seconds=90", "--set", "max_iterations=30", "--set", "start_candidates=2"]
    res = runner.invoke(app, ["reproduce", "diffdrive", "--trials", "1", "--out", str(out), *side, *fast])
    assert res.exit_code == 0, res.output
    dd = json.loads((out / "diffdrive.json").read_text())
    assert dd["config"]["learner"]["action"]["zero_mean"] == [] and dd["config"]["learner"]["action"]["inputs"] == []
    md = (out / "diffdrive.md").read_text()
    assert "sideways_gain" in dd["seeds"]["seed0"]["simulated"] and "| sideways gain |" in md
    assert "Simulated side-stepping robots" in md


@pytest.mark.parametrize("sensor", ["camera", "radio"])
def test_wheel_speeds_learn_what_v_and_omega_learn(sensor):
    """Exact reduction: the settings for wheel speeds hold the forward speed to the wheels' sum (and, for
    a sensor without bearings, the turn rate to their difference): the family of (v, omega)'s settings,
    forward from v (and turn from omega), in other commands. So EM on one drive logged either way has the
    same likelihood at every iteration and moves the robot alike."""

    base = DiffDriveConfig(seconds=60, seed=4, sensor=sensor)
    fits = []
    for axle in (0.0, 235.0):
        sim = replace(base, wheel_axle_mm=axle)
        log = simulate_diffdrive(sim).log()
        res = fit_em(log, None, diffdrive.simulator_settings(sim).replace(max_iterations=6, start_candidates=2))
        fits.append((log, res))
    (log_vw, vw), (log_w, w) = fits
    assert log_w.command_names == ("left_mm_s", "right_mm_s")
    np.testing.assert_allclose(w.loglik_history, vw.loglik_history, rtol=1e-9)
    np.testing.assert_allclose(
        w.model.action.step_velocity(log_w), vw.model.action.step_velocity(log_vw), rtol=1e-6, atol=1e-9
    )
    beta = w.model.action.coefficients  # rows 1, left, right
    assert beta[1, 1] == beta[2, 1] and (sensor == "camera") != (beta[1, 2] == -beta[2, 2])


def test_reproduce_diffdrive_on_wheel_speeds_learns_with_the_wheel_settings(tmp_path):
    """`reproduce diffdrive --set wheel_axle_mm=...` learns with what `simulate diffdrive` writes for wheel
    speeds (MRCLAM's settings with the forward speed from the wheels' sum instead of from v, a command a
    wheel log lacks; before, it stopped there)."""
    fast = ["--set", "seconds=60", "--set", "max_iterations=5", "--set", "start_candidates=2"]
    res = runner.invoke(
        app, ["reproduce", "diffdrive", "--trials", "1", "--out", str(tmp_path), "--set", "wheel_axle_mm=235", *fast]
    )
    assert res.exit_code == 0, res.output
    learner = json.loads((tmp_path / "diffdrive.json").read_text())["config"]["learner"]
    action = learner["action"]
    assert action["inputs"] == ["v_y_mm_s:(left_mm_s+right_mm_s)"] and action["zero_mean"] == ["v_x_mm_s"]


def _true_model_file(log, path):
    """The simulated robot's own action model (its coefficients and delay) and camera (its range line,
    sigmas and bearing terms) in a model.json that says it was learned on ``log``, in the families EM
    starts from: what a perfect learner would write."""
    from sensact.learn.em import initial_model

    lf = read_landmark_log(log)
    truth = lf.meta["truth"]
    model = initial_model(lf.data, read_settings_file(log / "em_config.yaml"))
    action = replace(
        model.action, coefficients=np.array(truth["action_coefficients"]), delay_steps=truth["delay_steps"]
    )
    sim, f = truth["config"], model.sensor.channels[0].function
    line = f.__class__((sim["range_offset_mm"], sim["range_gain"], *[0.0] * (len(f.coef) - 2)))
    fits = [(line, truth["range_sigma_mm"], tuple(truth["range_bearing_terms"]))]
    sensor = model.sensor.with_fits(fits, truth["bearing_sigma_rad"])
    doc = {"model": replace(model, action=action, sensor=sensor).to_dict(), "log": str(log), "dt_s": 1 / 30}
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.slow
def test_evaluate_fleet_scores_every_model_on_every_log(tmp_path):
    """Two robots of one kind whose motors differ (forward and turn gains 0.95 / 0.92 against 0.75 / 0.70),
    each with its own true action model: every pair scores exactly as `evaluate log` scores it and is
    placed exactly as `localize` places it (exact reductions); each robot's own model is the better one on
    its log, clears the action bars and is the more likely, the other robot's misses them; the pairs a
    model was learned on are found from model.json's ``log``; without recorded poses, the likelihood
    alone."""
    from sensact.app.fleet import fleet_cell

    logs = {"slow": ["--set", "forward_gain=0.75", "--set", "turn_gain=0.70"], "std": []}
    models = {}
    for name, extra in logs.items():
        res = runner.invoke(
            app, ["simulate", "diffdrive", "--out", str(tmp_path / name), "--seconds", "90", "--seed", "3", *extra]
        )
        assert res.exit_code == 0, res.output
        models[name] = _true_model_file(tmp_path / name, tmp_path / f"m_{name}.json")
    out = tmp_path / "fleet.json"
    args = [str(tmp_path / "std"), str(tmp_path / "slow")]
    for name in ("std", "slow"):
        args += ["--model", str(models[name])]
    res = runner.invoke(app, ["evaluate", "fleet", *args, "--out", str(out)])
    assert res.exit_code == 0, res.output
    fleet = json.loads(out.read_text())
    assert fleet["logs"] == ["std", "slow"] and fleet["models"] == ["m_std", "m_slow"]
    assert fleet["own"] == {"m_std": "std", "m_slow": "slow"}
    for m in ("std", "slow"):
        for g in ("std", "slow"):
            e = tmp_path / f"e_{m}_{g}.json"
            run = runner.invoke(app, ["evaluate", "log", str(tmp_path / g), "--model", str(models[m]), "--out", str(e)])
            assert run.exit_code == 0, run.output
            assert fleet["cells"][f"m_{m}"][g] == json.loads(json.dumps(fleet_cell(json.loads(e.read_text()))))
    c = fleet["cells"]
    for own, other in (("std", "slow"), ("slow", "std")):
        mine, theirs = c[f"m_{own}"][own], c[f"m_{other}"][own]
        assert mine["translation_ratio"] < 1.3 and theirs["translation_ratio"] > 1.5 * mine["translation_ratio"]
        assert all(mine["bars"][k] for k in ("action_translation_ratio", "action_rotation_ratio"))
        assert not theirs["bars"]["action_translation_ratio"]
    s = fleet["summary"]
    assert s["own"]["pairs"] == 2 and s["own"]["clear_action_bars"] == 2
    assert s["other"]["pairs"] == 2 and s["other"]["clear_action_bars"] == 0
    flat = " ".join(res.output.split())
    assert "a robot's own model (2 pairs): 2 clear the action bars" in flat
    assert "another robot's model (2 pairs): 0 clear the action bars" in flat
    assert (tmp_path / "fleet.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the Markdown table (reproduce real's) bolds a robot's own pair and marks each number past its bar
    from sensact.report.tables_fleet import fleet_table

    _, head, rows = fleet_table(fleet)
    assert head == ["model \\ log", "std", "slow"] and rows[-1][0] == "From-Truth"
    assert rows[0][1].startswith("**") and not rows[0][2].startswith("**")
    tr = f"{c['m_std']['slow']['translation_ratio']:.2f}"
    assert rows[0][2].startswith(f"{tr} (miss) / ") and f"{c['m_std']['std']['translation_ratio']:.2f} /" in rows[0][1]
    # a model that does not fit one of the logs, or a log with nothing to score against, is one line
    wheels = tmp_path / "wheels"
    res = runner.invoke(
        app, ["simulate", "diffdrive", "--out", str(wheels), "--seconds", "30", "--set", "wheel_axle_mm=235"]
    )
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["evaluate", "fleet", *args, str(wheels)])
    flat = " ".join(res.output.split())
    assert res.exit_code == 2 and "action.command_names" in flat and "Traceback" not in res.output, flat
    # by the likelihood, with no truth: each pair is `sensact localize` of the model on the log (an exact
    # reduction), and on each log its own robot's model is the more likely one by a clear margin
    lk = fleet["likelihood"]
    for m in ("std", "slow"):
        for g in ("std", "slow"):
            run = tmp_path / f"l_{m}_{g}.json"
            res = runner.invoke(app, ["localize", str(tmp_path / g), "--model", str(models[m]), "--out", str(run)])
            assert_written(res)
            placed = json.loads(run.read_text())
            assert lk["cells"][f"m_{m}"][g]["per_sighting"] == placed["loglik_per_sighting"]
            assert lk["cells"][f"m_{m}"][g]["n_used"] == placed["n_used"]
    for own, other in (("std", "slow"), ("slow", "std")):
        assert lk["cells"][f"m_{own}"][own]["below_best"] == 0.0
        assert lk["cells"][f"m_{other}"][own]["below_best"] > 0.1
    assert lk["summary"]["own_most_likely"] == lk["summary"]["logs_with_own"] == 2
    from sensact.report.tables_fleet import fleet_likelihood_table

    _, head, rows = fleet_likelihood_table(fleet)
    assert rows[0][1].startswith("**") and "(most likely)" in rows[0][1] and " below)" in rows[0][2]
    assert rows[-1][0] == "sightings used"
    # logs without recorded poses are placed and compared by the likelihood alone
    for name in ("std", "slow"):
        (tmp_path / name / "groundtruth.csv").unlink()
    out2 = tmp_path / "fleet_no_truth.json"
    res = runner.invoke(app, ["evaluate", "fleet", *args, "--out", str(out2)])
    flat = " ".join(res.output.split())
    assert res.exit_code == 0, flat
    assert "not scored against ground truth: std, slow have no recorded poses" in flat
    assert "on 2 of 2 logs the robot's own model is the most likely" in flat
    blind = json.loads(out2.read_text())
    assert "cells" not in blind and blind["no_truth"] == ["std", "slow"]
    assert blind["likelihood"] == lk
    assert (tmp_path / "fleet_no_truth.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_fleet_pair_the_filter_fails_on_is_a_cell_without_a_likelihood(tmp_path, monkeypatch):
    """A model the filter fails with from every start (``localize`` refuses it) does not stop the fleet:
    its cell has no likelihood, the others are ranked without it, and the table and a line say so."""
    from sensact.app import fleet as fleet_mod
    from sensact.errors import ConfigError
    from sensact.learn.em import EMConfig
    from sensact.report.tables_fleet import fleet_likelihood_lines, fleet_likelihood_table

    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(tmp_path / "a"), "--seconds", "30"])
    assert res.exit_code == 0, res.output
    lf = read_landmark_log(tmp_path / "a")
    good = _true_model_file(tmp_path / "a", tmp_path / "good.json")
    model = EMModel.from_dict(json.loads(good.read_text())["model"])
    real_localize = fleet_mod.localize

    def failing(m, data, config):
        if m is bad:
            raise ConfigError("the filter failed from every start tried (6)", file=data.source, field="start")
        return real_localize(m, data, config)

    bad = model.replace(prior_mean=model.prior_mean + 1.0)
    monkeypatch.setattr(fleet_mod, "localize", failing)
    cfg = EMConfig()
    fleet = fleet_mod.score_fleet(
        {"good": model, "bad": bad}, {"a": lf}, {"good": "a"}, configs={"good": cfg, "bad": cfg}
    )
    lk = fleet["likelihood"]
    assert lk["cells"]["bad"]["a"]["per_sighting"] is None and lk["cells"]["bad"]["a"]["below_best"] is None
    assert lk["cells"]["good"]["a"]["below_best"] == 0.0
    assert lk["summary"]["per_log"]["a"] == {"most_likely": "good", "closest_other": None, "closest_other_below": None}
    _, _, rows = fleet_likelihood_table(fleet)
    assert rows[1] == ["bad", "the filter failed"] and rows[-1] == [
        "sightings used",
        str(lk["cells"]["good"]["a"]["n_used"]),
    ]
    assert fleet_likelihood_lines(fleet)[-1] == "not placed: bad on a: the filter failed from every start tried (6)"


def test_a_log_that_another_model_explains_better_than_its_own_is_said_so():
    """The likelihood lines: where another robot's model is the most likely on a log, the line names the
    log's own model and its fall, not a fall of 0 for the other (turtlebot1d's calibration.csv, whose own
    model was learned at one command), and suggests learning that log again from the better model."""
    from sensact.app.fleet import likelihood_summary
    from sensact.report.tables_fleet import fleet_likelihood_lines

    per = {"tr1": {"training1": -5.771, "calibration": -6.241}, "cal": {"training1": -8.064, "calibration": -6.316}}
    cells = {
        m: {g: {"per_sighting": v, "n_used": 10, "filter_ok": True} for g, v in row.items()} for m, row in per.items()
    }
    for g in ("training1", "calibration"):
        best = max(per[m][g] for m in per)
        for m in per:
            cells[m][g]["below_best"] = best - per[m][g]
    own = {"tr1": "training1", "cal": "calibration"}
    fleet = {"own": own, "likelihood": {"cells": cells, "summary": likelihood_summary(cells, list(per["tr1"]), own)}}
    lines = fleet_likelihood_lines(fleet)
    assert lines[0].startswith("by the likelihood (no ground truth): on 1 of 2 logs the robot's own model")
    assert lines[1] == (
        "the closest other model on each log: cal on training1 (2.293 a sighting below), "
        "tr1 on calibration (the most likely: cal, its own, 0.075 below)"
    )
    assert lines[2] == (
        "a log's own model that another beats may be learned again from that one (calibration from tr1's): "
        "sensact learn em LOG --start-from MODEL.json"
    )


def test_a_model_is_matched_to_the_log_it_names(tmp_path, monkeypatch):
    """`learn em` records the log folder as it was given: a relative one matches the end of a log's full
    path from any folder, ``.`` only the folder it is run from; another folder never matches."""
    from sensact.app.fleet import fleet_names, learned_on_log

    (tmp_path / "fleet" / "r1").mkdir(parents=True)
    (tmp_path / "other" / "r1").mkdir(parents=True)
    monkeypatch.chdir(tmp_path)
    assert learned_on_log({"log": "fleet/r1"}, tmp_path / "fleet" / "r1")
    assert learned_on_log({"log": "r1"}, Path("fleet/r1"))
    assert not learned_on_log({"log": "fleet/r1"}, tmp_path / "other" / "r1")
    assert learned_on_log({"log": str(tmp_path / "fleet" / "r1")}, Path("fleet/r1"))
    assert not learned_on_log({"log": "."}, Path("fleet/r1"))
    monkeypatch.chdir(tmp_path / "fleet" / "r1")
    assert learned_on_log({"log": "."}, tmp_path / "fleet" / "r1")
    assert not learned_on_log({}, tmp_path / "fleet" / "r1")
    # two logs of one name are told apart by their folders, each name one folder under --out (issue 95)
    assert fleet_names([Path("a/r1"), Path("b/r1"), Path("c/r2")], lambda p: p.name) == ["a_r1", "b_r1", "r2"]
    deep = [tmp_path / "x" / "a" / "log", tmp_path / "y" / "a" / "log"]
    assert fleet_names(deep, lambda p: p.name) == ["x_a_log", "y_a_log"]
    assert all("/" not in n for n in fleet_names([tmp_path / "log", tmp_path / "b" / "log"], lambda p: p.name))


def test_learn_em_warns_when_a_hand_written_folders_range_is_in_another_unit(tmp_path):
    """Metres written under range_mm: the ranges are a thousandth of the map's size, said before the fit."""
    log = tmp_path / "dd"
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(log), "--seconds", "30", "--seed", "3"])
    assert res.exit_code == 0, res.output
    lines = (log / "observations.csv").read_text().splitlines()
    col = lines[0].split(",").index("range_mm")
    rows = [line.split(",") for line in lines[1:]]
    for cells in rows:
        cells[col] = repr(float(cells[col]) / 1000.0) if cells[col] else ""
    (log / "observations.csv").write_text("\n".join([lines[0], *(",".join(c) for c in rows)]) + "\n")
    res = runner.invoke(app, ["learn", "em", str(log), "--set", "max_iterations=2", "--out", str(tmp_path / "m.json")])
    flat = " ".join(res.output.split())
    assert_written(res)
    assert "warning: the median range reading" in flat and f"(in {log})" in flat
    assert "commanded speed" not in flat  # the commands, in their unit, are not doubted
    assert flat.index("is its unit right") < flat.index("finding the start pose")
