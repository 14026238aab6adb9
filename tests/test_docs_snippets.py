"""Every Python snippet in README.md and docs/ runs as printed, on the simulated logs it names (written here
by `sensact simulate`, as a user would), and what it returns is short to print and saved where it says."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from sensact.cli import app

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.MULTILINE | re.DOTALL)
# the log folders the snippets name, as a user makes them (short: the snippets' own settings are kept)
LOGS = {
    "run-001": ["simulate", "field2d", "--seconds", "120", "--seed", "1"],
    "robot_log": ["simulate", "diffdrive", "--seconds", "120", "--seed", "2"],
}


def _snippets() -> list[tuple[str, str]]:
    return [
        (f"{page.name}#{k + 1}", code)
        for page in PAGES
        for k, code in enumerate(BLOCK.findall(page.read_text(encoding="utf-8")))
    ]


@pytest.fixture(scope="module")
def logs_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("snippets")
    for name, args in LOGS.items():
        res = CliRunner().invoke(app, [*args, "--out", str(root / name)])
        assert res.exit_code == 0, res.output
    return root


def test_the_docs_have_snippets_and_every_log_they_name_is_made_here():
    snippets = _snippets()
    assert len(snippets) >= 2
    opened = r"(?:open_log|read_landmark_log)\(\"([^\"]+)\"\)"
    assert {name for _, code in snippets for name in re.findall(opened, code)} <= set(LOGS)


@pytest.mark.parametrize("where, code", _snippets(), ids=[w for w, _ in _snippets()])
def test_a_docs_snippet_runs_as_printed(logs_dir, monkeypatch, where, code):
    monkeypatch.chdir(logs_dir)
    scope: dict = {"__name__": "__snippet__"}
    exec(compile(code, where, "exec"), scope)  # the docs' own code, run as a user pastes it
    for name in ("cal", "result", "log"):
        if name in scope:  # a result at the prompt is a few lines, never its arrays
            assert len(repr(scope[name])) < 2000, (name, len(repr(scope[name])))
    if "result" in scope:  # EMResult: one line, its arrays as their shapes
        text = repr(scope["result"])
        assert text.startswith("EMResult(") and "array(" in text and "\n" not in text
    if "cal" in scope:  # what was calibrated, how EM ended, its health, and how to write it
        cal, text = scope["cal"], repr(scope["cal"])
        assert text.startswith(f"Calibration of {cal.log.name!r}") and len(text.splitlines()) <= 6
        assert f"{cal.result.stop_reason} after {cal.result.iterations} iterations" in text and "health:" in text
    if "save_calibration(cal, " in code:
        out = Path(re.search(r'save_calibration\(cal, "([^"]+)"\)', code).group(1))
        doc = json.loads(out.read_text())
        assert doc["summary"]["iterations"] == scope["cal"].result.iterations
        assert out.with_suffix(".path.npz").is_file()  # everything --out writes, from a str path
