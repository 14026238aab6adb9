"""learn.bootstrap (sec. 3.2, Algorithm 1): exact reductions, an independent reference, recovery, invariants."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sensact.core.polyfit import weighted_polyfit
from sensact.evaluate.track1d import score_track_models
from sensact.learn.bootstrap import (
    BootstrapConfig,
    BootstrapLearner,
    Normalization,
    learn_action_from_sensor,
    learn_bootstrap,
    learn_sensor_from_action,
)
from sensact.models.polynomial import Polynomial1D
from sensact.sim.track1d import Track1DConfig, simulate_track

GRID_C = np.linspace(-300, 300, 13)


def literal_algorithm_1(t, c, o, cfg: BootstrapConfig, a0=lambda c: c):
    """Algorithm 1 as printed (window 1), with every regression redone by batch weighted lstsq.

    Deliberately naive and independent of the compiled code: it keeps all data points and re-solves
    eq. 3.3 from scratch with weights gamma^(n-i) at every observation.
    """
    d_s, d_a, g = cfg.sensor_degree, cfg.action_degree, cfg.gamma
    k0 = int(np.flatnonzero(c != 0)[0])  # the clock starts at the first command (Algorithm 1's robot moves)
    t, c, o = t[k0:], c[k0:], o[k0:]
    w_a, t0 = 0.0, t[0]
    s_x, s_y, a_X, a_y = [], [], [], []
    S = A = None
    cum = np.zeros(d_a + 1)
    for k in range(len(t)):
        if k > 0:
            dt = t[k] - t[k - 1]
            use_a0 = (t[k - 1] - t0) < 2 * cfg.t_start_s or A is None
            w_a += (a0(c[k - 1]) if use_a0 else np.polyval(A[::-1], c[k - 1])) * dt
            cum += c[k - 1] ** np.arange(d_a + 1) * dt  # eq. 3.2 regressors
        if not np.isfinite(o[k]):
            continue
        if t[k] - t0 > cfg.t_start_s and S is not None:
            w_s = np.polyval(S[::-1], o[k])
            a_X.append(np.r_[1.0, cum])
            a_y.append(w_s)
            if len(a_y) >= d_a + 2:
                X, y = np.array(a_X), np.array(a_y)
                sw = np.sqrt(g ** (len(y) - 1 - np.arange(len(y))))
                beta, *_ = np.linalg.lstsq(X * sw[:, None], y * sw, rcond=None)
                A = beta[1:]
            w_a = (1 - cfg.alpha) * w_a + cfg.alpha * w_s
        s_x.append(o[k])
        s_y.append(w_a)
        if len(s_y) >= d_s + 1:
            n = len(s_y)
            S = weighted_polyfit(np.array(s_x), np.array(s_y), d_s, g ** (n - 1 - np.arange(n)))
    return S, A


def test_compiled_algorithm_1_equals_the_literal_reference(short_run):
    """Independent reference: the compiled learner with window 1 is Algorithm 1, step for step."""
    r = short_run
    k = 700  # 35 s: through both ramp-up phases and into mutual learning
    cfg = BootstrapConfig(observation_window=1, t_start_s=10.0, ridge=0.0)
    res = learn_bootstrap(r.times_s[:k], r.commands_mm_s[:k], r.heights_px[:k], cfg)
    S, A = literal_algorithm_1(r.times_s[:k], r.commands_mm_s[:k], r.heights_px[:k], cfg)
    o = np.linspace(11, 30, 9)
    np.testing.assert_allclose(res.sensor(o), np.polyval(S[::-1], o), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(res.action(GRID_C), np.polyval(A[::-1], GRID_C), rtol=1e-6, atol=1e-6)


def test_batch_and_streaming_are_identical(short_run):
    r = short_run
    cfg = BootstrapConfig(auto_sensor_degree=True, degree_warmup_s=5.0, degree_eval_s=5.0)
    norm = Normalization.from_data(r.commands_mm_s, r.heights_px, cfg)
    batch = learn_bootstrap(r.times_s, r.commands_mm_s, r.heights_px, cfg, normalization=norm)
    stream = BootstrapLearner(cfg, normalization=norm)
    for t, c, o in zip(r.times_s, r.commands_mm_s, r.heights_px, strict=True):
        stream.update(t, c, None if np.isnan(o) else o)
    out = stream.result()
    assert out.sensor.coef == batch.sensor.coef  # bit-identical
    assert out.action.coef == batch.action.coef
    assert (out.status, out.sensor_degree, out.n_observations) == (
        batch.status,
        batch.sensor_degree,
        batch.n_observations,
    )
    assert stream.w_a == batch.history.w_a[-1]


def _held_still_first(r, seconds: float):
    """``r`` with the robot held still (command 0, its first reading again, with noise) for ``seconds`` first."""
    dt = float(np.median(np.diff(r.times_s)))
    n = int(seconds / dt)
    rng = np.random.default_rng(3)
    first = r.heights_px[np.isfinite(r.heights_px)][0]
    t = np.r_[r.times_s[0] - dt * np.arange(n, 0, -1), r.times_s]
    c = np.r_[np.zeros(n), r.commands_mm_s]
    o = np.r_[first + rng.normal(0.0, 0.3, n), r.heights_px]
    return t, c, o, n


def test_the_clock_starts_at_the_first_command(short_run):
    """Exact reduction: a robot held still for 50 s before it is first commanded learns, bit for bit, what it
    learns from its first command on (before, S learned every idle reading as w_a = 0 and A_t stayed at zero,
    reported "ok"); the streaming learner waits alike; a log never commanded is refused."""
    r = short_run
    assert r.commands_mm_s[0] != 0.0
    cfg = BootstrapConfig(t_start_s=20.0)
    t, c, o, n = _held_still_first(r, 50.0)
    norm = Normalization.from_data(r.commands_mm_s, r.heights_px, cfg)
    moved = learn_bootstrap(r.times_s, r.commands_mm_s, r.heights_px, cfg, normalization=norm)
    held = learn_bootstrap(t, c, o, cfg, normalization=norm)
    assert held.sensor.coef == moved.sensor.coef and held.action.coef == moved.action.coef
    assert held.n_observations == moved.n_observations and held.status == "ok"
    assert np.all(np.isnan(held.history.w_a[:n])) and np.array_equal(held.history.w_a[n:], moved.history.w_a)
    stream = BootstrapLearner(cfg, normalization=norm)
    for tk, ck, ok in zip(t, c, o, strict=True):
        stream.update(tk, ck, ok)
    assert stream.result().sensor.coef == moved.sensor.coef
    with pytest.raises(ValueError, match="every command is zero"):
        learn_bootstrap(t[:n], c[:n], o[:n], cfg)


def test_a_zero_innovation_scale_does_not_shut_the_outlier_gate(short_run):
    """Invariant: the gate's scale of zero (S fitted exactly to a w_a held at zero by a robot standing still)
    gates nothing; it had gated every later reading, so S stayed flat."""
    r = short_run
    t, c, o, _ = _held_still_first(r, 50.0)
    action = Polynomial1D((0.0, 1.0), 0.0, 1.0)  # A(c) = c: w_a stays 0 while the robot stands
    cfg = BootstrapConfig(t_start_s=20.0)
    free = learn_sensor_from_action(t, c, o, action, cfg)
    gated = learn_sensor_from_action(t, c, o, action, dataclasses.replace(cfg, outlier_gate=3.0))
    grid = np.linspace(11, 30, 9)
    assert np.ptp(free.sensor(grid)) > 1000.0  # mm: S reads the walk
    assert gated.n_gated < 0.05 * gated.n_observations
    np.testing.assert_allclose(gated.sensor(grid), free.sensor(grid), rtol=0.05, atol=0.02 * np.ptp(free.sensor(grid)))


def test_streaming_without_normalization_learns_the_same_models(short_run):
    """Normalization is conditioning only: models agree to rounding whatever scales are used."""
    r = short_run
    batch = learn_bootstrap(r.times_s, r.commands_mm_s, r.heights_px)
    stream = BootstrapLearner()
    for t, c, o in zip(r.times_s, r.commands_mm_s, r.heights_px, strict=True):
        stream.update(t, c, o)
    np.testing.assert_allclose(
        stream.sensor_model(np.linspace(11, 30, 9)), batch.sensor(np.linspace(11, 30, 9)), rtol=1e-5
    )
    np.testing.assert_allclose(stream.action_model(GRID_C), batch.action(GRID_C), rtol=1e-5, atol=1e-6)


def test_sensor_from_constant_action_is_regression_on_time(short_run):
    """Sec. 3.2.1: with A = 1, no forgetting and window 1 the learner fits (o_t, t)."""
    r = short_run
    cfg = BootstrapConfig(gamma=1.0, observation_window=1, ridge=0.0)
    res = learn_sensor_from_action(r.times_s, r.commands_mm_s, r.heights_px, None, cfg)
    m = np.isfinite(r.heights_px)
    ref = weighted_polyfit(r.heights_px[m], r.times_s[m] - r.times_s[0], 3)
    o = np.linspace(11, 30, 9)
    np.testing.assert_allclose(res.sensor(o), np.polyval(ref[::-1], o), rtol=1e-8, atol=1e-8)


def test_action_from_sensor_solves_eq_3_2(short_run):
    """Sec. 3.2.2: the learned A is the weighted lstsq of eq. 3.2 with cumulative command powers."""
    r = short_run
    truth = r.truth
    c_fit = np.linspace(10, 32, 40)
    sensor = Polynomial1D(tuple(weighted_polyfit(c_fit, -truth.distance_mm(c_fit), 3, center=20, scale=10)), 20, 10)
    cfg = BootstrapConfig(observation_window=1, ridge=0.0)
    res = learn_action_from_sensor(r.times_s, r.commands_mm_s, r.heights_px, sensor, cfg)
    t, c, o = r.times_s, r.commands_mm_s, r.heights_px
    dt = np.diff(t)
    cum = np.vstack([np.zeros(5), np.cumsum((c[:-1, None] ** np.arange(5)) * dt[:, None], axis=0)])
    m = np.isfinite(o)
    X = np.column_stack([np.ones(m.sum()), cum[m]])
    y = sensor(o[m])
    sw = np.sqrt(cfg.gamma ** (m.sum() - 1 - np.arange(m.sum())))
    beta, *_ = np.linalg.lstsq(X * sw[:, None], y * sw, rcond=None)
    np.testing.assert_allclose(res.action(GRID_C), np.polyval(beta[1:][::-1], GRID_C), rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_recovers_the_simulated_models(seed):
    """Seeded recovery: thesis defaults on a 150 s trial give both models within a stated tolerance."""
    run = simulate_track(Track1DConfig(seconds=150.0, seed=seed))
    res = learn_bootstrap(run.times_s, run.commands_mm_s, run.heights_px)
    sc = score_track_models(res.sensor, res.action, run.truth)
    assert res.status == "ok"
    assert sc.sensor_rms < 110.0  # mm; the best cubic is 14.5
    assert sc.action_rms < 40.0  # mm/s; the best quartic is 17.4, A0 is 41.7
    assert sc.consistency < 0.12


def test_constant_start_also_recovers():
    run = simulate_track(Track1DConfig(seconds=300.0, seed=4))
    res = learn_bootstrap(run.times_s, run.commands_mm_s, run.heights_px, BootstrapConfig(a0="constant"))
    sc = score_track_models(res.sensor, res.action, run.truth)
    assert sc.sensor_rms < 150.0 and sc.action_rms < 45.0


def test_a0_names_match_their_callables(short_run):
    r = short_run
    for name, fn in (("linear", lambda c: c), ("sign", np.sign), ("constant", lambda c: 1.0)):
        a = learn_bootstrap(r.times_s, r.commands_mm_s, r.heights_px, BootstrapConfig(a0=name))
        b = learn_bootstrap(r.times_s, r.commands_mm_s, r.heights_px, BootstrapConfig(a0="linear"), a0=fn)
        assert a.sensor.coef == b.sensor.coef and a.action.coef == b.action.coef


def test_non_finite_input_ends_the_run_as_diverged_with_finite_models(short_run):
    r = short_run
    obs = r.heights_px.copy()
    obs[900] = np.inf  # a corrupt reading at 45 s
    res = learn_bootstrap(r.times_s, r.commands_mm_s, obs)
    assert res.status == "diverged"
    assert res.diverged_at_s == pytest.approx(r.times_s[900] - r.times_s[0])
    assert res.sensor.is_finite() and res.action.is_finite()


def test_runaway_is_detected():
    run = simulate_track(Track1DConfig(seconds=120.0, seed=5))
    # any factor below 1 must trip once A_t takes over at 2 t_start
    res = learn_bootstrap(run.times_s, run.commands_mm_s, run.heights_px, BootstrapConfig(divergence_factor=0.5))
    assert res.status == "diverged" and res.diverged_at_s >= 2 * BootstrapConfig().t_start_s
    assert res.sensor.is_finite() and res.action.is_finite()
    h = res.history
    assert np.all(np.isnan(h.w_a[h.times_s - h.times_s[0] > res.diverged_at_s + 1e-9]))


def test_models_are_scale_free_in_the_command_unit(short_run):
    """Invariant: commands in m/s instead of mm/s give the same S and the same A(c) after unit change."""
    r = short_run
    cfg = BootstrapConfig(a0="sign")
    mm = learn_bootstrap(r.times_s, r.commands_mm_s, r.heights_px, cfg)
    m = learn_bootstrap(r.times_s, r.commands_mm_s / 1000.0, r.heights_px, cfg)
    o = np.linspace(11, 30, 9)
    np.testing.assert_allclose(m.sensor(o), mm.sensor(o), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(m.action(GRID_C / 1000.0), mm.action(GRID_C), rtol=1e-6, atol=1e-6)


def test_auto_degree_on_the_simulated_sensor_exceeds_linear():
    from sensact.experiments.track1d import best_action_polynomial

    run = simulate_track(Track1DConfig(seconds=300.0, seed=6))
    cfg = dataclasses.replace(BootstrapConfig(), auto_sensor_degree=True)
    res = learn_sensor_from_action(
        run.times_s, run.commands_mm_s, run.heights_px, best_action_polynomial(run.truth), cfg
    )
    assert 3 <= res.sensor_degree <= cfg.degree_max
    assert np.all(np.diff(res.history.snapshot_sensor_degree) >= 0)


def test_config_rejects_bad_values():
    with pytest.raises(ValueError, match="gamma"):
        BootstrapConfig(gamma=1.5)
    with pytest.raises(ValueError, match="observation_window"):
        BootstrapConfig(observation_window=0)
    with pytest.raises(ValueError, match="strictly increasing"):
        learn_bootstrap(np.array([0.0, 0.0, 1.0]), np.zeros(3), np.ones(3))


def test_errors_in_variables_justify_the_observation_window():
    """Why observation_window defaults to 20 (docs/bootstrap.md): regressing the *true* distance on the
    noisy height is already biased by ~0.1 m at the thesis grid; averaging the window removes most of it."""
    from sensact.evaluate.track1d import measured_models

    raw, windowed = [], []
    for seed in range(3):
        run = simulate_track(Track1DConfig(seconds=150.0, seed=seed))
        m = measured_models(run.truth)
        h = run.heights_px
        for obs, out in ((h, raw), (np.convolve(h, np.ones(20) / 20, mode="same"), windowed)):
            coef = weighted_polyfit(obs[20:-20], run.distance_mm[20:-20], 3, center=20.0, scale=10.0)
            fit = Polynomial1D(tuple(coef), 20.0, 10.0)
            out.append(np.sqrt(np.mean((fit(m.heights_px) - m.distances_mm) ** 2)))
    assert np.mean(raw) > 70.0  # more than the thesis's whole error budget (70.4 mm), before any learning
    assert np.mean(windowed) < 0.5 * np.mean(raw)


def test_the_figures_velocity_of_w_s_is_each_windows_least_squares_slope():
    from sensact.report.figures_bootstrap import _velocity_of_w_s

    t = np.arange(200) * 0.05
    w = np.where(t < 5.0, 3.0 * t + 1.0, -2.0 * t + 26.0)  # a turn at 5 s, continuous
    w[::4] = np.nan  # steps without an observation
    w[120:150] = np.nan  # 1.5 s without any: the windows there hold fewer than three
    v = _velocity_of_w_s(t, w, window_s=1.02)  # edges between samples: a window is 21 steps
    np.testing.assert_allclose(v[20:90], 3.0, rtol=1e-10)  # windows before the turn
    np.testing.assert_allclose(v[111:119], -2.0, rtol=1e-10)
    assert np.isnan(v[130:140]).all()
    i = 100  # a window across the turn: numpy's own least squares on the same points
    near = (np.abs(t - t[i]) < 0.51) & np.isfinite(w)
    assert v[i] == pytest.approx(np.polyfit(t[near], w[near], 1)[0], rel=1e-9)
