"""EM beyond the thesis: continuous-command action models, learned Sigma_m, several reading channels,
robust observations, and the real datasets (MRCLAM, Turtlebot)."""

from __future__ import annotations

import json
import math
import re
import threading
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from sensact import cli
from sensact.cli.base import console
from sensact.cli.scores import print_truth_score
from sensact.config import config_from_dict
from sensact.core.pose_models import apply_displacement, landmark_bearing, landmark_distance
from sensact.errors import ConfigError
from sensact.learn.em import EMConfig, e_step, fit_em, initial_model, log_likelihood
from sensact.learn.em.actions import linear_action_update, linear_coefficients, step_motion_var, table_velocities
from sensact.learn.em.config import ChannelConfig
from sensact.learn.em.delay_search import search_delay, with_delay
from sensact.learn.em.mstep import sample_gamma
from sensact.learn.em.ridge import search_ridge, shifted_forward
from sensact.learn.em.start import race_starts, race_trials, search_grid, start_candidates
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.models.linear_action import LinearActionModel, command_features, delayed, one_hot

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
MRCLAM = DATA / "mrclam" / "MRCLAM_Dataset6"
TURTLEBOT = DATA / "turtlebot1d" / "training1.csv"

TRUE_BETA = np.array([[5.0, 20.0, 0.02], [0.0, 0.9, 0.0], [30.0, 0.0, 0.8]])  # rows 1, v, omega
TRUE_SD = np.array([4.0, 5.0, 0.02])  # per step
LANDMARKS = np.array([[0.0, 2500.0], [3000.0, 0.0], [0.0, -2500.0], [-3000.0, 0.0], [2000.0, 2000.0]])


def _simulate(
    seed: int,
    T: int = 9000,
    outlier_frac: float = 0.0,
    beta=TRUE_BETA,
    bearing_terms=(0.0, 0.0),
    sd=TRUE_SD,
    turn_var: float = 0.0,
    delay_steps: int = 0,
):
    """A robot on continuous commands among five landmarks, range and bearing. The range reads
    ``1.05 d + 40 + d (a_1 b + a_2 b^2)`` with ``bearing_terms`` (a_1, a_2) at the measured bearing b.
    The heading's motion variance per step is ``sd[2]^2 + turn_var |omega_t|``. The robot obeys each
    command ``delay_steps`` steps late."""
    rng = np.random.default_rng(seed)
    dt = 1 / 30
    seg = rng.integers(30, 120, T // 30)
    levels = np.column_stack([rng.uniform(0, 300, seg.size), rng.uniform(-0.6, 0.6, seg.size)])
    commands = np.repeat(levels, seg, axis=0)[:T]
    v = command_features("affine", 1, commands) @ beta
    poses = np.zeros((T, 3))
    for t in range(T - 1):
        # steer back toward the middle, so the robot stays among the landmarks
        if np.hypot(*poses[t, :2]) > 1500:
            commands[t, 1] = 0.6
            v[t] = command_features("affine", 1, commands[t : t + 1]) @ beta
        if delay_steps:
            late = max(t - delay_steps, 0)
            v[t] = command_features("affine", 1, commands[late : late + 1]) @ beta
        step_sd = np.array([sd[0], sd[1], math.sqrt(sd[2] ** 2 + turn_var * abs(v[t, 2]))])
        poses[t + 1] = apply_displacement(poses[t], (v[t] + rng.normal(size=3) * step_sd / dt) * dt)[0]
    steps = np.arange(0, T, 6)
    which = rng.integers(0, len(LANDMARKS), steps.size)
    d = landmark_distance(poses[steps], LANDMARKS[which])
    rng_mm = 1.05 * d + 40.0 + rng.normal(size=d.size) * 30.0
    bearing = landmark_bearing(poses[steps], LANDMARKS[which]) + rng.normal(size=d.size) * 0.02
    a1, a2 = bearing_terms
    rng_mm += d * (a1 * bearing + a2 * bearing**2)
    bad = rng.random(d.size) < outlier_frac
    rng_mm[bad] = rng.uniform(200, 8000, bad.sum())
    data = LandmarkLog(
        "planar",
        dt,
        np.full(T, -1),
        np.zeros((0, 2)),
        ("v_mm_s", "omega_rad_s"),
        steps,
        which,
        rng_mm,
        bearing,
        LANDMARKS,
        reading_names=("range_mm",),
        step_commands=commands,
    )
    return data, poses


def _config(**kw) -> EMConfig:
    base = dict(
        action_basis="affine",
        motion_noise="shared",
        motion_sd_mm=10.0,
        motion_sd_rad=0.05,
        channels=(ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0),),
        start_prior_sd=(100.0, 100.0, 0.1),
        prune_rad_per_step=0.0,
        max_iterations=300,
        refine_from=0,  # a near start: no need to hold Sigma_m and the bearing terms first
    )
    base.update(kw)
    return EMConfig(**base)


@pytest.fixture(scope="module")
def continuous_fit():
    data, poses = _simulate(1)
    return data, poses, fit_em(data, None, _config())


def test_one_hot_basis_is_the_action_table():
    """Eq. 4.18 is the weighted least squares of D on a one-hot Phi (any weights constant per action)."""
    rng = np.random.default_rng(0)
    T, A, dt = 400, 5, 0.05
    actions = rng.integers(-1, A, T)
    disp = rng.normal(size=(T - 1, 3))
    data = LandmarkLog("planar", dt, actions, np.eye(A, 3), ("a", "b", "c"), [], [], [], [], np.zeros((1, 2)))
    table = table_velocities(disp, data, np.zeros((A, 3)))
    Phi = one_hot(actions[:-1], A)
    var = np.ones((T - 1, 3)) * rng.uniform(0.5, 2.0, A + 1)[actions[:-1], None]
    np.testing.assert_allclose(linear_coefficients(Phi, disp, var, dt, np.zeros((A, 3))), table, atol=1e-12)


@pytest.mark.parametrize("weights", ["per step", "shared"])
def test_action_update_picks_the_delay_and_beta_that_least_squares_on_the_delayed_rows_give(weights):
    """Independent reference: for every delay, numpy's lstsq on the explicitly delayed rows (each
    component on its free, nonzero columns) and its weighted squared error; the M-step's sums formed
    once per delay must give each delay's beta and pick the same delay, with a variance per step
    (``turning``) or one for all steps (``shared``, where the sums are prefix sums). A command that
    is zero until the last steps has no rows at large delays, so its coefficient keeps its previous
    value there."""
    rng = np.random.default_rng(5)
    T, dt, true_delay = 900, 0.05, 4
    commands = rng.normal(size=(T, 2))
    commands[: T - 3, 1] = 0.0  # the turn command starts 3 steps before the end
    act = LinearActionModel.zero("affine", 1, ("v", "w"), ("vx", "vy", "vt"), zero_mean=("vy",))
    act = act.with_coefficients(np.full((3, 3), 0.5), 0)
    Phi0 = command_features("affine", 1, commands)
    beta_true = np.array([[10.0, 0.0, 0.1], [0.9, 0.0, 0.0], [3.0, 0.0, 1.1]])
    disp = delayed(Phi0, true_delay)[:-1] @ beta_true * dt + rng.normal(scale=0.01, size=(T - 1, 3))
    var = rng.uniform(0.5, 2.0, size=(T - 1, 3)) * 1e-4
    if weights == "shared":
        var = np.broadcast_to(var[0], var.shape)  # as the M-step passes a shared Sigma_m
    data = LandmarkLog(
        "planar", dt, np.full(T, -1), np.zeros((0, 2)), ("v", "w"), [], [], [], [], np.zeros((1, 2)),
        reading_names=("r",), step_commands=commands,
    )  # fmt: skip
    free = act.free_coefficients
    refs = []
    for d in range(9):
        X = delayed(Phi0, d)[:-1] * dt
        beta = act.coefficients.copy()
        beta[~free] = 0.0
        for i in range(3):
            cols = free[:, i] & np.any(X != 0.0, axis=0)
            if cols.any():
                sw = 1.0 / np.sqrt(var[:, i])
                beta[cols, i] = np.linalg.lstsq(X[:, cols] * sw[:, None], disp[:, i] * sw, rcond=None)[0]
        refs.append((float(np.sum((disp - X @ beta) ** 2 / var)), beta))
    best = int(np.argmin([r[0] for r in refs]))
    assert best == true_delay
    got = linear_action_update(act, data, disp, var, 8)
    assert got.delay_steps == best
    np.testing.assert_allclose(got.coefficients, refs[best][1], rtol=1e-8, atol=1e-12)
    for d, (_, ref) in enumerate(refs):
        at_d = linear_action_update(act.with_coefficients(act.coefficients, d), data, disp, var, 0)
        np.testing.assert_allclose(at_d.coefficients, ref, rtol=1e-8, atol=1e-12)
    # at delay 5 the turn command has no nonzero row: its coefficients are kept
    kept = linear_action_update(act.with_coefficients(act.coefficients, 5), data, disp, var, 0)
    assert kept.delay_steps == 5
    np.testing.assert_array_equal(kept.coefficients[2, 2], act.coefficients[2, 2])
    X5 = delayed(Phi0, 5)[:-1] * dt
    assert not X5[:, 2].any()


@pytest.mark.parametrize("weights", ["shared", "per_step"])
def test_combined_inputs_on_wheel_speeds_are_the_v_omega_restriction(weights):
    """Exact reduction: wheel speeds with the turn rate held to ``(right-left)`` and the forward speed to
    ``(left+right)`` are (v, omega) with ``v_theta:omega`` and ``v_y:v`` in other units, so the M-step on
    either log, at every delay, moves the robot alike; the wheels' turn coefficients are exactly
    opposite whatever the axle (``models/linear_action.py``)."""
    rng = np.random.default_rng(11)
    T, dt, axle = 700, 0.05, 235.0
    wheels = rng.normal(200.0, 80.0, size=(T, 2))
    vw = np.column_stack([wheels.mean(axis=1), (wheels[:, 1] - wheels[:, 0]) / 250.0])  # a nominal axle
    velocities = ("v_x_mm_s", "v_y_mm_s", "v_theta_rad_s")
    true_vel = np.column_stack([np.zeros(T), 0.95 * wheels.mean(axis=1), 0.92 * (wheels[:, 1] - wheels[:, 0]) / axle])
    disp = delayed(true_vel, 3)[:-1] * dt + rng.normal(scale=[0.2, 0.2, 0.002], size=(T - 1, 3))
    var = rng.uniform(0.5, 2.0, size=(T - 1, 3)) * [1.0, 1.0, 1e-4]
    if weights == "shared":
        var = np.broadcast_to(var[0], var.shape)
    fits = {}
    for names, commands, inputs in (
        (
            ("left_mm_s", "right_mm_s"),
            wheels,
            ("v_y_mm_s:(left_mm_s+right_mm_s)", "v_theta_rad_s:(right_mm_s-left_mm_s)"),
        ),
        (("v_mm_s", "omega_rad_s"), vw, ("v_y_mm_s:v_mm_s", "v_theta_rad_s:omega_rad_s")),
    ):
        act = LinearActionModel.zero("affine", 1, names, velocities, zero_mean=("v_x_mm_s",), inputs=inputs)
        data = LandmarkLog(
            "planar", dt, np.full(T, -1), np.zeros((0, 2)), names, [], [], [], [], np.zeros((1, 2)),
            reading_names=("r",), step_commands=commands,
        )  # fmt: skip
        fits[names[0]] = (act, commands, linear_action_update(act, data, disp, var, 6))
    (act_w, wheels, got_w), (_, vw, got_vw) = fits["left_mm_s"], fits["v_mm_s"]
    assert got_w.delay_steps == got_vw.delay_steps == 3
    np.testing.assert_allclose(got_w.features(wheels) @ got_w.coefficients, got_vw.features(vw) @ got_vw.coefficients,
                               rtol=1e-9, atol=1e-9)  # fmt: skip
    beta = got_w.coefficients
    assert beta[1, 2] == -beta[2, 2] and beta[1, 1] == beta[2, 1] and not beta[:, 0].any()
    assert abs(beta[2, 2] * axle / 0.92 - 1.0) < 0.02 and abs(beta[1, 1] * 2 / 0.95 - 1.0) < 0.02  # the true model
    np.testing.assert_array_equal(act_w.free_coefficients, [[False, True, True]] * 3)
    again = LinearActionModel.from_dict(got_w.to_dict())
    assert again.inputs == act_w.inputs and set(again.combined_inputs) == {1, 2}
    for bad, message in (
        ("v_theta_rad_s:(right_mm_s-lft)", "'lft'"),
        ("v_theta_rad_s:(right_mm_s*left_mm_s)", "right_mm_s\\*left_mm_s"),
        ("v_theta_rad_s:(right_mm_s-right_mm_s)", "write a combined input"),
        ("v_theta_rad_s:right_mm_s-left_mm_s", "bracketed, as \\(right_mm_s-left_mm_s\\)"),
    ):
        with pytest.raises(ValueError, match=message):
            LinearActionModel.zero("affine", 1, ("left_mm_s", "right_mm_s"), velocities, inputs=(bad,))
    with pytest.raises(ValueError, match="needs the affine action basis"):
        LinearActionModel.zero("cross", 1, ("left_mm_s", "right_mm_s"), velocities, inputs=(act_w.inputs[1],))


def test_action_inputs_fit_each_velocity_on_its_own_commands():
    """Independent reference: with ``inputs`` each component is the weighted least squares on its own
    columns (numpy's lstsq), and the coefficients it may not use are exactly zero."""
    rng = np.random.default_rng(3)
    act = LinearActionModel.zero(
        "cross", 1, ("v_mm_s", "omega_rad_s"), ("v_x_mm_s", "v_y_mm_s", "v_theta_rad_s"),
        zero_mean=("v_x_mm_s",), inputs=("v_y_mm_s:v_mm_s",),
    )  # fmt: skip
    free = act.free_coefficients  # features 1, v, omega, v*omega
    np.testing.assert_array_equal(free[:, 0], [False] * 4)
    np.testing.assert_array_equal(free[:, 1], [True, True, False, False])
    np.testing.assert_array_equal(free[:, 2], [True] * 4)
    Phi = command_features("cross", 1, rng.normal(size=(400, 2)))
    disp = rng.normal(size=(400, 3))
    var = rng.uniform(0.5, 2.0, size=(400, 3))
    dt = 0.1
    beta = linear_coefficients(Phi, disp, var, dt, np.ones((4, 3)), free)
    assert np.all(beta[~free] == 0.0)
    for i in (1, 2):
        sw = 1.0 / np.sqrt(var[:, i])
        ref = np.linalg.lstsq(Phi[:, free[:, i]] * dt * sw[:, None], disp[:, i] * sw, rcond=None)[0]
        np.testing.assert_allclose(beta[free[:, i], i], ref, rtol=1e-9)
    again = LinearActionModel.from_dict(act.to_dict())
    assert again.inputs == act.inputs
    np.testing.assert_array_equal(again.free_coefficients, free)
    cfg = config_from_dict(EMConfig, {"action_basis": "affine", "action_inputs": "v_y_mm_s:v_mm_s"})
    assert cfg.action_inputs == ("v_y_mm_s:v_mm_s",)
    with pytest.raises(ValueError, match="'omega'"):
        LinearActionModel.zero("affine", 1, ("v", "w"), ("a",), inputs=("a:omega",))
    with pytest.raises(ValueError, match="action_inputs"):
        EMConfig(action_inputs=("v_y_mm_s:v_mm_s",))  # the table basis has no commands to restrict


