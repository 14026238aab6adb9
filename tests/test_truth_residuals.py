"""What the ground truth's own residuals hold (the bars' reference): heading drift that grows with turning,
bearing errors a frame's sightings share, the sensor's mount, a path shifted in the robot frame, and the
truth's own heading error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from continuous_robot import TruthLog, continuous_config, simulate_continuous
from sensact.cli.base import console
from sensact.cli.scores import print_truth_score
from sensact.core import pose_models
from sensact.core.pose_models import apply_displacement, landmark_bearing, landmark_distance
from sensact.learn.em import initial_model
from sensact.logs.landmark_log import LandmarkLog


def test_truth_noise_structure_recovers_turn_dependent_drift_and_frame_correlation():
    """Seeded recovery: windows whose heading drift has variance a + b |turn|, and bearing residuals
    that are independent (correlation about 0) or carry a slow common error (correlation near 1)."""
    from sensact.evaluate.landmark_truth import truth_noise_structure

    rng = np.random.default_rng(3)
    N, W, dt = 4000, 30, 1 / 30
    turn = rng.uniform(0.0, 0.5, N)
    v = np.zeros((N, W, 3))
    v[:, :, 2] = turn[:, None] * rng.choice([-1.0, 1.0], N)[:, None]
    D_true = dead_reckon_windows(v, dt)
    a, b = 0.01**2, 0.06**2  # rad^2, rad^2 per rad/s
    D_true[:, 2] += rng.normal(size=N) * np.sqrt(a + b * turn)
    frames = np.sort(rng.choice(200_000, 6000, replace=False))
    independent = rng.normal(0.0, 0.01, frames.size)
    slow = np.interp(frames, np.arange(0, 200_000, 300), rng.normal(0.0, 0.01, 667)) + 0.001 * independent
    out = truth_noise_structure(v, D_true, dt, independent, frames, W)
    busy = np.percentile(turn, 90)
    assert out["turning_rad_s"] == pytest.approx(busy)
    assert out["heading_drift_rms_at_rest_rad"] == pytest.approx(0.01, rel=0.2)
    assert out["heading_drift_rms_turning_rad"] == pytest.approx(math.sqrt(a + b * busy), rel=0.1)
    assert abs(out["bearing_frame_correlation"]) < 0.1
    assert truth_noise_structure(v, D_true, dt, slow, frames, W)["bearing_frame_correlation"] > 0.8
    # exact reduction: windows that turn in place miss no position
    assert out["translation_drift_rms_mm"] == [0.0, 0.0]
    # seeded recovery: a sideways and forward random walk of 1.5 and 3 mm per step
    walk = D_true.copy()
    walk[:, :2] += rng.normal(size=(N, 2)) * np.array([1.5, 3.0]) * math.sqrt(W)
    side, fwd = truth_noise_structure(v, walk, dt, independent, frames, W)["translation_drift_rms_mm"]
    assert side == pytest.approx(1.5 * math.sqrt(W), rel=0.05)
    assert fwd == pytest.approx(3.0 * math.sqrt(W), rel=0.05)


def _seen_from(data: LandmarkLog, sensor_poses: np.ndarray, seed: int) -> LandmarkLog:
    """``data`` with its range (1.05 d + 40, sd 30 mm) and bearing (sd 0.02 rad) read from ``sensor_poses``."""
    rng = np.random.default_rng(seed)
    at = sensor_poses[data.obs_step]
    lm = data.landmarks_xy[data.obs_landmark]
    d = landmark_distance(at, lm)
    return LandmarkLog(
        "planar",
        data.dt_s,
        data.actions,
        data.action_commands,
        data.command_names,
        data.obs_step,
        data.obs_landmark,
        1.05 * d + 40.0 + rng.normal(size=d.size) * 30.0,
        landmark_bearing(at, lm) + rng.normal(size=d.size) * 0.02,
        data.landmarks_xy,
        reading_names=data.reading_names,
        step_commands=data.step_commands,
    )


def test_sensor_mount_is_fitted_from_the_bearings():
    """Exact reduction and seeded recovery: bearings read exactly at the truth's poses give no mount;
    a camera 120 mm ahead, 30 mm aside and yawed 0.02 rad, with 0.01-rad noise, is found."""
    from sensact.evaluate.landmark_truth import as_mount, fit_sensor_mount

    data, poses = simulate_continuous(2, T=6000)
    at, lm = poses[data.obs_step], data.landmarks_xy[data.obs_landmark]
    assert np.allclose(fit_sensor_mount(at, lm, landmark_bearing(at, lm)), 0.0, atol=1e-6)
    mount = np.array([30.0, 120.0, 0.02])
    noisy = (
        landmark_bearing(pose_models.sensor_poses(at, as_mount(mount)), lm)
        + np.random.default_rng(3).normal(size=len(at)) * 0.01
    )
    noisy[::50] += 0.5  # outliers the trimming drops
    got = fit_sensor_mount(at, lm, noisy)
    assert got[:2] == pytest.approx(mount[:2], abs=8.0)
    assert got[2] == pytest.approx(mount[2], abs=0.002)


def test_path_offset_reads_a_shift_in_the_truths_robot_frame():
    """Exact reduction: the truth itself is 0 off; the truth moved 80 mm forward and 30 mm right in its
    own frame (sec. 2.5.1: x right, y forward) reads exactly that, and steps without truth are ignored."""
    from sensact.evaluate.landmark_truth import path_offset

    _, poses = simulate_continuous(2, T=600)
    valid = np.ones(len(poses), dtype=bool)
    valid[::7] = False
    same = path_offset(poses, poses, valid)
    assert [same[k] for k in ("median_mm", "median_raw_mm", "right_median_mm", "forward_median_mm")] == pytest.approx(
        [0.0] * 4, abs=1e-9
    )
    shifted = apply_displacement(poses, np.broadcast_to([30.0, 80.0, 0.0], poses.shape))
    shifted[~valid] = 1e9
    off = path_offset(shifted, poses, valid)
    assert off["right_median_mm"] == pytest.approx(30.0) and off["forward_median_mm"] == pytest.approx(80.0)
    assert off["median_raw_mm"] == pytest.approx(math.hypot(30.0, 80.0))
    # one fixed offset explains it whole: the truth's point 80 mm behind and 30 mm left of the path's
    assert off["median_mm"] == pytest.approx(0.0, abs=1e-6)
    assert off["fitted_offset"] == pytest.approx({"forward_mm": -80.0, "left_mm": 30.0})


def test_truth_restart_starts_from_from_truths_range_function_and_the_true_start(continuous_fit):
    """Exact reduction: the restart's start is EM's model with only the range function, its bearing
    terms and the prior replaced, by From-Truth's and the truth's first pose. Seeded recovery: From-Truth
    finds the simulated range ``1.05 d + 40``, and EM from there ends on the truth's path with the
    same sightings and a score of its own."""
    from sensact.experiments.real import RESTART_PRIOR_SD, evaluate_mrclam, restart_from_truth, truth_informed_start

    data, poses, res = continuous_fit
    ml = TruthLog(data, poses)
    score = evaluate_mrclam(ml, res)
    start = truth_informed_start(res.model, score["range"], poses[0])
    ch = start.sensor.channels[0]
    d = np.array([1000.0, 2500.0, 4000.0])
    assert ch.predict(d, np.zeros(3)) == pytest.approx(1.05 * d + 40.0, abs=15.0)
    assert np.array_equal(start.prior_mean, poses[0])
    assert np.allclose(np.sqrt(np.diag(start.prior_cov)), RESTART_PRIOR_SD)
    assert np.array_equal(start.action.coefficients, res.model.action.coefficients)
    assert np.array_equal(start.motion_sd, res.model.motion_sd)
    assert ch.sigma == res.model.sensor.channels[0].sigma
    assert start.sensor.sigma_bearing_rad == res.model.sensor.sigma_bearing_rad

    again = restart_from_truth(ml, res, score, continuous_config())
    assert again["sightings_used"] == again["sightings_used_poor_start"]
    assert again["loglik_poor_start"] == res.loglik_best
    assert again["score"]["path"]["median_mm"] < 60.0
    assert set(again["score"]["bars"]) == set(score["bars"])


def test_truth_residuals_are_taken_at_the_sensor():
    """Seeded recovery: a camera mounted ahead of the truth's origin and yawed reads 0.02-rad bearings
    and 30-mm ranges from where it is; the score finds its mount and those sigmas, while at the truth's
    origin the bearing residual is several times larger. Exact reduction: without the fit, the sensor's
    residuals are the origin's."""
    from sensact.evaluate.landmark_truth import as_mount, score_against_truth

    data, poses = simulate_continuous(2, T=6000)
    mount = np.array([-20.0, 150.0, 0.03])
    data = _seen_from(data, pose_models.sensor_poses(poses, as_mount(mount)), seed=4)
    model = initial_model(data, continuous_config())
    valid = np.ones(len(poses), dtype=bool)
    sc = score_against_truth(model, data, poses, valid)
    m, b = sc["sensor_mount"]["fitted_to_truth"], sc["bearing"]
    assert [-m["left_mm"], m["forward_mm"]] == pytest.approx(mount[:2], abs=8.0)
    assert m["yaw_rad"] == pytest.approx(mount[2], abs=0.002)
    assert b["sigma_truth_rad"] == pytest.approx(0.02, rel=0.05)
    assert sc["range"]["sigma_truth_mm"] == pytest.approx(30.0, rel=0.05)
    assert b["truth_origin_sigma_rad"] > 2 * b["sigma_truth_rad"]
    assert b["truth_origin_sigma_ratio"] == pytest.approx(model.sensor.sigma_bearing_rad / b["truth_origin_sigma_rad"])
    plain = score_against_truth(model, data, poses, valid, fit_mount=False)
    assert plain["bearing"]["sigma_truth_rad"] == plain["bearing"]["truth_origin_sigma_rad"]
    assert plain["sensor_mount"]["fitted_to_truth"] == {"forward_mm": 0.0, "left_mm": -0.0, "yaw_rad": 0.0}
    assert plain["sensor_mount"]["learned"] == model.sensor.mount.to_dict()
    with console.capture() as out:  # what `learn em` and `evaluate mrclam` print of it
        print_truth_score(sc)
    printed = " ".join(out.get().split())
    assert f"sensor pose fitted to the truth (from the truth's point): {m['forward_mm']:.0f} mm forward" in printed
    # the learned Sigma_m's translational random walk over the 30-step windows, beside the truth's miss
    n = sc["truth_noise"]
    assert n["learned_translation_drift_mm"] == pytest.approx(math.sqrt(30) * model.motion_sd[0, :2])
    side, fwd = n["learned_translation_drift_mm"]
    assert f"(Sigma_m: {side:.1f} / {fwd:.1f})" in " ".join(out.get().split())
    # this robot turns nearly all the time: too few straight frames to set its truth's heading against
    # its direction of travel, and the line says nothing of it
    assert n["truth_heading_error"]["frames"] < 20 and math.isnan(n["truth_heading_error"]["variance_rad2"])
    assert "the truth's own heading" not in out.get()


