"""EM's searches beyond the thesis: the start race, the ridge search along the robot's forward axis, the
command-delay search, and the start search grid, which turns and moves with the map."""

from __future__ import annotations

import math
import threading
from dataclasses import replace
from functools import partial
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import assert_written
from continuous_robot import LANDMARKS, TruthLog, continuous_config, simulate_continuous, tiny_track
from sensact import cli
from sensact.errors import ConfigError
from sensact.learn.em import EMConfig, e_step, fit_em, initial_model, log_likelihood
from sensact.learn.em.loop import held_trial
from sensact.learn.em.mstep import sample_gamma
from sensact.learn.em.searches.delay import search_delay, with_delay
from sensact.learn.em.searches.ridge import search_ridge, shifted_forward
from sensact.learn.em.searches.start_race import race_starts, race_trials, search_grid, start_candidates
from sensact.records import to_json


def test_start_race_halves_the_field_on_the_held_gaussian_likelihood():
    """The race's bookkeeping with a scripted EM: six candidates, then three, then two, then the best;
    every trial runs the held, Gaussian, unpruned stage so that their likelihoods compare."""
    data, _ = simulate_continuous(6, T=600)
    cfg = continuous_config(start_search_s=10.0, refine_from=100, prune_rad_per_step=0.6)
    start = initial_model(data, cfg)
    quality = [3.0, 1.0, 6.0, 2.0, 5.0, 4.0]  # candidate 2 is best; 4 second
    cands = [start.replace(prior_mean=np.array([q, 0.0, 0.0])) for q in quality]
    seen = []

    class Trial:  # what loop.held_trial returns, as far as the race reads it
        def __init__(self, model, iterations):
            self.model, self.iterations = model, iterations
            self.loglik_best = 100.0 * model.prior_mean[0] - model.prior_mean[1]

    def run(data, model, iterations):
        seen.append(iterations)
        return Trial(model.replace(prior_mean=model.prior_mean + np.array([0.0, 1.0, 0.0])), iterations)

    heard = []
    model, info = race_starts(data, cands, cfg, run, on_trial=lambda done, planned: heard.append((done, planned)))
    assert [len(r) for r in info.rounds] == [6, 3, 2] and info.winner == 2
    assert heard == [(k, 11) for k in range(1, 12)]  # every trial heard of once, in order, out of 6 + 3 + 2
    assert set(info.rounds[1]) == {"2", "4", "5"} and set(info.rounds[2]) == {"2", "4"}
    assert model.prior_mean[0] == 6.0 and model.prior_mean[1] == 3.0  # the winner's model after 3 rounds
    assert info.winner_iterations == 3 * cfg.search.start_trial_iterations
    assert seen == [cfg.search.start_trial_iterations] * 11


def test_race_trials_counts_each_round_until_two_are_left():
    """The progress bar's total: a field of n, then halves rounded up, until two are left."""
    assert [race_trials(n) for n in (1, 2, 3, 4, 5, 6, 7, 9)] == [1, 2, 5, 6, 10, 11, 13, 19]


def test_start_race_does_not_rerun_a_trial_that_found_nothing_better():
    """A trial whose best model is its start would repeat itself exactly; the race reuses its score and
    still counts its iterations, so the winner's EM budget is the same as if it had run."""
    data, _ = simulate_continuous(6, T=600)
    cfg = continuous_config(start_search_s=10.0, refine_from=100)
    start = initial_model(data, cfg)
    cands = [start.replace(prior_mean=np.array([q, 0.0, 0.0])) for q in (1.0, 5.0, 3.0, 4.0)]
    runs = []

    class Trial:
        def __init__(self, model, iterations):
            self.model, self.iterations = model, iterations
            self.loglik_best = 100.0 * model.prior_mean[0] + model.prior_mean[1]

    def run(data, model, iterations):
        runs.append(model.prior_mean[0])
        if model.prior_mean[0] == 5.0:  # stalls: its best model is the one it was given
            return Trial(model, iterations)
        return Trial(model.replace(prior_mean=model.prior_mean + np.array([0.0, 1.0, 0.0])), iterations)

    heard = []
    model, info = race_starts(data, cands, cfg, run, on_trial=lambda done, planned: heard.append((done, planned)))
    assert [len(r) for r in info.rounds] == [4, 2] and info.winner == 1
    assert heard == [(1, 6), (2, 6), (3, 6), (4, 6), (5, 6), (6, 6)]  # the stalled one's second trial: done unrun
    assert runs.count(5.0) == 1 and runs.count(4.0) == 2  # the stalled one ran once, the other twice
    assert info.rounds[0]["1"] == info.rounds[1]["1"] == 500.0
    assert info.winner_iterations == 2 * cfg.search.start_trial_iterations
    assert model is cands[1]


