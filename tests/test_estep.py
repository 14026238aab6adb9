"""The E-step (sec. 4.2) against exact and independent references (DESIGN.md oracles 1, 2 and 4)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from reference_ekf import reference_ekf
from sensact.core.pose_models import landmark_bearing, landmark_distance
from sensact.learn.em import e_step, initial_model, log_likelihood
from sensact.learn.em.config import EMConfig
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.landmark_sensor import LandmarkSensor, ReadingChannel
from sensact.models.polynomial import Polynomial1D

SM = 10.0  # motion sd per step, mm


def _linear_track(T=40, seed=1):
    """A 1-D track with a straight-line f: exactly linear-Gaussian, so the EKF smoother must be exact."""
    rng = np.random.default_rng(seed)
    dt = 0.1
    acts = rng.integers(0, 3, T)
    vel = np.array([[100.0], [-50.0], [0.0]])
    d = np.empty(T)
    d[0] = 2000 + rng.normal() * 100
    for t in range(T - 1):
        d[t + 1] = d[t] - vel[acts[t], 0] * dt + rng.normal() * SM
    steps = np.sort(rng.choice(T, 25, replace=False))
    f = Polynomial1D((20.0, -3.0), 2000.0, 500.0)
    y = f(d[steps]) + rng.normal(size=steps.size) * 1.5
    data = LandmarkLog(
        "track",
        dt,
        acts,
        [[1.0], [-1.0], [0.0]],
        ("c",),
        steps,
        np.zeros(steps.size, int),
        y,
        np.full(steps.size, np.nan),
        np.zeros((1, 2)),
    )
    m0 = initial_model(data, EMConfig.of(motion_sd_mm=SM))
    model = m0.replace(
        action=m0.action.with_velocities(vel),
        sensor=LandmarkSensor.single(f, 1.5, None),
        prior_mean=np.array([2000.0]),
        prior_cov=np.array([[100.0**2]]),
    )
    # the dense joint Gaussian of all states and observations
    u = np.array([vel[a, 0] * dt for a in acts[:-1]])
    mu = 2000 - np.concatenate([[0], np.cumsum(u)])
    idx = np.arange(T)
    S = 100.0**2 + SM**2 * np.minimum.outer(idx, idx)
    H = np.zeros((steps.size, T))
    H[np.arange(steps.size), steps] = -3 / 500
    b = 20 + (-3 / 500) * (-2000)
    return data, model, y, mu, S, H, b, steps


def _condition(mu, S, H, b, y, R):
    Sy = H @ S @ H.T + R
    K = S @ H.T @ np.linalg.inv(Sy)
    return mu + K @ (y - H @ mu - b), S - K @ H @ S, Sy


def test_linear_gaussian_smoother_is_exact():
    data, model, y, mu, S, H, b, steps = _linear_track()
    post = e_step(model, data, np.array([SM**2]))
    assert post.ok
    R = 1.5**2 * np.eye(y.size)
    mp, Sp, Sy = _condition(mu, S, H, b, y, R)
    # eq. 4.14 against the dense marginal likelihood of every observation
    assert post.loglik == pytest.approx(multivariate_normal(H @ mu + b, Sy).logpdf(y), abs=1e-9)
    # gamma (eqs. 4.9-4.10) equals the exact smoothed marginals
    np.testing.assert_allclose(post.mean_gamma[:, 0], mp, atol=1e-8)
    np.testing.assert_allclose(post.cov_gamma[:, 0, 0], np.diag(Sp), atol=1e-7)
    # xi (eqs. 4.11-4.12): mean and variance of D(w_t, w_t+1) = w_t - w_t+1 under the exact pairwise posterior
    np.testing.assert_allclose(post.disp_mean[:, 0], mp[:-1] - mp[1:], atol=1e-8)
    var = np.diag(Sp)[:-1] + np.diag(Sp)[1:] - 2 * np.diag(Sp, 1)
    np.testing.assert_allclose(post.disp_cov[:, 0, 0], var, atol=1e-7)
    # alpha: the filter at t conditions on the observations up to t only
    for t in (0, 7, 20, 39):
        k = steps <= t
        ma, Sa, _ = _condition(mu, S, H[k], b, y[k], R[np.ix_(k, k)])
        assert post.mean_alpha[t, 0] == pytest.approx(ma[t], abs=1e-8)
        assert post.cov_alpha[t, 0, 0] == pytest.approx(Sa[t, t], abs=1e-7)


def _planar_case(T=300, seed=3):
    from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

    cfg = Field2DConfig(seconds=(T - 1) * 0.05, seed=seed)
    run = simulate_field(cfg)
    data = to_landmark_log(run)
    d = np.linspace(1000, 4500, 100)
    coef = np.polyfit((d - 2700) / 1000, cfg.height_px(d), 3)[::-1]
    m0 = initial_model(data, EMConfig())
    model = m0.replace(
        action=m0.action.with_velocities(run.true_velocities),
        sensor=LandmarkSensor.single(Polynomial1D(tuple(coef), 2700.0, 1000.0), 1.0, 0.5),
        prior_cov=np.diag([50.0**2, 50.0**2, 0.05**2]),
    )
    return run, data, model


def test_planar_forward_pass_matches_an_independent_ekf():
    _run, data, model = _planar_case()
    var = np.array([100.0, 100.0, 0.01])
    post = e_step(model, data, var)
    means, ll = reference_ekf(model, data, var)
    np.testing.assert_allclose(post.mean_alpha, means, atol=1e-4)
    assert post.loglik == pytest.approx(ll, rel=1e-8)


def test_planar_posteriors_are_valid_and_informative():
    run, data, model = _planar_case(T=1200)
    post = e_step(model, data, np.array([100.0, 100.0, 0.01]))
    for name in ("cov_alpha", "cov_gamma", "disp_cov"):
        C = getattr(post, name)
        np.testing.assert_allclose(C, np.swapaxes(C, 1, 2), atol=1e-9, err_msg=name)
        assert np.all(np.linalg.eigvalsh(C) > 0), name
    # smoothing never adds uncertainty, and it tracks the true poses better than filtering
    assert np.all(np.trace(post.cov_gamma, axis1=1, axis2=2) <= np.trace(post.cov_alpha, axis1=1, axis2=2) + 1e-9)
    err_a = np.hypot(*(post.mean_alpha[:, :2] - run.poses[:, :2]).T)
    err_g = np.hypot(*(post.mean_gamma[:, :2] - run.poses[:, :2]).T)
    assert np.sqrt(np.mean(err_g**2)) < np.sqrt(np.mean(err_a**2))
    # the smoothed poses are about as far from the truth as their covariances say
    z = (post.mean_gamma[:, :2] - run.poses[:, :2]) / np.sqrt(np.diagonal(post.cov_gamma, axis1=1, axis2=2)[:, :2])
    assert 0.5 < np.sqrt(np.mean(z**2)) < 2.0


def test_bearing_innovations_are_wrapped():
    """A beacon straight behind the robot: observed at -pi + e while predicted near +pi."""
    lm = np.array([[0.0, -2000.0]])
    f = Polynomial1D((15.0,), 2000.0, 1000.0)
    rows = {}
    for obs in (np.pi - 0.01, -np.pi + 0.01):
        data = LandmarkLog(
            "planar", 0.05, [0, 0], [[0.0, 0.0, 0.0]], ("a_x", "a_y", "a_theta"), [1], [0], [15.0], [obs], lm
        )
        m0 = initial_model(data, EMConfig())
        model = m0.replace(sensor=LandmarkSensor.single(f, 1.0, 0.05), prior_cov=np.diag([1.0, 1.0, 1e-4]))
        post = e_step(model, data, np.array([1.0, 1.0, 1e-4]))
        rows[obs] = post
        assert landmark_bearing(np.zeros(3), lm[0])[0] == pytest.approx(-np.pi)
        assert landmark_distance(np.zeros(3), lm[0])[0] == pytest.approx(2000.0)
    a, b = rows.values()
    assert a.loglik == pytest.approx(b.loglik, abs=1e-9)  # +-0.01 rad off, either way round
    assert abs(a.mean_gamma[1, 2] + b.mean_gamma[1, 2]) < 1e-9 and abs(a.mean_gamma[1, 2]) < 0.01


def test_first_iteration_pruning_drops_false_positives():
    from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

    cfg = Field2DConfig.preset("real_robot", seconds=120.0, seed=5, false_positive_rate=0.05)
    run = simulate_field(cfg)
    data = to_landmark_log(run)
    _, _, model = _planar_case()
    model = model.replace(
        action=model.action.with_velocities(run.true_velocities),
        sensor=LandmarkSensor.single(model.sensor.height, cfg.sigma_height_px, cfg.sigma_bearing_rad),
    )
    post = e_step(model, data, np.array([100.0, 100.0, 0.01]), prune_rad_per_step=0.6)
    dropped = ~post.obs_used
    assert run.obs_false.sum() >= 20
    assert (dropped & run.obs_false).sum() >= 0.6 * run.obs_false.sum()  # most false sightings go
    assert (dropped & ~run.obs_false).sum() <= 0.05 * (~run.obs_false).sum()  # few true ones
    assert post.n_used == int(post.obs_used.sum())


def test_the_passes_are_compiled_for_a_track_and_a_planar_pose_only():
    """Each state size has its own compiled passes (their loops unrolled); another size is refused with
    the sizes there are, rather than running passes whose loops stop short."""
    from sensact.core.ekf_smoother import passes_for

    assert all(a is not b for a, b in zip(passes_for(1), passes_for(3), strict=True))
    with pytest.raises(ValueError, match=r"1 \(track\) or 3 \(planar\) numbers, not 2"):
        passes_for(2)


def test_an_e_step_compiles_no_record_and_no_joint_t_it_does_not_use():
    """The innovations' record and the joint Student-t are passed as None when off, so numba prunes
    their code from the forward pass it compiles for an E-step (a typed None could not index an array:
    were the branches kept, this compile would fail)."""
    from numba import types

    from sensact.core.ekf_smoother import passes_for

    _run, data, model = _planar_case(T=60)
    assert e_step(model, data).ok
    forward = passes_for(3)[0]
    # (..., joint_dof, weights, mu_a, P_a, innov, innov_sens)
    assert any(sig[7] == types.none and sig[11] == types.none and sig[12] == types.none for sig in forward.signatures)


def test_the_forward_pass_alone_gives_the_e_steps_likelihood_bit_for_bit():
    """Exact reduction: ``log_likelihood`` (what the searches compare) is eq. 4.14 from the forward pass
    alone, the very number ``e_step`` returns, on a track, on the field with Student-t heights and
    gated bearings, and with observations masked; a filter that fails is -inf, not a number."""
    data, model = _linear_track()[:2]
    assert log_likelihood(model, data) == e_step(model, data).loglik
    _run, data, model = _planar_case(T=600)
    (ch,) = model.sensor.channels
    robust = model.replace(
        sensor=LandmarkSensor(
            (ReadingChannel(ch.name, ch.function, ch.sigma, robust="student_t", robust_param=4.0),), 0.5, "gate", 2.0
        )
    )
    mask = np.arange(data.n_observations) % 3 != 0
    for m in (model, robust):
        full = e_step(m, data)
        assert full.ok and log_likelihood(m, data) == full.loglik
        assert log_likelihood(m, data, obs_use=mask) == e_step(m, data, obs_use=mask).loglik
    assert e_step(robust, data).weights[:, 1].min() == 0.0  # the gate did drop bearings
    broken = model.replace(prior_cov=-model.prior_cov)
    assert not e_step(broken, data).ok and log_likelihood(broken, data) == -np.inf