def test_the_score_warns_when_the_truths_heading_points_off_the_way_it_moves():
    """A log folder's recorded heading a quarter turn off (sensact's frame has 0 facing +y; a REP 103
    heading copied in unturned) is named, with the column that fixes it, where `learn em` and `evaluate`
    print the score; the right heading adds nothing to the score."""
    from sensact.evaluate.landmark_truth import score_against_truth
    from sensact.presets import mrclam_config
    from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

    run = simulate_diffdrive(DiffDriveConfig(seconds=300.0, seed=5))
    data, poses = run.log(), run.poses
    model = initial_model(data, mrclam_config())
    valid = np.ones(len(poses), dtype=bool)
    assert "truth_heading_doubt" not in score_against_truth(model, data, poses, valid)
    # the tests' continuous robot slips sideways as it circles (its moves agree with its heading at 0.89):
    # not a differential drive's truth, and not judged
    slipping, slipping_poses = simulate_continuous(2, T=6000)
    slipped = score_against_truth(
        initial_model(slipping, continuous_config()),
        slipping,
        slipping_poses + np.array([0.0, 0.0, 1.0]),
        np.ones(len(slipping_poses), dtype=bool),
    )
    assert "truth_heading_doubt" not in slipped
    rep103 = poses + np.array([0.0, 0.0, 0.5 * np.pi])
    sc = score_against_truth(model, data, rep103, valid)
    assert "is -1.571 rad (-90 deg) off the way the robot moves" in sc["truth_heading_doubt"]
    assert sc["truth_heading_doubt"].endswith("write theta_rad = theta_rad - 1.571")
    with console.capture() as out:
        print_truth_score(sc)
    assert "0 facing +y; `convert csv` turns a ROS REP 103 heading into it" in " ".join(out.get().split())