def test_start_race_runs_a_round_in_threads_and_gives_the_serial_race():
    """Invariant: the trials of a round run at once (two of them meet at a barrier, which a serial race
    would never reach), and with the real EM the threaded race gives the serial one's scores and
    winner exactly, the trials being seeded and independent."""
    data, _ = simulate_continuous(6, T=600)
    cfg = continuous_config(start_search_s=10.0, refine_from=100, start_trial_iterations=4)
    start = initial_model(data, cfg)
    cands = [start.replace(prior_mean=start.prior_mean + np.array([dx, dy, 0.0])) for dx, dy in
             [(0.0, 0.0), (400.0, 0.0), (0.0, -400.0), (-300.0, 300.0)]]  # fmt: skip
    barrier = threading.Barrier(2, timeout=10)

    trial = partial(held_trial, cfg=cfg)

    def meeting(data, model, iterations):
        barrier.wait()  # raises BrokenBarrierError after 10 s alone
        return trial(data, model, iterations)

    race_starts(data, cands[:2], cfg, meeting, workers=2)
    serial_model, serial = race_starts(data, cands, cfg, trial, workers=1)
    threaded_model, threaded = race_starts(data, cands, cfg, trial, workers=3)
    assert threaded == serial and len(serial.rounds) == 2
    np.testing.assert_array_equal(threaded_model.prior_mean, serial_model.prior_mean)
    np.testing.assert_array_equal(threaded_model.action.coefficients, serial_model.action.coefficients)


def test_shifted_forward_reads_the_same_from_further_ahead(continuous_fit):
    """Exact reduction: the shifted model's start is ``delta`` ahead along its heading, its range
    function is ``f(d + delta)``, and nothing else changes; a zero shift is the model itself."""
    m = continuous_fit[2].model.replace(prior_mean=np.array([100.0, -50.0, 0.3]))
    moved = shifted_forward(m, 200.0)
    ahead = np.array([-200.0 * math.sin(0.3), 200.0 * math.cos(0.3), 0.0])  # theta = 0 faces +y
    assert moved.prior_mean == pytest.approx(m.prior_mean + ahead)
    d = np.array([500.0, 1500.0, 4000.0])
    f, g = m.sensor.channels[0].function, moved.sensor.channels[0].function
    assert g(d) == pytest.approx(f(d + 200.0), rel=1e-12)
    assert np.array_equal(moved.action.coefficients, m.action.coefficients)
    assert np.array_equal(moved.prior_cov, m.prior_cov) and moved.sensor.sigma_bearing_rad == m.sensor.sigma_bearing_rad
    same = shifted_forward(m, 0.0)
    assert np.array_equal(same.prior_mean, m.prior_mean) and same.sensor.channels[0].function(d) == pytest.approx(f(d))


