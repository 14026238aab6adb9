"""Issue 94, item 1: a learned model's one-step-ahead innovations on another run, against its predictive law
(learn/em/uses/consistency.py), through `evaluate log` and `localize`."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import norm
from scipy.stats import t as student_t
from typer.testing import CliRunner

from sensact.cli import app
from sensact.learn.em.uses.consistency import Z90, consistency, normal_scores, reading_key

runner = CliRunner()


def test_the_scores_are_the_predictive_laws_quantiles_in_n01():
    """Exact: a Student-t channel's 95th percentile is N(0, 1)'s; a Gaussian one's score is the innovation."""
    nu = 4.0
    assert normal_scores(np.array([student_t.ppf(0.95, nu)]), "student_t", nu)[0] == pytest.approx(Z90, abs=1e-9)
    z = np.array([-2.0, 0.3, np.nan])
    assert np.array_equal(normal_scores(z, "none", 0.0), z, equal_nan=True)
    assert Z90 == pytest.approx(norm.ppf(0.95))
    assert [reading_key(n) for n in ("range_mm", "height_px", "sonar1", "_mm")] == ["range", "height", "sonar1", "_mm"]


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """A model learned on one simulated minute, and another minute of the same robot (another seed)."""
    root = tmp_path_factory.mktemp("runs")
    for name, seed in (("a", "1"), ("b", "2")):
        res = runner.invoke(
            app, ["simulate", "diffdrive", "--out", str(root / name), "--seconds", "90", "--seed", seed]
        )
        assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["learn", "em", str(root / "a"), "--out", str(root / "m.json"), "--no-report"])
    assert res.exit_code == 0, res.output
    return root / "a", root / "b", root / "m.json"


def _placed(model: Path, log: Path):
    from sensact.app.logs import read_model_and_log
    from sensact.learn.em.uses.place import learned_config, localize

    doc, m, opened = read_model_and_log(log, model, 21, use="run")
    return localize(m, opened.data, learned_config(doc["summary"]["config"])).model, opened.data


def test_a_learned_model_is_honest_on_another_run_and_a_wrong_sigma_is_not(two_runs):
    """Seeded recovery: the model learned on run a holds 90 % of run b's readings in its 90 % intervals; the
    same model with every sigma halved holds fewer, doubled nearly all. (The innovation's variance holds the
    pose's uncertainty too, which the sigmas do not scale: a bearing's NIS moves less than 4 or 1/4.)"""
    _, b, model = two_runs
    placed, data = _placed(model, b)
    held = consistency(placed, data)
    assert held.filter_ok and set(held.readings) == {"range", "bearing"}
    for r in held.readings.values():
        assert r.n > 200 and 0.85 <= r.coverage90 <= 0.95 and 0.6 <= r.nis_mean <= 1.6
    for scale, check in ((0.5, lambda r: r.coverage90 < 0.87 and r.nis_mean > 1.3),
                         (2.0, lambda r: r.coverage90 > 0.97 and r.nis_mean < 0.6)):  # fmt: skip
        s = placed.sensor
        channels = tuple(replace(ch, sigma=ch.sigma * scale) for ch in s.channels)
        wrong = placed.replace(sensor=replace(s, channels=channels, sigma_bearing_rad=s.sigma_bearing_rad * scale))
        assert all(check(r) for r in consistency(wrong, data).readings.values())


def test_evaluate_log_and_localize_write_the_consistency_the_issue_names(two_runs, tmp_path):
    _, b, model = two_runs
    res = runner.invoke(app, ["evaluate", "log", str(b), "--model", str(model), "--out", str(tmp_path / "e.json")])
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "e.json").read_text())
    for name in ("range", "bearing"):
        assert 0.85 <= doc["consistency"][name]["coverage90"] <= 0.95
        assert doc["consistency"][name]["nis_mean"] > 0
    assert doc["evaluation"]["path"]["median_mm"] <= 80.0
    res = runner.invoke(app, ["localize", str(b), "--model", str(model), "--out", str(tmp_path / "p.json")])
    assert res.exit_code == 0, res.output
    placed = json.loads((tmp_path / "p.json").read_text())
    assert placed["consistency"]["range"] == doc["consistency"]["range"]  # the same placement, the same filter
    learned = json.loads(model.read_text())["consistency"]  # and on the log it was learned on
    assert learned["range"]["n"] > 200 and 0.8 <= learned["range"]["coverage90"] <= 1.0
