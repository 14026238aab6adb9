"""`sensact fleet learn` on a LocalCluster of 2 workers: each log's model is `learn em`'s, a bad log is
reported and does not stop the others, and the cross-scores are `evaluate fleet`'s."""

from __future__ import annotations

import json
import shutil

import pytest
from typer.testing import CliRunner

from conftest import assert_written
from sensact.cli import app

runner = CliRunner()
pytest.importorskip("distributed", reason="the fleet extra (dask.distributed) comes with the test extra")


def _model(path):
    doc = json.loads(path.read_text())
    doc["summary"].pop("seconds")  # EM's own timing, the one field that differs
    return doc


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Two simulated robots and a log whose actions.csv is broken, through `fleet learn` on 2 workers."""
    root = tmp_path_factory.mktemp("fleet")
    for name, seed in (("a", "1"), ("b", "2")):
        res = runner.invoke(
            app, ["simulate", "diffdrive", "--out", str(root / name), "--seconds", "30", "--seed", seed]
        )
        assert res.exit_code == 0, res.output
    shutil.copytree(root / "a", root / "broken")
    (root / "broken" / "actions.csv").write_text("t_s,v_mm_s,omega_rad_s\n0.0,abc,0.1\n")
    logs = [str(root / g) for g in ("a", "b", "broken")]
    res = runner.invoke(app, ["fleet", "learn", *logs, "--out", str(root / "F"), "--workers", "2", "--no-report"])
    return root, res


@pytest.mark.slow
def test_each_model_is_learn_ems_and_a_bad_log_stops_no_other(fleet):
    root, res = fleet
    assert res.exit_code == 3, res.output  # written, but not every log learned
    summary = json.loads((root / "F" / "fleet.json").read_text())
    assert (summary["learned"], summary["failed"]) == (2, 1)
    assert summary["engine"] == {"where": "a LocalCluster of 2 workers", "workers": 2}
    # issue 94: what the cluster bought, from the jobs' own times (the learned logs', not the failed one's)
    jobs = [e for e in summary["logs"].values() if e["status"] == "learned"]
    assert summary["jobs_seconds"] == pytest.approx(sum(e["job_seconds"] for e in jobs))
    assert summary["speedup_at_most"] == pytest.approx(summary["jobs_seconds"] / summary["seconds"])
    assert all(0 < e["cpu_seconds"] and e["seconds"] <= e["job_seconds"] for e in jobs)
    broken = summary["logs"]["broken"]
    assert broken["status"] == "failed" and broken["bad_input"] is True
    assert "actions.csv" in broken["error"] and "\n" not in broken["error"]
    for g in ("a", "b"):
        entry = summary["logs"][g]
        assert entry["status"] == "learned" and entry["model"] == str(root / "F" / g / "model.json")
        alone = root / f"alone_{g}.json"
        res = runner.invoke(app, ["learn", "em", str(root / g), "--out", str(alone), "--no-report"])
        assert_written(res)
        assert _model(root / "F" / g / "model.json") == _model(alone)
        assert entry["stop_reason"] == json.loads(alone.read_text())["summary"]["stop_reason"]


def test_the_cross_scores_are_evaluate_fleets(fleet):
    root, _ = fleet
    cross = json.loads((root / "F" / "fleet.json").read_text())["cross_scores"]
    assert cross["models"] == ["a", "b"] and cross["logs"] == ["a", "b"] and cross["own"] == {"a": "a", "b": "b"}
    assert (root / "F" / "fleet.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    models = [str(root / "F" / g / "model.json") for g in ("a", "b")]
    logs = [str(root / g) for g in ("a", "b")]
    scored = {}
    for workers in ("1", "2"):
        out = root / f"cross_{workers}.json"
        res = runner.invoke(
            app,
            [
                "evaluate",
                "fleet",
                *logs,
                *[x for m in models for x in ("--model", m)],
                "--out",
                str(out),
                "--workers",
                workers,
            ],
        )
        assert res.exit_code == 0, res.output
        scored[workers] = json.loads(out.read_text())
        scored[workers].pop("sensact_version")
    assert scored["1"] == scored["2"]
    # the same cells; `evaluate fleet` names the models by their files, which here are all model.json
    assert [row["a"]["per_sighting"] for row in scored["1"]["likelihood"]["cells"].values()] == [
        cross["likelihood"]["cells"][m]["a"]["per_sighting"] for m in ("a", "b")
    ]


def test_a_fleet_with_no_log_learned_exits_2(tmp_path):
    (tmp_path / "empty").mkdir()
    res = runner.invoke(
        app,
        [
            "fleet",
            "learn",
            str(tmp_path / "empty"),
            str(tmp_path / "missing"),
            "--out",
            str(tmp_path / "F"),
            "--workers",
            "1",
        ],
    )
    assert res.exit_code == 2, res.output
    # a run that failed writes nothing (issue 95): the table says why each log failed, the line the first
    assert not (tmp_path / "F").exists()
    assert "2 of 2 logs could not be learned" in res.output and "empty" in res.output and "missing" in res.output


def test_out_must_be_a_folder(tmp_path):
    (tmp_path / "F").write_text("")
    res = runner.invoke(app, ["fleet", "learn", str(tmp_path), "--out", str(tmp_path / "F"), "--workers", "1"])
    assert res.exit_code == 2
    assert "is a file" in res.output


def _untimed(doc):
    """A result without its wall-clock fields."""
    if isinstance(doc, dict):
        return {k: _untimed(v) for k, v in doc.items() if k != "seconds"}
    if isinstance(doc, list):
        return [_untimed(v) for v in doc]
    return doc


@pytest.mark.slow
@pytest.mark.parametrize(
    ("experiment", "extra"),
    [("field2d", ["--trials", "2", "--set", "seconds=120"]), ("diffdrive", ["--trials", "2", "--set", "seconds=60"])],
)
def test_reproduce_on_two_workers_gives_what_one_gives(tmp_path, experiment, extra):
    results = {}
    for workers in ("1", "2"):
        out = tmp_path / workers
        res = runner.invoke(app, ["reproduce", experiment, *extra, "--out", str(out), "--workers", workers])
        assert res.exit_code == 0, res.output
        results[workers] = _untimed(json.loads((out / f"{experiment}.json").read_text()))
    assert results["1"] == results["2"]
    assert len(results["1"]["per_trial" if experiment == "field2d" else "seeds"]) == 2


@pytest.mark.slow
def test_a_fleets_error_bars_are_learn_ems(fleet, tmp_path):
    """`fleet learn --uncertainty B` gives each log the model file `learn em --uncertainty B` writes (the
    bootstrap is seeded), timing aside."""
    root, _ = fleet
    res = runner.invoke(
        app,
        [
            "fleet",
            "learn",
            str(root / "a"),
            "--out",
            str(tmp_path / "F"),
            "--workers",
            "1",
            "--uncertainty",
            "2",
            "--no-report",
        ],
    )
    assert res.exit_code == 0, res.output
    alone = tmp_path / "alone.json"
    res = runner.invoke(app, ["learn", "em", str(root / "a"), "--out", str(alone), "--uncertainty", "2", "--no-report"])
    assert_written(res)
    fleet_doc = _model(tmp_path / "F" / "a" / "model.json")
    assert fleet_doc["uncertainty"]["used"] == 2
    assert fleet_doc == _model(alone)
