"""The M-step (sec. 4.3) on posteriors whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.core.pose_models import landmark_bearing, landmark_distance
from sensact.learn.em.estep import Posteriors
from sensact.learn.em.mstep import prior, sample_gamma, sensor_and_map
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.action_table import ActionTable
from sensact.models.landmark_sensor import LandmarkSensor
from sensact.models.polynomial import Polynomial1D


def _post(mean, cov, disp=None, used=None):
    T, n = mean.shape
    disp = np.zeros((T - 1, n)) if disp is None else disp
    used = np.ones(0, bool) if used is None else used
    weights = np.ones((used.size, 2))  # one reading channel and the bearing, all used at full weight
    return Posteriors(0.0, True, mean, cov, mean, cov, disp, np.zeros((T - 1, n, n)), used, int(used.sum()), weights)


def test_action_table_is_the_mean_displacement_over_q_a():
    """Eq. 4.18, with an action that never ran keeping its old value."""
    rng = np.random.default_rng(0)
    T, dt = 101, 0.05
    actions = rng.integers(0, 3, T)
    disp = rng.normal(size=(T - 1, 3))
    data = LandmarkLog("planar", dt, actions, np.eye(4, 3), ("a", "b", "c"), [], [], [], [], np.zeros((1, 2)))
    post = _post(np.zeros((T, 3)), np.tile(np.eye(3), (T, 1, 1)), disp)
    prev = np.full((4, 3), 7.0)
    table = ActionTable(np.eye(4, 3), prev, ("a", "b", "c"), ("v_x_mm_s", "v_y_mm_s", "v_theta_rad_s"))
    v = table.update(data, post.disp_mean, np.ones_like(post.disp_mean), 0).velocities
    for a in range(3):
        np.testing.assert_allclose(v[a], disp[actions[:-1] == a].mean(axis=0) / dt)
    np.testing.assert_array_equal(v[3], prev[3])


def test_sensor_model_recovers_f_and_sigmas_from_certain_poses():
    """With (nearly) certain poses eq. 4.25 is a plain regression and eqs. 4.27-4.28 plain RMS errors."""
    rng = np.random.default_rng(1)
    T = 400
    poses = np.column_stack([rng.uniform(-2000, 2000, T), rng.uniform(-1500, 1500, T), rng.uniform(-3, 3, T)])
    lm = np.array([[1350.0, 1950.0], [-1350.0, -1950.0]])
    which = rng.integers(0, 2, T)
    truth = Polynomial1D((15.0, -5.0, 1.2, -0.3), 2500.0, 800.0)
    d = landmark_distance(poses, lm[which])
    h = truth(d) + rng.normal(size=T) * 0.7
    b = landmark_bearing(poses, lm[which]) + rng.normal(size=T) * 0.2
    data = LandmarkLog(
        "planar", 0.05, np.zeros(T, int), [[0.0, 0.0, 0.0]], ("a", "b", "c"), np.arange(T), which, h, b, lm
    )
    post = _post(poses, np.tile(np.eye(3) * 1e-10, (T, 1, 1)), used=np.ones(T, bool))
    prev = LandmarkSensor.single(Polynomial1D((0.0, 0.0, 0.0, 0.0)), 10.0, 0.2)  # a cubic
    s = sensor_and_map(post, data, 1, np.random.default_rng(2), prev)[0]
    np.testing.assert_allclose(s.height(d), np.polyval(np.polyfit(d, h, 3), d), atol=1e-6)
    assert s.sigma_height_px == pytest.approx(np.sqrt(np.mean((s.height(d) - h) ** 2)), rel=1e-6)
    assert 0.6 < s.sigma_height_px < 0.8 and 0.17 < s.sigma_bearing_rad < 0.23
    # pruned observations take no part
    post2 = _post(poses, post.cov_gamma, used=np.arange(T) < 200)
    s2 = sensor_and_map(post2, data, 1, np.random.default_rng(2), prev)[0]
    np.testing.assert_allclose(s2.height(d[:200]), np.polyval(np.polyfit(d[:200], h[:200], 3), d[:200]), atol=1e-6)


def test_samples_follow_gamma():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 3))
    cov = A @ A.T + np.eye(3)
    mean = np.array([[100.0, -50.0, 0.3]])
    post = _post(mean.repeat(2, 0), np.stack([cov, cov]))
    w = sample_gamma(post, np.zeros(20000, int), 1, np.random.default_rng(4))[0]
    np.testing.assert_allclose(w.mean(axis=0), mean[0], atol=0.05)
    np.testing.assert_allclose(np.cov(w.T), cov, rtol=0.05, atol=0.05)


def test_prior_is_gamma_0_with_a_floor():
    cov = np.diag([1e-6, 400.0, 1e-9])
    post = _post(np.array([[1.0, 2.0, 3.0], [0, 0, 0]]), np.stack([cov, cov]))
    m, P = prior(post, np.array([1.0, 1.0, 1e-6]))
    np.testing.assert_array_equal(m, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(np.diag(P), [1.0, 400.0, 1e-6])