def test_continuous_model_and_motion_noise_are_recovered(continuous_fit):
    """Seeded recovery: beta, the range function and a known Sigma_m (within 15 %) from no motion."""
    _data, _poses, res = continuous_fit
    m = res.model
    np.testing.assert_allclose(m.motion_sd[0], TRUE_SD, rtol=0.15)
    assert m.action.coefficients[1, 1] == pytest.approx(0.9, rel=0.05)  # forward gain
    assert m.action.coefficients[2, 2] == pytest.approx(0.8, rel=0.05)  # turn gain
    x = np.linspace(800, 4500, 20)
    np.testing.assert_allclose(m.sensor.channels[0].function(x), 1.05 * x + 40, atol=25)
    assert m.sensor.channels[0].sigma == pytest.approx(30.0, rel=0.15)
    # sigma_2 is learned high here (about 0.027): heading noise of 0.02 rad a step is as large as the
    # bearing noise, and the linearized smoother gives part of it to the bearings
    assert m.sensor.sigma_bearing_rad == pytest.approx(0.02, rel=0.4)


def test_bearing_terms_and_a_held_lateral_velocity_are_recovered():
    """Seeded recovery: a differential drive (no sideways motion) whose range is distorted with the
    bearing, learned from no motion and a plain line."""
    beta = TRUE_BETA.copy()
    beta[:, 0] = 0.0
    data, _ = _simulate(4, beta=beta, bearing_terms=(0.01, -0.02))
    ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0, bearing_degree=2)
    cfg = _config(channels=(ch,), action_zero_mean=("v_x_mm_s",), action_inputs=("v_y_mm_s:v_mm_s",))
    res = fit_em(data, None, cfg)
    m = res.model
    assert np.all(m.action.coefficients[:, 0] == 0.0)  # held, not fitted
    assert m.action.coefficients[2, 1] == 0.0  # the turn command cannot drive the axle forward
    assert m.action.coefficients[0, 1] == pytest.approx(20.0, abs=3.0)  # the forward constant is still fitted
    assert m.action.coefficients[1, 1] == pytest.approx(0.9, rel=0.05)
    assert m.action.coefficients[2, 2] == pytest.approx(0.8, rel=0.05)
    chan = m.sensor.channels[0]
    np.testing.assert_allclose(chan.bearing_terms, (0.01, -0.02), atol=0.004)
    assert chan.sigma == pytest.approx(30.0, rel=0.15)
    # the thesis's f(d) alone cannot read this sensor: its sigma is several times larger
    plain = fit_em(data, None, _config(channels=(ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0),), max_iterations=150))
    assert plain.model.sensor.channels[0].sigma > 2 * chan.sigma


def test_sigma_m_and_bearing_terms_are_held_until_refine_from():
    data, _ = _simulate(4, T=3000, bearing_terms=(0.01, -0.02))
    ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0, bearing_degree=2)
    res = fit_em(data, None, _config(channels=(ch,), refine_from=8, max_iterations=12, patience=50))
    sd = res.motion_sd_history[:, 0]
    np.testing.assert_array_equal(sd[:9], np.repeat(sd[:1], 9, axis=0))  # lambda_0..8: the start's
    assert np.all(sd[9] != sd[0])  # the M-step after iteration 8 learns Sigma_m
    assert res.model.sensor.channels[0].bearing_terms != (0.0, 0.0)


def test_zero_bearing_terms_are_the_thesis_sensor(continuous_fit):
    """Exact reduction: bearing terms of zero change neither the E-step nor the prediction."""
    data, _poses, res = continuous_fit
    m = res.model
    ch = m.sensor.channels[0]
    held = m.replace(sensor=m.sensor.with_fits([(ch.function, ch.sigma, (0.0, 0.0))], m.sensor.sigma_bearing_rad))
    a, b = e_step(m, data), e_step(held, data)
    assert a.loglik == b.loglik
    np.testing.assert_array_equal(a.mean_gamma, b.mean_gamma)
    d = np.linspace(500, 4000, 7)
    np.testing.assert_array_equal(held.sensor.channels[0].predict(d, np.full(7, 0.3)), ch.function(d))


def test_robust_readings_start_gaussian_until_refine_from():
    """Graduated robustness: before refine_from the E-step is the thesis's Gaussian one (every used
    reading has weight 1); after it the Student-t weights discount the outliers."""
    data, _ = _simulate(3, T=3000, outlier_frac=0.1)
    ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0, robust="student_t", robust_param=4.0)
    held = fit_em(data, None, _config(channels=(ch,), refine_from=1000, max_iterations=10))
    w = held.posteriors.weights[:, 0]
    assert set(np.unique(w[w > 0])) == {1.0}
    freed = fit_em(data, None, _config(channels=(ch,), refine_from=5, max_iterations=15, patience=50))
    w = freed.posteriors.weights[:, 0]
    assert held.freed_at == -1 and freed.freed_at == 5
    assert freed.best_iteration > 5 and w.min() < 0.05  # the best model is one scored by the robust likelihood


def test_start_race_halves_the_field_on_the_held_gaussian_likelihood():
    """The race's bookkeeping with a scripted EM: six candidates, then three, then two, then the best;
    every trial runs the held, Gaussian, unpruned stage so that their likelihoods compare."""
    data, _ = _simulate(6, T=600)
    cfg = _config(start_search_s=10.0, refine_from=100, prune_rad_per_step=0.6)
    start = initial_model(data, cfg)
    quality = [3.0, 1.0, 6.0, 2.0, 5.0, 4.0]  # candidate 2 is best; 4 second
    cands = [start.replace(prior_mean=np.array([q, 0.0, 0.0])) for q in quality]
    seen = []

    class Trial:  # what fit_em returns, as far as the race reads it
        def __init__(self, model, cfg):
            self.model, self.iterations = model, cfg.max_iterations
            self.loglik_best = 100.0 * model.prior_mean[0] - model.prior_mean[1]

    def run(data, model, trial_cfg):
        seen.append(trial_cfg)
        return Trial(model.replace(prior_mean=model.prior_mean + np.array([0.0, 1.0, 0.0])), trial_cfg)

    heard = []
    model, info = race_starts(data, cands, cfg, run, on_trial=lambda done, planned: heard.append((done, planned)))
    assert [len(r) for r in info["rounds"]] == [6, 3, 2] and info["winner"] == 2
    assert heard == [(k, 11) for k in range(1, 12)]  # every trial heard of once, in order, out of 6 + 3 + 2
    assert set(info["rounds"][1]) == {"2", "4", "5"} and set(info["rounds"][2]) == {"2", "4"}
    assert model.prior_mean[0] == 6.0 and model.prior_mean[1] == 3.0  # the winner's model after 3 rounds
    assert info["winner_iterations"] == 3 * cfg.start_trial_iterations
    for t in seen:
        assert t.max_iterations == cfg.start_trial_iterations and t.prune_rad_per_step == 0.0
        assert t.refine_from > t.max_iterations and t.patience > t.max_iterations and t.start_search_s == 0.0


def test_race_trials_counts_each_round_until_two_are_left():
    """The progress bar's total: a field of n, then halves rounded up, until two are left."""
    assert [race_trials(n) for n in (1, 2, 3, 4, 5, 6, 7, 9)] == [1, 2, 5, 6, 10, 11, 13, 19]


def test_start_race_does_not_rerun_a_trial_that_found_nothing_better():
    """A trial whose best model is its start would repeat itself exactly; the race reuses its score and
    still counts its iterations, so the winner's EM budget is the same as if it had run."""
    data, _ = _simulate(6, T=600)
    cfg = _config(start_search_s=10.0, refine_from=100)
    start = initial_model(data, cfg)
    cands = [start.replace(prior_mean=np.array([q, 0.0, 0.0])) for q in (1.0, 5.0, 3.0, 4.0)]
    runs = []

    class Trial:
        def __init__(self, model, iterations):
            self.model, self.iterations = model, iterations
            self.loglik_best = 100.0 * model.prior_mean[0] + model.prior_mean[1]

    def run(data, model, trial_cfg):
        runs.append(model.prior_mean[0])
        if model.prior_mean[0] == 5.0:  # stalls: its best model is the one it was given
            return Trial(model, trial_cfg.max_iterations)
        return Trial(model.replace(prior_mean=model.prior_mean + np.array([0.0, 1.0, 0.0])), trial_cfg.max_iterations)

    heard = []
    model, info = race_starts(data, cands, cfg, run, on_trial=lambda done, planned: heard.append((done, planned)))
    assert [len(r) for r in info["rounds"]] == [4, 2] and info["winner"] == 1
    assert heard == [(1, 6), (2, 6), (3, 6), (4, 6), (5, 6), (6, 6)]  # the stalled one's second trial: done unrun
    assert runs.count(5.0) == 1 and runs.count(4.0) == 2  # the stalled one ran once, the other twice
    assert info["rounds"][0]["1"] == info["rounds"][1]["1"] == 500.0
    assert info["winner_iterations"] == 2 * cfg.start_trial_iterations
    assert model is cands[1]


def test_start_race_runs_a_round_in_threads_and_gives_the_serial_race():
    """Invariant: the trials of a round run at once (two of them meet at a barrier, which a serial race
    would never reach), and with the real EM the threaded race gives the serial one's scores and
    winner exactly, the trials being seeded and independent."""
    data, _ = _simulate(6, T=600)
    cfg = _config(start_search_s=10.0, refine_from=100, start_trial_iterations=4)
    start = initial_model(data, cfg)
    cands = [start.replace(prior_mean=start.prior_mean + np.array([dx, dy, 0.0])) for dx, dy in
             [(0.0, 0.0), (400.0, 0.0), (0.0, -400.0), (-300.0, 300.0)]]  # fmt: skip
    barrier = threading.Barrier(2, timeout=10)

    def meeting(data, model, trial_cfg):
        barrier.wait()  # raises BrokenBarrierError after 10 s alone
        return fit_em(data, model, trial_cfg)

    race_starts(data, cands[:2], cfg, meeting, workers=2)
    serial_model, serial = race_starts(data, cands, cfg, fit_em, workers=1)
    threaded_model, threaded = race_starts(data, cands, cfg, fit_em, workers=3)
    assert threaded == serial and len(serial["rounds"]) == 2
    np.testing.assert_array_equal(threaded_model.prior_mean, serial_model.prior_mean)
    np.testing.assert_array_equal(threaded_model.action.coefficients, serial_model.action.coefficients)


def test_shifted_forward_reads_the_same_from_further_ahead(continuous_fit):
    """Exact reduction: the shifted model's start is ``delta`` ahead along its heading, its range
    function is ``f(d + delta)``, and nothing else changes; a zero shift is the model itself."""
    m = continuous_fit[2].model.replace(prior_mean=np.array([100.0, -50.0, 0.3]))
    moved = shifted_forward(m, 200.0)
    ahead = np.array([-200.0 * math.sin(0.3), 200.0 * math.cos(0.3), 0.0])  # theta = 0 faces +y
    assert moved.prior_mean == pytest.approx(m.prior_mean + ahead)
    d = np.array([500.0, 1500.0, 4000.0])
    f, g = m.sensor.channels[0].function, moved.sensor.channels[0].function
    assert g(d) == pytest.approx(f(d + 200.0), rel=1e-12)
    assert np.array_equal(moved.action.coefficients, m.action.coefficients)
    assert np.array_equal(moved.prior_cov, m.prior_cov) and moved.sensor.sigma_bearing_rad == m.sensor.sigma_bearing_rad
    same = shifted_forward(m, 0.0)
    assert np.array_equal(same.prior_mean, m.prior_mean) and same.sensor.channels[0].function(d) == pytest.approx(f(d))


def test_ridge_search_finds_a_model_moved_behind_and_never_lowers_the_likelihood(continuous_fit):
    """Seeded recovery: EM's converged model moved 250 mm behind (and its f read 250 mm further) is
    found again by the search; from the converged model itself it stays within a few centimetres, and in
    both cases the likelihood does not fall."""
    data, _, res = continuous_fit

    def evaluate(m):
        return e_step(m, data)

    def score(m):
        return log_likelihood(m, data)

    behind = shifted_forward(res.model, -250.0)
    model, post, info = search_ridge(behind, evaluate(behind), score, evaluate, 500.0)
    assert info["shift_mm"] == pytest.approx(250.0, abs=40.0)
    assert post.loglik == info["loglik_after"] > info["loglik_before"] + 10.0
    assert model.prior_mean == pytest.approx(res.model.prior_mean, abs=45.0)
    _, _, info0 = search_ridge(res.model, evaluate(res.model), score, evaluate, 500.0)
    assert abs(info0["shift_mm"]) < 40.0 and info0["loglik_after"] >= info0["loglik_before"]
    assert 0 < info0["forward_passes"] <= 30 and info0["expansions"] == 0
    # beyond the bracket: the search starts again from its edge until the peak is inside
    far = shifted_forward(res.model, -900.0)
    model, post, info = search_ridge(far, evaluate(far), score, evaluate, 500.0)
    assert info["shift_mm"] == pytest.approx(900.0, abs=40.0) and info["expansions"] >= 1
    assert post.loglik == info["loglik_after"] > info["loglik_before"] + 10.0
    assert model.prior_mean == pytest.approx(res.model.prior_mean, abs=45.0)
    # the shift it found is smoothed once; a smoother that fails there leaves the model where it was
    start = evaluate(behind)
    model, post, info = search_ridge(behind, start, score, lambda m: replace(start, ok=False), 500.0)
    assert model is behind and post is start and info["shift_mm"] == 0.0


@pytest.fixture(scope="module")
def delayed_fit():
    data, poses = _simulate(3, T=3000, delay_steps=6)
    return data, poses, fit_em(data, None, _config(action_delay_max_s=0.5, max_iterations=60))


def test_delay_search_finds_the_command_delay_and_never_lowers_the_likelihood(delayed_fit):
    """Seeded recovery: a robot that obeys its commands 6 steps late. EM's model with its delay set to
    0, and to 15, is brought back to 6 (+-1) by the search, with beta unchanged; from EM's own model
    the search keeps its delay, and the likelihood never falls."""
    data, _, res = delayed_fit
    assert res.model.action.delay_steps == pytest.approx(6, abs=1)

    def evaluate(m):
        return e_step(m, data)

    def score(m):
        return log_likelihood(m, data)

    for wrong in (0, 15):
        start = with_delay(res.model, wrong)
        model, post, info = search_delay(start, evaluate(start), score, evaluate, 15)
        assert info["delay_from"] == wrong and abs(info["delay_to"] - 6) <= 1
        assert model.action.delay_steps == info["delay_to"]
        assert np.array_equal(model.action.coefficients, res.model.action.coefficients)
        assert post.loglik == info["loglik_after"] > info["loglik_before"] + 10.0
        assert info["forward_passes"] <= 10  # 0, 3, ..., 15, then the best one's neighbours
    start = with_delay(res.model, 0)
    first = evaluate(start)
    model, post, info = search_delay(start, first, score, lambda m: replace(first, ok=False), 15)
    assert model is start and post is first and info["delay_to"] == 0  # its smoother failed: stay
    same, _, info0 = search_delay(res.model, evaluate(res.model), score, evaluate, 15)
    assert info0["loglik_after"] >= info0["loglik_before"]
    assert abs(same.action.delay_steps - res.model.action.delay_steps) <= 1
    # a robot without a delay: searched from the same config, EM learns none
    prompt, _ = _simulate(3, T=3000)
    assert fit_em(prompt, None, _config(action_delay_max_s=0.5, max_iterations=60)).model.action.delay_steps <= 1


