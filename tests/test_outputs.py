"""What a command may write over: its own earlier output of the same kind, never a user's file (unless
--force) nor another kind of output; and two models in one folder get a report page each."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from sensact.cli import app
from sensact.outputs import EM_MODEL, MONITOR, is_output_of

runner = CliRunner()
QUICK = ("--set", "max_iterations=15", "--set", "search.start_candidates=1")


def _run(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def learned(tmp_path_factory):
    root = tmp_path_factory.mktemp("outputs")
    assert _run("simulate", "diffdrive", "--out", root / "log", "--seconds", "30", "--seed", "4").exit_code == 0
    for name in ("a", "b"):
        res = _run("learn", "em", root / "log", "--out", root / f"{name}.json", *QUICK)
        assert res.exit_code in (0, 3), res.output
    return root


def test_two_models_in_one_folder_get_a_report_page_each(learned):
    for name in ("a", "b"):
        page = (learned / f"{name}.report.html").read_text()
        assert f"the model is {name}.json" in page
    assert not (learned / "report.html").exists()
    assert is_output_of(learned / "a.json", EM_MODEL) and not is_output_of(learned / "a.json", MONITOR)


def test_out_refuses_a_users_file_and_another_kind_and_force_replaces(learned, tmp_path):
    notes = tmp_path / "existing.txt"
    notes.write_text("my notes, not a model\n")
    res = _run("learn", "em", learned / "log", "--out", notes, *QUICK)
    text = " ".join(res.output.split())
    assert res.exit_code == 2 and "is not a sensact em model" in text and "--force" in text, text
    assert notes.read_text() == "my notes, not a model\n"
    other = tmp_path / "mon.json"  # a sensact output, of another kind
    other.write_text(json.dumps({"sensact_version": "0.1.0", "sensact_output": MONITOR, "changed": False}))
    assert _run("learn", "em", learned / "log", "--out", other, *QUICK).exit_code == 2
    res = _run("learn", "em", learned / "log", "--out", notes, "--force", *QUICK)
    assert res.exit_code in (0, 3), res.output
    assert json.loads(notes.read_text())["sensact_output"] == EM_MODEL
    res = _run("learn", "em", learned / "log", "--out", notes, *QUICK)  # its own output again: replaced
    assert res.exit_code in (0, 3), res.output


def test_export_never_replaces_the_model_or_a_users_file(learned, tmp_path):
    model = learned / "a.json"
    before = model.read_bytes()
    res = _run("export", model, "--format", "robot-localization", "--out", model)
    assert res.exit_code == 2 and "is the model being exported" in " ".join(res.output.split())
    assert model.read_bytes() == before
    mine = tmp_path / "rl.yaml"
    mine.write_text("ekf_filter_node: {ros__parameters: {frequency: 30}}\n")
    res = _run("export", model, "--format", "robot-localization", "--out", mine)
    assert res.exit_code == 2 and "--force" in res.output and "frequency: 30" in mine.read_text()
    flagged = not json.loads(before)["health"]["ok"]  # a few EM iterations: written, and exit 3 says so
    for extra in (("--force",), ()):  # forced once, then its own export is replaced without asking
        res = _run("export", model, "--format", "robot-localization", "--out", mine, *extra)
        assert res.exit_code == (3 if flagged else 0), res.output
    res = _run("export", model, "--format", "tum", "--out", tmp_path / "p.tum", "--truth-out", tmp_path / "p.tum")
    assert res.exit_code == 2 and "each its own path" in " ".join(res.output.split())


def test_no_command_writes_over_its_own_input_model_even_forced(learned):
    """localize --out, monitor --out or --relearn, evaluate log --out and learn em --start-from: the model read
    is never the path written, whatever --force says."""
    model = learned / "a.json"
    before = model.read_bytes()
    for args in (
        ("localize", learned / "log", "--model", model, "--out", model, "--force"),
        ("monitor", learned / "log", "--model", model, "--relearn", model, "--force"),
        ("monitor", learned / "log", "--model", model, "--out", model),
        ("evaluate", "log", learned / "log", "--model", model, "--out", model, "--force"),
        ("learn", "em", learned / "log", "--start-from", model, "--out", model, *QUICK),
    ):
        res = _run(*args)
        text = " ".join(res.output.split())
        assert res.exit_code == 2 and "are both" in text and ("--model" in text or "--start-from" in text), text
        assert model.read_bytes() == before
