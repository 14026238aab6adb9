"""A lost fit, caught and started again: a range function that turns or bends within its distances, a
likelihood that never settles, and the restarts that keep the most likely fit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from continuous_robot import LANDMARKS, continuous_config, simulate_continuous
from sensact.core.pose_models import landmark_distance
from sensact.learn.em import fit_em, log_likelihood
from sensact.learn.em.config import ChannelConfig, SearchSettings


def _turning_cubic(center: float, scale: float, at: float = 0.0, width: float = 1.0):
    """h((x - at) / width) with h(v) = v^3 - 6 v^2 + 9 v, whose slope 3 (v - 1)(v - 3) changes sign at
    v = 1 and 3, so at x = at + width and at + 3 width; stored about ``center`` and ``scale``."""
    from numpy.polynomial import Polynomial

    from sensact.models.polynomial import Polynomial1D

    x_of_u = Polynomial([center, scale])
    in_u = Polynomial([0.0, 9.0, -6.0, 1.0])((x_of_u - at) / width)
    return Polynomial1D(tuple(in_u.coef), center=center, scale=scale)


def test_turning_points_are_where_the_slope_changes_sign():
    from sensact.models.polynomial import Polynomial1D

    f = _turning_cubic(2.0, 1.5)
    np.testing.assert_allclose(f.turning_points(0.0, 4.0), [1.0, 3.0], atol=1e-9)
    np.testing.assert_allclose(f.turning_points(1.5, 4.0), [3.0], atol=1e-9)
    assert f.turning_points(3.5, 9.0).size == 0
    # an independent reference: the sign changes of the slope on a dense grid
    x = np.linspace(-1.0, 5.0, 600_001)
    slope = np.gradient(f(x), x)
    flips = x[1:][np.sign(slope[1:]) != np.sign(slope[:-1])]
    np.testing.assert_allclose(flips, f.turning_points(-1.0, 5.0), atol=1e-4)
    # a slope that touches zero without changing sign (x^3), a rising cubic, a line and a constant do not turn
    for coef in ((0.0, 0.0, 0.0, 1.0), (0.0, 1.0, 0.0, 1.0), (3.0, 2.0), (5.0,), (1.0, 2.0, 0.0, 0.0)):
        assert Polynomial1D(coef, center=0.7, scale=3.0).turning_points(-10.0, 10.0).size == 0, coef


def test_slope_range_is_the_least_and_greatest_slope_over_the_interval():
    """Polynomial1D.slope_range against an independent reference: the slope on a dense grid."""
    from sensact.models.polynomial import Polynomial1D

    f = _turning_cubic(2.0, 1.5)  # slope 3 (x - 1)(x - 3): least -3 at x = 2
    assert f.slope_range(0.0, 4.0) == pytest.approx((-3.0, 9.0), abs=1e-9)
    assert f.slope_range(3.0, 5.0) == pytest.approx((0.0, 24.0), abs=1e-9)  # the slope's turn outside
    for coef, lo, hi in (((1.0, -0.4, 0.3, 0.05), -2.0, 3.0), ((2.0, 1.3, -0.2), 0.0, 9.0), ((3.0, 2.0), -5.0, 5.0)):
        g = Polynomial1D(coef, center=0.7, scale=3.0)
        x = np.linspace(lo, hi, 400_001)
        slope = np.gradient(g(x), x)
        assert g.slope_range(lo, hi) == pytest.approx((slope.min(), slope.max()), abs=1e-6), coef
        np.testing.assert_allclose(g.slope(x[1:-1]), slope[1:-1], atol=1e-6)
    assert Polynomial1D((5.0,)).slope_range(0.0, 1.0) == (0.0, 0.0)


def test_a_length_reading_whose_slope_changes_with_distance_is_flagged(continuous_fit):
    """learn/em/checks/lost_signs.py: the fit that found the robot has an f of one slope; an f whose slope changes
    threefold over the fitted distances without turning is flagged when the channel reads a length in the
    map's unit (``_mm``), not when it is a line off by a scale, not under another unit, and an f that
    turns is ``range_function_turns``'s alone; ``lost_fit_signs`` holds both."""
    from sensact.learn.em.checks.lost_signs import (
        describe_lost_fit,
        lost_fit_signs,
        range_function_bends,
        range_function_turns,
    )
    from sensact.models.polynomial import Polynomial1D

    data, _poses, res = continuous_fit
    assert range_function_bends(res.model, res.posteriors, data) == []
    assert lost_fit_signs(res.model, res.posteriors, data) == []
    use = res.posteriors.obs_used
    d = landmark_distance(res.posteriors.mean_gamma[data.obs_step[use]], LANDMARKS[data.obs_landmark[use]])
    lo, hi = np.percentile(d, [2, 98])
    f0 = res.model.sensor.channels[0].function

    def with_f(f, name="range_mm"):
        ch = replace(res.model.sensor.channels[0], function=f, name=name)
        return res.model.replace(sensor=replace(res.model.sensor, channels=(ch,)))

    def quadratic(slope_lo, slope_hi):
        """lo + a (x - lo) + b (x - lo)^2, its slope slope_lo at lo and slope_hi at hi, stored in
        u = (x - center) / scale as the fit stores f."""
        a, b, e = slope_lo, 0.5 * (slope_hi - slope_lo) / (hi - lo), f0.center - lo
        coef = (lo + a * e + b * e**2, (a + 2 * b * e) * f0.scale, b * f0.scale**2)
        return Polynomial1D(coef, center=f0.center, scale=f0.scale)

    bent = quadratic(0.6, 1.8)
    assert bent(np.array([lo]))[0] == pytest.approx(lo) and bent.slope(np.array([lo, hi])) == pytest.approx([0.6, 1.8])
    signs = range_function_bends(with_f(bent), res.posteriors, data)
    assert len(signs) == 1 and signs[0].channel == "range_mm" and signs[0].sign == "bends"
    np.testing.assert_allclose(signs[0].slopes, [0.6, 1.8], rtol=1e-9)
    np.testing.assert_allclose(signs[0].distances_mm, [lo, hi])
    assert range_function_turns(with_f(bent), res.posteriors, data) == []
    assert lost_fit_signs(with_f(bent), res.posteriors, data) == signs
    said = describe_lost_fit(signs)
    assert "range_mm's f has slopes from 0.60 to 1.80 mm per mm, inside the" in said and "start_sigma" in said
    assert "off by a scale, but not by one that changes with distance" in said
    # at the ratio, a steeper or a falling line, and a bend under another unit: not flagged
    under = quadratic(0.6, 0.6 * SearchSettings.lost_bend_ratio * 0.99)
    assert range_function_bends(with_f(under), res.posteriors, data) == []
    for line in (Polynomial1D((100.0, 2.5 * f0.scale), f0.center, f0.scale), Polynomial1D((9e3, -0.4 * f0.scale))):
        assert range_function_bends(with_f(line), res.posteriors, data) == []
    assert range_function_bends(with_f(bent, name="height_px"), res.posteriors, data) == []
    # a falling reading bent threefold is flagged too
    falling = Polynomial1D(tuple(-c for c in bent.coef), center=f0.center, scale=f0.scale)
    assert range_function_bends(with_f(falling), res.posteriors, data)[0].slopes == pytest.approx([-1.8, -0.6])
    # an f that turns is a turn, not a bend
    turning = _turning_cubic(f0.center, f0.scale, at=0.5 * (lo + hi) - 0.2 * (hi - lo), width=0.1 * (hi - lo))
    signs = lost_fit_signs(with_f(turning), res.posteriors, data)
    assert len(signs) == 1 and signs[0].sign == "turns" and "does not turn" in describe_lost_fit(signs)


