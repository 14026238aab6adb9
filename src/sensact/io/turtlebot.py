"""The Turtlebot 1-D CSV (University of Canterbury ENMT482): a robot driving toward and away from a wall.

Columns: ``<index>, time, range, velocity_command, raw_ir1..raw_ir4, sonar1, sonar2``; ``range`` is the
true distance to the wall (evaluation only) and is absent from ``test.csv``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.csvtable import read_csv_rows, read_numeric_csv
from sensact.io.resample import step_count
from sensact.io.timed_csv import MAX_DEFAULT_STEP_S
from sensact.io.unit_checks import refuse_scrambled_path
from sensact.logs.landmark_log import LandmarkLog
from sensact.logs.track_log import TrackLog
from sensact.records import JsonObject

# a gap this many median steps long (and over a second) is a recording paused: the command held across it
# would move the robot by Algorithm 1's clock (eq. 3.2's dt) for as long as nobody logged what it did
MAX_GAP_STEPS = 100
MIN_STEP_S = 1e-3  # rows closer than a millisecond are a clock in another unit, not a Turtlebot's ten a second
MAX_COMMAND_M_S = 5.0  # a Turtlebot drives at well under a metre a second: beyond this, mm/s
MAX_SONAR_M = 20.0  # an ultrasonic range finder reads a few metres: beyond this, mm

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
LEARNER_SETTINGS: dict[str, JsonObject] = {
    "sonar1": {"observation_min": 0.05, "observation_max": 4.0, "outlier_gate": 3.0},
    "sonar2": {"observation_min": 0.3, "observation_max": 4.0},
    "raw_ir3": {"observation_min": 0.55, "observation_max": 2.5},
    "raw_ir4": {"observation_min": 1.6, "observation_max": 3.3},
}


EM_READINGS = ("sonar1", "raw_ir1", "raw_ir2", "raw_ir3", "raw_ir4")
EM_SCALE = {"sonar1": 1000.0}  # sonar m -> mm; the IR readings stay in volts


def turtlebot_sensors(path: str | Path) -> tuple[str, ...]:
    """The sensor columns (``UNITS``) a Turtlebot CSV's header names, in ``UNITS`` order; () when the
    file cannot be read, so that the reader reports why."""
    try:
        rows, _ = read_csv_rows(Path(path))
    except (OSError, LogFormatError):
        return ()
    header = {h.strip() for h in (rows[0] if rows else [])}
    return tuple(s for s in UNITS if s in header)


def _read_checked(path: str | Path, readings: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The time, command and reading columns, with the time and command columns checked."""
    cols = read_numeric_csv(path, ["time", "velocity_command"], what="Turtlebot CSV", missing_fix=_not_turtlebot(path))
    missing = [r for r in readings if r not in cols]
    if missing:
        raise LogFormatError(
            f"no {missing[0]} column; found {', '.join(cols)}.",
            file=path,
            field=missing[0],
            fix="choose a sensor the file has (--sensor), or check the file's columns.",
        )
    t = cols["time"]
    if len(t) < 2 or np.any(~np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise LogFormatError(
            "time must be finite and strictly increasing, over at least two rows.",
            file=path,
            field="time",
            fix="sort the rows by time and drop duplicates.",
        )
    step = float(np.median(np.diff(t)))
    if step > MAX_DEFAULT_STEP_S:  # the same bound as a timed CSV's commands: a clock in another unit
        raise LogFormatError(
            f"the rows are {step:.4g} s apart (the median): a Turtlebot logs about ten rows a second.",
            file=path,
            field="time",
            fix="write time in seconds (a time in milliseconds divided by 1000).",
        )
    if step < MIN_STEP_S:
        raise LogFormatError(
            f"the rows are {step:.4g} s apart (the median): a Turtlebot logs about ten rows a second.",
            file=path,
            field="time",
            fix="write time in seconds (a time in microseconds times 1e-6).",
        )
    gaps = np.diff(t)
    if gaps.max() > max(MAX_GAP_STEPS * step, 1.0):
        row = int(np.argmax(gaps)) + 2  # the row after the gap, counting the header as row 1
        raise LogFormatError(
            f"no row for {gaps.max():.4g} s before row {row} (rows are {step:.4g} s apart): the recording paused, "
            "and the command in force would be held across the gap.",
            file=path,
            field="time",
            fix="split the log at the gap and learn from each part.",
        )
    step_count(t[-1] - t[0], step, str(path))  # bounded before anything steps at this rate (sensact.limits)
    if np.any(~np.isfinite(cols["velocity_command"])):
        raise LogFormatError(
            "a velocity_command cell is empty.", file=path, field="velocity_command", fix="fill every command cell."
        )
    fastest = float(np.max(np.abs(cols["velocity_command"])))
    if fastest > MAX_COMMAND_M_S:
        raise LogFormatError(
            f"velocity_command reaches {fastest:.4g}: a Turtlebot's is in m/s, under {MAX_COMMAND_M_S:g}.",
            file=path,
            field="velocity_command",
            fix="write it in m/s (mm/s divided by 1000).",
        )
    for sonar in ("sonar1", "sonar2"):
        r = cols.get(sonar, np.zeros(0))
        r = r[np.isfinite(r)]
        if r.size and not (0 <= float(np.median(r)) <= MAX_SONAR_M and np.mean(r < 0) < 0.05):
            raise LogFormatError(
                f"{sonar}'s readings run {float(np.min(r)):.4g} to {float(np.max(r)):.4g} (median "
                f"{float(np.median(r)):.4g}): a sonar's range in m is 0 to {MAX_SONAR_M:g}.",
                file=path,
                field=sonar,
                fix="write the sonar's range in metres (mm divided by 1000), an empty cell where it read nothing.",
            )
    if "range" in cols:  # the recorded distance, scored against
        refuse_scrambled_path(Path(path), cols["range"], "range")
    return cols


def _not_turtlebot(path: str | Path) -> str:
    """The fix for a .csv without a Turtlebot's time and command columns, which a learner reads as one:
    most likely a log folder's own file, or a robot's timed records that `convert csv` turns into one."""
    folder = Path(path).parent
    if (folder / "meta.json").is_file():
        return f"a .csv is read as a Turtlebot's log: give the log folder {folder}, not one of its files."
    return (
        "a .csv is read as a Turtlebot's log (time, velocity_command, sonar1, IR columns); a robot's own timed "
        "records become a log folder first: `sensact convert csv --commands C.csv --sightings S.csv --landmarks "
        "L.csv --out DIR` (docs/em-real.md, section 1), then give DIR; a 1-D robot with other columns: "
        "`sensact convert track FILE.csv --out DIR` (the same section)."
    )


def read_turtlebot_landmark_log(path: str | Path, dt_s: float | None = None) -> tuple[LandmarkLog, np.ndarray]:
    """The CSV on a fixed step (its median spacing): commands held, each row's readings at the nearest
    step. Returns the log and the true range (mm) per step, for evaluation only. The readings are
    sonar1 and whichever IR columns the file has: sonar1 reads a distance, which sets the state's
    unit (mm) that the IR sensors' datasheet windows are given in."""
    cols = _read_checked(path, ())
    if "sonar1" not in cols:
        raise LogFormatError(
            "EM on a Turtlebot CSV needs the sonar1 column: its readings are distances (m), which set the "
            "learned state's unit that the IR sensors' datasheet windows are given in.",
            file=path,
            field="sonar1",
            fix="add the sonar1 column, or write a log folder (docs/formats.md) with your own channels and windows.",
        )
    readings = tuple(r for r in EM_READINGS if r in cols)
    t = cols["time"]
    dt = float(np.median(np.diff(t))) if dt_s is None else dt_s
    T = step_count(t[-1] - t[0], dt, str(path))
    grid = t[0] + np.arange(T) * dt
    held = np.clip(np.searchsorted(t, grid + 1e-9, side="right") - 1, 0, len(t) - 1)
    commands = (cols["velocity_command"][held] * 1000.0).reshape(-1, 1)
    steps = np.clip(np.rint((t - t[0]) / dt).astype(np.int64), 0, T - 1)
    values = np.column_stack([cols[r] * EM_SCALE.get(r, 1.0) for r in readings])
    truth = np.interp(grid, t, cols["range"]) * 1000.0 if "range" in cols else np.full(T, np.nan)
    data = LandmarkLog.continuous_track(dt, ("v_cmd_mm_s",), commands, steps, values, readings, str(path))
    return data, truth


def read_turtlebot_csv(path: str | Path, sensor: str = "sonar1") -> TrackLog:
    path = Path(path)
    if sensor not in UNITS:
        raise LogFormatError(
            f"unknown sensor {sensor!r}.", file=path, field="sensor", fix=f"choose one of {', '.join(UNITS)}."
        )
    cols = _read_checked(path, (sensor,))
    if not np.isfinite(cols[sensor]).any():
        raise LogFormatError(
            f"the {sensor} column holds no reading.",
            file=path,
            field=sensor,
            fix="choose a sensor that read something with --sensor, or check the file's columns.",
        )
    return TrackLog(
        cols["time"],
        cols["velocity_command"],
        cols[sensor],
        "m/s",
        sensor,
        UNITS[sensor],
        str(path),
        {"platform": "turtlebot1d"},
        cols.get("range"),
        "m",
    )
