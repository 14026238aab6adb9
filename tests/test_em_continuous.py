"""EM beyond the thesis, on a simulated robot: continuous-command action models (a one-hot basis is the
thesis's table), learned motion noise Sigma_m, bearing terms, several reading channels with windows,
robust readings, and the config's round trips."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from continuous_robot import LANDMARKS, TRUE_BETA, TRUE_SD, continuous_config, simulate_continuous, tiny_track
from sensact.config import config_from_dict
from sensact.core.pose_models import landmark_distance
from sensact.errors import ConfigError
from sensact.learn.em import EMConfig, e_step, fit_em, initial_model
from sensact.learn.em.actions import step_motion_var
from sensact.learn.em.config import ChannelConfig
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.action_table import table_velocities
from sensact.models.em_model import EMModel
from sensact.models.linear_action import LinearActionModel, command_features, delayed, one_hot
from sensact.models.linear_action_fit import linear_coefficients


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
    got = act.update(data, disp, var, 8)
    assert got.delay_steps == best
    np.testing.assert_allclose(got.coefficients, refs[best][1], rtol=1e-8, atol=1e-12)
    for d, (_, ref) in enumerate(refs):
        at_d = act.with_coefficients(act.coefficients, d).update(data, disp, var, 0)
        np.testing.assert_allclose(at_d.coefficients, ref, rtol=1e-8, atol=1e-12)
    # at delay 5 the turn command has no nonzero row: its coefficients are kept
    kept = act.with_coefficients(act.coefficients, 5).update(data, disp, var, 0)
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
        fits[names[0]] = (act, commands, act.update(data, disp, var, 6))
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
    assert cfg.action.inputs == ("v_y_mm_s:v_mm_s",)
    with pytest.raises(ValueError, match="'omega'"):
        LinearActionModel.zero("affine", 1, ("v", "w"), ("a",), inputs=("a:omega",))
    with pytest.raises(ValueError, match=r"action\.inputs"):
        EMConfig.of(action_inputs=("v_y_mm_s:v_mm_s",))  # the table basis has no commands to restrict


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
    data, _ = simulate_continuous(4, beta=beta, bearing_terms=(0.01, -0.02))
    ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0, bearing_degree=2)
    cfg = continuous_config(channels=(ch,), action_zero_mean=("v_x_mm_s",), action_inputs=("v_y_mm_s:v_mm_s",))
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
    plain = fit_em(
        data, None, continuous_config(channels=(ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0),), max_iterations=150)
    )
    assert plain.model.sensor.channels[0].sigma > 2 * chan.sigma


def test_sigma_m_and_bearing_terms_are_held_until_refine_from():
    data, _ = simulate_continuous(4, T=3000, bearing_terms=(0.01, -0.02))
    ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0, bearing_degree=2)
    res = fit_em(
        data, None, continuous_config(channels=(ch,), refine_from=8, max_iterations=12, patience=50, accelerate=False)
    )
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
    data, _ = simulate_continuous(3, T=3000, outlier_frac=0.1)
    ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0, robust="student_t", robust_param=4.0)
    held = fit_em(data, None, continuous_config(channels=(ch,), refine_from=1000, max_iterations=10, accelerate=False))
    w = held.posteriors.weights[:, 0]
    assert set(np.unique(w[w > 0])) == {1.0}
    freed = fit_em(
        data, None, continuous_config(channels=(ch,), refine_from=5, max_iterations=15, patience=50, accelerate=False)
    )
    w = freed.posteriors.weights[:, 0]
    assert held.freed_at == -1 and freed.freed_at == 5
    assert freed.best_iteration > 5 and w.min() < 0.05  # the best model is one scored by the robust likelihood


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


def test_sideways_motion_noise_starts_apart_from_the_forward():
    """Exact: the sideways start replaces Sigma_m's x entry only (0 leaves motion_sd_mm), a fixed
    Sigma_m keeps it through EM, and it is refused where it means nothing (a track) or is negative."""
    data, _ = simulate_continuous(2, T=600)
    same = initial_model(data, continuous_config())
    apart = initial_model(data, continuous_config(motion_sd_sideways_mm=0.5))
    assert same.motion_sd.tolist() == [[10.0, 10.0, 0.05]]
    assert apart.motion_sd.tolist() == [[0.5, 10.0, 0.05]]
    fixed = fit_em(data, None, continuous_config(motion_noise="fixed", motion_sd_sideways_mm=0.5, max_iterations=2))
    assert fixed.model.motion_sd.tolist() == [[0.5, 10.0, 0.05]]
    with pytest.raises(ValueError, match=r"motion_noise\.sideways_mm must be > 0, or null"):
        continuous_config(motion_sd_sideways_mm=-1.0)
    with pytest.raises(ConfigError, match=r"t\.csv: motion_noise\.sideways_mm: .* a track has no sideways"):
        fit_em(tiny_track(), None, EMConfig.of(motion_sd_sideways_mm=0.5))


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
    data, _ = simulate_continuous(6, beta=beta, sd=sd, turn_var=2e-3)
    # the sensor sits at the robot's point here, and is held there: learned, the mount takes up some of the
    # forward noise (Sigma_m's forward sd 7.8 mm for 5; docs/em.md, "The sensor's mount")
    held = {"action_zero_mean": ("v_x_mm_s",), "sensor_mount": (0.0, 0.0, 0.0)}
    res = fit_em(data, None, continuous_config(motion_noise="turning", **held))
    m = res.model
    assert m.turn_var == pytest.approx(2e-3, rel=0.2)
    assert m.motion_sd[0, 2] == pytest.approx(0.01, rel=0.2)
    np.testing.assert_allclose(m.motion_sd[0, :2], sd[:2], rtol=0.2)
    shared = fit_em(data, None, continuous_config(max_iterations=150, **held))
    assert res.loglik_best > shared.loglik_best + 20  # the data tell the two apply

    data0, _, fitted = continuous_fit
    plain = fitted.model
    zero = plain.replace(turn_var=0.0)
    np.testing.assert_array_equal(step_motion_var(zero, data0), step_motion_var(plain, data0))
    assert e_step(zero, data0).loglik == e_step(plain, data0).loglik
    again = EMModel.from_dict(m.to_dict())
    assert again.turn_var == m.turn_var and plain.to_dict()["turn_var"] is None


def test_turning_noise_needs_a_planar_shared_model():
    track = tiny_track()
    with pytest.raises(ConfigError, match=r"motion_noise\.kind: .* a track has no heading"):
        initial_model(track, EMConfig.of(motion_noise="turning"))
    data, _ = simulate_continuous(1, T=300)
    m = initial_model(data, continuous_config(motion_noise="turning"))
    assert m.turn_var == 0.0
    with pytest.raises(ValueError, match="turn_var must be >= 0"):
        m.replace(turn_var=-1.0)


def test_per_action_noise_learns_one_row_per_action():
    from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

    data = to_landmark_log(simulate_field(Field2DConfig(seconds=120.0, seed=2)))
    cfg = EMConfig.of(motion_noise="per_action", prune_rad_per_step=0.0, max_iterations=30, refine_from=0)
    res = fit_em(data, None, cfg)
    sd = res.model.motion_sd
    assert sd.shape == (data.n_actions, 3) and np.all(sd >= [0.05, 0.05, 5e-4])
    assert np.ptp(sd[:, 0]) > 0  # the rows are learned separately


def test_student_t_makes_outliers_harmless():
    """With 10 % gross range outliers a Gaussian channel's sigma balloons; Student-t keeps the inliers'."""
    data, _ = simulate_continuous(3, T=6000, outlier_frac=0.1)
    ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0)
    gauss = fit_em(data, None, continuous_config(channels=(ch,), max_iterations=120))
    robust_ch = ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0, robust="student_t", robust_param=4.0)
    robust = fit_em(data, None, continuous_config(channels=(robust_ch,), max_iterations=120))
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
        EMConfig.of(action_basis="affine", motion_noise="per_action")


def test_a_config_written_in_a_model_json_reads_back_exactly(tmp_path):
    """Exact round trip of the config a model.json holds (`summary.config`, which `learn em --start-from`
    reads): JSON has no infinity, so a channel's open window is written as null and read back as the
    default it was; a null for a float field whose default is finite stays an error naming the field."""
    from dataclasses import asdict

    from sensact.io.atomic import write_json
    from sensact.presets import mrclam_config, turtlebot_em_config

    for cfg in (mrclam_config(), turtlebot_em_config(), EMConfig.of(), EMConfig().replace(warm_start=True)):
        write_json(tmp_path / "m.json", {"config": asdict(cfg)})
        assert config_from_dict(EMConfig, json.loads((tmp_path / "m.json").read_text())["config"]) == cfg
    assert json.loads((tmp_path / "m.json").read_text())["config"]["search"]["warm_start"] is True
    write_json(tmp_path / "t.json", asdict(turtlebot_em_config()))
    sonar = json.loads((tmp_path / "t.json").read_text())["channels"][0]
    assert sonar["valid_min"] is None and sonar["valid_max"] is None  # written as nulls, read back as +-inf
    with pytest.raises(ConfigError, match="start_sigma: expected float, got None"):
        config_from_dict(ChannelConfig, {"name": "x", "start_sigma": None}, source="m.json: channels")


def test_a_config_written_as_yaml_reads_back_exactly(tmp_path):
    """Exact round trip of the YAML `convert mrclam` writes: only the fields that differ from the
    defaults (a channel's infinite window left out), and `build_config` gives the same config back."""
    from sensact.config import build_config, config_to_yaml
    from sensact.presets import mrclam_config, turtlebot_em_config

    for cfg in (mrclam_config(), turtlebot_em_config(), EMConfig()):
        text = config_to_yaml(cfg, "first line\nsecond line")
        assert text.startswith("# first line\n# second line\n")
        (tmp_path / "c.yaml").write_text(text)
        assert build_config(EMConfig, tmp_path / "c.yaml") == cfg
    text = config_to_yaml(mrclam_config())
    assert "ridge_mm: 500.0" in text and "inf" not in text and "patience" not in text
    assert config_to_yaml(EMConfig()) == ""  # nothing differs from the defaults
