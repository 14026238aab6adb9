"""The chapter-4 field simulator reproduces the conditions of secs. 4.4.1-4.4.2."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.core.pose_models import landmark_bearing, landmark_distance, relative_displacement
from sensact.sim.field2d import OMEGAS, Field2DConfig, attempted_commands, simulate_field


@pytest.fixture(scope="module")
def run():
    return simulate_field(Field2DConfig(seed=0))


def test_forty_actions_of_eqs_4_29_to_4_31():
    a = attempted_commands()
    assert a.shape == (40, 3)
    np.testing.assert_allclose((a**2).sum(axis=1), 1.0)
    assert sorted(set(np.round(a[:, 2], 9))) == sorted(set(np.round(OMEGAS, 9)))
    assert len({tuple(r) for r in np.round(a, 9)}) == 40
    psi = np.arctan2(a[:, 1], a[:, 0])
    assert len(set(np.round(np.mod(psi, 2 * np.pi), 6))) == 8


def test_true_velocity_ranges_are_the_thesiss():
    """About 710 mm/s in x, 840 mm/s in y and pi rad/s in theta (sec. 4.4.2)."""
    v = Field2DConfig().true_velocities()
    ranges = np.ptp(v, axis=0)
    assert ranges[0] == pytest.approx(710, rel=0.05)
    assert ranges[1] == pytest.approx(840, rel=0.05)
    assert ranges[2] == pytest.approx(np.pi, rel=0.05)
    # distorted and cross-coupled: not a diagonal scaling of the attempted velocities
    a = attempted_commands()
    coef, *_ = np.linalg.lstsq(a, v, rcond=None)
    assert np.abs(coef - np.diag(np.diag(coef))).max() > 0.02 or np.abs(a @ coef - v).max() > 10


def test_run_length_actions_and_field(run):
    cfg = run.config
    assert run.times_s.size == 18001  # 15 minutes of 0.05 s steps
    counts = np.bincount(run.actions[:: round(cfg.action_hold_s / cfg.dt_s)], minlength=40)
    assert counts.min() >= 4 and counts.max() - counts.min() <= 1  # every action about four times
    assert np.all(np.abs(run.poses[:, 0]) <= cfg.field_x_mm / 2)
    assert np.all(np.abs(run.poses[:, 1]) <= cfg.field_y_mm / 2)


def test_motion_follows_the_true_velocities(run):
    D = relative_displacement(run.poses[:-1], run.poses[1:]) / run.config.dt_s
    a = run.actions[:-1]
    means = np.array([D[a == k].mean(axis=0) for k in range(40)])
    err = np.sqrt(np.mean((means - run.true_velocities) ** 2, axis=0))
    assert err[0] < 10 and err[1] < 10 and err[2] < 0.03  # only the white motion noise remains


def test_observations_are_within_sight_and_noisy_as_configured():
    cfg = Field2DConfig(seconds=300.0, seed=1)
    run = simulate_field(cfg)
    lm = np.asarray(cfg.landmarks_xy_mm)[run.obs_landmark]
    d = landmark_distance(run.poses[run.obs_step], lm)
    assert d.min() >= cfg.min_range_mm and d.max() <= cfg.max_range_mm
    assert 0.3 < run.obs_step.size / run.times_s.size < 1.0  # roughly the thesis's 8659 per 18000 steps
    h_err = run.obs_height_px - cfg.height_px(d)
    b_err = np.angle(np.exp(1j * (run.obs_bearing_rad - landmark_bearing(run.poses[run.obs_step], lm))))
    assert np.std(h_err) == pytest.approx(cfg.sigma_height_px, rel=0.05)
    assert np.std(b_err) == pytest.approx(cfg.sigma_bearing_rad, rel=0.05)
    assert not run.obs_false.any()


def test_seeded_and_presets():
    a = simulate_field(Field2DConfig(seconds=30.0, seed=3))
    b = simulate_field(Field2DConfig(seconds=30.0, seed=3))
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(a.obs_height_px, b.obs_height_px)
    real = Field2DConfig.preset("real_robot")
    assert real.dt_s == pytest.approx(1 / 30) and real.sigma_bearing_rad == pytest.approx(0.0267)
    with pytest.raises(ValueError, match="unknown setting"):
        Field2DConfig.preset("moon")