def test_a_range_function_that_turns_within_its_distances_is_flagged(continuous_fit):
    """learn/em/checks/lost_signs.py: the fit that found the robot has a rising f; the same fit with an f that turns
    inside the fitted distances is flagged there, and not when the turn is outside them or outside the
    channel's window."""
    from sensact.learn.em.checks.lost_signs import describe_lost_fit, range_function_turns

    data, _poses, res = continuous_fit
    assert range_function_turns(res.model, res.posteriors, data) == []
    use = res.posteriors.obs_used
    d = landmark_distance(res.posteriors.mean_gamma[data.obs_step[use]], LANDMARKS[data.obs_landmark[use]])
    lo, hi = np.percentile(d, [2, 98])
    mid = 0.5 * (lo + hi)

    def with_f(f, **window):
        ch = replace(res.model.sensor.channels[0], function=f, **window)
        return res.model.replace(sensor=replace(res.model.sensor, channels=(ch,)))

    # turns at mid -/+ a tenth of the span, stored as the fit stores f
    a = 0.1 * (hi - lo)
    f0 = res.model.sensor.channels[0].function
    f = _turning_cubic(f0.center, f0.scale, at=mid - 2.0 * a, width=a)
    turned = range_function_turns(with_f(f), res.posteriors, data)
    assert len(turned) == 1 and turned[0].channel == "range_mm"
    np.testing.assert_allclose(turned[0].turns_at_mm, [mid - a, mid + a], rtol=1e-9)
    np.testing.assert_allclose(turned[0].distances_mm, [lo, hi])
    assert "turns over at" in describe_lost_fit(turned) and "start_sigma" in describe_lost_fit(turned)
    far = _turning_cubic(f0.center, f0.scale, at=hi + 2.0 * a, width=a)  # turns at hi + 3a and hi + 5a
    assert range_function_turns(with_f(far), res.posteriors, data) == []
    assert range_function_turns(with_f(f, valid_max=mid - 1.5 * a), res.posteriors, data) == []