def test_ridge_search_finds_a_model_moved_behind_and_never_lowers_the_likelihood(continuous_fit):
    """Seeded recovery: EM's converged model moved 250 mm behind (and its f read 250 mm further) is
    found again by the search; from the converged model itself it stays within a few centimetres, and in
    both cases the likelihood does not fall."""
    data, _, res = continuous_fit

    def evaluate(m):
        return e_step(m, data)

    def score(m):
        return log_likelihood(m, data)

    behind = shifted_forward(res.model, -250.0)
    model, post, info = search_ridge(behind, evaluate(behind), score, evaluate, 500.0)
    assert info.shift_mm == pytest.approx(250.0, abs=40.0)
    assert post.loglik == info.loglik_after > info.loglik_before + 10.0
    assert model.prior_mean == pytest.approx(res.model.prior_mean, abs=45.0)
    _, _, info0 = search_ridge(res.model, evaluate(res.model), score, evaluate, 500.0)
    assert abs(info0.shift_mm) < 40.0 and info0.loglik_after >= info0.loglik_before
    assert 0 < info0.forward_passes <= 30 and info0.expansions == 0
    # beyond the bracket: the search starts again from its edge until the peak is inside
    far = shifted_forward(res.model, -900.0)
    model, post, info = search_ridge(far, evaluate(far), score, evaluate, 500.0)
    assert info.shift_mm == pytest.approx(900.0, abs=40.0) and info.expansions >= 1
    assert post.loglik == info.loglik_after > info.loglik_before + 10.0
    assert model.prior_mean == pytest.approx(res.model.prior_mean, abs=45.0)
    # the shift it found is smoothed once; a smoother that fails there leaves the model where it was
    start = evaluate(behind)
    model, post, info = search_ridge(behind, start, score, lambda m: replace(start, ok=False), 500.0)
    assert model is behind and post is start and info.shift_mm == 0.0


@pytest.fixture(scope="module")
def delayed_fit():
    data, poses = simulate_continuous(3, T=3000, delay_steps=6)
    return data, poses, fit_em(data, None, continuous_config(action_delay_max_s=0.5, max_iterations=60))


def test_delay_search_finds_the_command_delay_and_never_lowers_the_likelihood(delayed_fit):
    """Seeded recovery: a robot that obeys its commands 6 steps late. EM's model with its delay set to
    0, and to 15, is brought back to 6 (+-1) by the search, with beta unchanged; from EM's own model
    the search keeps its delay, and the likelihood never falls."""
    data, _, res = delayed_fit
    assert res.model.action.delay_steps == pytest.approx(6, abs=1)

    def evaluate(m):
        return e_step(m, data)

    def score(m):
        return log_likelihood(m, data)

    for wrong in (0, 15):
        start = with_delay(res.model, wrong)
        model, post, info = search_delay(start, evaluate(start), score, evaluate, 15)
        assert info.delay_from == wrong and abs(info.delay_to - 6) <= 1
        assert model.action.delay_steps == info.delay_to
        assert np.array_equal(model.action.coefficients, res.model.action.coefficients)
        assert post.loglik == info.loglik_after > info.loglik_before + 10.0
        assert info.forward_passes <= 10  # 0, 3, ..., 15, then the best one's neighbours
    start = with_delay(res.model, 0)
    first = evaluate(start)
    model, post, info = search_delay(start, first, score, lambda m: replace(first, ok=False), 15)
    assert model is start and post is first and info.delay_to == 0  # its smoother failed: stay
    same, _, info0 = search_delay(res.model, evaluate(res.model), score, evaluate, 15)
    assert info0.loglik_after >= info0.loglik_before
    assert abs(same.action.delay_steps - res.model.action.delay_steps) <= 1
    # a robot without a delay: searched from the same config, EM learns none
    prompt, _ = simulate_continuous(3, T=3000)
    assert (
        fit_em(prompt, None, continuous_config(action_delay_max_s=0.5, max_iterations=60)).model.action.delay_steps <= 1
    )


