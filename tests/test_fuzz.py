"""Issue 74's fuzz suite: malformed inputs for every format, run as a user runs them (tests/fuzz_corpus.py).

By default a fixed sample of the corpus runs (about two minutes); ``SENSACT_FUZZ=all python -m pytest
tests/test_fuzz.py`` runs every case. A hypothesis test feeds the log folder reader random cells in-process.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzz_corpus import Case, base_inputs, cases, problems, run_case
from sensact.errors import SensactError

ALL = os.environ.get("SENSACT_FUZZ") == "all"
SAMPLE_EVERY = 32  # CI runs every 32nd case of the corpus (34 of 1,087): about a minute and a half


def _chosen() -> list[Case]:
    every = cases()
    return every if ALL else every[::SAMPLE_EVERY]


def test_the_corpus_holds_at_least_300_cases_over_every_kind_of_input_and_command():
    every = cases()
    targets = {c.target.split(":")[0] for c in every}
    assert len(every) >= 300
    assert len({c.name for c in every}) == len(every)  # each case is told apart by its name
    expected = {"log/actions.csv", "log/observations.csv", "log/groundtruth.csv", "log/meta.json"}
    expected |= {"log/em_config.yaml", "model.json", "tb.csv", "track.csv", ""}
    expected |= {"bag/robot.bag", "bag/map.csv", "bag2/robot/robot.mcap", "bag2/robot/metadata.yaml", "bag1d.bag"}
    expected |= {"model.path.npz", "car_model.json", "car/velodyne.pcap", "calib.yaml", "mrclam/Robot1_Odometry.dat"}
    # issue 95's surfaces: ROS 2 sqlite3 bags, the other lidars' calibrations
    expected |= {"bag3/robot/robot.db3", "bag3/robot/metadata.yaml", "lidarbag3/robot/robot.db3"}
    expected |= {"os1/metadata_true.json", "car16/calibration_true.yaml"}
    assert expected <= targets
    # every command a user runs on a file, by its first two words
    commands = {" ".join(a for a in c.argv[:2] if not a.startswith(("{", "-"))) for c in every}
    for command in ("learn em", "learn bootstrap", "learn car", "localize", "monitor", "evaluate log"):
        assert command in commands
    for command in ("evaluate fleet", "fleet learn", "convert bag", "convert csv", "convert track", "convert mrclam"):
        assert command in commands
    assert {"export", "reproduce track1d", "simulate diffdrive"} <= commands


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return base_inputs(tmp_path_factory.mktemp("fuzz") / "base")


@pytest.mark.parametrize("case", _chosen(), ids=lambda c: c.name)
def test_a_malformed_input_ends_cleanly(case: Case, base: Path, tmp_path: Path):
    ended = run_case(case, base, tmp_path)
    assert problems(case, ended) == [], ended.stderr[-2000:]


# ---- in-process: the log folder reader on random cells ---------------------------------------------------------

CELLS = st.one_of(
    st.sampled_from(["nan", "inf", "-inf", "", "1e308", "-1e308", "1e400", "0", "-0", "abc", "1,5", "\x00"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(max_size=8),
)


@pytest.fixture(scope="module")
def small_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from sensact.io.landmark_folder import write_landmark_log
    from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

    run = simulate_diffdrive(DiffDriveConfig(seconds=10.0))
    folder = tmp_path_factory.mktemp("small") / "log"
    write_landmark_log(folder, run.log("small"))
    return folder


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    file=st.sampled_from(["actions.csv", "observations.csv"]),
    row=st.integers(1, 40),
    col=st.integers(0, 3),
    cell=CELLS,
)
def test_any_cell_is_read_or_refused_by_name(small_log: Path, tmp_path_factory, file, row, col, cell):
    from sensact.io.landmark_folder import read_landmark_log

    work = tmp_path_factory.mktemp("cell") / "log"
    shutil.copytree(small_log, work)
    lines = (work / file).read_text().splitlines()
    row = 1 + (row - 1) % (len(lines) - 1)
    cells = lines[row].split(",")
    cells[min(col, len(cells) - 1)] = cell
    lines[row] = ",".join(cells)
    (work / file).write_text("\n".join(lines) + "\n", encoding="utf-8", errors="surrogateescape")
    try:
        data = read_landmark_log(work).data
    except SensactError as exc:
        assert "\n" not in str(exc) and str(work) in str(exc)
        return
    commands = data.step_commands if data.is_continuous else data.action_commands
    assert np.all(np.isfinite(commands)) and np.all(np.isfinite(data.landmarks_xy))
    readings = data.obs_readings[np.isfinite(data.obs_readings)]
    assert np.all(np.abs(readings) <= 1e9)  # an empty cell is a missing reading; no number is absurd
    assert np.all(np.diff(data.obs_step) >= 0)
