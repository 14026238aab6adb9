"""Issue 74: how a command ends (exit codes 0, 2, 3, 70, 130; SIGTERM as Ctrl-C), what it may write over,
the fit health flags, and the bounds checked before allocation."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fuzz_corpus import sensact_argv
from sensact.cli import app
from sensact.errors import EXIT_BAD_INPUT, EXIT_FLAGGED, EXIT_INTERNAL, EXIT_INTERRUPTED, SensactError

runner = CliRunner()


@pytest.fixture(scope="module")
def planar_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("planar") / "log"
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(out), "--seconds", "60"])
    assert res.exit_code == 0, res.output
    return out


def test_an_unexpected_exception_is_one_line_and_exit_70(monkeypatch, tmp_path):
    import sensact.sim.track1d as track1d

    def broken(cfg):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(track1d, "simulate_track", broken)
    res = runner.invoke(app, ["simulate", "track1d", "--out", str(tmp_path / "t")])
    assert res.exit_code == EXIT_INTERNAL
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("internal error: ZeroDivisionError: a bug")
    assert "--debug" in lines[0] and "Traceback" not in res.output


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (["--seconds", "nan"], "--seconds"),
        (["--seconds", "1e12"], "--seconds"),
        (["--seed", "-1"], "--seed"),
    ],
)
def test_simulate_refuses_a_bogus_length_or_seed_before_allocating(tmp_path, args, field):
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(tmp_path / "s"), *args])
    assert res.exit_code == EXIT_BAD_INPUT and field in res.output
    assert not (tmp_path / "s").exists()


def test_out_refuses_a_device_a_folder_and_the_figures_name(planar_log, tmp_path):
    for out in ("/dev/null", str(tmp_path), str(tmp_path / "model.png")):
        res = runner.invoke(app, ["learn", "em", str(planar_log), "--out", out])
        assert res.exit_code == EXIT_BAD_INPUT, (out, res.output)
        assert "--out" in res.output
    assert Path("/dev/null").is_char_device() and list(tmp_path.iterdir()) == []


def test_an_atomic_write_never_replaces_a_device_or_another_output_of_the_run(tmp_path):
    from sensact.io.atomic import one_run, write_bytes, write_json

    with pytest.raises(SensactError, match="not a regular file"):
        write_json("/dev/null", {"a": 1})
    with one_run():
        write_json(tmp_path / "m.json", {"a": 1})
        write_json(tmp_path / "m.json", {"a": 2})  # the same output again (a model with its error bars)
        with pytest.raises(SensactError, match="wrote another of its outputs here"):
            write_bytes(tmp_path / "m.json", b"\x89PNG")
    assert json.loads((tmp_path / "m.json").read_text()) == {"a": 2}
    write_bytes(tmp_path / "m.json", b"x")  # outside a command, a library caller decides
    assert list(tmp_path.glob("*.tmp")) == []


def test_sigterm_ends_em_as_ctrl_c_does_with_the_best_model_written_and_no_temporary_file(planar_log, tmp_path):
    out = tmp_path / "m.json"
    never_done = ("--set", "max_iterations=100000", "--set", "patience=100000")
    proc = subprocess.Popen(
        sensact_argv("learn", "em", str(planar_log), "--out", str(out), "--no-report", *never_done),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    time.sleep(25)  # the kernels compiled and EM under way (before it, SIGTERM ends the command all the same)
    assert proc.poll() is None
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == EXIT_INTERRUPTED, stderr.decode()[-2000:]
    assert b"Traceback" not in stderr
    assert list(tmp_path.glob("*.tmp")) == [] and list(tmp_path.glob(".*.tmp")) == []
    if out.exists():  # interrupted in EM: the best model so far, whole
        doc = json.loads(out.read_text())
        assert doc["summary"]["stop_reason"] == "interrupted"


def _copy_with_readings(log: Path, dest: Path, readings) -> Path:
    shutil.copytree(log, dest)
    lines = (dest / "observations.csv").read_text().splitlines()
    col = lines[0].split(",").index("range_mm")
    rows = []
    for i, line in enumerate(lines[1:]):
        cells = line.split(",")
        cells[col] = repr(float(readings(i)))
        rows.append(",".join(cells))
    (dest / "observations.csv").write_text("\n".join([lines[0], *rows]) + "\n")
    return dest


@pytest.mark.parametrize("kind", ["constant", "noise"])
def test_a_degenerate_fit_is_written_flagged_and_exits_3(planar_log, tmp_path, kind):
    rng = np.random.default_rng(5)
    readings = (lambda i: 3000.0) if kind == "constant" else (lambda i: rng.uniform(1000, 6000))
    log = _copy_with_readings(planar_log, tmp_path / kind, readings)
    out = tmp_path / "m.json"
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(out), "--no-report"])
    assert res.exit_code == EXIT_FLAGGED, res.output
    health = json.loads(out.read_text())["health"]
    assert health["ok"] is False
    codes = {f["code"] for f in health["flags"]}
    if kind == "constant":
        assert "reading_constant" in codes
    else:
        assert codes & {"reading_explains_nothing", "gain_sign_flips"}


def test_a_healthy_fit_has_no_flags(planar_log, tmp_path):
    out = tmp_path / "m.json"
    res = runner.invoke(app, ["learn", "em", str(planar_log), "--out", str(out), "--no-report"])
    assert res.exit_code == 0, res.output
    assert json.loads(out.read_text())["health"] == {"ok": True, "flags": []}


def test_a_model_that_is_not_a_model_is_refused(planar_log, tmp_path):
    from sensact.app.logs import read_em_model

    res = runner.invoke(app, ["learn", "em", str(planar_log), "--out", str(tmp_path / "m.json"), "--no-report"])
    assert res.exit_code == 0
    good = json.loads((tmp_path / "m.json").read_text())
    bad = {
        "prior_cov": [[1, 2, 0], [2, 1, 0], [0, 0, 1]],
        "prior_mean": [float("nan"), 0, 0],
    }
    for key, value in bad.items():
        doc = json.loads(json.dumps(good))
        doc["model"][key] = value
        (tmp_path / "bad.json").write_text(json.dumps(doc))
        with pytest.raises(SensactError):
            read_em_model(tmp_path / "bad.json")
    doc = json.loads(json.dumps(good))
    doc["model"]["action"]["delay_steps"] = 10**9
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(SensactError, match="delay_steps"):
        read_em_model(tmp_path / "bad.json")


def test_delayed_commands_never_allocate_more_than_the_log():
    from sensact.models.linear_action import delayed

    c = np.arange(5.0)[:, None]
    assert delayed(c, 2).ravel().tolist() == [0, 0, 0, 1, 2]
    assert delayed(c, 10**12).ravel().tolist() == [0, 0, 0, 0, 0]
