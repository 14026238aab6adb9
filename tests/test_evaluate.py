"""evaluate: the optimal-scale comparisons of sec. 3.3.2 and the measured models of real logs."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.evaluate.measured import (
    ONE_COMMAND_SHARE,
    dominant_command,
    first_reversal_s,
    measure_action,
    measure_sensor,
)
from sensact.evaluate.scaled import consistency, fit_scale, fit_scale_offset, score_models
from sensact.evaluate.track1d import COMMAND_GRID_MM_S, DISTANCE_GRID_MM
from sensact.models.polynomial import Polynomial1D


def test_thesis_grids():
    assert len(COMMAND_GRID_MM_S) == 31 and COMMAND_GRID_MM_S[0] == -300 and COMMAND_GRID_MM_S[-1] == 300
    assert len(DISTANCE_GRID_MM) == 13 and DISTANCE_GRID_MM[0] == 1200 and DISTANCE_GRID_MM[-1] == 3600


def test_scale_fits_are_exact_and_scale_free():
    rng = np.random.default_rng(0)
    p = rng.normal(size=50)
    m = 3.0 * p + rng.normal(0, 0.1, 50)
    f = fit_scale(p, m)
    assert f.scale == pytest.approx(3.0, abs=0.05)
    # a learned model in another unit scores the same
    g = fit_scale(p / 7.0, m)
    assert g.rms == pytest.approx(f.rms, rel=1e-12) and g.scale == pytest.approx(7 * f.scale, rel=1e-12)
    h = fit_scale_offset(-0.2 * p + 5.0, m)
    assert h.rms == pytest.approx(fit_scale_offset(p, m).rms, rel=1e-10)
    assert fit_scale_offset(2 * p + 1, p).rms < 1e-12


def test_consistency():
    assert consistency(2.0, -2.0) == 0.0
    assert consistency(1.1, 1.0) == pytest.approx(0.1)
    assert consistency(1.0, 0.0) == np.inf


def test_perfect_models_score_their_best_fit():
    c = np.linspace(-300, 300, 31)
    v = 0.8 * c
    o = np.linspace(10, 30, 13)
    d = 40000.0 / o
    A = Polynomial1D((0.0, 1.0))  # A(c) = c
    S = Polynomial1D(tuple(np.polynomial.polynomial.polyfit((o - 20) / 10, -d / 5, 3)), 20.0, 10.0)
    sc = score_models(S, A, observations=o, distances=d, commands=c, velocities=v)
    assert sc.action_rms < 1e-9 and sc.action_scale_k == pytest.approx(0.8)
    assert sc.sensor_rms == pytest.approx(sc.sensor_best_rms, rel=1e-6)
    assert sc.consistency == pytest.approx(abs(0.8 / 5.0 - 1.0), rel=1e-6)


def test_measure_action_times_each_held_command():
    t = np.arange(0, 60, 0.05)
    c = np.where(t < 20, 0.2, np.where(t < 40, -0.1, 0.3))
    v = 0.9 * c
    x = np.cumsum(v * 0.05)
    ma = measure_action(t, c, x)
    np.testing.assert_allclose(ma.commands, [-0.1, 0.2, 0.3])
    np.testing.assert_allclose(ma.velocities, [-0.09, 0.18, 0.27], rtol=1e-6)


def test_measure_sensor_uses_medians_and_drops_non_invertible_bins():
    rng = np.random.default_rng(1)
    x = rng.uniform(0.1, 3.0, 20000)
    o = 2 * x + rng.normal(0, 0.01, x.size)
    o[rng.random(x.size) < 0.1] = 8.0  # outliers: the median ignores them
    ms = measure_sensor(o, x, bin_width=0.1, window=(0.0, 5.0))
    np.testing.assert_allclose(ms.observations, 2 * ms.positions, atol=0.02)
    assert ms.positions.max() < 2.5  # bins whose median is above 5.0 are left out


def test_dominant_command_counts_the_steps_at_the_median_command():
    held = np.r_[np.full(95, 0.02), np.zeros(3), np.full(2, -0.02)]  # calibration.csv's pattern
    assert dominant_command(held) == (0.02, 0.95) and 0.95 >= ONE_COMMAND_SHARE
    # within 2 % of the largest command's size counts as the same command; 3 % does not
    assert dominant_command(np.r_[np.full(50, 1.0), np.full(50, 0.98)])[1] == 1.0
    assert dominant_command(np.r_[np.full(50, 1.0), np.full(49, 0.97), [np.nan]])[1] == 50 / 99
    sweep = np.sin(np.linspace(0.0, 20.0, 1000))  # a sine never holds a command
    assert dominant_command(sweep)[1] < 0.05
    assert np.isnan(dominant_command(np.full(3, np.nan))[0]) and dominant_command(np.full(3, np.nan))[1] == 0.0


def test_the_real_robot_gain_goes_through_the_sensor_scale_not_the_actions_own():
    """Exact: a robot at gain 0.9 and a sensor read in half-metres. An S that is right (d = 0.5 o)
    with an A that says 1.8 half-metres per unit command is consistent, gain 0.9; the same S with
    A twice too fast has gain 1.8, which A's own optimal scale would have hidden (0.9 again)."""
    from types import SimpleNamespace

    from sensact.evaluate.real_track import evaluate_real
    from sensact.io.logfolder import TrackLog
    from sensact.learn.bootstrap import BootstrapConfig

    t = np.arange(0.0, 40.0, 0.05)
    cmd = np.where(t < 20.0, 0.1, -0.2)
    x = 1.0 + np.cumsum(0.9 * cmd * 0.05)
    log = TrackLog(t, cmd, 2.0 * x, "m/s", "half_m", "half-metres", "synthetic", true_position=x, position_unit="m")
    sensor = Polynomial1D((0.0, 1.0))  # w = o: the learned unit is the sensor's half-metres
    for a_slope, gain in ((1.8, 0.9), (3.6, 1.8)):
        result = SimpleNamespace(sensor=sensor, action=Polynomial1D((0.0, a_slope)))
        run = evaluate_real(log, result, BootstrapConfig())
        assert run.true_gain == pytest.approx(0.9, rel=1e-9)
        assert run.score.sensor_scale_b == pytest.approx(0.5, rel=1e-9)
        assert run.learned_gain == pytest.approx(gain, rel=1e-9)
        assert run.score.action_scale_k * a_slope == pytest.approx(0.9, rel=1e-9)  # the action's own: always 0.9