def test_a_fit_whose_likelihood_keeps_falling_far_below_its_best_has_not_settled(continuous_fit):
    """learn/em/checks/lost_signs.py ``unsettled_fit``: the mean fall below the best over the iterations after it, per
    sighting used, against ``SearchSettings.lost_fall_per_sighting`` (exact on built histories); the fit that found the
    robot has not that sign, the same fit with a history that thrashes after its best has, and says so;
    a 1-D log's history is not judged."""
    from sensact.learn.em.checks.lost_signs import describe_lost_fit, lost_fit_signs, unsettled_fit

    UNSETTLED_PER_SIGHTING = SearchSettings.lost_fall_per_sighting

    n = 1000
    limit = UNSETTLED_PER_SIGHTING * n
    at_limit = np.array([-900.0, -500.0, -500.0 - 0.5 * limit, -500.0 - 1.5 * limit])  # falls 0.5 and 1.5 limit
    assert unsettled_fit(at_limit, 1, n) == []  # a mean fall of the limit itself
    over = at_limit.copy()
    over[3] -= 1e-6 * limit
    (sign,) = unsettled_fit(over, 1, n)
    assert sign.sign == "unsettled" and sign.best_iteration == 1 and sign.iterations_after == 2
    assert sign.mean_fall == pytest.approx(limit * (1 + 0.5e-6)) and sign.per_sighting == pytest.approx(
        sign.mean_fall / n
    )
    assert unsettled_fit(over, 3, n) == [] and unsettled_fit(over, 1, 0) == []  # nothing after the best; no sighting
    assert unsettled_fit(over, 1, 2 * n) == []  # the same falls over twice the sightings

    data, _poses, res = continuous_fit
    h, b = res.loglik_history, res.best_iteration
    assert b < h.size - 1 and lost_fit_signs(res.model, res.posteriors, data, h, b) == []
    used = int(res.posteriors.obs_used.sum())
    assert res.n_used == used == res.n_observations - res.n_pruned
    assert res.summary()["fall_per_sighting"] == pytest.approx(
        sum(h[b] - h[i] for i in range(b + 1, h.size)) / (h.size - b - 1) / used
    )
    assert 0 < res.summary()["fall_per_sighting"] < UNSETTLED_PER_SIGHTING
    thrashing = h.copy()
    thrashing[b + 1 :] -= 2.0 * UNSETTLED_PER_SIGHTING * used
    signs = lost_fit_signs(res.model, res.posteriors, data, thrashing, b)
    assert [s.sign for s in signs] == ["unsettled"] and not hasattr(signs[0], "channel")
    assert signs[0].per_sighting == pytest.approx(2.0 * UNSETTLED_PER_SIGHTING + np.mean(h[b] - h[b + 1 :]) / used)
    said = describe_lost_fit(signs)
    assert f"iterations after its best one ({b}) EM's log-likelihood stayed on average" in said
    assert "moves little from it: EM has probably lost the robot" in said
    assert lost_fit_signs(res.model, res.posteriors, data) == []  # without the history, the f signs alone
    track = replace(data, geometry="track")
    assert unsettled_fit(thrashing, b, used) and lost_fit_signs(res.model, res.posteriors, track, thrashing, b) == []


