"""`--uncertainty information` (learn/em/uses/information.py): the observed information and the profiles
reduce to the Gaussian's exact intervals on a quadratic log-likelihood, an unbounded direction gives an
open interval, and on a simulated log the model JSON gets an interval for every learned parameter."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import assert_written
from sensact.cli import app
from sensact.learn.em.uses.error_bars import Parameter, Z
from sensact.learn.em.uses.information import PROFILE_DROP, Curvature, _profile, observed_information

runner = CliRunner()


class Quadratic:
    """A stand-in for ``LearnedSpace``: ``log L(p) = -(p - mu)' A (p - mu) / 2``, flat along ``flat``."""

    def __init__(self, A: np.ndarray, mu: np.ndarray) -> None:
        self.A, self.mu = A, mu

    def loglik(self, p: np.ndarray) -> float:
        d = p - self.mu
        return float(-0.5 * d @ self.A @ d)


@pytest.fixture
def gaussian():
    rng = np.random.default_rng(3)
    M = rng.normal(size=(4, 4))
    A = M @ M.T + np.diag([1.0, 4.0, 0.01, 100.0])  # scales 100x apart, correlated
    return Quadratic(A, np.array([1.0, -2.0, 30.0, 0.5]))


def test_the_observed_information_of_a_quadratic_is_its_matrix(gaussian):
    info, scale, top = observed_information(gaussian, gaussian.mu)
    assert top == 0.0
    np.testing.assert_allclose(info, gaussian.A, rtol=1e-6, atol=1e-9 * np.abs(gaussian.A).max())
    curve = Curvature.of(info, scale)
    np.testing.assert_allclose(curve.cov, np.linalg.inv(gaussian.A), rtol=1e-5)
    g = np.array([1.0, 0.0, -2.0, 0.5])  # a function's variance: g' A^-1 g (the delta method)
    assert curve.variance(g) == pytest.approx(g @ np.linalg.inv(gaussian.A) @ g, rel=1e-5)


def test_a_quadratic_profile_is_the_wald_interval_wherever_it_starts(gaussian):
    C = np.linalg.inv(gaussian.A)
    for j in range(4):
        sd = math.sqrt(C[j, j])
        for start in (gaussian.mu, gaussian.mu + 0.7 * np.sqrt(np.diag(C))):  # at the top, and off it
            lo, hi = _profile(gaussian, start, C, gaussian.A, np.sqrt(np.diag(C)), j)
            # chi^2_1's 90 % point is z_0.95 squared: the profile's interval is mu +- 1.645 sd, exactly
            assert math.isclose(2 * PROFILE_DROP, Z**2, rel_tol=1e-12)
            assert lo == pytest.approx(gaussian.mu[j] - Z * sd, rel=1e-3, abs=1e-3 * sd)
            assert hi == pytest.approx(gaussian.mu[j] + Z * sd, rel=1e-3, abs=1e-3 * sd)


def test_a_direction_the_likelihood_does_not_bound_is_open():
    A = np.diag([4.0, 0.0])  # the second entry does not move the likelihood
    space = Quadratic(A, np.zeros(2))
    info, scale, _ = observed_information(space, np.zeros(2))
    curve = Curvature.of(info, scale)
    assert curve.variance(np.array([1.0, 0.0])) == pytest.approx(0.25)
    assert math.isinf(curve.variance(np.array([0.0, 1.0]))) and math.isinf(curve.variance(np.array([1.0, 0.1])))
    assert _profile(space, np.zeros(2), curve.cov, info, scale, 1) == (None, None)


def test_an_open_end_holds_everything_beyond_it():
    p = Parameter("Sigma_m[0].v_x_mm_s", "Sigma_m", 1.0, None, (0.0, None), None, (True, True))
    assert p.covers(1e9) and p.covers(0.0) and not p.covers(-1.0) and not p.held
    assert p.to_dict()["interval"] == [0.0, None] and p.to_dict()["open_ended"] == [True, True]