def test_frame_shared_bearing_error_splits_a_frames_residuals():
    """Seeded recovery: an error every sighting of a frame shares (sd 0.006) plus each sighting's own
    (sd 0.004), three sightings a frame, is split into the own sd and the shared fraction 0.36/0.52;
    frames of one sighting cannot be split."""
    from sensact.evaluate.landmark_truth import frame_shared_bearing_error

    rng = np.random.default_rng(5)
    frames = np.repeat(np.arange(4000) * 7, 3)
    res = rng.normal(size=4000).repeat(3) * 0.006 + rng.normal(size=frames.size) * 0.004
    within, shared = frame_shared_bearing_error(res, frames)
    assert within == pytest.approx(0.004, rel=0.03)
    assert shared == pytest.approx(0.36 / 0.52, abs=0.03)
    assert all(math.isnan(x) for x in frame_shared_bearing_error(res[:10], np.arange(10)))


def test_sighting_motion_labels_still_straight_and_turning_truth():
    """Exact reduction: a truth path that stands, then drives straight at 200 mm/s, then turns on the
    spot at 0.3 rad/s labels the sightings in the middle of each part still, straight and turning."""
    from sensact.evaluate.landmark_truth import MOTIONS, sighting_motion

    dt, n = 1 / 30, 120
    poses = np.zeros((3 * n, 3))
    poses[n:, 1] = np.minimum(np.arange(2 * n), n) * 200.0 * dt  # drive along the heading (y at theta 0)
    poses[2 * n :, 2] = np.arange(n) * 0.3 * dt
    got = sighting_motion(poses, np.array([n // 2, n + n // 2, 2 * n + n // 2]), dt, 30)
    assert [MOTIONS[i] for i in got] == ["still", "straight", "turning"]


def test_frame_shared_fraction_is_split_by_the_robots_motion():
    """Seeded recovery: frames taken still carry only each sighting's own error, frames taken turning
    also a shared one (sd 0.006 with own 0.004); the split gives about 0 and 0.36/0.52, the whole log
    a share in between."""
    from sensact.evaluate.landmark_truth import truth_noise_structure
    from sensact.report.tables_real import shared_by_motion

    rng = np.random.default_rng(8)
    nf = 3000
    frames = np.repeat(np.arange(nf) * 7, 3)
    motion = np.repeat(rng.choice([0, 2], nf), 3)
    shared = rng.normal(size=nf).repeat(3) * 0.006 * (motion == 2)
    res = shared + rng.normal(size=frames.size) * 0.004
    v = np.zeros((50, 30, 3))
    D_true = np.zeros((50, 3))
    D_true[:, 2] = rng.normal(size=50) * 0.01
    out = truth_noise_structure(v, D_true, 1 / 30, res, frames, 30, motion)
    split = out["bearing_frame_shared_by_motion"]
    assert split["still"]["shared_fraction"] == pytest.approx(0.0, abs=0.05)
    assert split["turning"]["shared_fraction"] == pytest.approx(0.36 / 0.52, abs=0.04)
    assert split["straight"]["sightings"] == 0 and math.isnan(split["straight"]["shared_fraction"])
    assert 0.1 < out["bearing_frame_shared_fraction"] < split["turning"]["shared_fraction"]
    # what `evaluate mrclam` prints of it: a share per motion, '-' where no frame could be split
    assert shared_by_motion(out) == (
        f" (still {split['still']['shared_fraction']:.0%}, straight -, "
        f"turning {split['turning']['shared_fraction']:.0%})"
    )


def test_heading_drift_of_windows_that_dead_reckon_to_the_truth_is_zero():
    """Exact reduction: velocities that integrate to the true displacement leave no drift, and a
    known heading error comes back as the drift; the turn rate is the window's mean |v_theta|."""
    from sensact.evaluate.landmark_truth import heading_drift

    rng = np.random.default_rng(8)
    v = rng.normal(size=(50, 30, 3)) * [20.0, 200.0, 0.3]
    D = dead_reckon_windows(v, 1 / 30)
    turn, drift = heading_drift(v, D, 1 / 30)
    np.testing.assert_array_equal(drift, np.zeros(50))
    np.testing.assert_allclose(turn, np.abs(v[:, :, 2]).mean(axis=1))
    D[:, 2] -= 0.01
    np.testing.assert_allclose(heading_drift(v, D, 1 / 30)[1], 0.01, rtol=1e-9)


def dead_reckon_windows(v: np.ndarray, dt: float) -> np.ndarray:
    from sensact.core.pose_models import dead_reckon

    return dead_reckon(v, dt)


def _straight_and_turning_drive(rng, T, dt, yaw_gap):
    """A robot driving 10-s straight stretches at 100 mm/s joined by 2-s turns in place; its true
    headings, and the truth's positions (0.3 mm of noise) with a heading ``yaw_gap`` off its wheels."""
    heading = np.zeros(T)
    speed = np.zeros(T)
    t = 0
    while t < T:
        speed[t : t + 300] = 100.0
        rate = rng.uniform(-0.5, 0.5)
        heading[t + 300 : t + 360] = rate * dt
        t += 360
    heading = np.cumsum(heading)
    step = np.column_stack([-np.sin(heading), np.cos(heading)]) * (speed * dt)[:, None]  # theta 0 faces +y
    xy = np.cumsum(step, axis=0) + rng.normal(size=(T, 2)) * 0.3
    return heading, np.column_stack([xy, heading + yaw_gap])


def _slow(rng, T, sd, tau_steps):
    phi = np.exp(-1.0 / tau_steps)
    z = rng.normal(size=T) * sd * np.sqrt(1 - phi**2)
    out = np.empty(T)
    out[0] = rng.normal() * sd
    for i in range(1, T):
        out[i] = phi * out[i - 1] + z[i]
    return out


def test_truth_heading_error_recovers_the_truths_own_heading_error_not_the_sensors():
    """Seeded recovery: the truth's heading carries a slow error (sd 0.005 rad, 2 s) that every bearing
    residual against it holds, beside a camera sway (sd 0.004, 2 s) and white noise that it does not.
    Minus the covariance of a frame's mean residual with the truth's travel-minus-heading gap recovers
    the first (2.5e-5 rad^2) and not the others; with a perfect truth heading it is about 0. The
    turns in place are left out, and the constant yaw between the truth's frame and the wheels is the
    median gap."""
    from sensact.cli.scores import truth_heading_clause
    from sensact.evaluate.landmark_truth import truth_heading_error
    from sensact.report.tables_real import truth_heading_cell

    rng = np.random.default_rng(11)
    dt, T = 1 / 30, 36000
    _, poses = _straight_and_turning_drive(rng, T, dt, yaw_gap=0.012)
    error = _slow(rng, T, 0.005, 60)
    frames = np.arange(20, T - 20, 5)
    sway = _slow(rng, T, 0.004, 60)[frames]
    own = rng.normal(size=frames.size) * 0.004
    valid = np.ones(T, dtype=bool)
    valid[18000:18100] = False  # a gap in the truth: its frames' windows are not used

    with_error = poses.copy()
    with_error[:, 2] += error
    got = truth_heading_error(with_error, valid, error[frames] + sway + own, frames, dt, 30)
    assert got["variance_rad2"] == pytest.approx(2.5e-5, rel=0.25)
    assert got["interval_rad2"][0] < got["variance_rad2"] < got["interval_rad2"][1]
    assert got["median_gap_rad"] == pytest.approx(-0.012, abs=0.002)
    straight = frames.size * 300 / 360
    assert 0.8 * straight < got["frames"] < straight
    assert 0.3 < got["share"] < 0.7  # the sway and the camera's own noise are the rest
    assert truth_heading_cell({"truth_heading_error": got}) == (
        f"{np.sqrt(got['variance_rad2']):.4f} ({got['share']:.0%})"
    )
    assert truth_heading_clause({"truth_heading_error": got}).startswith(
        f"; driving straight, the truth's own heading is off by {np.sqrt(got['variance_rad2']):.4f} rad "
        f"(sd; {got['share']:.0%} of the frame means' variance)"
    )

    perfect = truth_heading_error(poses, valid, sway + own, frames, dt, 30)
    assert abs(perfect["variance_rad2"]) < 0.1 * 2.5e-5
    # too few straight frames: nothing to say, and the report says so
    few = truth_heading_error(with_error, valid, own[:10], frames[:10], dt, 30)
    assert few["frames"] < 20 and math.isnan(few["variance_rad2"])
    assert truth_heading_cell({"truth_heading_error": few}) == "-" and truth_heading_cell({}) == "-"
    assert truth_heading_clause({"truth_heading_error": few}) == "" and truth_heading_clause({}) == ""
    written = {"truth_heading_error": {**few, "variance_rad2": None, "share": None}}  # NaN is null in JSON
    assert truth_heading_cell(written) == "-" and truth_heading_clause(written) == ""
    # a robot that side-steps (a legged one) travels off its heading: those windows are not heading errors
    strafing = with_error.copy()
    strafing[(np.arange(T) // 600) % 3 == 1, 2] += 0.5
    assert truth_heading_error(strafing, valid, error[frames] + sway + own, frames, dt, 30)["variance_rad2"] == (
        pytest.approx(2.5e-5, rel=0.35)
    )