def test_fit_searches_the_delay_on_the_ridge_schedule_only_when_a_delay_is_learned(tmp_path):
    """Exact bookkeeping: the delay search runs when the held stage ends and every search_every
    iterations after, is in the summary, never lowers the likelihood, and is off with
    ``delay_search: false`` or without a delay to learn (then EM is as before, bit for bit)."""
    data, poses = simulate_continuous(3, T=1500, delay_steps=6)
    cfg = continuous_config(
        refine_from=4, max_iterations=12, patience=50, search_every=3, action_delay_max_s=0.5, accelerate=False
    )
    on = fit_em(data, None, cfg)
    assert [r.iteration for r in on.delay_search] == [4, 7, 10]
    for r in on.delay_search:
        assert r.loglik_after >= r.loglik_before and 0 <= r.delay_to <= 15
        assert on.loglik_history[r.iteration] == r.loglik_after
    assert on.summary()["delay_search"] == to_json(on.delay_search) and on.ridge is None
    off = fit_em(
        data,
        None,
        continuous_config(refine_from=4, max_iterations=12, search_every=3, action_delay_max_s=0.5, delay_search=False),
    )
    assert off.delay_search is None
    # the report sets the learned delay beside From-Truth's, with the searches' moves
    from sensact.experiments.real import evaluate_mrclam
    from sensact.report.tables_real import real_tables

    row = {"em": on.summary(), "score": evaluate_mrclam(TruthLog(data, poses), on)}
    _, headers, cells = real_tables({"mrclam": {"on": row}})[0]
    cell = cells[0][headers.index("command delay s, learned / From-Truth")]
    assert cell.startswith(f"{on.model.action.delay_steps * data.dt_s:.3f} / ")
    moved = [r for r in on.delay_search if r.delay_to != r.delay_from]
    assert moved and f"{moved[0].delay_from}->{moved[0].delay_to}" in cell
    from sensact.report.figures_real import figure_loglik

    assert figure_loglik({"on": on}, tmp_path / "ll.png").stat().st_size > 0  # delay searches, no ridge
    # the CLI says where each search moved the delay
    from typer.testing import CliRunner

    from sensact.io.landmark_folder import write_landmark_log

    write_landmark_log(tmp_path / "log", data)
    sets = [
        "action_basis=affine",
        "action_delay_max_s=0.5",
        "motion_noise=shared",
        "refine_from=4",
        "search_every=3",
        "max_iterations=8",
        "prune_rad_per_step=0",
        "accelerate=false",  # the schedule counts plain EM's iterations
    ]
    run = CliRunner().invoke(cli.app, ["learn", "em", str(tmp_path / "log")] + [a for x in sets for a in ("--set", x)])
    assert_written(run)
    assert "delay search at iteration 4: command delay" in run.output
    plain = fit_em(data, None, continuous_config(refine_from=4, max_iterations=12, search_every=3))
    plain_off = fit_em(
        data, None, continuous_config(refine_from=4, max_iterations=12, search_every=3, delay_search=False)
    )
    assert plain.delay_search is None
    assert np.array_equal(plain.loglik_history, plain_off.loglik_history)


def test_fit_searches_the_ridge_when_the_held_stage_ends_and_every_so_often_after(tmp_path):
    from sensact.experiments.real import evaluate_mrclam
    from sensact.report.figures_real import figure_loglik
    from sensact.report.tables_real import real_tables

    data, poses = simulate_continuous(2, T=1500)
    off = fit_em(data, None, continuous_config(refine_from=4, max_iterations=12, accelerate=False))
    cfg = continuous_config(
        refine_from=4, max_iterations=12, patience=50, ridge_search_mm=300.0, search_every=3, accelerate=False
    )
    on = fit_em(data, None, cfg)
    assert off.ridge is None and on.freed_at == 4
    assert [r.iteration for r in on.ridge] == [4, 7, 10]
    # with nothing held (refine_from 0) the searches count from the start
    unheld = fit_em(
        data, None, continuous_config(refine_from=0, max_iterations=8, ridge_search_mm=300.0, search_every=3)
    )
    assert unheld.freed_at == -1 and [r.iteration for r in unheld.ridge] == [3, 6]
    for r in on.ridge:
        assert r.loglik_after >= r.loglik_before and abs(r.shift_mm) <= 300.0
        assert on.loglik_history[r.iteration] == r.loglik_after  # the history holds the moved model
    assert on.posteriors.loglik == on.loglik_best  # the reported best is the returned model's likelihood
    assert on.summary()["ridge"] == to_json(on.ridge)
    with pytest.raises(ValueError, match=r"search\.ridge_mm"):
        continuous_config(ridge_search_mm=-1.0)
    with pytest.raises(ValueError, match=r"search\.every"):
        continuous_config(search_every=0)
    with pytest.raises(ConfigError, match=r"t\.csv: search\.ridge_mm: .* needs a planar log"):
        fit_em(tiny_track(), None, EMConfig.of(ridge_search_mm=100.0))
    # the report lists each search's move, and a dash for a run without the search
    rows = {
        name: {"em": r.summary(), "score": evaluate_mrclam(TruthLog(data, poses), r)}
        for name, r in (("on", on), ("off", off))
    }
    _, headers, cells = real_tables({"mrclam": rows})[0]
    col = headers.index("ridge moves mm, forward (the first as the held stage ends)")
    assert [float(m) for m in cells[0][col].split(", ")] == pytest.approx([r.shift_mm for r in on.ridge], abs=0.5)
    assert cells[1][col] == "-"
    # the noise table sets the learned Sigma_m's translational walk over 1 s beside the truth's miss
    title, nh, ncells = next(t for t in real_tables({"mrclam": rows}) if "what the truth says" in t[0])
    col = nh.index("sideways / forward miss per 1 s mm, truth; Sigma_m")
    side, fwd = math.sqrt(30) * on.model.motion_sd[0, :2]
    assert ncells[0][col].endswith(f"; {side:.1f} / {fwd:.1f}")
    del rows["on"]["score"]["truth_noise"]["translation_drift_rms_mm"]  # results written before it
    assert next(t for t in real_tables({"mrclam": rows}) if t[0] == title)[2][0][col] == "-"
    assert figure_loglik({"on": on, "off": off}, tmp_path / "ll.png").stat().st_size > 0


