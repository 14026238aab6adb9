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


def require(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"real data not found at {path} (set SENSACT_DATA or check out ../shared/data)")
    return path


@pytest.fixture(scope="session")
def short_run():
    """A 60 s simulated track log, shared by the learner tests."""
    from sensact.sim.track1d import Track1DConfig, simulate_track

    return simulate_track(Track1DConfig(seconds=60.0, seed=11))