def test_fit_searches_the_delay_on_the_ridge_schedule_only_when_a_delay_is_learned(tmp_path):
    """Exact bookkeeping: the delay search runs when the held stage ends and every search_every
    iterations after, is in the summary, never lowers the likelihood, and is off with
    ``delay_search: false`` or without a delay to learn (then EM is as before, bit for bit)."""
    data, poses = _simulate(3, T=1500, delay_steps=6)
    cfg = _config(refine_from=4, max_iterations=12, patience=50, search_every=3, action_delay_max_s=0.5)
    on = fit_em(data, None, cfg)
    assert [r["iteration"] for r in on.delay_search] == [4, 7, 10]
    for r in on.delay_search:
        assert r["loglik_after"] >= r["loglik_before"] and 0 <= r["delay_to"] <= 15
        assert on.loglik_history[r["iteration"]] == r["loglik_after"]
    assert on.summary()["delay_search"] == on.delay_search and on.ridge is None
    off = fit_em(
        data,
        None,
        _config(refine_from=4, max_iterations=12, search_every=3, action_delay_max_s=0.5, delay_search=False),
    )
    assert off.delay_search is None
    # the report sets the learned delay beside From-Truth's, with the searches' moves
    from sensact.experiments.real import evaluate_mrclam
    from sensact.report.tables_real import real_tables

    row = {"em": on.summary(), "score": evaluate_mrclam(_TruthLog(data, poses), on)}
    _, headers, cells = real_tables({"mrclam": {"on": row}})[0]
    cell = cells[0][headers.index("command delay s, learned / From-Truth")]
    assert cell.startswith(f"{on.model.action.delay_steps * data.dt_s:.3f} / ")
    moved = [r for r in on.delay_search if r["delay_to"] != r["delay_from"]]
    assert moved and f"{moved[0]['delay_from']}->{moved[0]['delay_to']}" in cell
    from sensact.report.figures_real import figure_loglik

    assert figure_loglik({"on": on}, tmp_path / "ll.png").stat().st_size > 0  # delay searches, no ridge
    # the CLI says where each search moved the delay
    from typer.testing import CliRunner

    from sensact.io.landmark_log import write_landmark_log

    write_landmark_log(tmp_path / "log", data)
    sets = [
        "action_basis=affine",
        "action_delay_max_s=0.5",
        "motion_noise=shared",
        "refine_from=4",
        "search_every=3",
        "max_iterations=8",
        "prune_rad_per_step=0",
    ]
    run = CliRunner().invoke(cli.app, ["learn", "em", str(tmp_path / "log")] + [a for x in sets for a in ("--set", x)])
    assert run.exit_code == 0, run.output
    assert "delay search at iteration 4: command delay" in run.output
    plain = fit_em(data, None, _config(refine_from=4, max_iterations=12, search_every=3))
    plain_off = fit_em(data, None, _config(refine_from=4, max_iterations=12, search_every=3, delay_search=False))
    assert plain.delay_search is None
    assert np.array_equal(plain.loglik_history, plain_off.loglik_history)


def test_heading_noise_bins_skip_the_empty_tenths_of_tied_turn_rates():
    """Exact: 60 windows at one turn rate (a half log that stood still) and 40 spread ones give the
    tied ones one bin (the 60 values' RMS) and four of ten each for the rest; no bin is empty, so the
    figure's axis limit is finite (it was NaN, and `reproduce real` failed, on half of Dataset 6)."""
    from sensact.report.figures_real import binned_rms

    turn = np.concatenate([np.full(60, 0.01), np.linspace(0.1, 0.4, 40)])
    drift = np.concatenate([np.full(60, 2.0), np.arange(40.0)])
    mid, rms = binned_rms(turn, drift)
    assert np.all(np.isfinite(rms)) and len(mid) == len(rms) == 5
    assert mid[0] == 0.01 and rms[0] == 2.0
    for k, chunk in enumerate(np.split(np.arange(40.0), 4)):
        assert rms[k + 1] == pytest.approx(np.sqrt(np.mean(chunk**2)))
    spread = np.random.default_rng(1).uniform(0, 1, 1000)
    assert len(binned_rms(spread, spread)[0]) == 10


def test_fit_searches_the_ridge_when_the_held_stage_ends_and_every_so_often_after(tmp_path):
    from sensact.experiments.real import evaluate_mrclam
    from sensact.report.figures_real import figure_loglik
    from sensact.report.tables_real import real_tables

    data, poses = _simulate(2, T=1500)
    off = fit_em(data, None, _config(refine_from=4, max_iterations=12))
    cfg = _config(refine_from=4, max_iterations=12, patience=50, ridge_search_mm=300.0, search_every=3)
    on = fit_em(data, None, cfg)
    assert off.ridge is None and on.freed_at == 4
    assert [r["iteration"] for r in on.ridge] == [4, 7, 10]
    # with nothing held (refine_from 0) the searches count from the start
    unheld = fit_em(data, None, _config(refine_from=0, max_iterations=8, ridge_search_mm=300.0, search_every=3))
    assert unheld.freed_at == -1 and [r["iteration"] for r in unheld.ridge] == [3, 6]
    for r in on.ridge:
        assert r["loglik_after"] >= r["loglik_before"] and abs(r["shift_mm"]) <= 300.0
        assert on.loglik_history[r["iteration"]] == r["loglik_after"]  # the history holds the moved model
    assert on.posteriors.loglik == on.loglik_best  # the reported best is the returned model's likelihood
    assert on.summary()["ridge"] == on.ridge
    with pytest.raises(ValueError, match="ridge_search"):
        _config(ridge_search_mm=-1.0)
    with pytest.raises(ValueError, match="ridge_search"):
        _config(search_every=0)
    with pytest.raises(ConfigError, match=r"t\.csv: ridge_search_mm: .* needs a planar log"):
        fit_em(_tiny_track(), None, EMConfig(ridge_search_mm=100.0))
    # the report lists each search's move, and a dash for a run without the search
    rows = {
        name: {"em": r.summary(), "score": evaluate_mrclam(_TruthLog(data, poses), r)}
        for name, r in (("on", on), ("off", off))
    }
    _, headers, cells = real_tables({"mrclam": rows})[0]
    col = headers.index("ridge moves mm, forward (the first as the held stage ends)")
    assert [float(m) for m in cells[0][col].split(", ")] == pytest.approx([r["shift_mm"] for r in on.ridge], abs=0.5)
    assert cells[1][col] == "-"
    # the noise table sets the learned Sigma_m's translational walk over 1 s beside the truth's miss
    title, nh, ncells = next(t for t in real_tables({"mrclam": rows}) if "what the truth says" in t[0])
    col = nh.index("sideways / forward miss per 1 s mm, truth; Sigma_m")
    side, fwd = math.sqrt(30) * on.model.motion_sd[0, :2]
    assert ncells[0][col].endswith(f"; {side:.1f} / {fwd:.1f}")
    del rows["on"]["score"]["truth_noise"]["translation_drift_rms_mm"]  # results written before it
    assert next(t for t in real_tables({"mrclam": rows}) if t[0] == title)[2][0][col] == "-"
    assert figure_loglik({"on": on, "off": off}, tmp_path / "ll.png").stat().st_size > 0


def test_sideways_motion_noise_starts_apart_from_the_forward():
    """Exact: the sideways start replaces Sigma_m's x entry only (0 leaves motion_sd_mm), a fixed
    Sigma_m keeps it through EM, and it is refused where it means nothing (a track) or is negative."""
    data, _ = _simulate(2, T=600)
    same = initial_model(data, _config())
    apart = initial_model(data, _config(motion_sd_sideways_mm=0.5))
    assert same.motion_sd.tolist() == [[10.0, 10.0, 0.05]]
    assert apart.motion_sd.tolist() == [[0.5, 10.0, 0.05]]
    fixed = fit_em(data, None, _config(motion_noise="fixed", motion_sd_sideways_mm=0.5, max_iterations=2))
    assert fixed.model.motion_sd.tolist() == [[0.5, 10.0, 0.05]]
    with pytest.raises(ValueError, match="motion_sd_sideways_mm must be >= 0"):
        _config(motion_sd_sideways_mm=-1.0)
    with pytest.raises(ConfigError, match=r"t\.csv: motion_sd_sideways_mm: .* a track has no sideways"):
        fit_em(_tiny_track(), None, EMConfig(motion_sd_sideways_mm=0.5))


def test_start_search_candidates_are_distinct_and_one_is_near_the_start():
    data, poses = _simulate(6, T=4500)
    cfg = _config(start_search_s=20.0, start_candidates=6)
    cands, info = start_candidates(data, initial_model(data, cfg), cfg)
    means = np.array([c.prior_mean for c in cands])
    assert len(cands) == 6 == len(info["candidates"])
    gaps = np.hypot(*(means[:, None, :2] - means[None, :, :2]).transpose(2, 0, 1))
    assert gaps[~np.eye(6, dtype=bool)].min() >= 2.5 * cfg.start_search_grid_mm
    assert np.hypot(*(means[:, :2] - poses[0, :2]).T).min() <= math.sqrt(2) * cfg.start_search_grid_mm  # a cell


def _turn(xy: np.ndarray, angle: float, shift=(0.0, 0.0)) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.asarray(xy) @ np.array([[c, s], [-s, c]]) + shift


def test_start_search_grid_turns_and_moves_with_the_map():
    """Invariant: the grid is the map's own, so turning and moving the map turns and moves the grid
    point for point; it covers every landmark and four cells around the map, and keeps off the
    first sighting's landmark. One landmark, or one at the centroid, still give a grid."""
    g = 500.0
    grid = search_grid(LANDMARKS, LANDMARKS[1], g)
    for angle, shift in [(1.0, (5000.0, -3000.0)), (-2.5, (0.0, 0.0)), (math.pi / 2, (-120.0, 7.0))]:
        moved = search_grid(_turn(LANDMARKS, angle, shift), _turn(LANDMARKS[1], angle, shift), g)
        np.testing.assert_allclose(moved, _turn(grid, angle, shift), atol=1e-6)
    near = np.hypot(*(grid[:, None, :] - LANDMARKS[None, :, :]).transpose(2, 0, 1)).min(axis=0)
    assert near[[0, 2, 3, 4]].max() <= g / math.sqrt(2) + 1e-9  # every other landmark is in a cell of it
    assert np.hypot(*(grid - LANDMARKS[1]).T).min() >= 1.5 * g  # the four cells about the landmark are left out
    # the grid reaches four cells past the map along its own axes: past the farthest landmark too
    assert np.hypot(*(grid - LANDMARKS[1]).T).max() >= np.hypot(*(LANDMARKS - LANDMARKS[1]).T).max() + 4 * g
    one = search_grid(LANDMARKS[:1], LANDMARKS[0], g)
    assert len(one) == 10 * 10 - 4 and np.allclose(one.mean(axis=0), LANDMARKS[0])
    ring = np.array([[0.0, 0.0], [1000.0, 0.0], [-1000.0, 0.0]])  # the first landmark is the centroid
    assert len(search_grid(ring, ring[0], g)) > 0


