"""report.html beside every calibration (`learn em`, `learn bootstrap`, `learn car`): one self-contained page
that a real headless browser opens offline with every image loaded and no request out."""

from __future__ import annotations

import re

import pytest
from typer.testing import CliRunner

from conftest import open_page
from sensact.cli import app

runner = CliRunner()
EM_SECTIONS = (
    "Summary",
    "Flags and warnings",
    "Convergence, the sensor functions and the path",
    "Residuals",
    "Action model",
    "Sensor mount",
)


def _ok(args):
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res


def _loads_whole(seen, n_images):
    assert len(seen["images"]) >= n_images, seen["images"]
    assert all(i["complete"] and i["width"] > 100 for i in seen["images"]), seen["images"]  # no broken image
    assert not seen["failed_requests"] and not seen["console_errors"] and not seen["links_out"], seen


@pytest.fixture(scope="module")
def em_report(tmp_path_factory):
    root = tmp_path_factory.mktemp("report")
    _ok(["simulate", "diffdrive", "--out", root / "log", "--seconds", "90", "--seed", "4"])
    res = _ok(["learn", "em", root / "log", "--out", root / "model.json"])
    return root, res


def test_learn_em_writes_a_report_a_browser_opens_whole(em_report, browser):
    root, res = em_report
    page = root / "report.html"
    assert "report.html" in res.output and page.is_file()
    seen = open_page(browser, page)
    for title in (*EM_SECTIONS, "Against recorded poses (never learned from)"):
        assert title in seen["headings"], (title, seen["headings"])
    _loads_whole(seen, 4)  # the fit, the residuals, the commands, and the truth's figures


def test_the_report_flags_what_the_fit_flags(em_report):
    """Every warning line of the fit is on the page, or the page says no flag was raised."""
    root, res = em_report
    text = (root / "report.html").read_text()
    warned = [line.removeprefix("warning: ") for line in res.output.splitlines() if line.startswith("warning: ")]
    assert ("No flag raised." in text) == (not warned)
    for line in warned:  # the page wraps nothing: each line's first words are there as printed
        assert " ".join(line.split()[:8]) in " ".join(text.split()), line
    # one frame and one set of units, as the exports: REP 103 and SI (no millimetre left on the page but in
    # the fit's own warning lines, quoted as the console printed them)
    page = re.sub(r'src="data:[^"]*"', "", text)
    for line in warned:
        page = page.replace(" ".join(line.split()[:8]), "")
    body = re.sub(r"<section[^>]*>\s*<h2>Flags and warnings</h2>.*?</section>", "", page, flags=re.S)
    assert "REP 103" in text and not re.search(r"\bmm\b|_mm\b|mm/s", body)


def test_no_report_writes_none(tmp_path):
    _ok(["simulate", "diffdrive", "--out", tmp_path / "log", "--seconds", "30", "--seed", "4"])
    _ok(["learn", "em", tmp_path / "log", "--out", tmp_path / "m.json", "--no-report"])
    assert not list(tmp_path.glob("*.html")) and (tmp_path / "m.json").is_file()


def test_learn_bootstrap_writes_a_report_a_browser_opens_whole(tmp_path, browser):
    _ok(["simulate", "track1d", "--seconds", "60", "--seed", "2", "--out", tmp_path / "log"])
    _ok(["learn", "bootstrap", tmp_path / "log", "--out", tmp_path / "m.json"])
    seen = open_page(browser, tmp_path / "m.report.html")
    assert {"Summary", "Flags and warnings", "Figures"} <= set(seen["headings"])
    _loads_whole(seen, 1)