@pytest.mark.slow
def test_learn_em_gives_every_learned_parameter_an_interval_from_the_likelihood(tmp_path):
    log, out = tmp_path / "log", tmp_path / "m" / "model.json"
    # 90 s, as the coverage check's logs (30 s can leave EM at a saddle, where the intervals are open)
    assert runner.invoke(app, ["simulate", "diffdrive", "--out", str(log), "--seconds", "90"]).exit_code == 0
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(out), "--uncertainty", "information"])
    assert_written(res)
    doc = json.loads(out.read_text())
    unc = doc["uncertainty"]
    assert unc["method"] == "observed information"
    params = unc["parameters"]
    assert {p["family"] for p in params.values()} == {"action", "f", "sigma", "Sigma_m", "mount"}
    held = {n for n, p in params.items() if p["held"]}
    assert held == {n for n, p in params.items() if p["family"] == "action" and p["value"] == 0.0}
    bounded = 0
    for name, p in params.items():
        if p["held"]:
            continue
        lo, hi = p["interval"]
        if p["family"] in ("sigma", "Sigma_m"):  # a profile on the log scale: positive, or open at 0
            assert (lo > 0 or p["open_ended"][0]) and (hi is None or hi > lo), name
        elif p["se"] is None:  # along a direction the likelihood does not bound: open both ways
            assert (lo, hi) == (None, None) and p["open_ended"] == [True, True], name
        else:  # Wald: symmetric about the value, 1.645 standard errors each side
            bounded += 1
            assert p["se"] > 0 and lo == pytest.approx(p["value"] - Z * p["se"]), name
            assert hi == pytest.approx(p["value"] + Z * p["se"]), name
    assert bounded >= 8  # the action model's and f's at least
    assert "From the likelihood itself" in (out.parent / "report.html").read_text()


def test_uncertainty_is_information_or_a_count(tmp_path):
    log = tmp_path / "log"
    assert runner.invoke(app, ["simulate", "diffdrive", "--out", str(log), "--seconds", "20"]).exit_code == 0
    for bad in ("banana", "2.5"):
        res = runner.invoke(app, ["learn", "em", str(log), "--uncertainty", bad])
        assert res.exit_code == 2 and "neither 'information' nor a number" in res.output


def test_the_sandwich_reduces_to_the_information_when_the_scores_spread_as_it_says(gaussian):
    """Exact reduction: with the meat equal to the information (a correct model's scores), I^-1 B I^-1 is
    I^-1; and the meat sums each block's scores before their outer product."""
    from types import SimpleNamespace

    from sensact.learn.em.uses.information import sandwich_meat

    info, scale, _ = observed_information(gaussian, gaussian.mu)
    curve = Curvature.of(info, scale)
    np.testing.assert_allclose(curve.sandwiched(info).cov, curve.cov, rtol=1e-8, atol=1e-12)
    scores = np.array([[1.0, 0.0], [2.0, 1.0], [0.0, -1.0], [3.0, 3.0]])
    log = SimpleNamespace(dt_s=0.5, obs_step=np.array([0, 1, 2, 5]))  # blocks of 1 s: two steps each
    summed = np.array([[3.0, 1.0], [0.0, -1.0], [3.0, 3.0]])
    np.testing.assert_allclose(sandwich_meat(scores, log), summed.T @ summed)


def test_the_sightings_shares_sum_to_the_likelihood():
    """Invariant: the per-sighting shares the sandwich differentiates add up to the forward pass's total."""
    from sensact.learn.em import EMConfig, fit_em, initial_model
    from sensact.learn.em.estep import log_likelihood, sighting_logliks
    from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

    data = to_landmark_log(simulate_field(Field2DConfig(seconds=60.0, seed=2)))
    em = EMConfig.of(max_iterations=10, prune_rad_per_step=0.0)
    model = fit_em(data, initial_model(data, em), em).model
    shares = sighting_logliks(model, data)
    assert shares is not None and np.count_nonzero(shares) > 0.9 * data.n_observations
    assert shares.sum() == pytest.approx(log_likelihood(model, data), rel=1e-12)


@pytest.mark.slow
def test_a_coverage_trial_gives_the_sandwich_beside_the_information():
    """`reproduce uncertainty`'s trial: both likelihood methods give every action, f and mount parameter a
    finite interval about the same value, the profiled sigmas the same interval both ways."""
    from dataclasses import replace

    from sensact.experiments.coverage import CoverageExperiment, coverage_trial, truth_of
    from sensact.sim.diffdrive import DiffDriveConfig

    exp = replace(CoverageExperiment(), simulator=DiffDriveConfig(seconds=45.0))
    template, truth, config = truth_of(exp)
    trial = coverage_trial(template, truth, config, 1, 0)
    assert trial.sandwich is not None and trial.sandwich.method == "sandwich"
    info, sand = trial.information.by_name(), trial.sandwich.by_name()
    assert info.keys() == sand.keys()
    for name, p in info.items():
        s = sand[name]
        assert s.value == p.value
        if p.family == "sigma":
            assert s.interval == p.interval
        elif p.se is not None and p.family in ("action", "f", "mount"):
            assert s.se is not None and 0 < s.se < 10 * p.se and p.se < 10 * s.se, name