def test_pose_samples_turn_with_the_map():
    """Invariant: the M-step's poses (sec. 4.3.2) drawn from a posterior turned with the map are the
    same draws turned, for the same seed; their spread is still Sigma_gamma."""
    rng = np.random.default_rng(3)
    k = 40
    mean = np.column_stack([rng.normal(size=(k, 2)) * 1000, rng.uniform(-3, 3, k)])
    a = rng.normal(size=(k, 3, 3)) * [30.0, 30.0, 0.01]
    cov = a @ a.transpose(0, 2, 1) + np.diag([1.0, 1.0, 1e-6])
    angle = 1.0
    rot = np.eye(3)
    rot[:2, :2] = [[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]
    turned = SimpleNamespace(mean_gamma=mean @ rot.T + [5000.0, -3000.0, angle], cov_gamma=rot @ cov @ rot.T)
    here = sample_gamma(SimpleNamespace(mean_gamma=mean, cov_gamma=cov), np.arange(k), 5, np.random.default_rng(0))
    there = sample_gamma(turned, np.arange(k), 5, np.random.default_rng(0))
    np.testing.assert_allclose(there, here @ rot.T + [5000.0, -3000.0, angle], atol=1e-6)
    many = sample_gamma(SimpleNamespace(mean_gamma=mean[:1], cov_gamma=cov[:1]), np.zeros(200_000, int), 1, rng)[0]
    scale = np.sqrt(np.outer(np.diag(cov[0]), np.diag(cov[0])))
    assert np.abs((np.cov(many.T) - cov[0]) / scale).max() < 0.01


def test_a_turned_and_moved_map_learns_the_same_model():
    """Invariant: the map's frame is arbitrary, so a log whose map is turned by 1 rad and moved 5 m
    learns the same action model, sensor model and Sigma_m from the same poor start (start search,
    race and all), and starts at the same pose turned with the map."""
    data, _ = _simulate(6, T=3000)
    moved = replace(data, landmarks_xy=_turn(data.landmarks_xy, 1.0, (5000.0, -3000.0)))
    cfg = _config(start_search_s=20.0, start_candidates=3, start_trial_iterations=5, max_iterations=30)
    heard = []
    here = fit_em(
        data,
        None,
        cfg,
        progress=lambda it, *_: heard.append(("iteration", it)),
        on_race=lambda done, planned: heard.append(("race", done, planned)),
    )
    there = fit_em(moved, None, cfg)
    a, b = here.model, there.model
    assert here.iterations == there.iterations > 0
    # the start race's progress, every trial of its rounds, before the first iteration's
    race = [h for h in heard if h[0] == "race"]
    trials = sum(len(r) for r in here.start_search["race"]["rounds"])
    assert race == [("race", k, 5) for k in range(1, trials + 1)] and heard[: len(race)] == race
    assert heard[len(race)] == ("iteration", 0)
    np.testing.assert_allclose(b.action.coefficients, a.action.coefficients, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(b.motion_sd, a.motion_sd, rtol=1e-6)
    for cb, ca in zip(b.sensor.channels, a.sensor.channels, strict=True):
        np.testing.assert_allclose(cb.function.coef, ca.function.coef, rtol=1e-6, atol=1e-9)
        assert cb.sigma == pytest.approx(ca.sigma, rel=1e-6)
    assert b.sensor.sigma_bearing_rad == pytest.approx(a.sensor.sigma_bearing_rad, rel=1e-6)
    assert here.loglik_best == pytest.approx(there.loglik_best, abs=1e-6 * abs(here.loglik_best))
    np.testing.assert_allclose(b.prior_mean[:2], _turn(a.prior_mean[:2], 1.0, (5000.0, -3000.0)), atol=1e-3)
    assert float(np.angle(np.exp(1j * (b.prior_mean[2] - a.prior_mean[2] - 1.0)))) == pytest.approx(0.0, abs=1e-9)


def _turning_cubic(center: float, scale: float, at: float = 0.0, width: float = 1.0):
    """h((x - at) / width) with h(v) = v^3 - 6 v^2 + 9 v, whose slope 3 (v - 1)(v - 3) changes sign at
    v = 1 and 3, so at x = at + width and at + 3 width; stored about ``center`` and ``scale``."""
    from numpy.polynomial import Polynomial

    from sensact.models.polynomial import Polynomial1D

    x_of_u = Polynomial([center, scale])
    in_u = Polynomial([0.0, 9.0, -6.0, 1.0])((x_of_u - at) / width)
    return Polynomial1D(tuple(in_u.coef), center=center, scale=scale)


def test_turning_points_are_where_the_slope_changes_sign():
    from sensact.models.polynomial import Polynomial1D

    f = _turning_cubic(2.0, 1.5)
    np.testing.assert_allclose(f.turning_points(0.0, 4.0), [1.0, 3.0], atol=1e-9)
    np.testing.assert_allclose(f.turning_points(1.5, 4.0), [3.0], atol=1e-9)
    assert f.turning_points(3.5, 9.0).size == 0
    # an independent reference: the sign changes of the slope on a dense grid
    x = np.linspace(-1.0, 5.0, 600_001)
    slope = np.gradient(f(x), x)
    flips = x[1:][np.sign(slope[1:]) != np.sign(slope[:-1])]
    np.testing.assert_allclose(flips, f.turning_points(-1.0, 5.0), atol=1e-4)
    # a slope that touches zero without changing sign (x^3), a rising cubic, a line and a constant do not turn
    for coef in ((0.0, 0.0, 0.0, 1.0), (0.0, 1.0, 0.0, 1.0), (3.0, 2.0), (5.0,), (1.0, 2.0, 0.0, 0.0)):
        assert Polynomial1D(coef, center=0.7, scale=3.0).turning_points(-10.0, 10.0).size == 0, coef


def test_slope_range_is_the_least_and_greatest_slope_over_the_interval():
    """Polynomial1D.slope_range against an independent reference: the slope on a dense grid."""
    from sensact.models.polynomial import Polynomial1D

    f = _turning_cubic(2.0, 1.5)  # slope 3 (x - 1)(x - 3): least -3 at x = 2
    assert f.slope_range(0.0, 4.0) == pytest.approx((-3.0, 9.0), abs=1e-9)
    assert f.slope_range(3.0, 5.0) == pytest.approx((0.0, 24.0), abs=1e-9)  # the slope's turn outside
    for coef, lo, hi in (((1.0, -0.4, 0.3, 0.05), -2.0, 3.0), ((2.0, 1.3, -0.2), 0.0, 9.0), ((3.0, 2.0), -5.0, 5.0)):
        g = Polynomial1D(coef, center=0.7, scale=3.0)
        x = np.linspace(lo, hi, 400_001)
        slope = np.gradient(g(x), x)
        assert g.slope_range(lo, hi) == pytest.approx((slope.min(), slope.max()), abs=1e-6), coef
        np.testing.assert_allclose(g.slope(x[1:-1]), slope[1:-1], atol=1e-6)
    assert Polynomial1D((5.0,)).slope_range(0.0, 1.0) == (0.0, 0.0)


def test_a_length_reading_whose_slope_changes_with_distance_is_flagged(continuous_fit):
    """learn/em/checks.py: the fit that found the robot has an f of one slope; an f whose slope changes
    threefold over the fitted distances without turning is flagged when the channel reads a length in the
    map's unit (``_mm``), not when it is a line off by a scale, not under another unit, and an f that
    turns is ``range_function_turns``'s alone; ``lost_fit_signs`` holds both."""
    from sensact.learn.em.checks import (
        BEND_RATIO,
        describe_lost_fit,
        lost_fit_signs,
        range_function_bends,
        range_function_turns,
    )
    from sensact.models.polynomial import Polynomial1D

    data, _poses, res = continuous_fit
    assert range_function_bends(res.model, res.posteriors, data) == []
    assert lost_fit_signs(res.model, res.posteriors, data) == []
    use = res.posteriors.obs_used
    d = landmark_distance(res.posteriors.mean_gamma[data.obs_step[use]], LANDMARKS[data.obs_landmark[use]])
    lo, hi = np.percentile(d, [2, 98])
    f0 = res.model.sensor.channels[0].function

    def with_f(f, name="range_mm"):
        ch = replace(res.model.sensor.channels[0], function=f, name=name)
        return res.model.replace(sensor=replace(res.model.sensor, channels=(ch,)))

    def quadratic(slope_lo, slope_hi):
        """lo + a (x - lo) + b (x - lo)^2, its slope slope_lo at lo and slope_hi at hi, stored in
        u = (x - center) / scale as the fit stores f."""
        a, b, e = slope_lo, 0.5 * (slope_hi - slope_lo) / (hi - lo), f0.center - lo
        coef = (lo + a * e + b * e**2, (a + 2 * b * e) * f0.scale, b * f0.scale**2)
        return Polynomial1D(coef, center=f0.center, scale=f0.scale)

    bent = quadratic(0.6, 1.8)
    assert bent(np.array([lo]))[0] == pytest.approx(lo) and bent.slope(np.array([lo, hi])) == pytest.approx([0.6, 1.8])
    signs = range_function_bends(with_f(bent), res.posteriors, data)
    assert len(signs) == 1 and signs[0]["channel"] == "range_mm" and signs[0]["sign"] == "bends"
    np.testing.assert_allclose(signs[0]["slopes"], [0.6, 1.8], rtol=1e-9)
    np.testing.assert_allclose(signs[0]["distances_mm"], [lo, hi])
    assert range_function_turns(with_f(bent), res.posteriors, data) == []
    assert lost_fit_signs(with_f(bent), res.posteriors, data) == signs
    said = describe_lost_fit(signs)
    assert "range_mm's f has slopes from 0.60 to 1.80 mm per mm, inside the" in said and "start_sigma" in said
    assert "off by a scale, but not by one that changes with distance" in said
    # at the ratio, a steeper or a falling line, and a bend under another unit: not flagged
    assert range_function_bends(with_f(quadratic(0.6, 0.6 * BEND_RATIO * 0.99)), res.posteriors, data) == []
    for line in (Polynomial1D((100.0, 2.5 * f0.scale), f0.center, f0.scale), Polynomial1D((9e3, -0.4 * f0.scale))):
        assert range_function_bends(with_f(line), res.posteriors, data) == []
    assert range_function_bends(with_f(bent, name="height_px"), res.posteriors, data) == []
    # a falling reading bent threefold is flagged too
    falling = Polynomial1D(tuple(-c for c in bent.coef), center=f0.center, scale=f0.scale)
    assert range_function_bends(with_f(falling), res.posteriors, data)[0]["slopes"] == pytest.approx([-1.8, -0.6])
    # an f that turns is a turn, not a bend
    turning = _turning_cubic(f0.center, f0.scale, at=0.5 * (lo + hi) - 0.2 * (hi - lo), width=0.1 * (hi - lo))
    signs = lost_fit_signs(with_f(turning), res.posteriors, data)
    assert len(signs) == 1 and signs[0]["sign"] == "turns" and "does not turn" in describe_lost_fit(signs)


def test_a_range_function_that_turns_within_its_distances_is_flagged(continuous_fit):
    """learn/em/checks.py: the fit that found the robot has a rising f; the same fit with an f that turns
    inside the fitted distances is flagged there, and not when the turn is outside them or outside the
    channel's window."""
    from sensact.learn.em.checks import describe_lost_fit, range_function_turns

    data, _poses, res = continuous_fit
    assert range_function_turns(res.model, res.posteriors, data) == []
    use = res.posteriors.obs_used
    d = landmark_distance(res.posteriors.mean_gamma[data.obs_step[use]], LANDMARKS[data.obs_landmark[use]])
    lo, hi = np.percentile(d, [2, 98])
    mid = 0.5 * (lo + hi)

    def with_f(f, **window):
        ch = replace(res.model.sensor.channels[0], function=f, **window)
        return res.model.replace(sensor=replace(res.model.sensor, channels=(ch,)))

    # turns at mid -/+ a tenth of the span, stored as the fit stores f
    a = 0.1 * (hi - lo)
    f0 = res.model.sensor.channels[0].function
    f = _turning_cubic(f0.center, f0.scale, at=mid - 2.0 * a, width=a)
    turned = range_function_turns(with_f(f), res.posteriors, data)
    assert len(turned) == 1 and turned[0]["channel"] == "range_mm"
    np.testing.assert_allclose(turned[0]["turns_at_mm"], [mid - a, mid + a], rtol=1e-9)
    np.testing.assert_allclose(turned[0]["distances_mm"], [lo, hi])
    assert "turns over at" in describe_lost_fit(turned) and "start_sigma" in describe_lost_fit(turned)
    far = _turning_cubic(f0.center, f0.scale, at=hi + 2.0 * a, width=a)  # turns at hi + 3a and hi + 5a
    assert range_function_turns(with_f(far), res.posteriors, data) == []
    assert range_function_turns(with_f(f, valid_max=mid - 1.5 * a), res.posteriors, data) == []


def test_a_fit_whose_likelihood_keeps_falling_far_below_its_best_has_not_settled(continuous_fit):
    """learn/em/checks.py ``unsettled_fit``: the mean fall below the best over the iterations after it, per
    sighting used, against ``UNSETTLED_PER_SIGHTING`` (exact on built histories); the fit that found the
    robot has not that sign, the same fit with a history that thrashes after its best has, and says so;
    a 1-D log's history is not judged."""
    from sensact.learn.em.checks import UNSETTLED_PER_SIGHTING, describe_lost_fit, lost_fit_signs, unsettled_fit

    n = 1000
    limit = UNSETTLED_PER_SIGHTING * n
    at_limit = np.array([-900.0, -500.0, -500.0 - 0.5 * limit, -500.0 - 1.5 * limit])  # falls 0.5 and 1.5 limit
    assert unsettled_fit(at_limit, 1, n) == []  # a mean fall of the limit itself
    over = at_limit.copy()
    over[3] -= 1e-6 * limit
    (sign,) = unsettled_fit(over, 1, n)
    assert sign["sign"] == "unsettled" and sign["best_iteration"] == 1 and sign["iterations_after"] == 2
    assert sign["mean_fall"] == pytest.approx(limit * (1 + 0.5e-6)) and sign["per_sighting"] == pytest.approx(
        sign["mean_fall"] / n
    )
    assert unsettled_fit(over, 3, n) == [] and unsettled_fit(over, 1, 0) == []  # nothing after the best; no sighting
    assert unsettled_fit(over, 1, 2 * n) == []  # the same falls over twice the sightings

    data, _poses, res = continuous_fit
    h, b = res.loglik_history, res.best_iteration
    assert b < h.size - 1 and lost_fit_signs(res.model, res.posteriors, data, h, b) == []
    used = int(res.posteriors.obs_used.sum())
    assert res.n_used == used == res.n_observations - res.n_pruned
    assert res.summary()["fall_per_sighting"] == pytest.approx(
        sum(h[b] - h[i] for i in range(b + 1, h.size)) / (h.size - b - 1) / used
    )
    assert 0 < res.summary()["fall_per_sighting"] < UNSETTLED_PER_SIGHTING
    thrashing = h.copy()
    thrashing[b + 1 :] -= 2.0 * UNSETTLED_PER_SIGHTING * used
    signs = lost_fit_signs(res.model, res.posteriors, data, thrashing, b)
    assert [s["sign"] for s in signs] == ["unsettled"] and "channel" not in signs[0]
    assert signs[0]["per_sighting"] == pytest.approx(2.0 * UNSETTLED_PER_SIGHTING + np.mean(h[b] - h[b + 1 :]) / used)
    said = describe_lost_fit(signs)
    assert f"iterations after its best one ({b}) EM's log-likelihood stayed on average" in said
    assert "moves little from it: EM has probably lost the robot" in said
    assert lost_fit_signs(res.model, res.posteriors, data) == []  # without the history, the f signs alone
    track = replace(data, geometry="track")
    assert unsettled_fit(thrashing, b, used) and lost_fit_signs(res.model, res.posteriors, track, thrashing, b) == []


def test_em_restarts_from_a_tighter_start_while_f_turns_and_keeps_the_most_likely_fit(monkeypatch):
    """fit.restart_while_lost, with the turn check replaced by one that flags the first ``flagged``
    fits: each restart's start sigma is a third of the last, no more than ``turn_restarts`` restarts run,
    none once f does not turn, and the fit kept is the most likely one, scored on the sightings every run
    used (each run's own likelihood here: nothing is pruned)."""
    import sensact.learn.em.fit as fit_module

    data, _ = _simulate(3, T=2400)
    calls = {"n": 0, "flagged": 0}

    def flags_the_first(model, post, log, *history):
        calls["n"] += 1
        turn = [{"channel": "range_mm", "sign": "turns", "turns_at_mm": [2000.0], "distances_mm": [1000.0, 3000.0]}]
        if calls.get("unsettled"):  # checks.unsettled_fit's sign names no channel
            turn = [
                {"sign": "unsettled", "best_iteration": 5, "iterations_after": 4, "mean_fall": 9e3, "per_sighting": 2}
            ]
        return turn if calls["n"] <= calls["flagged"] else []

    monkeypatch.setattr(fit_module, "lost_fit_signs", flags_the_first)
    heard = []
    for restarts, flagged, runs in ((2, 9, 3), (2, 1, 2), (0, 9, 1), (3, 0, 1)):
        calls.update(n=0, flagged=flagged)
        # from a vague start, the tighter restarts climb faster in 10 iterations: the most likely run is
        # neither the first nor always the last, so keeping either would fail
        wide = (ChannelConfig("range_mm", 1, 0.0, 0.8, 3000.0),)
        cfg = _config(max_iterations=10, turn_restarts=restarts, channels=wide)
        res = fit_em(data, None, cfg, on_restart=lambda k, turned, sigmas: heard.append((k, sigmas)))
        if runs == 1:
            assert res.restarts is None
            continue
        info = res.restarts
        assert len(info) == runs and [r["start_sigma"]["range_mm"] for r in info] == pytest.approx(
            [3000.0 / 3**k for k in range(runs)], rel=1e-12
        )
        assert [bool(r["f_turns"]) for r in info] == [True] * (runs - 1) + [runs - 1 < flagged]
        kept = [r for r in info if r["kept"]]
        assert len(kept) == 1 and kept[0]["loglik"] == max(r["loglik"] for r in info) and not info[0]["kept"]
        assert res.loglik_best == pytest.approx(kept[0]["loglik"], abs=1e-6 * abs(res.loglik_best))
        assert all(r["loglik"] == pytest.approx(r["loglik_best"], abs=1e-6 * abs(r["loglik"])) for r in info)
        # the kept model, its likelihood computed again from the forward pass alone
        assert log_likelihood(res.model, data) == pytest.approx(kept[0]["loglik"], abs=1e-6 * abs(res.loglik_best))
    assert [k for k, _ in heard] == [1, 2, 1] and heard[1][1]["range_mm"] == pytest.approx(3000.0 / 9)
    assert "restarts" in res.summary()
    # a fit that did not settle names no channel: every channel starts a third as vague
    calls.update(n=0, flagged=1, unsettled=True)
    heard.clear()
    res = fit_em(data, None, replace(cfg, turn_restarts=2), on_restart=lambda k, signs, sigmas: heard.append(sigmas))
    assert heard == [{"range_mm": pytest.approx(1000.0)}] and len(res.restarts) == 2
    assert [r["f_turns"][0]["sign"] for r in res.restarts[:1]] == ["unsettled"] and not res.restarts[1]["f_turns"]
    calls["unsettled"] = False

    # Ctrl-C ends the fit: no restart after it, whatever the signs
    def interrupt(it, ll, best, since):
        if it == 3:
            raise KeyboardInterrupt

    calls.update(n=0, flagged=9)
    heard.clear()
    res = fit_em(data, None, cfg, progress=interrupt, on_restart=lambda k, signs, sigmas: heard.append(sigmas))
    assert res.stop_reason == "interrupted" and res.restarts is None and heard == [] and calls["n"] == 1
    # what `learn em` and `reproduce real` show of the last two-run fit
    from sensact.report.tables_real import kept_run_cell, restart_runs_cell

    calls.update(n=0, flagged=1)
    two = fit_em(data, None, replace(cfg, turn_restarts=1))
    cell = restart_runs_cell(two.restarts)
    assert cell.startswith("range_mm 3000: ") and "(f turned); range_mm 1000: " in cell
    assert kept_run_cell(two.restarts) == ("restart 1" if two.restarts[1]["kept"] else "the first run")
    unsettled = {
        "sign": "unsettled",
        "best_iteration": 5,
        "iterations_after": 4,
        "mean_fall": 900.0,
        "per_sighting": 1.0,
    }
    cell = restart_runs_cell([dict(two.restarts[0], f_turns=[unsettled]), two.restarts[1]])
    assert cell.startswith("range_mm 3000: ") and "(EM unsettled); range_mm 1000: " in cell
    bend = {"channel": "range_mm", "sign": "bends", "slopes": [0.7, 2.1], "distances_mm": [1000.0, 3000.0]}
    both = [dict(two.restarts[0], f_turns=[bend]), dict(two.restarts[1], f_turns=[bend, *two.restarts[0]["f_turns"]])]
    assert "(f bent); range_mm 1000: " in restart_runs_cell(both) and restart_runs_cell(both).endswith(
        "(f turned and bent)"
    )


def test_model_json_round_trip(continuous_fit):
    m = continuous_fit[2].model
    again = EMModel.from_dict(m.to_dict())
    np.testing.assert_array_equal(again.action.coefficients, m.action.coefficients)
    np.testing.assert_array_equal(again.motion_sd, m.motion_sd)
    assert again.sensor == m.sensor and isinstance(again.action, LinearActionModel)


def test_turning_variance_is_the_maximum_likelihood_fit():
    """Independent reference: scipy's bounded minimization of the Gaussian negative log-likelihood
    ``sum log v_t + s_t / v_t`` with ``v_t = a + b |turn_t|``; and the two bounds."""
    from scipy.optimize import minimize

    from sensact.learn.em.actions import turning_variance

    rng = np.random.default_rng(5)
    turn = rng.uniform(-0.6, 0.6, 4000)
    second = (1e-4 + 2e-3 * np.abs(turn)) * rng.chisquare(1, turn.size)
    a, b = turning_variance(second, turn, 1e-8, (second.mean(), 0.0))

    def nll(p):
        v = p[0] + p[1] * np.abs(turn)
        return float(np.sum(np.log(v) + second / v))

    ref = minimize(nll, [second.mean(), 0.0], bounds=[(1e-8, None), (0.0, None)], method="L-BFGS-B", tol=1e-14)
    np.testing.assert_allclose([a, b], ref.x, rtol=1e-3)
    assert nll([a, b]) <= ref.fun + 1e-6
    assert a == pytest.approx(1e-4, rel=0.2) and b == pytest.approx(2e-3, rel=0.1)
    # no turning in the log: b stays 0 and a is the plain mean (the shared Sigma_m's update)
    assert turning_variance(second, np.zeros_like(turn), 1e-8, (1e-3, 0.0)) == pytest.approx((second.mean(), 0.0))
    # more noise when still than turning cannot make b negative; a floor holds a up
    a0, b0 = turning_variance(1e-3 / (1 + 10 * np.abs(turn)) * rng.chisquare(1, turn.size), turn, 1e-8, (1e-3, 0.0))
    assert b0 == 0.0 and a0 > 0
    assert turning_variance(np.full(turn.size, 1e-9), turn, 1e-6, (1e-3, 0.0))[0] == 1e-6


def test_turning_noise_is_recovered_and_zero_turning_is_the_shared_model(continuous_fit):
    """Seeded recovery of a heading noise that grows with turning (within 20 %), from a constant start;
    and the exact reduction: turn_var 0 gives the shared model's E-step, to the last bit."""
    beta = TRUE_BETA.copy()
    beta[:, 0] = 0.0
    sd = np.array([4.0, 5.0, 0.01])  # rad a step at rest; 0.025 turning at 0.25 rad/s
    data, _ = _simulate(6, beta=beta, sd=sd, turn_var=2e-3)
    res = fit_em(data, None, _config(motion_noise="turning", action_zero_mean=("v_x_mm_s",)))
    m = res.model
    assert m.turn_var == pytest.approx(2e-3, rel=0.2)
    assert m.motion_sd[0, 2] == pytest.approx(0.01, rel=0.2)
    np.testing.assert_allclose(m.motion_sd[0, :2], sd[:2], rtol=0.2)
    shared = fit_em(data, None, _config(action_zero_mean=("v_x_mm_s",), max_iterations=150))
    assert res.loglik_best > shared.loglik_best + 20  # the data tell the two apply

    data0, _, fitted = continuous_fit
    plain = fitted.model
    zero = plain.replace(turn_var=0.0)
    np.testing.assert_array_equal(step_motion_var(zero, data0), step_motion_var(plain, data0))
    assert e_step(zero, data0).loglik == e_step(plain, data0).loglik
    again = EMModel.from_dict(m.to_dict())
    assert again.turn_var == m.turn_var and plain.to_dict()["turn_var"] is None


def _tiny_track() -> LandmarkLog:
    """A five-step track log with one sighting: enough for the checks that refuse a track."""
    return LandmarkLog(
        "track",
        0.1,
        np.zeros(5, dtype=int),
        np.zeros((1, 1)),
        ("v",),
        np.array([0]),
        np.array([0]),
        np.array([100.0]),
        np.array([np.nan]),
        np.zeros((1, 2)),
        source="t.csv",
    )


def test_turning_noise_needs_a_planar_shared_model():
    track = _tiny_track()
    with pytest.raises(ConfigError, match=r"motion_noise: .* a track has no heading"):
        initial_model(track, EMConfig(motion_noise="turning"))
    data, _ = _simulate(1, T=300)
    m = initial_model(data, _config(motion_noise="turning"))
    assert m.turn_var == 0.0
    with pytest.raises(ValueError, match="turn_var must be >= 0"):
        m.replace(turn_var=-1.0)


def test_per_action_noise_learns_one_row_per_action():
    from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

    data = to_landmark_log(simulate_field(Field2DConfig(seconds=120.0, seed=2)))
    cfg = EMConfig(motion_noise="per_action", prune_rad_per_step=0.0, max_iterations=30, refine_from=0)
    res = fit_em(data, None, cfg)
    sd = res.model.motion_sd
    assert sd.shape == (data.n_actions, 3) and np.all(sd >= [0.05, 0.05, 5e-4])
    assert np.ptp(sd[:, 0]) > 0  # the rows are learned separately


def test_student_t_makes_outliers_harmless():
    """With 10 % gross range outliers a Gaussian channel's sigma balloons; Student-t keeps the inliers'."""
    data, _ = _simulate(3, T=6000, outlier_frac=0.1)
    ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0)
    gauss = fit_em(data, None, _config(channels=(ch,), max_iterations=120))
    robust_ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0, robust="student_t", robust_param=4.0)
    robust = fit_em(data, None, _config(channels=(robust_ch,), max_iterations=120))
    assert gauss.model.sensor.channels[0].sigma > 300
    assert robust.model.sensor.channels[0].sigma < 80  # a fifth of the Gaussian one; true inlier sigma 30
    x = np.linspace(800, 4500, 20)
    np.testing.assert_allclose(robust.model.sensor.channels[0].function(x), 1.05 * x + 40, atol=40)
    w = robust.posteriors.weights[:, 0]
    assert w.min() < 0.05 and np.median(w) > 0.8  # outliers count for little, inliers nearly fully


