"""sim.track1d (sec. 3.3): the behaviour and truth the thesis describes."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.config import build_config
from sensact.errors import ConfigError
from sensact.sim.track1d import Track1DConfig, TrackTruth, simulate_track


@pytest.fixture(scope="module")
def run():
    return simulate_track(Track1DConfig(seconds=150.0, seed=7))


def test_deterministic_and_prefix_stable(run):
    again = simulate_track(Track1DConfig(seconds=150.0, seed=7))
    np.testing.assert_array_equal(run.distance_mm, again.distance_mm)
    longer = simulate_track(Track1DConfig(seconds=200.0, seed=7))
    np.testing.assert_array_equal(run.commands_mm_s, longer.commands_mm_s[: len(run.times_s)])


def test_behaviour_matches_section_3_3(run):
    c = run.commands_mm_s
    assert np.all(np.abs(c) <= 300.0)
    # commands change at most every 3 s, except at a turn-around
    changes = np.flatnonzero(np.diff(c) != 0) + 1
    holds = np.diff(run.times_s[changes])
    assert np.median(holds) == pytest.approx(3.0, abs=0.06)
    # walking toward (c > 0) shrinks the distance
    assert np.mean(np.sign(c[:-1]) * np.sign(-np.diff(run.distance_mm))) > 0.8
    # the turn-around thresholds keep it within about 1.2 to 3.6 m
    assert 1000 < run.distance_mm.min() < 1300 and 3300 < run.distance_mm.max() < 4000
    # 20 Hz observations with about 1.5 px noise
    m = np.isfinite(run.heights_px)
    assert m.mean() == pytest.approx(1.0)
    resid = run.heights_px[m] - run.truth.height_px(run.distance_mm[m])
    assert np.std(resid) == pytest.approx(1.5, rel=0.1)


def test_truth_is_near_the_camera_model_but_not_equal():
    tr = TrackTruth()
    d = np.arange(1200.0, 3601.0, 200.0)
    h = tr.height_px(d)
    rel = h / (38388.7 / d) - 1
    assert np.all(np.abs(rel) < 0.1) and np.max(np.abs(rel)) > 0.02
    assert np.all(np.diff(h) < 0)
    np.testing.assert_allclose(tr.distance_mm(h), d, rtol=1e-12)


def test_action_curve_has_a_dead_band_and_saturates():
    tr = TrackTruth()
    assert tr.velocity_mm_s(10.0) == 0.0 and tr.velocity_mm_s(-20.0) == 0.0
    assert tr.velocity_mm_s(300.0) < 0.7 * 300.0
    assert np.all(np.diff(tr.velocity_mm_s(np.linspace(-300, 300, 61))) >= 0)


def test_every_parameter_is_overridable(tmp_path):
    yaml_file = tmp_path / "sim.yaml"
    yaml_file.write_text(
        "observation_noise_px: 0.5\naction_knots_v_mm_s: [-100, 0, 100]\naction_knots_c_mm_s: [-300, 0, 300]\n"
    )
    cfg = build_config(Track1DConfig, yaml_file, ["seed=9", "turn_far_px=12.5"])
    assert (cfg.observation_noise_px, cfg.seed, cfg.turn_far_px) == (0.5, 9, 12.5)
    assert cfg.truth().velocity_mm_s(150.0) == pytest.approx(50.0)
    with pytest.raises(ConfigError, match="non-decreasing"):
        build_config(Track1DConfig, None, ["action_knots_v_mm_s=[1, 0, 2]", "action_knots_c_mm_s=[-1, 0, 1]"])
    with pytest.raises(ConfigError, match="unknown field 'noise'") as err:
        build_config(Track1DConfig, None, ["noise=1"])
    assert "did you mean" not in str(err.value)  # nothing near enough to name
    with pytest.raises(ConfigError, match="did you mean 'turn_far_px'"):  # a typo names the field it is near
        build_config(Track1DConfig, None, ["turn_far_pxx=12.5"])
    with pytest.raises(ConfigError, match="seed"):
        build_config(Track1DConfig, None, ["seed=abc"])
