"""Real data: the Turtlebot 1-D logs of ../shared/data/turtlebot1d (skipped when absent)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import require
from sensact.errors import LogFormatError
from sensact.experiments.turtlebot import run_turtlebot
from sensact.io.logfolder import read_track_log

pytestmark = pytest.mark.realdata


@pytest.fixture(scope="module")
def training1(data_dir):
    return require(data_dir / "turtlebot1d" / "training1.csv")


def test_reads_the_csv(training1, data_dir):
    log = read_track_log(training1, sensor="raw_ir4")
    assert len(log.times_s) == 4819 and log.command_unit == "m/s"
    assert np.abs(log.commands).max() == pytest.approx(0.5317, abs=1e-4)
    assert log.true_position is not None and 0.09 < log.true_position.min() < 0.11
    test = read_track_log(require(data_dir / "turtlebot1d" / "test.csv"))
    assert test.true_position is None
    with pytest.raises(LogFormatError, match="unknown sensor"):
        read_track_log(training1, sensor="lidar")


def test_algorithm_1_learns_the_real_robot(training1):
    """End to end on a real robot: S within 10 % of the distance range, A's gain within 5 %."""
    res, _ = run_turtlebot(training1, sensors=("sonar1",))
    row = res["rows"]["sonar1"]
    assert row["status"] == "ok"
    assert row["sensor_rms_pct"] < 10.0
    assert row["gain_error_pct"] < 5.0
    assert row["consistency"] < 0.2
    assert 0 < row["n_gated"] < 0.3 * row["n_observations"]  # sonar1's outliers are gated, not the rest