def test_gate_and_window_decide_which_readings_count(continuous_fit):
    data, poses, res = continuous_fit
    d = landmark_distance(poses[data.obs_step], LANDMARKS[data.obs_landmark])
    ch = res.model.sensor.channels[0]
    import dataclasses

    windowed = res.model.replace(
        sensor=dataclasses.replace(
            res.model.sensor, channels=(dataclasses.replace(ch, valid_min=1500, valid_max=3000),)
        )
    )
    w = e_step(windowed, data).weights[:, 0]
    clear = (d < 1300) | (d > 3200)
    assert np.all(w[clear] == 0) and np.all(w[(d > 1700) & (d < 2800)] == 1)
    junk = data.obs_readings.copy()
    junk[::10] += 5000.0
    bad = LandmarkLog(
        **{
            **{
                f: getattr(data, f)
                for f in (
                    "geometry",
                    "dt_s",
                    "actions",
                    "action_commands",
                    "command_names",
                    "obs_step",
                    "obs_landmark",
                    "obs_bearing_rad",
                    "landmarks_xy",
                    "reading_names",
                    "step_commands",
                )
            },
            "obs_readings": junk,
        }
    )
    gated = res.model.replace(
        sensor=dataclasses.replace(
            res.model.sensor, channels=(dataclasses.replace(ch, robust="gate", robust_param=4.0),)
        )
    )
    post = e_step(gated, bad)
    assert np.all(post.weights[::10, 0] == 0) and (post.weights[:, 0] > 0).mean() > 0.85


def test_channels_parse_from_a_config_mapping():
    cfg = config_from_dict(
        EMConfig,
        {
            "action_basis": "cross",
            "channels": [{"name": "ir", "valid_min": 150, "valid_max": 1500, "robust": "gate", "robust_param": 3}],
        },
    )
    assert cfg.channels[0].valid_max == 1500 and cfg.channels[0].robust == "gate"
    assert math.isinf(ChannelConfig("x").valid_max)
    with pytest.raises(ValueError, match="per_action"):
        EMConfig(action_basis="affine", motion_noise="per_action")


def test_a_config_written_in_a_model_json_reads_back_exactly(tmp_path):
    """Exact round trip of the config a model.json holds (`summary.config`, which `learn em --start-from`
    reads): JSON has no infinity, so a channel's open window is written as null and read back as the
    default it was; a null for a float field whose default is finite stays an error naming the field."""
    from dataclasses import asdict

    from sensact.experiments.real import mrclam_config
    from sensact.experiments.turtlebot_em import turtlebot_em_config
    from sensact.io.atomic import write_json

    for cfg in (mrclam_config(), turtlebot_em_config(), EMConfig(), replace(EMConfig(), warm_start=True)):
        write_json(tmp_path / "m.json", {"config": asdict(cfg)})
        assert config_from_dict(EMConfig, json.loads((tmp_path / "m.json").read_text())["config"]) == cfg
    assert json.loads((tmp_path / "m.json").read_text())["config"]["warm_start"] is True
    write_json(tmp_path / "t.json", asdict(turtlebot_em_config()))
    sonar = json.loads((tmp_path / "t.json").read_text())["channels"][0]
    assert sonar["valid_min"] is None and sonar["valid_max"] is None  # written as nulls, read back as +-inf
    with pytest.raises(ConfigError, match="start_sigma: expected float, got None"):
        config_from_dict(ChannelConfig, {"name": "x", "start_sigma": None}, source="m.json: channels")


def test_a_config_written_as_yaml_reads_back_exactly(tmp_path):
    """Exact round trip of the YAML `convert mrclam` writes: only the fields that differ from the
    defaults (a channel's infinite window left out), and `build_config` gives the same config back."""
    from sensact.config import build_config, config_to_yaml
    from sensact.experiments.real import mrclam_config
    from sensact.experiments.turtlebot_em import turtlebot_em_config

    for cfg in (mrclam_config(), turtlebot_em_config(), EMConfig()):
        text = config_to_yaml(cfg, "first line\nsecond line")
        assert text.startswith("# first line\n# second line\n")
        (tmp_path / "c.yaml").write_text(text)
        assert build_config(EMConfig, tmp_path / "c.yaml") == cfg
    text = config_to_yaml(mrclam_config())
    assert "ridge_search_mm: 500.0" in text and "inf" not in text and "patience" not in text
    assert config_to_yaml(EMConfig()) == "{}\n"


@pytest.mark.skipif(not MRCLAM.is_dir(), reason=f"MRCLAM data not found at {MRCLAM}")
def test_a_robot_that_sees_no_landmark_is_refused_in_one_line_and_reproduce_goes_on(tmp_path):
    """Dataset 6 with robot 3's camera seeing only other robots: `convert mrclam` warns, `fit_em` refuses
    the log in one line naming the sightings, and `reproduce real`'s run records why robot 3 was not run
    (its table "Not run") instead of stopping every robot's run on it."""
    from typer.testing import CliRunner

    from sensact.errors import LogFormatError
    from sensact.experiments.real import mrclam_config, run_real
    from sensact.io.mrclam import read_mrclam
    from sensact.report.tables_real import real_tables

    folder = tmp_path / "data" / "mrclam" / MRCLAM.name
    folder.mkdir(parents=True)
    for f in MRCLAM.iterdir():
        (folder / f.name).symlink_to(f)
    robots = {
        int(b)
        for s, b, *_ in (ln.split() for ln in (MRCLAM / "Barcodes.dat").read_text().splitlines())
        if s.isdigit() and int(s) <= 5
    }
    lines = (MRCLAM / "Robot3_Measurement.dat").read_text().splitlines(keepends=True)
    (folder / "Robot3_Measurement.dat").unlink()
    (folder / "Robot3_Measurement.dat").write_text(
        "".join(ln for ln in lines if ln.startswith("#") or int(ln.split()[1]) in robots)
    )
    run = CliRunner().invoke(cli.app, ["convert", "mrclam", str(folder), "--robot", "3", "--out", str(tmp_path / "c")])
    flat = " ".join(run.output.split())
    assert run.exit_code == 0 and "kept 0 landmark sightings" in flat and "robot 3 sees no landmark" in flat, flat
    with pytest.raises(LogFormatError, match=r"Robot3: observations: the log has no landmark sightings.* Fix: "):
        fit_em(read_mrclam(folder, 3).data, None, mrclam_config())
    out, _ = run_real(tmp_path / "data", robots=(3,))
    assert out["mrclam"] == {} and out["scorecard"] == []
    assert out["skipped"][0].startswith("MRCLAM robot3: ") and "no landmark sightings" in out["skipped"][0]
    title, headers, rows = real_tables(out)[-1]
    assert headers == ["what", "why"]
    assert title == "Not run" and rows[0][0] == "MRCLAM robot3" and "no landmark sightings" in rows[0][1]


