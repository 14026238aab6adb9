"""SQUAREM on EM's map (learn/em/squarem.py): exact reductions of its coordinates and its step, the
deterministic M-step it needs, and the same fixed point as plain EM in fewer E-steps (seeded recovery)."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.learn.em import EMConfig, fit_em, initial_model
from sensact.learn.em.squarem import Coordinates, extrapolate, step_length


@pytest.fixture(scope="module")
def field():
    from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

    cfg = Field2DConfig(seconds=120.0, seed=7)
    run = simulate_field(cfg)
    return cfg, run, to_landmark_log(run)


@pytest.fixture(scope="module")
def learned(field):
    """A model with every part set: a fit's result, its f a cubic with its own centre and scale."""
    _cfg, _run, data = field
    em = EMConfig.of(max_iterations=30, prune_rad_per_step=0.0)
    return fit_em(data, initial_model(data, em), em).model


def test_coordinates_round_trip_exactly(learned, field):
    data = field[2]
    coords = Coordinates.about(learned, data, np.ones(np.size(learned.action.parameters), bool))
    x = coords.vector(learned)
    back = coords.model(x)
    np.testing.assert_allclose(coords.vector(back), x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(back.prior_cov, learned.prior_cov, rtol=1e-12)
    np.testing.assert_allclose(back.motion_sd, learned.motion_sd, rtol=1e-12)
    d = np.linspace(500.0, 4000.0, 7)
    for a, b in zip(back.sensor.channels, learned.sensor.channels, strict=True):
        np.testing.assert_allclose(a.function(d), b.function(d), rtol=1e-10)
        assert a.sigma == pytest.approx(b.sigma, rel=1e-12)


def test_f_is_a_vector_whatever_its_centre_and_scale(learned, field):
    """A refit moves f's centre and scale; its coordinates are its values at the template's knots."""
    from dataclasses import replace

    data = field[2]
    ch = learned.sensor.channels[0]
    f = ch.function
    x = np.linspace(f.center - 2 * f.scale, f.center + 2 * f.scale, 50)
    coef = np.polynomial.polynomial.polyfit((x - f.center - 100.0) / (2 * f.scale), f(x), f.degree)
    moved = replace(f, coef=tuple(coef), center=f.center + 100.0, scale=2 * f.scale)
    other = learned.replace(sensor=replace(learned.sensor, channels=(replace(ch, function=moved),)))
    coords = Coordinates.about(learned, data, np.ones(np.size(learned.action.parameters), bool))
    np.testing.assert_allclose(coords.vector(other), coords.vector(learned), rtol=1e-9, atol=1e-9)


def test_a_step_of_length_one_is_em_s_two_steps():
    rng = np.random.default_rng(0)
    x0, x1, x2 = rng.normal(size=(3, 9))
    np.testing.assert_allclose(extrapolate(x0, x1, x2, 1.0), x2, atol=1e-12)


def test_the_step_length_is_s3_s_clipped():
    x0, x1 = np.zeros(2), np.array([1.0, 0.0])
    x2 = np.array([1.9, 0.0])  # a contraction of 0.9: r = 1, v = -0.1
    assert step_length(x0, x1, x2, 1e6) == pytest.approx(10.0)
    assert step_length(x0, x1, x2, 4.0) == 4.0
    assert step_length(x0, x1, x1 * 2, 4.0) == 1.0  # v = 0: EM's own step
    # on a linear map the step of length 1/(1 - rho) lands on the fixed point
    np.testing.assert_allclose(extrapolate(x0, x1, x2, 10.0), [10.0, 0.0], atol=1e-12)


def test_sigma_points_have_the_posterior_s_mean_and_covariance(field):
    from sensact.learn.em import e_step
    from sensact.learn.em.mstep import sample_gamma

    _cfg, _run, data = field
    em = EMConfig()
    post = e_step(initial_model(data, em), data)
    steps = np.arange(0, data.n_steps, 97)
    pts = sample_gamma(post, steps, 1, np.random.default_rng(0), sigma_points=True)
    assert pts.shape == (6, len(steps), 3)
    again = sample_gamma(post, steps, 1, np.random.default_rng(1), sigma_points=True)
    np.testing.assert_array_equal(pts, again)  # deterministic: the M-step is a map
    np.testing.assert_allclose(pts.mean(axis=0)[:, :2], post.mean_gamma[steps, :2], atol=1e-3)  # mm


def test_settings_refuse_squarem_on_random_draws():
    with pytest.raises(ValueError, match="accelerate=true needs pose_draws=sigma_points"):
        EMConfig.of(accelerate=True, pose_draws="random")
    with pytest.raises(ValueError, match="pose_draws must be one of"):
        EMConfig.of(pose_draws="halton")
    assert not EMConfig().accelerate and not EMConfig().sigma_points  # the thesis's EM by default
    assert EMConfig.of(accelerate=True).sigma_points and EMConfig.of(pose_draws="sigma_points").sigma_points


def test_squarem_reaches_plain_em_s_fixed_point_in_fewer_e_steps(field):
    """Seeded recovery: the same log, the same start, the same deterministic map; SQUAREM's fit is as
    likely as plain EM's (within 1.0, or above) and its model the same to well within the truth's errors."""
    _cfg, run, data = field
    fits = {}
    for accelerate in (False, True):
        em = EMConfig.of(accelerate=accelerate, pose_draws="sigma_points", prune_rad_per_step=0.0, max_iterations=1500)
        fits[accelerate] = fit_em(data, initial_model(data, em), em)
    plain, fast = fits[False], fits[True]
    assert fast.loglik_best >= plain.loglik_best - 1.0
    assert fast.e_steps < 0.7 * plain.e_steps
    v_plain, v_fast = plain.model.action.velocities, fast.model.action.velocities
    err = np.abs(v_plain - run.true_velocities).max(axis=0)
    assert np.all(np.abs(v_fast - v_plain).max(axis=0) <= np.maximum(err, 1e-3))
    assert fast.model.sensor.channels[0].sigma == pytest.approx(plain.model.sensor.channels[0].sigma, rel=0.05)


def test_a_step_s_length_in_the_observed_information_is_exact_on_a_quadratic():
    """Exact reduction: on l(p) = -1/2 (p - m)' A (p - m), a step d's length about any p is sqrt(d' A d)."""
    from types import SimpleNamespace

    from sensact.learn.em.fixed_point import Information

    A, m = np.array([[4.0, 1.0, 0.0], [1.0, 2.0, 0.3], [0.0, 0.3, 1e4]]), np.array([1.0, -5.0, 0.2])

    def loglik(p):
        return -0.5 * float((p - m) @ A @ (p - m))

    p0 = m + np.array([0.3, -2.0, 0.01])  # not at the top: the gradient cancels
    info = Information(SimpleNamespace(p0=p0, loglik=loglik), loglik(p0))
    for d in (np.array([1.0, 0.0, 0.0]), np.array([0.2, -0.7, 1e-3])):
        assert info.length(d) == pytest.approx(np.sqrt(d @ A @ d), rel=1e-9)
    assert info.length(np.zeros(3)) == 0.0


def test_the_rest_of_the_way_is_exact_on_a_linear_contraction():
    """Exact reduction: x_k = r^k x_0 converges to 0; from x_1, its step and the one before give -x_1."""
    from sensact.learn.em.fixed_point import rest_of_the_way

    x0, r = np.array([3.0, -1.0, 0.5]), 0.97
    x1, x2 = r * x0, r * r * x0
    np.testing.assert_allclose(rest_of_the_way(x1 - x0, x2 - x1), -x1, rtol=1e-12)
    assert rest_of_the_way(x1 - x0, 1.01 * (x1 - x0)) is None  # not contracting: not stopped
    assert not np.any(rest_of_the_way(x1 - x0, np.zeros(3)))


@pytest.mark.parametrize("accelerate", [False, True])
def test_the_deterministic_em_stops_at_its_fixed_point(field, accelerate):
    """Invariant: a deterministic EM stopped by the fixed-point rule returns a model that one more EM step
    moves by less than STOP_SD standard errors (its length in the observed information); the summary
    names the rule; the E-step's likelihood is the forward pass's the rule measures with."""
    from functools import partial

    from sensact.learn.em.estep import e_step
    from sensact.learn.em.fixed_point import STOP_SD, Information
    from sensact.learn.em.loop import prior_floor_var, stage_loglik
    from sensact.learn.em.mount import mount_freedom
    from sensact.learn.em.mstep import m_step
    from sensact.learn.em.space import LearnedSpace
    from sensact.learn.em.stage import plan_stages

    _cfg, _run, data = field
    em = EMConfig.of(
        accelerate=accelerate, pose_draws="sigma_points", prune_rad_per_step=0.0, max_iterations=1500, patience=300
    )  # patience only the backstop: the likelihood of EM with an EKF E-step need not climb to the fixed point
    res = fit_em(data, initial_model(data, em), em)
    assert res.stopped_because == "fixed_point" and res.summary()["stopped_because"] == "fixed_point"
    model, used = res.model, res.posteriors.obs_used
    freedom = mount_freedom(model, em.sensor_mount is not None, model.sensor.reads_bearing)
    stage = plan_stages(em, model, freedom)[-1]
    post = e_step(model, data, obs_use=used)
    score = partial(stage_loglik, data=data, obs_use=used, robust=True)
    assert post.loglik == pytest.approx(score(model), abs=1e-9)
    moved = m_step(
        post, data, model, n_samples=1, floor_var=prior_floor_var(em, 3), rng=np.random.default_rng(0),
        stage=stage, sigma_points=True,
    )  # fmt: skip
    info = Information(LearnedSpace.about(model, data, stage.mount, score), post.loglik)
    assert 0 < info.length(info.step(model, moved)) < STOP_SD
