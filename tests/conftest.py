"""Shared fixtures. Real-data tests look in ../shared/data (or $SENSACT_DATA) and skip when it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("SENSACT_DATA", ROOT.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def data_dir() -> Path:
    return DATA


def write_csv(path: Path, columns) -> Path:
    """Columns as a CSV with a header row, each number as its shortest round-tripping repr, NaN empty."""
    import numpy as np

    names = list(columns)
    rows = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    lines = [",".join(names)] + [",".join("" if np.isnan(v) else repr(float(v)) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def rewrite_capture(src: Path, dst: Path, writer) -> Path:
    """The records of the classic pcap ``src`` written again by ``writer(handle)``, a dpkt writer (pcapng, or a
    nanosecond pcap): the same packets in another framing."""
    import dpkt

    with open(src, "rb") as fin, open(dst, "wb") as fout:
        w = writer(fout)
        for stamp, frame in dpkt.pcap.Reader(fin):
            w.writepkt(frame, ts=stamp)
    return dst


def require(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"real data not found at {path} (set SENSACT_DATA or check out ../shared/data)")
    return path


@pytest.fixture(scope="session")
def short_run():
    """A 60 s simulated track log, shared by the learner tests."""
    from sensact.sim.track1d import Track1DConfig, simulate_track

    return simulate_track(Track1DConfig(seconds=60.0, seed=11))


@pytest.fixture(scope="session")
def continuous_fit():
    """tests/continuous_robot.py's robot (seed 1) learned by EM from a near start, shared by the EM tests that
    read it (none changes it)."""
    from continuous_robot import continuous_config, simulate_continuous
    from sensact.learn.em import fit_em

    data, poses = simulate_continuous(1)
    return data, poses, fit_em(data, None, continuous_config())


CHROMIUM = Path("/usr/bin/chromium")  # Debian's; .ci/run installs it
CHROMIUM_ARGS = [  # as root, offline: no sandbox, and none of the connections a closed network refuses
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


@pytest.fixture(scope="session")
def browser():
    """A real headless Chromium driven by Playwright. Skips where there is none, except in CI, which
    installs one and must run the check."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright comes with the test extra")
    if not CHROMIUM.is_file():
        if os.environ.get("CI"):
            pytest.fail(f"CI has no {CHROMIUM}: .ci/run installs Debian's chromium")
        pytest.skip(f"no browser at {CHROMIUM} (apt-get install chromium)")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield b
        b.close()


def open_page(browser, path: Path) -> dict:
    """``path`` loaded offline (any request off the page is refused): its headings, each image's loaded
    width, the requests that failed and what the console said in error."""
    context = browser.new_context(offline=True)
    page = context.new_page()
    errors: list[str] = []
    failed: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("requestfailed", lambda r: failed.append(r.url))
    page.goto(path.resolve().as_uri(), wait_until="load")
    seen = page.evaluate(
        """() => ({
            headings: [...document.querySelectorAll('h1, h2')].map(h => h.textContent),
            images: [...document.images].map(i => ({complete: i.complete, width: i.naturalWidth})),
            links_out: [...document.querySelectorAll('[src], [href]')]
                .map(e => e.getAttribute('src') || e.getAttribute('href'))
                .filter(u => !u.startsWith('data:') && !u.startsWith('#')),
        })"""
    )
    context.close()
    return seen | {"console_errors": errors, "failed_requests": failed}


# a few iterations stop EM before it learns every f (its residuals then follow the path's error from step to
# step); a path placed with such a model carries its flag
CAPPED = ("not_converged", "reading_explains_nothing", "residuals_correlated", "model_flagged")


def assert_written(res, allowed=CAPPED):
    """A command that wrote its result: exit 0, or exit 3 flagged only for what the test chose (``allowed``;
    None: any flag), as a cap on EM's iterations that keeps a test quick stops EM before it converges."""
    import re

    if res.exit_code == 3:
        codes = set(re.findall(r"flagged \((\w+)\)", res.output))
        assert codes and (allowed is None or codes <= set(allowed)), res.output
    else:
        assert res.exit_code == 0, res.output
