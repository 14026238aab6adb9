"""Scoring chapter 4's models (evaluate/em.py): exact recoveries and the scale-free invariants."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.errors import ModelFormatError
from sensact.evaluate.em import component_rms, fit_distance_map, score_planar, score_track
from sensact.models.action_table import ActionTable
from sensact.models.em_model import EMModel
from sensact.models.landmark_sensor import LandmarkSensor
from sensact.models.polynomial import Polynomial1D

D = np.arange(1200.0, 3601.0, 200.0)


def _true_height(d):
    return 40200.0 / (np.asarray(d) + 110.0) - 0.6


def _track_model(k: float, b: float, velocities: np.ndarray) -> EMModel:
    """A learned model whose state is x = k d + b: f_learned(x) = cubic fit of f_true((x - b) / k)."""
    x = k * np.linspace(1000, 3800, 400) + b
    center, scale = float(x.mean()), float(abs(k) * 800)
    coef = np.polyfit((x - center) / scale, _true_height((x - b) / k), 3)[::-1]
    f = Polynomial1D(tuple(coef), center, scale)
    table = ActionTable(np.linspace(-1, 1, len(velocities))[:, None], velocities[:, None], ("a_y",), ("v_mm_s",))
    return EMModel("track", table, LandmarkSensor.single(f, 1.0), np.zeros(1), np.eye(1))


def test_distance_map_recovers_a_known_affine_map():
    """With a cubic truth the learned f is exactly a cubic of x = k d + b, so the map comes back exactly."""
    truth = Polynomial1D((15.0, -6.0, 1.5, -0.4), 2400.0, 1200.0)
    k, b = -0.37, 5000.0
    x = k * np.linspace(1000, 3800, 50) + b
    coef = np.polyfit((x - 4000) / 300, truth((x - b) / k), 3)[::-1]
    learned = Polynomial1D(tuple(coef), 4000.0, 300.0)
    dmap = fit_distance_map(learned, truth, D)
    assert dmap.scale == pytest.approx(k, rel=1e-6)
    assert dmap.offset == pytest.approx(b, rel=1e-6)
    assert dmap.rms_px < 1e-6


def test_track_scores_are_free_of_the_learned_unit():
    tv = np.linspace(-390, 405, 21) + 15 * np.sin(np.arange(21))
    learned = 1.1 * tv + np.random.default_rng(0).normal(size=21) * 5
    a = score_track(_track_model(1.0, 0.0, learned), tv, _true_height, D)
    b = score_track(_track_model(2.5, -700.0, 2.5 * learned), tv, _true_height, D)
    for key in ("sensor_rms_px", "action_rms_mm_s", "scale_ratio"):
        assert a[key] == pytest.approx(b[key], rel=1e-3), key
    assert a["scale_ratio"] == pytest.approx(1.1, rel=0.01)  # the learned velocities are 10 % too fast


def test_planar_score_of_the_truth_is_zero():
    tv = np.random.default_rng(1).normal(size=(40, 3)) * [200, 200, 1]
    table = ActionTable(np.zeros((40, 3)), tv, ("a", "b", "c"), ("vx", "vy", "vt"))
    d = np.linspace(1000, 4500, 200)
    coef = np.polyfit((d - 2700) / 1000, _true_height(d), 3)[::-1]
    m = EMModel(
        "planar", table, LandmarkSensor.single(Polynomial1D(tuple(coef), 2700, 1000), 1.0, 0.5), np.zeros(3), np.eye(3)
    )
    sc = score_planar(m, tv, _true_height, 1.0, 0.5)
    assert sc["vx_rms_mm_s"] == 0 and sc["sigma1_error_pct"] == 0 and sc["sigma2_error_pct"] == 0
    assert sc["sensor_rms_px"] < 0.3  # a cubic through 1/d
    np.testing.assert_allclose(component_rms(tv + np.array([3.0, 4.0, 0.0]), tv), [3, 4, 0])


def test_em_model_round_trips_through_json():
    import json

    m = _track_model(1.0, 0.0, np.linspace(-300, 300, 21))
    back = EMModel.from_dict(json.loads(json.dumps(m.to_dict())))
    np.testing.assert_array_equal(back.action.velocities, m.action.velocities)
    assert back.sensor.height.coef == m.sensor.height.coef and back.sensor.sigma_bearing_rad is None
    with pytest.raises(ModelFormatError, match="not an EM model"):
        EMModel.from_dict({"kind": "polynomial1d"})
    bad = m.to_dict()
    bad["action"]["velocities"] = [[1.0]]
    with pytest.raises(ModelFormatError, match="action table"):
        EMModel.from_dict(bad)
