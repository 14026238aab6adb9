"""The Turtlebot 1-D CSV (University of Canterbury ENMT482): a robot driving toward and away from a wall.

Columns: ``<index>, time, range, velocity_command, raw_ir1..raw_ir4, sonar1, sonar2``; ``range`` is the
true distance to the wall (evaluation only) and is absent from ``test.csv``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.csvtable import read_numeric_csv
from sensact.io.logfolder import TrackLog

UNITS = {"sonar1": "m", "sonar2": "m", "raw_ir1": "V", "raw_ir2": "V", "raw_ir3": "V", "raw_ir4": "V"}

# The datasheet ranges of assignment-brief.md. Used only to pick where a measured model is compared.
SPEC_RANGE_M = {
    "sonar1": (0.02, 4.0),
    "sonar2": (0.3, 5.0),
    "raw_ir1": (0.15, 1.5),
    "raw_ir2": (0.04, 0.3),
    "raw_ir3": (0.1, 0.8),
    "raw_ir4": (1.0, 5.0),
}

# Learner settings a user would pick per sensor: the readings where it can be inverted (read off the
# raw signal's shape, as from a datasheet curve; both sonars report about 4.5-8 m when too close or
# lost), and the outlier gate for the HC-SR04, whose readings are wrong 14 % of the time.
LEARNER_SETTINGS: dict[str, dict[str, Any]] = {
    "sonar1": {"observation_min": 0.05, "observation_max": 4.0, "outlier_gate": 3.0},
    "sonar2": {"observation_min": 0.3, "observation_max": 4.0},
    "raw_ir3": {"observation_min": 0.55, "observation_max": 2.5},
    "raw_ir4": {"observation_min": 1.6, "observation_max": 3.3},
}


def read_turtlebot_csv(path: str | Path, sensor: str = "sonar1") -> TrackLog:
    path = Path(path)
    if sensor not in UNITS:
        raise LogFormatError(
            f"unknown sensor {sensor!r}.", file=path, field="sensor", fix=f"choose one of {', '.join(UNITS)}."
        )
    cols = read_numeric_csv(path, ["time", "velocity_command", sensor], what="Turtlebot CSV")
    t = cols["time"]
    if np.any(~np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise LogFormatError(
            "time must be finite and strictly increasing.",
            file=path,
            field="time",
            fix="sort the rows by time and drop duplicates.",
        )
    commands = cols["velocity_command"]
    if np.any(~np.isfinite(commands)):
        raise LogFormatError(
            "a velocity_command cell is empty.", file=path, field="velocity_command", fix="fill every command cell."
        )
    return TrackLog(
        t,
        commands,
        cols[sensor],
        "m/s",
        sensor,
        UNITS[sensor],
        str(path),
        {"platform": "turtlebot1d"},
        cols.get("range"),
        "m",
    )
