"""The sensact command: help for every command, end-to-end runs, and one-line errors."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from sensact.cli import app

runner = CliRunner()


@pytest.mark.parametrize(
    "args", [[], ["simulate"], ["learn"], ["simulate", "track1d"], ["learn", "bootstrap"], ["reproduce"]]
)
def test_every_command_has_help(args):
    res = runner.invoke(app, [*args, "--help"])
    assert res.exit_code == 0, res.output
    assert "Usage" in res.output


def test_simulate_then_learn(tmp_path):
    log = tmp_path / "log"
    res = runner.invoke(
        app,
        [
            "simulate",
            "track1d",
            "--seconds",
            "60",
            "--seed",
            "2",
            "--out",
            str(log),
            "--set",
            "observation_noise_px=1.0",
        ],
    )
    assert res.exit_code == 0, res.output
    meta = json.loads((log / "meta.json").read_text())
    assert meta["simulator"]["config"]["observation_noise_px"] == 1.0
    res = runner.invoke(app, ["learn", "bootstrap", str(log), "--a0", "sign", "--out", str(tmp_path / "m.json")])
    assert res.exit_code == 0, res.output
    assert "S(o) =" in res.output and "vs truth" in res.output
    out = json.loads((tmp_path / "m.json").read_text())
    assert out["status"] == "ok" and out["config"]["a0"] == "sign"
    assert out["sensor"]["kind"] == "polynomial1d" and len(out["action"]["coef"]) == 5
    assert out["evaluation"]["sensor_rms"] > 0
    assert (tmp_path / "m.history.npz").is_file()


@pytest.mark.parametrize(
    "args,needle",
    [
        (["learn", "bootstrap", "/nonexistent/log"], "not a log folder"),
        (["learn", "bootstrap", ".", "--a0", "cubic"], "--a0"),
        (["simulate", "track1d", "--out", "x", "--set", "gamma=0.5"], "unknown field 'gamma'"),
        (["reproduce", "nothing"], "unknown experiment"),
    ],
)
def test_bad_input_is_one_line_without_traceback(args, needle):
    res = runner.invoke(app, args)
    assert res.exit_code == 2
    assert needle in res.output
    assert "Traceback" not in res.output


def test_debug_shows_the_traceback():
    res = runner.invoke(app, ["--debug", "learn", "bootstrap", "/nonexistent/log"])
    assert res.exit_code != 0 and res.exception is not None


def test_reproduce_track1d_writes_the_documented_shape(tmp_path):
    res = runner.invoke(app, ["reproduce", "track1d", "--trials", "2", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "track1d.json").read_text())
    assert out["experiment"] == "track1d" and set(out["rows"]) == {"linear", "sign", "constant"}
    for row in out["rows"].values():
        assert {
            "sensor_rms_mm",
            "sensor_rms_mm_std",
            "action_rms_mm_s",
            "action_rms_mm_s_std",
            "consistency",
            "converged",
            "trials",
        } <= set(row)
        assert row["trials"] == 2
    assert {"degree_selection", "thesis", "seconds"} <= set(out)
    for fig in ("fig3_7_location_estimates.png", "fig3_8_learned_vs_measured.png", "fig3_9_learning_curves.png"):
        assert (tmp_path / fig).stat().st_size > 10_000
    assert "Table 3.1" in (tmp_path / "track1d.md").read_text()