@pytest.mark.skipif(not MRCLAM.is_dir(), reason=f"MRCLAM data not found at {MRCLAM}")
def test_mrclam_reader_and_log_folder_round_trip(tmp_path):
    from sensact.io.landmark_log import read_landmark_log, write_landmark_log
    from sensact.io.mrclam import read_mrclam

    ml = read_mrclam(MRCLAM, 1)
    s = ml.summary
    assert (
        s["kept"] + s["dropped_robot"] + s["dropped_unknown_barcode"] + s["dropped_outside_time"]
        == s["measurement_rows"]
    )
    assert s["kept"] == ml.data.n_observations and s["dropped_robot"] > 0
    # zero-order hold: each step's command is the last odometry row at or before it
    odo = np.loadtxt(MRCLAM / "Robot1_Odometry.dat", comments="#")
    t = ml.t0_s + 500 * ml.data.dt_s
    np.testing.assert_allclose(ml.data.step_commands[500], odo[odo[:, 0] <= t + 1e-9][-1, 1:] * [1000.0, 1.0])
    assert np.all(ml.data.obs_readings > 0)
    write_landmark_log(tmp_path / "log", ml.data, groundtruth=ml.groundtruth)
    back = read_landmark_log(tmp_path / "log")
    # the command writes the same folder, with the EM settings its printed command passes
    from typer.testing import CliRunner

    from sensact.config import build_config
    from sensact.experiments.real import bar_checks, mrclam_config

    run = CliRunner().invoke(cli.app, ["convert", "mrclam", str(MRCLAM), "--robot", "1", "--out", str(tmp_path / "c")])
    assert run.exit_code == 0, run.output
    assert f"--config {tmp_path / 'c' / 'em_config.yaml'}" in run.output.replace("\n", "")
    assert build_config(EMConfig, tmp_path / "c" / "em_config.yaml") == mrclam_config()
    assert (tmp_path / "c" / "overview.png").stat().st_size > 20_000  # the conversion, to check by eye
    np.testing.assert_array_equal(read_landmark_log(tmp_path / "c").data.obs_readings, back.data.obs_readings)
    np.testing.assert_allclose(back.data.step_commands, ml.data.step_commands)
    np.testing.assert_allclose(back.data.obs_readings, ml.data.obs_readings)
    np.testing.assert_array_equal(back.data.obs_step, ml.data.obs_step)
    np.testing.assert_allclose(back.groundtruth["x_mm"], ml.groundtruth["x_mm"], rtol=1e-9)
    # learn on the folder (a short fit) and score the model with `evaluate mrclam`: the same table
    # and bars both ways, and the JSON carries the bars the table marks
    cfg = ["--config", str(tmp_path / "c" / "em_config.yaml"), "--set", "start_search_s=0", "--set", "max_iterations=2"]
    model = tmp_path / "m" / "model.json"
    run = CliRunner().invoke(cli.app, ["learn", "em", str(tmp_path / "c"), *cfg, "--out", str(model)])
    assert run.exit_code == 0, run.output
    assert "against ground truth" in run.output and "bearing sigma (rad)" in run.output
    assert (tmp_path / "m" / "model_bearing.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert read_landmark_log(tmp_path / "c").title(tmp_path / "c") == "c (MRCLAM_Dataset6 robot 1)"
    run = CliRunner().invoke(
        cli.app,
        ["evaluate", "mrclam", str(MRCLAM), "--model", str(model), "--robot", "1", "--out", str(tmp_path / "e.json")],
    )
    assert run.exit_code == 0, run.output
    score = json.loads((tmp_path / "e.json").read_text())
    assert score["bars"] == bar_checks(score) and len(score["bars"]) == 5
    marks = [
        ln.split()[-2] for ln in run.output.splitlines() if "RMS (mm/s)" in ln or "RMS (rad/s)" in ln or "sigma (" in ln
    ]
    assert marks == [
        "pass" if ok else "miss"
        for ok in (
            score["bars"]["action_translation_ratio"] and score["bars"]["action_translation_abs"],
            score["bars"]["action_rotation_ratio"],
            score["bars"]["range_sigma"],
            score["bars"]["bearing_sigma"],
        )
    ]
    # a model of other commands (wheel speeds) is refused in one line, with how to learn one on the robot
    wheels = model.read_text().replace("v_mm_s", "left_mm_s").replace("omega_rad_s", "right_mm_s")
    (tmp_path / "wheels.json").write_text(wheels)
    run = CliRunner().invoke(cli.app, ["evaluate", "mrclam", str(MRCLAM), "--model", str(tmp_path / "wheels.json")])
    flat = " ".join(run.output.split())
    assert run.exit_code == 2 and "wheels.json: action.command_names:" in flat and "Traceback" not in run.output
    assert f"sensact convert mrclam {MRCLAM} --robot 1 --out DIR" in flat, flat
    # beside the JSON, the four figures `reproduce real` draws per robot; with no EM run to take the
    # smoothed path from, the bearing figure has Vicon's residuals alone, the ones the bar scores
    for kind in ("actions", "range", "heading_noise", "bearing"):
        assert (tmp_path / f"e_{kind}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from sensact.evaluate.landmark_truth import trimmed
    from sensact.report.figures_real import bearing_residuals

    truth, em = bearing_residuals(ml, score)
    assert em is None
    keep = trimmed(truth, 3.0)
    assert np.sqrt(np.mean(truth[keep] ** 2)) == pytest.approx(score["bearing"]["sigma_truth_rad"], rel=1e-9)


@pytest.mark.skipif(not MRCLAM.is_dir(), reason=f"MRCLAM data not found at {MRCLAM}")
def test_mrclam_reader_reads_vicon_rows_in_any_order(tmp_path):
    """Invariant: Vicon's rows are interpolated by time, so a copy of robot 1's files whose ground-truth
    rows run backwards reads the same log and the same truth on the step grid."""
    from sensact.io.mrclam import read_mrclam

    for name in ("Robot1_Odometry.dat", "Robot1_Measurement.dat", "Barcodes.dat", "Landmark_Groundtruth.dat"):
        (tmp_path / name).write_bytes((MRCLAM / name).read_bytes())
    lines = (MRCLAM / "Robot1_Groundtruth.dat").read_text().splitlines()
    header = [ln for ln in lines if ln.startswith("#")]
    rows = [ln for ln in lines if ln.strip() and not ln.startswith("#")]
    (tmp_path / "Robot1_Groundtruth.dat").write_text("\n".join(header + rows[::-1]) + "\n")
    here, there = read_mrclam(MRCLAM, 1), read_mrclam(tmp_path, 1)
    np.testing.assert_array_equal(there.data.obs_step, here.data.obs_step)
    np.testing.assert_array_equal(there.data.step_commands, here.data.step_commands)
    assert there.groundtruth["valid"].mean() > 0.8
    for key in ("x_mm", "y_mm", "theta_rad", "valid"):
        np.testing.assert_array_equal(there.groundtruth[key], here.groundtruth[key])


@pytest.mark.skipif(not MRCLAM.is_dir(), reason=f"MRCLAM data not found at {MRCLAM}")
def test_a_lost_fit_whose_f_bends_without_turning_starts_again_and_finds_its_robot():
    """Real data: robot 4's second quarter of Dataset 6 (as benchmarks/em_real_parts.py cuts it) is lost
    from MRCLAM's start with an f that rises throughout but whose slope changes about threefold; the bend
    check sees it, and the restart from a third of the start sigma finds the robot with a far higher
    likelihood (docs/em-real-results.md, "What you see without ground truth")."""
    from sensact.evaluate.landmark_truth import path_offset
    from sensact.experiments.real import mrclam_config
    from sensact.io.mrclam import read_mrclam
    from sensact.learn.em import initial_model
    from sensact.learn.em.checks import range_function_bends, range_function_turns
    from sensact.learn.em.fit import restart_while_lost

    ml = read_mrclam(MRCLAM, 4)
    a, b = np.linspace(0, ml.data.n_steps, 5).round().astype(int)[1:3]
    part = ml.data.slice_steps(int(a), int(b))
    poses, valid = ml.truth_poses()
    cfg = mrclam_config()
    lost = fit_em(part, None, replace(cfg, turn_restarts=0))
    assert path_offset(lost.posteriors.mean_gamma, poses[a:b], valid[a:b])["median_mm"] > 500.0
    assert range_function_turns(lost.model, lost.posteriors, part) == []
    bent = range_function_bends(lost.model, lost.posteriors, part)
    assert [t["channel"] for t in bent] == ["range_mm"] and bent[0]["slopes"][1] > 2.0 * bent[0]["slopes"][0] > 0
    res = restart_while_lost(part, initial_model(part, cfg), cfg, lost)
    runs = res.restarts
    assert runs[0]["f_turns"] == bent and runs[1]["start_sigma"]["range_mm"] == pytest.approx(100.0 / 3)
    assert runs[1]["kept"] and not runs[1]["f_turns"] and runs[1]["loglik"] > runs[0]["loglik"] + 100.0
    assert path_offset(res.posteriors.mean_gamma, poses[a:b], valid[a:b])["median_mm"] < 300.0


def dataset_with_landmarks(tmp_path: Path, kept: set[int]) -> Path:
    """A copy of Dataset 6 (links to its files) whose map keeps the landmarks ``kept``, as
    ``benchmarks/em_real_landmarks.py`` cuts one (``KEEP:SEED``: numpy.random.default_rng(SEED)'s draw)."""
    copy = tmp_path / MRCLAM.name
    copy.mkdir()
    for f in MRCLAM.iterdir():
        if f.name != "Landmark_Groundtruth.dat":
            (copy / f.name).symlink_to(f.resolve())
    rows = (MRCLAM / "Landmark_Groundtruth.dat").read_text().splitlines()
    rows = [r for r in rows if r.startswith("#") or not r.strip() or int(r.split()[0]) in kept]
    (copy / "Landmark_Groundtruth.dat").write_text("\n".join(rows) + "\n")
    return copy


@pytest.mark.skipif(not MRCLAM.is_dir(), reason=f"MRCLAM data not found at {MRCLAM}")
def test_a_lost_fit_that_never_settles_starts_again_and_finds_its_robot(tmp_path):
    """Real data: Dataset 6 with 8 of its 15 landmarks (``benchmarks/em_real_landmarks.py --maps 8:2``).
    Robot 4 is lost from MRCLAM's start with an f that neither turns nor bends, while its likelihood keeps
    falling far below its best; that sign restarts EM from a third of the start sigma, which finds the
    robot with a far higher likelihood (docs/em-real-results.md, "Fewer landmarks")."""
    from sensact.evaluate.landmark_truth import path_offset
    from sensact.experiments.real import mrclam_config
    from sensact.io.mrclam import read_mrclam
    from sensact.learn.em import initial_model
    from sensact.learn.em.checks import lost_fit_signs
    from sensact.learn.em.fit import restart_while_lost

    copy = dataset_with_landmarks(tmp_path, {7, 8, 9, 10, 12, 16, 19, 20})  # the benchmark's map 8:2
    ml = read_mrclam(copy, 4)
    poses, valid = ml.truth_poses()
    cfg = mrclam_config()
    lost = fit_em(ml.data, None, replace(cfg, turn_restarts=0))
    assert path_offset(lost.posteriors.mean_gamma, poses, valid)["median_mm"] > 500.0
    signs = lost_fit_signs(lost.model, lost.posteriors, ml.data, lost.loglik_history, lost.best_iteration)
    assert [s["sign"] for s in signs] == ["unsettled"] and signs[0]["per_sighting"] > 0.5
    res = restart_while_lost(ml.data, initial_model(ml.data, cfg), cfg, lost)
    runs = res.restarts
    assert runs[0]["f_turns"] == signs and runs[1]["start_sigma"]["range_mm"] == pytest.approx(100.0 / 3)
    assert runs[1]["kept"] and not runs[1]["f_turns"] and runs[1]["loglik"] > runs[0]["loglik"] + 1000.0
    assert path_offset(res.posteriors.mean_gamma, poses, valid)["median_mm"] < 150.0


@pytest.mark.skipif(not MRCLAM.is_dir(), reason=f"MRCLAM data not found at {MRCLAM}")
def test_a_robot_lost_from_the_poor_start_is_found_from_another_robots_model(tmp_path):
    """Real data: Dataset 6 with 6 of its 15 landmarks (``benchmarks/em_real_landmarks.py --maps 6:1``),
    where robot 4 stays lost from the poor start (1169 mm off Vicon; docs/em-real-results.md, "Fewer
    landmarks"). Robot 1's model, learned on the same map from the poor start, places robot 4 on its log,
    and EM learned on from there (learn/em/warm_start.py) finds it (measured 107 mm) and meets every bar."""
    from sensact.experiments.real import evaluate_mrclam, mrclam_config
    from sensact.io.mrclam import read_mrclam
    from sensact.learn.em.warm_start import start_from_model

    copy = dataset_with_landmarks(tmp_path, {6, 8, 10, 11, 15, 18})  # the benchmark's map 6:1
    cfg = mrclam_config()
    source = fit_em(read_mrclam(copy, 1).data, None, cfg)
    ml = read_mrclam(copy, 4)
    placed, warm = start_from_model(source.model, ml.data, cfg)
    res = fit_em(ml.data, placed.model, warm)
    score = evaluate_mrclam(ml, res)
    assert score["path"]["median_mm"] < 200.0, score["path"]
    assert all(score["bars"].values()), score["bars"]


@pytest.mark.skipif(not MRCLAM.is_dir(), reason=f"MRCLAM data not found at {MRCLAM}")
def test_a_short_real_log_finds_its_robot_and_a_lost_fit_says_so_and_starts_again(tmp_path):
    """The first quarter of MRCLAM robot 1 (3.7 minutes) from the poor start: with mrclam_config()'s
    range start sigma EM finds the robot. With the tenfold vaguer start it had before and no restart,
    the first E-step trusts the bearings alone, EM puts the robot metres away and its f turns over; with
    mrclam_config()'s restarts, `learn em` says so, starts again from a third of that sigma, and keeps
    the far more likely fit, which found the robot (docs/em-real-results.md, Short logs)."""
    from typer.testing import CliRunner

    from sensact.config import config_to_yaml
    from sensact.evaluate.landmark_truth import path_offset
    from sensact.experiments.real import mrclam_config
    from sensact.io.landmark_log import write_landmark_log
    from sensact.io.mrclam import read_mrclam
    from sensact.learn.em.checks import range_function_turns

    ml = read_mrclam(MRCLAM, 1)
    stop = ml.data.n_steps // 4
    part = ml.data.slice_steps(0, stop)
    poses, valid = ml.truth_poses()
    res = fit_em(part, None, mrclam_config())
    assert path_offset(res.posteriors.mean_gamma, poses[:stop], valid[:stop])["median_mm"] < 150.0
    assert range_function_turns(res.model, res.posteriors, part) == [] and res.restarts is None
    cfg = mrclam_config()
    vague = replace(cfg, channels=(replace(cfg.channels[0], start_sigma=1000.0),))
    lost = fit_em(part, None, replace(vague, turn_restarts=0))
    assert path_offset(lost.posteriors.mean_gamma, poses[:stop], valid[:stop])["median_mm"] > 1000.0
    assert range_function_turns(lost.model, lost.posteriors, part)[0]["channel"] == "range_mm"
    # the vaguer start with the restarts, through the command a user runs
    gt = {k: v[:stop] for k, v in ml.groundtruth.items()}
    write_landmark_log(tmp_path / "q1", part, groundtruth=gt)
    (tmp_path / "vague.yaml").write_text(config_to_yaml(vague))
    out = tmp_path / "m.json"
    run = CliRunner().invoke(
        cli.app, ["learn", "em", str(tmp_path / "q1"), "--config", str(tmp_path / "vague.yaml"), "--out", str(out)]
    )
    assert run.exit_code == 0, run.output
    flat = " ".join(run.output.split())
    assert "range_mm's f turns over at" in flat and "EM starts again with range_mm's start sigma 333" in flat, flat
    written = json.loads(out.read_text())
    runs = written["summary"]["restarts"]
    assert runs[0]["start_sigma"]["range_mm"] == 1000.0 and runs[0]["f_turns"] and not runs[0]["kept"]
    assert runs[0]["loglik"] == pytest.approx(lost.loglik_best, abs=1e-6)  # the same run, all sightings kept
    kept = next(r for r in runs if r["kept"])
    assert kept["loglik"] > runs[0]["loglik"] + 100.0 and not kept["f_turns"]
    assert written["range_function_turns"] == written["range_function_bends"] == [] and written["em_unsettled"] is None
    assert "EM has probably lost the robot (a local" not in flat
    assert "smoothed path off the recorded poses: median" in flat and written["evaluation"]["path"]["median_mm"] < 150.0
    rng_score = written["evaluation"]["range"]  # lost, f was metres off From-Truth's and its sigma over 3 times
    assert rng_score["learned_vs_from_truth_rms_mm"] < 300.0 and rng_score["sigma_ratio"] < 1.5, rng_score


def test_bar_checks_hold_at_their_edges():
    """Issue 5's bars: ratios up to 1.5 pass, a sigma down to 1/1.5 passes, translation up to 50 mm/s."""
    from sensact.experiments.real import bar_checks

    def score(tr, rot, abs_mm_s, range_ratio, bearing_ratio):
        return {
            "action": {"ratio_translation": tr, "ratio_rotation": rot, "learned": {"translation_rms_mm_s": abs_mm_s}},
            "range": {"sigma_ratio": range_ratio},
            "bearing": {"sigma_ratio": bearing_ratio},
        }

    assert all(bar_checks(score(1.5, 1.5, 50.0, 1.5, 1 / 1.5)).values())
    missed = bar_checks(score(1.51, 1.0, 50.1, 0.66, 1.51))
    assert missed == {
        "action_translation_ratio": False,
        "action_rotation_ratio": True,
        "action_translation_abs": False,
        "range_sigma": False,
        "bearing_sigma": False,
    }


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
    from sensact.evaluate.landmark_truth import at_sensor, fit_sensor_mount

    data, poses = _simulate(2, T=6000)
    at, lm = poses[data.obs_step], data.landmarks_xy[data.obs_landmark]
    assert np.allclose(fit_sensor_mount(at, lm, landmark_bearing(at, lm)), 0.0, atol=1e-6)
    mount = np.array([30.0, 120.0, 0.02])
    noisy = landmark_bearing(at_sensor(at, mount), lm) + np.random.default_rng(3).normal(size=len(at)) * 0.01
    noisy[::50] += 0.5  # outliers the trimming drops
    got = fit_sensor_mount(at, lm, noisy)
    assert got[:2] == pytest.approx(mount[:2], abs=8.0)
    assert got[2] == pytest.approx(mount[2], abs=0.002)


def test_path_offset_reads_a_shift_in_the_truths_robot_frame():
    """Exact reduction: the truth itself is 0 off; the truth moved 80 mm forward and 30 mm right in its
    own frame (sec. 2.5.1: x right, y forward) reads exactly that, and steps without truth are ignored."""
    from sensact.evaluate.landmark_truth import path_offset

    _, poses = _simulate(2, T=600)
    valid = np.ones(len(poses), dtype=bool)
    valid[::7] = False
    assert path_offset(poses, poses, valid) == pytest.approx(
        {"median_mm": 0.0, "right_median_mm": 0.0, "forward_median_mm": 0.0}, abs=1e-9
    )
    shifted = apply_displacement(poses, np.broadcast_to([30.0, 80.0, 0.0], poses.shape))
    shifted[~valid] = 1e9
    off = path_offset(shifted, poses, valid)
    assert off["right_median_mm"] == pytest.approx(30.0) and off["forward_median_mm"] == pytest.approx(80.0)
    assert off["median_mm"] == pytest.approx(math.hypot(30.0, 80.0))


class _TruthLog:
    """What the MRCLAM experiment reads of an ``MrclamLog``: the log and its truth poses."""

    def __init__(self, data: LandmarkLog, poses: np.ndarray):
        self.data, self._poses = data, poses

    def truth_poses(self) -> tuple[np.ndarray, np.ndarray]:
        return self._poses, np.ones(len(self._poses), dtype=bool)


def test_truth_restart_starts_from_from_truths_range_function_and_the_true_start(continuous_fit):
    """Exact reduction: the restart's start is EM's model with only the range function, its bearing
    terms and the prior replaced, by From-Truth's and the truth's first pose. Seeded recovery: From-Truth
    finds the simulated range ``1.05 d + 40``, and EM from there ends on the truth's path with the
    same sightings and a score of its own."""
    from sensact.experiments.real import RESTART_PRIOR_SD, evaluate_mrclam, restart_from_truth, truth_informed_start

    data, poses, res = continuous_fit
    ml = _TruthLog(data, poses)
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

    again = restart_from_truth(ml, res, score, _config())
    assert again["sightings_used"] == again["sightings_used_poor_start"]
    assert again["loglik_poor_start"] == res.loglik_best
    assert again["score"]["path"]["median_mm"] < 60.0
    assert set(again["score"]["bars"]) == set(score["bars"])


def test_truth_residuals_are_taken_at_the_sensor():
    """Seeded recovery: a camera mounted ahead of the truth's origin and yawed reads 0.02-rad bearings
    and 30-mm ranges from where it is; the score finds its mount and those sigmas, while at the truth's
    origin the bearing residual is several times larger. Exact reduction: without the fit, the sensor's
    residuals are the origin's."""
    from sensact.evaluate.landmark_truth import at_sensor, score_against_truth

    data, poses = _simulate(2, T=6000)
    mount = np.array([-20.0, 150.0, 0.03])
    data = _seen_from(data, at_sensor(poses, mount), seed=4)
    model = initial_model(data, _config())
    valid = np.ones(len(poses), dtype=bool)
    sc = score_against_truth(model, data, poses, valid)
    m, b = sc["sensor_mount"], sc["bearing"]
    assert [m["lateral_mm"], m["forward_mm"]] == pytest.approx(mount[:2], abs=8.0)
    assert m["yaw_rad"] == pytest.approx(mount[2], abs=0.002)
    assert b["sigma_truth_rad"] == pytest.approx(0.02, rel=0.05)
    assert sc["range"]["sigma_truth_mm"] == pytest.approx(30.0, rel=0.05)
    assert b["truth_origin_sigma_rad"] > 2 * b["sigma_truth_rad"]
    assert b["truth_origin_sigma_ratio"] == pytest.approx(model.sensor.sigma_bearing_rad / b["truth_origin_sigma_rad"])
    plain = score_against_truth(model, data, poses, valid, fit_mount=False)
    assert plain["bearing"]["sigma_truth_rad"] == plain["bearing"]["truth_origin_sigma_rad"]
    assert plain["sensor_mount"] == {"lateral_mm": 0.0, "forward_mm": 0.0, "yaw_rad": 0.0}
    with console.capture() as out:  # what `learn em` and `evaluate mrclam` print of it
        print_truth_score(sc)
    assert f"sensor pose on the robot, fitted to the truth: {m['forward_mm']:.0f} mm forward" in out.get()
    # the learned Sigma_m's translational random walk over the 30-step windows, beside the truth's miss
    n = sc["truth_noise"]
    assert n["learned_translation_drift_mm"] == pytest.approx(math.sqrt(30) * model.motion_sd[0, :2])
    side, fwd = n["learned_translation_drift_mm"]
    assert f"(Sigma_m: {side:.1f} / {fwd:.1f})" in " ".join(out.get().split())
    # this robot turns nearly all the time: too few straight frames to set its truth's heading against
    # its direction of travel, and the line says nothing of it
    assert n["truth_heading_error"]["frames"] < 20 and math.isnan(n["truth_heading_error"]["variance_rad2"])
    assert "the truth's own heading" not in out.get()


def test_learn_em_on_a_folder_with_recorded_poses_draws_the_figures_against_them(tmp_path, monkeypatch):
    """A log folder whose groundtruth.csv holds poses: `learn em --out` scores the model against them and
    draws what `evaluate mrclam --out` draws, the bearing figure with EM's own path too. The action curves
    read two commands as (forward, turn); with three the other figures are still drawn."""
    from dataclasses import replace

    import matplotlib.pyplot as plt
    from typer.testing import CliRunner

    from sensact.config import config_to_yaml
    from sensact.evaluate.landmark_truth import score_against_truth
    from sensact.io.landmark_log import read_landmark_log, write_landmark_log
    from sensact.report import figures_real
    from sensact.report.figures_real import write_robot

    data, poses = _simulate(5, T=3000)
    gt = {"x_mm": poses[:, 0], "y_mm": poses[:, 1], "theta_rad": poses[:, 2]}
    source = {"source": {"dataset": "/d/Set9", "robot": 4}}
    write_landmark_log(tmp_path / "log", data, groundtruth=gt, meta_extra=source)
    lf = read_landmark_log(tmp_path / "log")
    # figures name the log by its folder, and by where it came from when meta.json's source says
    assert lf.title(tmp_path / "log") == "log (Set9 robot 4)"
    monkeypatch.chdir(tmp_path / "log")
    assert lf.title(".") == "log (Set9 robot 4)"  # run from inside the folder
    assert replace(lf, meta={k: v for k, v in lf.meta.items() if k != "source"}).title(tmp_path / "log") == "log"
    titles: list[str] = []
    save = figures_real._save

    def keep_title(fig, path):
        titles.extend(ax.get_title() for ax in fig.axes)
        return save(fig, path)

    monkeypatch.setattr(figures_real, "_save", keep_title)
    recorded, valid = lf.truth_poses()  # no valid column: every step counts
    np.testing.assert_allclose(recorded, poses, rtol=1e-9, atol=1e-9)
    assert valid.all() and valid.shape == (3000,)
    assert replace(lf, groundtruth={"x_mm": poses[:, 0]}).truth_poses() is None
    (tmp_path / "em.yaml").write_text(config_to_yaml(_config(max_iterations=4)))
    model = tmp_path / "fit" / "model.json"
    run = CliRunner().invoke(
        cli.app, ["learn", "em", str(tmp_path / "log"), "--config", str(tmp_path / "em.yaml"), "--out", str(model)]
    )
    assert run.exit_code == 0, run.output
    assert "against ground truth" in run.output
    said = " ".join(run.output.split())  # one sighting a frame: no within-frame split, said so, not "nan"
    assert "no frame has two sightings" in said and "nan%" not in said and "nan rad" not in said
    doc = json.loads(model.read_text())
    evaluation = doc["evaluation"]
    assert set(evaluation["bars"]) == {
        "action_translation_ratio",
        "action_translation_abs",
        "action_rotation_ratio",
        "range_sigma",
        "bearing_sigma",
    }
    for kind in ("actions", "range", "heading_noise", "bearing"):
        png = tmp_path / "fit" / f"model_{kind}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.name in run.output.replace("\n", "")
    assert titles and all(t.startswith("log (Set9 robot 4): ") for t in titles if t)
    # a third command: a column of action curves for it too
    extra = np.column_stack([data.step_commands, np.random.default_rng(0).normal(size=data.n_steps)])
    data3 = replace(
        data, command_names=(*data.command_names, "tilt"), action_commands=np.zeros((0, 3)), step_commands=extra
    )
    lf3 = replace(lf, data=data3)
    m3 = initial_model(data3, _config())
    n_titles = len(titles)
    paths = write_robot(lf3, m3, score_against_truth(m3, data3, poses, valid), tmp_path / "three", "three")
    assert [p.name for p in paths] == [f"three_{k}.png" for k in ("actions", "range", "heading_noise", "bearing")]
    assert sum(t.endswith(" against tilt") for t in titles[n_titles:]) >= 2
    # the legends and titles name the ground truth as told: Vicon only where it is Vicon
    texts: dict[str, list[str]] = {}

    def keep_text(fig, path):
        texts[path.name] = [ax.get_title() for ax in fig.axes] + [
            t.get_text() for ax in fig.axes for t in ax.get_legend().get_texts()
        ]
        plt.close(fig)
        return path

    monkeypatch.setattr(figures_real, "_save", keep_text)
    fitted = EMModel.from_dict(doc["model"])
    write_robot(lf, fitted, evaluation, tmp_path / "gt", "gt", truth="ground truth")
    write_robot(lf, fitted, evaluation, tmp_path / "vicon", "vicon")
    assert len(texts) == 8
    for name, words in texts.items():
        said = " ".join(words)
        assert ("Vicon" in said) == name.startswith("vicon") and ("ground truth" in said) == name.startswith("gt")
    # one sighting a frame: no sd about a frame's mean (null in the JSON), so no camera line
    assert evaluation["truth_noise"]["bearing_within_frame_sd_rad"] is None
    assert not any("camera's own" in t for t in texts["gt_bearing.png"])


@pytest.mark.parametrize("axle", [0.0, 235.0])
def test_action_curves_draw_each_velocity_against_each_command(axle, monkeypatch):
    """Whatever the commands: a row per velocity either model moves, a column per command. Each curve is
    that velocity along one command with the others at their medians, so an affine model's curve has
    that command's coefficient as its slope and every curve of a row passes through the velocity at the
    medians; the command itself is drawn only where it asks for that velocity outright (v for the
    forward speed, omega for the turn rate; no wheel speed alone)."""
    from dataclasses import replace
    from types import SimpleNamespace

    from sensact.report import figures_real
    from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

    d = simulate_diffdrive(DiffDriveConfig(seconds=60, seed=2, wheel_axle_mm=axle)).log()
    model = initial_model(d, _config())
    rng = np.random.default_rng(1)
    learned, from_truth = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    learned[:, 0] = 0.0  # no sideways motion learned; From-Truth's moves, so it gets a row
    model = replace(model, action=replace(model.action, coefficients=learned))
    drawn = {}
    monkeypatch.setattr(figures_real, "_save", lambda fig, path: drawn.setdefault("fig", fig) and path)
    score = {"action": {"from_truth_coefficients": from_truth.tolist()}}
    figures_real.figure_action_curves(SimpleNamespace(data=d), model, score, Path("a.png"), "t")
    axes = np.asarray(drawn["fig"].axes).reshape(3, 2)
    at_medians = command_features("affine", 1, np.median(d.step_commands, axis=0)[None]) @ np.c_[learned, from_truth]
    for r, j in enumerate([1, 2, 0]):  # forward, turn, sideways
        for i, name in enumerate(d.command_names):
            ax = axes[r, i]
            lines = {ln.get_label(): ln for ln in ax.get_lines()}
            for label, beta, k in (("learned (EM)", learned, j), ("From-Truth (Vicon)", from_truth, 3 + j)):
                x, y = lines[label].get_data()
                np.testing.assert_allclose(np.diff(y) / np.diff(x), beta[1 + i, j], rtol=1e-6, atol=1e-12)
                np.testing.assert_allclose(np.interp(np.median(d.step_commands[:, i]), x, y), at_medians[0, k])
            asks = (name, j) in {("v_mm_s", 1), ("omega_rad_s", 2)}
            assert ("command" in lines) == asks, (name, j)
    assert figures_real.action_panels(("v_x_mm_s", "v_y_mm_s", "v_theta_rad_s"), learned, learned) == [1, 2]
    assert figures_real.action_panels(("a", "v_theta_rad_s", "v_y_mm_s"), from_truth, from_truth) == [2, 1, 0]


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
    from sensact.evaluate.landmark_truth import dead_reckon

    return dead_reckon(v, dt)


def test_turtlebot_table_says_a_sensor_without_bins_is_not_scored():
    """A sensor whose window holds fewer than two distance bins has no span (NaN in memory, null once
    real.json is read back); the table says it was not scored instead of printing "nan", and so for a
    gain that a log at one speed cannot score."""
    from sensact.report.tables_real import real_tables

    sensor = {"rms_pct_of_span": 1.234, "span_mm": 1500.0}
    score = {"gain_learned": 0.9, "gain_true": 0.91, "gain_error_pct": 1.1, "delay_s": 0.12}
    score["sensors"] = {"sonar1": sensor, "raw_ir2": {"rms_pct_of_span": float("nan"), "span_mm": float("nan")}}
    score["sensors"]["raw_ir3"] = {"rms_pct_of_span": None, "span_mm": None}
    ch3 = {"learned_gain": 0.8, "gain_error_pct": 2.0, "sensor_rms_pct": 2.5}
    res = {"turtlebot": {"file": "/data/turtlebot1d/run7.csv", "score": score, "chapter3_sonar1": ch3}}
    (title, _, rows) = next(t for t in real_tables(res) if t[0].startswith("Turtlebot"))
    cells = {r[0]: r[1:] for r in rows}
    assert title.startswith("Turtlebot run7.csv: EM in 1-D")
    assert cells["sonar1 error, % of its span"] == ["1.23 % of its 1500 mm span", "2.50 %"]
    for name in ("raw_ir2", "raw_ir3"):
        not_scored = "not scored (readings in fewer than two 100-mm bins inside its window)"
        assert cells[f"{name} error, % of its span"] == [not_scored, "-"]
    flat = {"rms_pct_of_span": 478.0, "span_mm": 1200.0, "bins": 13, "bins_beyond_span": 1}
    score["sensors"]["raw_ir1"] = flat | {"rms_pct_of_span_within": 11.33}
    (_, _, rows) = next(t for t in real_tables(res) if t[0].startswith("Turtlebot"))
    assert {r[0]: r[1] for r in rows}["raw_ir1 error, % of its span"] == (
        "478.00 % of its 1200 mm span; 11.33 % without the 1 of its 13 bins off by more than the span, "
        "where f is nearly flat and the reading hardly tells the distance"
    )
    gain = "action gain (after the optimal scale)"
    assert cells[gain] == ["0.9000 (truth 0.9100, 1.10 % off)", "0.8000 (2.00 % off)"]
    # a log at one speed: neither gain is scored, each for its own reason
    score |= {"gain_error_pct": None, "one_command_share": 0.978}
    ch3["gain_error_pct"] = None
    (_, _, rows) = next(t for t in real_tables(res) if t[0].startswith("Turtlebot"))
    assert {r[0]: r[1:] for r in rows}[gain] == [
        "0.9000 (not scored: 98 % of the steps at one command)",
        "0.8000 (not scored: no command held for 2 s)",
    ]


@pytest.mark.skipif(not TURTLEBOT.is_file(), reason=f"Turtlebot data not found at {TURTLEBOT}")
def test_turtlebot_em_clears_its_bars(tmp_path):
    from sensact.experiments.turtlebot_em import run_turtlebot_em

    summary, run = run_turtlebot_em(TURTLEBOT)
    assert summary["score"]["gain_error_pct"] < 5.0
    assert summary["score"]["sensors"]["sonar1"]["rms_pct_of_span"] < 3.0
    # raw_ir1's readings stop changing past about 1 m: there f is flat, one bin's error exceeds the span,
    # and without it the sensor scores as its other bins do
    ir1, sonar = summary["score"]["sensors"]["raw_ir1"], summary["score"]["sensors"]["sonar1"]
    assert ir1["bins_beyond_span"] >= 1 and ir1["rms_pct_of_span"] > 100.0 > ir1["rms_pct_of_span_within"]
    assert sonar["bins_beyond_span"] == 0 and sonar["rms_pct_of_span_within"] == sonar["rms_pct_of_span"]
    # `evaluate log` on the real CSVs: on training1.csv the E-step alone places the robot as EM did and scores
    # the model as the run did; on calibration.csv (another run, 98 % at one speed) the gain is not scored
    # and sonar1 still reads the range (7.4 % of the span, measured; the bins past 3 m carry most of it)
    from typer.testing import CliRunner

    model = tmp_path / "tb.json"
    model.write_text(json.dumps({"model": run.result.model.to_dict(), "dt_s": run.data.dt_s}))
    scores = {}
    for csv in (TURTLEBOT, TURTLEBOT.with_name("calibration.csv")):
        out = tmp_path / f"{csv.stem}.json"
        res = CliRunner().invoke(cli.app, ["evaluate", "log", str(csv), "--model", str(model), "--out", str(out)])
        assert res.exit_code == 0, res.output
        scores[csv.stem] = json.loads(out.read_text())["evaluation"]
    own, other = scores[TURTLEBOT.stem], scores["calibration"]
    assert own["gain_learned"] == pytest.approx(summary["score"]["gain_learned"], rel=1e-3)
    assert own["sensors"]["sonar1"]["rms_pct_of_span"] == pytest.approx(sonar["rms_pct_of_span"], abs=0.01)
    assert other["gain_error_pct"] is None and other["one_command_share"] > 0.9
    assert other["sensors"]["sonar1"]["rms_pct_of_span"] < 10.0


@pytest.mark.skipif(not MRCLAM.is_dir(), reason=f"MRCLAM data not found at {MRCLAM}")
def test_mrclam_robot1_from_an_unknown_start(tmp_path):
    """Real data, end to end: robot 1 is lost without the start race and graduated robustness (its
    window score is flat across the grid; Student-t bearings from the start lose it even from the
    true pose), and stops 0.3 m behind the robot without the ridge search. Its action and range bars
    hold in either case and after the truth restart, so those are asserted; its bearing bar is not,
    as it passes only in the poorer basin (docs/em-real-results.md)."""
    from sensact.experiments.real import mrclam_folder, run_mrclam_robot

    row, ml, res = run_mrclam_robot(mrclam_folder(DATA), 1, truth_restart=True)
    for sc in (row["score"], row["truth_restart"]["score"]):
        held = {k: v for k, v in sc["bars"].items() if k != "bearing_sigma"}
        assert all(held.values()), held
    assert len(res.start_search["race"]["rounds"][0]) == 6
    # the report's heading-noise figure draws the learned Sigma_m the score describes
    from sensact.report.figures_real import figure_heading_noise

    a, b = row["score"]["truth_noise"]["learned_heading_variance_per_step"]
    assert a == pytest.approx(res.model.motion_sd[0, 2] ** 2) and b == (res.model.turn_var or 0.0)
    assert figure_heading_noise(ml, res.model, row["score"], tmp_path / "h.png", "robot 1").stat().st_size > 0
    # the bearing figure draws the residuals the bar scores: their trimmed RMS is the bar's truth sigma
    from sensact.evaluate.landmark_truth import trimmed
    from sensact.report.figures_real import bearing_residuals, figure_bearing_noise

    truth, em = bearing_residuals(ml, row["score"], res.posteriors)
    keep = trimmed(truth, 3.0)
    assert np.sqrt(np.mean(truth[keep] ** 2)) == pytest.approx(row["score"]["bearing"]["sigma_truth_rad"], rel=1e-9)
    assert em.size == int((res.posteriors.obs_used & (res.posteriors.weights[:, -1] > 0)).sum()) > 500
    png = figure_bearing_noise(ml, res.model, row["score"], tmp_path / "b.png", "robot 1", res.posteriors)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the held stage ends with the path behind the robot; the ridge search moves it forward along the
    # camera's view at a higher likelihood, and EM ends near the basin that the truth restart finds
    # (without the search: 311 mm off, 282 behind, 324 log-units below the restart)
    ridge = res.ridge[0]
    assert [r["iteration"] - res.freed_at for r in res.ridge] == list(range(0, res.iterations - res.freed_at, 50))
    # (about 0.2 m with the 1000-mm range start sigma of before, 1.0 m with 100 mm: the tighter start
    # trusts the poor line's reading of distance longer, and the line reads the landmarks farther away)
    assert 100.0 < ridge["shift_mm"] < 1500.0 and ridge["loglik_after"] > ridge["loglik_before"] + 20.0
    path = row["score"]["path"]
    assert path["median_mm"] < 150.0 and path["forward_median_mm"] > -150.0
    t = row["truth_restart"]
    assert t["sightings_used"] == t["sightings_used_poor_start"]
    assert t["loglik_best"] - t["loglik_poor_start"] < 100.0
    # `evaluate log` on real folders: on robot 1's own log it scores the model as the run did; robot 1's
    # model on robot 3's log (the same kind of robot) holds the action bars (docs/em-real-results.md, the fleet)
    from typer.testing import CliRunner

    from sensact.io.landmark_log import write_landmark_log
    from sensact.io.mrclam import read_mrclam

    model = tmp_path / "m1.json"
    model.write_text(json.dumps({"model": res.model.to_dict(), "dt_s": ml.data.dt_s}))
    scores = {}
    for robot in (1, 3):
        m = read_mrclam(mrclam_folder(DATA), robot)
        write_landmark_log(tmp_path / f"r{robot}", m.data, groundtruth=m.groundtruth)
        out = tmp_path / f"e{robot}.json"
        run = CliRunner().invoke(
            cli.app, ["evaluate", "log", str(tmp_path / f"r{robot}"), "--model", str(model), "--out", str(out)]
        )
        assert run.exit_code == 0, run.output
        scores[robot] = json.loads(out.read_text())
    for key in ("action", "range", "bearing", "bars"):
        assert scores[1][key] == row["score"][key], key
    held = {k: v for k, v in scores[3]["bars"].items() if k.startswith("action")}
    assert (
        all(held.values())
        and scores[3]["range"]["learned_residual_rms_mm"] > row["score"]["range"]["learned_residual_rms_mm"]
    )
    # `evaluate fleet` on the same two folders: each pair is the `evaluate log` score of it
    from sensact.experiments.fleet import fleet_cell

    out = tmp_path / "fleet.json"
    run = CliRunner().invoke(
        cli.app,
        ["evaluate", "fleet", str(tmp_path / "r1"), str(tmp_path / "r3"), "--model", str(model), "--out", str(out)],
    )
    assert run.exit_code == 0, run.output
    fleet = json.loads(out.read_text())
    assert fleet["own"] == {} and fleet["summary"]["other"]["pairs"] == 2  # model.json names no log
    for robot in (1, 3):
        assert fleet["cells"]["m1"][f"r{robot}"] == json.loads(json.dumps(fleet_cell(scores[robot])))


def test_reproduce_real_runs_every_mrclam_dataset_it_finds(tmp_path):
    """The same command on other datasets: every dataset folder under DATA/mrclam is run, keyed
    by dataset when there are several, with the tables titled and the figures named after them."""
    from dataclasses import replace

    from sensact.experiments.real import mrclam_config, mrclam_datasets, mrclam_row_key, run_real
    from sensact.report import figures_real
    from sensact.report.tables_real import real_tables

    root = tmp_path / "data"
    assert mrclam_datasets(root) == []
    (root / "mrclam" / "notes").mkdir(parents=True)  # a folder without robot files is not a dataset
    assert mrclam_datasets(root) == []
    assert mrclam_row_key(Path("x/MRCLAM_Dataset3"), 2, True) == "MRCLAM_Dataset3/robot2"
    assert mrclam_row_key(Path("x/MRCLAM_Dataset3"), 2, False) == "robot2"
    if not MRCLAM.is_dir():
        pytest.skip(f"MRCLAM data not found at {MRCLAM}")
    for name in ("MRCLAM_Dataset6", "MRCLAM_Dataset9"):
        (root / "mrclam" / name).mkdir()
        for f in MRCLAM.iterdir():
            (root / "mrclam" / name / f.name).symlink_to(f)
    assert [d.name for d in mrclam_datasets(root)] == ["MRCLAM_Dataset6", "MRCLAM_Dataset9"]
    cfg = replace(mrclam_config(), start_search_s=0.0, max_iterations=3)
    (root / "mrclam" / "MRCLAM_Dataset9" / "Robot3_Odometry.dat").unlink()  # a robot missing is skipped
    heard: list[str] = []
    res, art = run_real(root, robots=(2, 3), config=cfg, progress=heard.append)
    # the status line names each robot, then its iterations (no start search here, so no race)
    first = heard.index("MRCLAM MRCLAM_Dataset6/robot2")
    assert re.fullmatch(
        r"MRCLAM MRCLAM_Dataset6/robot2: EM iteration 0, best log-likelihood -?\d+\.\d", heard[first + 1]
    )
    assert sum(m.startswith("MRCLAM MRCLAM_Dataset9/robot2: EM iteration ") for m in heard) == 3
    assert list(res["mrclam"]) == ["MRCLAM_Dataset6/robot2", "MRCLAM_Dataset6/robot3", "MRCLAM_Dataset9/robot2"]
    assert any(s.startswith("MRCLAM MRCLAM_Dataset9/robot3: ") for s in res["skipped"])
    keys = [c["key"] for c in res["scorecard"]]  # every robot's bars, under its row's name
    assert len(keys) == 15 and keys[5] == "MRCLAM_Dataset6/robot3.action_translation_ratio"
    # a dataset with two robots or more gets its fleet table: on its diagonal, each robot's own score
    from sensact.experiments.fleet import fleet_cell

    assert list(res["fleet"]) == ["MRCLAM_Dataset6"]  # Dataset 9 has one robot left
    fleet = res["fleet"]["MRCLAM_Dataset6"]
    assert fleet["models"] == fleet["logs"] == ["robot2", "robot3"] and fleet["own"] == {
        "robot2": "robot2",
        "robot3": "robot3",
    }
    for r in ("robot2", "robot3"):
        assert fleet["cells"][r][r] == fleet_cell(res["mrclam"][f"MRCLAM_Dataset6/{r}"]["score"])
    # and by the likelihood, each model placed on each log as `localize` places it under the learned settings
    from sensact.learn.em.localize import localize

    assert "MRCLAM MRCLAM_Dataset6: each robot's model on every robot's log" in heard
    lk = fleet["likelihood"]["cells"]
    fit = art["mrclam"]["MRCLAM_Dataset6/robot3"][1]
    assert (
        lk["robot3"]["robot2"]["per_sighting"]
        == localize(fit.model, art["mrclam"]["MRCLAM_Dataset6/robot2"][0].data, cfg).loglik_per_sighting
    )
    for g in ("robot2", "robot3"):  # the most likely model on each log is the one 0 below
        assert min(lk[m][g]["below_best"] for m in ("robot2", "robot3")) == 0.0
    del res["mrclam"]["MRCLAM_Dataset6/robot3"], art["mrclam"]["MRCLAM_Dataset6/robot3"]
    assert [r["dataset"] for r in res["mrclam"].values()] == ["MRCLAM_Dataset6", "MRCLAM_Dataset9"]
    # the same log and seed give the same fit under either name
    a, b = (r["em"]["loglik_best"] for r in res["mrclam"].values())
    assert a == b
    assert res["skipped"][-1] == f"Turtlebot: no training*.csv in {root / 'turtlebot1d'}"
    titles = [t[0] for t in real_tables(res)]
    assert titles[0] == "MRCLAM Dataset 6, Dataset 9: learned / From-Truth (ratio)"
    assert any(t.startswith("MRCLAM_Dataset6, each robot's model on every robot's log") for t in titles)
    assert "MRCLAM_Dataset6: log-likelihood a sighting, each model placed on each log" in " ".join(titles)
    paths = figures_real.write_all(art, res, tmp_path)
    assert tmp_path / "real_mrclam_MRCLAM_Dataset9_robot2_range.png" in paths
    assert tmp_path / "real_mrclam_MRCLAM_Dataset9_robot2_bearing.png" in paths
    assert tmp_path / "real_fleet_MRCLAM_Dataset6.png" in paths
    assert all(p.stat().st_size > 0 for p in paths)


def test_reproduce_real_runs_every_turtlebot_training_log_it_finds(tmp_path, monkeypatch):
    """The same command on the course's other training logs: every DATA/turtlebot1d/training*.csv is
    learned and scored with the same bars, training1.csv as real.json's "turtlebot" and the others
    under "turtlebot_more_logs", each with its own bars, table and likelihood line."""
    from sensact.experiments.real import run_real
    from sensact.experiments.shared_data import turtlebot_logs
    from sensact.report import figures_real
    from sensact.report.tables_real import real_tables

    base = tmp_path / "data" / "turtlebot1d"
    base.mkdir(parents=True)
    assert turtlebot_logs(tmp_path / "data") == []
    for name in ("training10.csv", "training2.csv", "training1.csv", "calibration.csv", "training_notes"):
        (base / name).write_text("")
    (base / "training3.csv").mkdir()  # a folder is not a log
    assert [p.name for p in turtlebot_logs(tmp_path / "data")] == ["training1.csv", "training2.csv", "training10.csv"]
    if not TURTLEBOT.is_file():
        pytest.skip(f"Turtlebot data not found at {TURTLEBOT}")
    for f in base.iterdir():
        f.rmdir() if f.is_dir() else f.unlink()
    short = "".join(TURTLEBOT.read_text().splitlines(keepends=True)[:1500])  # about 90 s of the log
    for name in ("training1.csv", "training2.csv"):
        (base / name).write_text(short)
    # a log without the recorded range cannot be scored: one line says so, and the others still run
    rows = [line.split(",") for line in short.splitlines()]
    col = rows[0].index("range")
    (base / "training3.csv").write_text("".join(",".join(r[:col] + r[col + 1 :]) + "\n" for r in rows))
    heard: list[str] = []
    res, art = run_real(tmp_path / "data", progress=heard.append)
    assert f"Turtlebot training3.csv: {base / 'training3.csv'}: range: the log has no recorded range" in "".join(
        res["skipped"]
    )
    assert "Turtlebot EM on training1.csv" in heard and "Turtlebot EM on training2.csv" in heard
    assert Path(res["turtlebot"]["file"]).name == "training1.csv"
    assert list(res["turtlebot_more_logs"]) == ["training2"]
    more = res["turtlebot_more_logs"]["training2"]
    # the same log under either name: the same fit and the same scores
    assert more["em"]["loglik_best"] == res["turtlebot"]["em"]["loglik_best"]
    assert more["score"] == res["turtlebot"]["score"] and "chapter3_sonar1" in more
    keys = [c["key"] for c in res["scorecard"]]
    assert keys == ["turtlebot.gain", "turtlebot.sensor", "turtlebot/training2.gain", "turtlebot/training2.sensor"]
    cards = res["scorecard"]
    assert [c["cleared"] for c in cards[:2]] == [c["cleared"] for c in cards[2:]]
    assert cards[2]["quantity"].startswith("Turtlebot training2: ")
    titles = [t[0] for t in real_tables(res) if t[0].startswith("Turtlebot")]
    assert titles == [
        f"Turtlebot {n}: EM in 1-D against the chapter-3 learner" for n in ("training1.csv", "training2.csv")
    ]
    assert any(s.startswith("MRCLAM: no dataset folder") for s in res["skipped"])
    (tmp_path / "out").mkdir()
    drawn: list[str] = []
    loglik = figures_real.figure_loglik
    monkeypatch.setattr(figures_real, "figure_loglik", lambda runs, path: drawn.extend(runs) or loglik(runs, path))
    paths = figures_real.write_all(art, res, tmp_path / "out")
    # each log's fit against its recorded range, then one likelihood figure with a line per log
    names = ["real_turtlebot_training1.png", "real_turtlebot_training2.png", "real_loglik.png"]
    assert paths == [tmp_path / "out" / n for n in names] and all(p.stat().st_size > 0 for p in paths)
    assert drawn == ["Turtlebot training1", "Turtlebot training2"]
    for name in ("training1.csv", "training2.csv", "training3.csv"):
        (base / name).unlink()
    res, _ = run_real(tmp_path / "data")
    assert "turtlebot" not in res and res["skipped"][-1] == f"Turtlebot: no training*.csv in {base}"


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
