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


@pytest.fixture(scope="session")
def continuous_fit():
    """tests/continuous_robot.py's robot (seed 1) learned by EM from a near start, shared by the EM tests that
    read it (none changes it)."""
    from continuous_robot import continuous_config, simulate_continuous
    from sensact.learn.em import fit_em

    data, poses = simulate_continuous(1)
    return data, poses, fit_em(data, None, continuous_config())