def test_the_first_reversal_is_the_first_command_against_the_first_move():
    t = np.arange(0.0, 10.0, 0.5)
    # a stop, small jitter below 2 % of the largest command, forward at two speeds, then back
    cmd = np.r_[np.zeros(4), [0.01, -0.01], np.full(6, 0.3), np.full(4, 0.5), np.full(4, -0.5)]
    assert first_reversal_s(t, cmd) == 8.0
    assert first_reversal_s(t + 100.0, -cmd) == 8.0  # seconds into the log, whichever way it starts
    assert first_reversal_s(t, np.abs(cmd)) is None and first_reversal_s(t, np.zeros(t.size)) is None
    assert first_reversal_s(t, np.full(t.size, np.nan)) is None


def test_the_real_robot_sensor_is_scored_in_10_cm_bins_in_any_distance_unit():
    """Exact reduction: one run with its recorded distance in m, cm or mm (a `convert track` folder's) is
    scored in the same 10-cm bins, its sensor error and gains in that unit; a unit the scorer
    does not name is binned in 1/32 of the distances' span."""
    from types import SimpleNamespace

    from sensact.evaluate.real_track import evaluate_real, sensor_bin_width
    from sensact.io.logfolder import TrackLog
    from sensact.learn.bootstrap import BootstrapConfig

    t = np.arange(0.0, 80.0, 0.05)
    cmd = np.where((t // 20.0) % 2 == 0, 0.1, -0.1)
    x = 1.0 + np.cumsum(0.9 * cmd * 0.05)
    o = 2.0 * x + 0.1 * np.sin(3.0 * x) + np.random.default_rng(0).normal(0.0, 0.02, x.size)
    result = SimpleNamespace(sensor=Polynomial1D((0.0, 1.0)), action=Polynomial1D((0.0, 1.8)))

    def run(unit: str, metres: float):
        log = TrackLog(t, cmd, o, "m/s", "half_m", "", "synthetic", true_position=x / metres, position_unit=unit)
        return evaluate_real(log, result, BootstrapConfig())

    m = run("m", 1.0)
    assert m.measured_sensor.counts.size == 18 and m.score.sensor_rms > 0.01
    for unit, metres in (("cm", 0.01), ("mm", 0.001)):
        other = run(unit, metres)
        np.testing.assert_array_equal(other.measured_sensor.counts, m.measured_sensor.counts)
        assert other.score.sensor_rms == pytest.approx(m.score.sensor_rms / metres, rel=1e-9)
        assert other.sensor_span == pytest.approx(m.sensor_span / metres, rel=1e-9)
        # distance per command unit, both: their ratio is the same
        assert other.learned_gain == pytest.approx(m.learned_gain / metres, rel=1e-9)
        assert other.true_gain == pytest.approx(m.true_gain / metres, rel=1e-9)
    assert sensor_bin_width("ft", x / 0.3048) == pytest.approx(np.ptp(x) / 0.3048 / 32)