def test_em_restarts_from_a_tighter_start_while_f_turns_and_keeps_the_most_likely_fit(monkeypatch):
    """fit.restart_while_lost, with the turn check replaced by one that flags the first ``flagged``
    fits: each restart's start sigma is a third of the last, no more than ``turn_restarts`` restarts run,
    none once f does not turn, and the fit kept is the most likely one, scored on the sightings every run
    used (each run's own likelihood here: nothing is pruned)."""
    import sensact.learn.em.fit as fit_module
    from sensact.learn.em.result import FunctionTurns, Unsettled

    data, _ = simulate_continuous(3, T=2400)
    calls = {"n": 0, "flagged": 0}

    def flags_the_first(model, post, log, *history):
        calls["n"] += 1
        turn = [FunctionTurns("range_mm", turns_at_mm=(2000.0,), distances_mm=(1000.0, 3000.0))]
        if calls.get("unsettled"):  # checks.unsettled_fit's sign names no channel
            turn = [Unsettled(best_iteration=5, iterations_after=4, mean_fall=9e3, per_sighting=2)]
        return turn if calls["n"] <= calls["flagged"] else []

    monkeypatch.setattr(fit_module, "lost_fit_signs", flags_the_first)
    heard = []
    for restarts, flagged, runs in ((2, 9, 3), (2, 1, 2), (0, 9, 1), (3, 0, 1)):
        calls.update(n=0, flagged=flagged)
        # from a vague start, the tighter restarts climb faster in 10 iterations: the most likely run is
        # neither the first nor always the last, so keeping either would fail
        wide = (ChannelConfig("range_mm", 1, 0.0, 0.8, 3000.0),)
        cfg = continuous_config(max_iterations=10, turn_restarts=restarts, channels=wide)
        res = fit_em(data, None, cfg, on_restart=lambda k, turned, sigmas: heard.append((k, sigmas)))
        if runs == 1:
            assert res.restarts is None
            continue
        info = res.restarts
        assert len(info) == runs and [r.start_sigma["range_mm"] for r in info] == pytest.approx(
            [3000.0 / 3**k for k in range(runs)], rel=1e-12
        )
        assert [bool(r.f_turns) for r in info] == [True] * (runs - 1) + [runs - 1 < flagged]
        kept = [r for r in info if r.kept]
        assert len(kept) == 1 and kept[0].loglik == max(r.loglik for r in info) and not info[0].kept
        assert res.loglik_best == pytest.approx(kept[0].loglik, abs=1e-6 * abs(res.loglik_best))
        assert all(r.loglik == pytest.approx(r.loglik_best, abs=1e-6 * abs(r.loglik)) for r in info)
        # the kept model, its likelihood computed again from the forward pass alone
        assert log_likelihood(res.model, data) == pytest.approx(kept[0].loglik, abs=1e-6 * abs(res.loglik_best))
    assert [k for k, _ in heard] == [1, 2, 1] and heard[1][1]["range_mm"] == pytest.approx(3000.0 / 9)
    assert "restarts" in res.summary()
    # a fit that did not settle names no channel: every channel starts a third as vague
    calls.update(n=0, flagged=1, unsettled=True)
    heard.clear()
    res = fit_em(data, None, cfg.replace(turn_restarts=2), on_restart=lambda k, signs, sigmas: heard.append(sigmas))
    assert heard == [{"range_mm": pytest.approx(1000.0)}] and len(res.restarts) == 2
    assert [r.f_turns[0].sign for r in res.restarts[:1]] == ["unsettled"] and not res.restarts[1].f_turns
    calls["unsettled"] = False

    # Ctrl-C ends the fit: no restart after it, whatever the signs
    def interrupt(it, ll, best, since):
        if it == 3:
            raise KeyboardInterrupt

    calls.update(n=0, flagged=9)
    heard.clear()
    res = fit_em(data, None, cfg, on_iteration=interrupt, on_restart=lambda k, signs, sigmas: heard.append(sigmas))
    assert res.stop_reason == "interrupted" and res.restarts is None and heard == [] and calls["n"] == 1
    # what `learn em` and `reproduce real` show of the last two-run fit
    from sensact.records import to_json
    from sensact.report.tables_real import kept_run_cell, restart_runs_cell

    calls.update(n=0, flagged=1)
    two = fit_em(data, None, cfg.replace(turn_restarts=1))
    runs = to_json(two.restarts)  # as model.json and real.json hold them
    cell = restart_runs_cell(runs)
    assert cell.startswith("range_mm 3000: ") and "(f turned); range_mm 1000: " in cell
    assert kept_run_cell(runs) == ("restart 1" if two.restarts[1].kept else "the first run")
    unsettled = {
        "sign": "unsettled",
        "best_iteration": 5,
        "iterations_after": 4,
        "mean_fall": 900.0,
        "per_sighting": 1.0,
    }
    cell = restart_runs_cell([dict(runs[0], f_turns=[unsettled]), runs[1]])
    assert cell.startswith("range_mm 3000: ") and "(EM unsettled); range_mm 1000: " in cell
    bend = {"channel": "range_mm", "sign": "bends", "slopes": [0.7, 2.1], "distances_mm": [1000.0, 3000.0]}
    both = [dict(runs[0], f_turns=[bend]), dict(runs[1], f_turns=[bend, *runs[0]["f_turns"]])]
    assert "(f bent); range_mm 1000: " in restart_runs_cell(both) and restart_runs_cell(both).endswith(
        "(f turned and bent)"
    )