def test_start_search_candidates_are_distinct_and_one_is_near_the_start():
    data, poses = simulate_continuous(6, T=4500)
    cfg = continuous_config(start_search_s=20.0, start_candidates=6)
    cands, info = start_candidates(data, initial_model(data, cfg), cfg)
    means = np.array([c.prior_mean for c in cands])
    assert len(cands) == 6 == len(info.candidates)
    gaps = np.hypot(*(means[:, None, :2] - means[None, :, :2]).transpose(2, 0, 1))
    assert gaps[~np.eye(6, dtype=bool)].min() >= 2.5 * cfg.search.start_grid_mm
    assert np.hypot(*(means[:, :2] - poses[0, :2]).T).min() <= math.sqrt(2) * cfg.search.start_grid_mm  # a cell


def _turn(xy: np.ndarray, angle: float, shift=(0.0, 0.0)) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.asarray(xy) @ np.array([[c, s], [-s, c]]) + shift


def test_start_search_grid_turns_and_moves_with_the_map():
    """Invariant: the grid is the map's own, so turning and moving the map turns and moves the grid
    point for point; it covers every landmark and four cells around the map, and keeps off the
    first sighting's landmark. One landmark, or one at the centroid, still give a grid."""
    g = 500.0
    grid = search_grid(LANDMARKS, LANDMARKS[1], g)
    for angle, shift in [(1.0, (5000.0, -3000.0)), (-2.5, (0.0, 0.0)), (math.pi / 2, (-120.0, 7.0))]:
        moved = search_grid(_turn(LANDMARKS, angle, shift), _turn(LANDMARKS[1], angle, shift), g)
        np.testing.assert_allclose(moved, _turn(grid, angle, shift), atol=1e-6)
    near = np.hypot(*(grid[:, None, :] - LANDMARKS[None, :, :]).transpose(2, 0, 1)).min(axis=0)
    assert near[[0, 2, 3, 4]].max() <= g / math.sqrt(2) + 1e-9  # every other landmark is in a cell of it
    assert np.hypot(*(grid - LANDMARKS[1]).T).min() >= 1.5 * g  # the four cells about the landmark are left out
    # the grid reaches four cells past the map along its own axes: past the farthest landmark too
    assert np.hypot(*(grid - LANDMARKS[1]).T).max() >= np.hypot(*(LANDMARKS - LANDMARKS[1]).T).max() + 4 * g
    one = search_grid(LANDMARKS[:1], LANDMARKS[0], g)
    assert len(one) == 10 * 10 - 4 and np.allclose(one.mean(axis=0), LANDMARKS[0])
    ring = np.array([[0.0, 0.0], [1000.0, 0.0], [-1000.0, 0.0]])  # the first landmark is the centroid
    assert len(search_grid(ring, ring[0], g)) > 0


