"""The EM loop (secs. 4.1, 4.4): seeded recovery of known models, best-model bookkeeping, interruption."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.core.geometry import PLANAR
from sensact.evaluate.em import score_planar, score_track
from sensact.evaluate.track1d import DISTANCE_GRID_MM
from sensact.learn.em import EMConfig, e_step, fit_em, initial_model


@pytest.fixture(scope="module")
def field_fit():
    from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

    cfg = Field2DConfig(seconds=300.0, seed=4)
    run = simulate_field(cfg)
    data = to_landmark_log(run)
    em = EMConfig.of(prune_rad_per_step=0.0, max_iterations=400)
    return cfg, run, data, em, fit_em(data, initial_model(data, em), em)


def test_field2d_recovery_from_the_thesis_start(field_fit):
    """No motion and a poor linear f at the start; five minutes of data (a third of the thesis's)."""
    cfg, run, _data, _em, res = field_fit
    sc = score_planar(res.model, run.true_velocities, cfg.height_px, cfg.sigma_height_px, cfg.sigma_bearing_rad)
    assert res.stop_reason == "converged"
    assert sc["vx_rms_mm_s"] < 60 and sc["vy_rms_mm_s"] < 60 and sc["vtheta_rms_rad_s"] < 0.1
    assert sc["sigma1_error_pct"] < 10 and sc["sigma2_error_pct"] < 10
    assert sc["sensor_rms_px"] < 0.6
    assert res.loglik_history[res.best_iteration] > res.loglik_history[0] + 1000


def test_result_is_the_most_likely_model(field_fit):
    _cfg, _run, data, em, res = field_fit
    ll = res.loglik_history
    assert res.best_iteration == int(np.argmax(ll))
    assert res.iterations - 1 - res.best_iteration == em.thesis.patience  # stopped by the 50-iteration rule
    np.testing.assert_array_equal(res.velocity_history[res.best_iteration], res.model.action.velocities)
    again = e_step(res.model, data, PLANAR.motion_variance(em.thesis.motion_sd_mm, em.thesis.motion_sd_rad))
    assert again.loglik == pytest.approx(res.loglik_best, abs=1e-6)


def test_em1d_recovery_with_the_optimal_scale():
    import dataclasses

    from sensact.experiments.em1d import EM1D_TRACK, true_velocities
    from sensact.sim.track1d import simulate_track, to_landmark_log

    sim = dataclasses.replace(EM1D_TRACK, seconds=300.0, change_at_s=None, seed=5)
    data = to_landmark_log(simulate_track(sim))
    em = EMConfig.of(max_iterations=800)  # the unit keeps growing slowly after this; the scaled error does not
    res = fit_em(data, initial_model(data, em), em)
    sc = score_track(res.model, true_velocities(sim, False), sim.truth().height_px, DISTANCE_GRID_MM)
    assert sc["action_rms_pct"] < 2.0 and sc["sensor_rms_pct"] < 2.0
    assert abs(sc["scale_ratio"] - 1) < 0.1


def test_interrupt_returns_the_best_model_so_far(field_fit):
    _cfg, _run, data, em, _ = field_fit

    def stop(it, ll, best, since):
        if it == 3:
            raise KeyboardInterrupt

    res = fit_em(data, initial_model(data, em), em, on_iteration=stop)
    assert res.stop_reason == "interrupted" and res.iterations == 4
    assert res.best_iteration == int(np.argmax(res.loglik_history))
    from sensact.learn.em.checks.fit_health import em_health

    health = em_health(res, data)  # what the model file's health says: never ok, however good so far
    assert not health.ok and "interrupted" in [f.code for f in health.flags]


def test_divergence_is_reported():
    """A singular starting prior makes the filter's covariance invalid: EM stops and says so."""
    from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

    data = to_landmark_log(simulate_field(Field2DConfig(seconds=20.0, seed=1)))
    em = EMConfig.of(max_iterations=5)
    start = initial_model(data, em)
    res = fit_em(data, start.replace(prior_cov=-np.eye(3)), em)
    assert res.stop_reason == "diverged" and res.iterations == 0