def test_pose_samples_turn_with_the_map():
    """Invariant: the M-step's poses (sec. 4.3.2) drawn from a posterior turned with the map are the
    same draws turned, for the same seed; their spread is still Sigma_gamma."""
    rng = np.random.default_rng(3)
    k = 40
    mean = np.column_stack([rng.normal(size=(k, 2)) * 1000, rng.uniform(-3, 3, k)])
    a = rng.normal(size=(k, 3, 3)) * [30.0, 30.0, 0.01]
    cov = a @ a.transpose(0, 2, 1) + np.diag([1.0, 1.0, 1e-6])
    angle = 1.0
    rot = np.eye(3)
    rot[:2, :2] = [[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]
    turned = SimpleNamespace(mean_gamma=mean @ rot.T + [5000.0, -3000.0, angle], cov_gamma=rot @ cov @ rot.T)
    here = sample_gamma(SimpleNamespace(mean_gamma=mean, cov_gamma=cov), np.arange(k), 5, np.random.default_rng(0))
    there = sample_gamma(turned, np.arange(k), 5, np.random.default_rng(0))
    np.testing.assert_allclose(there, here @ rot.T + [5000.0, -3000.0, angle], atol=1e-6)
    many = sample_gamma(SimpleNamespace(mean_gamma=mean[:1], cov_gamma=cov[:1]), np.zeros(200_000, int), 1, rng)[0]
    scale = np.sqrt(np.outer(np.diag(cov[0]), np.diag(cov[0])))
    assert np.abs((np.cov(many.T) - cov[0]) / scale).max() < 0.01


def test_a_turned_and_moved_map_learns_the_same_model():
    """Invariant: the map's frame is arbitrary, so a log whose map is turned by 1 rad and moved 5 m
    learns the same action model, sensor model and Sigma_m from the same poor start (start search,
    race and all), and starts at the same pose turned with the map."""
    data, _ = simulate_continuous(6, T=3000)
    moved = replace(data, landmarks_xy=_turn(data.landmarks_xy, 1.0, (5000.0, -3000.0)))
    cfg = continuous_config(start_search_s=20.0, start_candidates=3, start_trial_iterations=5, max_iterations=30)
    heard = []
    here = fit_em(
        data,
        None,
        cfg,
        on_iteration=lambda it, *_: heard.append(("iteration", it)),
        on_race=lambda done, planned: heard.append(("race", done, planned)),
    )
    there = fit_em(moved, None, cfg)
    a, b = here.model, there.model
    assert here.iterations == there.iterations > 0
    # the start race's progress, every trial of its rounds, before the first iteration's
    race = [h for h in heard if h[0] == "race"]
    trials = sum(len(r) for r in here.start_search.race.rounds)
    assert race == [("race", k, 5) for k in range(1, trials + 1)] and heard[: len(race)] == race
    assert heard[len(race)] == ("iteration", 0)
    np.testing.assert_allclose(b.action.coefficients, a.action.coefficients, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(b.motion_sd, a.motion_sd, rtol=1e-6)
    for cb, ca in zip(b.sensor.channels, a.sensor.channels, strict=True):
        np.testing.assert_allclose(cb.function.coef, ca.function.coef, rtol=1e-6, atol=1e-9)
        assert cb.sigma == pytest.approx(ca.sigma, rel=1e-6)
    assert b.sensor.sigma_bearing_rad == pytest.approx(a.sensor.sigma_bearing_rad, rel=1e-6)
    assert here.loglik_best == pytest.approx(there.loglik_best, abs=1e-6 * abs(here.loglik_best))
    np.testing.assert_allclose(b.prior_mean[:2], _turn(a.prior_mean[:2], 1.0, (5000.0, -3000.0)), atol=1e-3)
    assert float(np.angle(np.exp(1j * (b.prior_mean[2] - a.prior_mean[2] - 1.0)))) == pytest.approx(0.0, abs=1e-9)
