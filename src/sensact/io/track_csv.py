"""A 1-D robot's own CSV as an EM track log (``sensact convert track``).

A robot that drives along one line toward a wall or a beacon (sec. 4.4.3's track; the Turtlebot of
docs/em-real.md) logs, in one file with a header row, a time column (``t_s``, or ``t_ms``, ``t_us``, ``t_ns``),
its velocity command, one column per sensor reading and, to score against, the recorded distance. A
row may hold any of them (an empty cell where a value was not logged):

* the **commands** (``--command``; by default the one column in a speed unit, ``_m_s``, ``_cm_s`` or
  ``_mm_s``) are held from each row that has them until the next (a zero-order hold) on a fixed step;
* each row's **readings** (``--reading``; by default every other column) go to the nearest step, a row
  with none read dropped and counted. One reading must be a distance (``_m``, ``_cm`` or ``_mm``): its unit
  becomes the state's, in which the other readings' validity windows are given;
* the **recorded distance** (``--distance``; by default ``distance_m`` or ``distance_mm``), for scoring
  only, is interpolated onto the steps it spans.

Units follow the column names' suffixes as in ``sensact convert csv`` (``_m`` and ``_cm`` to mm, ``_m_s``
and ``_cm_s`` to mm/s); other columns keep their own units (an IR sensor's volts).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.resample import held_on_grid, nearest_steps
from sensact.io.timed_csv import MAX_DEFAULT_STEP_S, table_and_sources
from sensact.io.unit_checks import refuse_scrambled_path
from sensact.limits import MAX_STEPS
from sensact.logs.landmark_log import LandmarkLog
from sensact.records import JsonObject

DISTANCE_COLUMN = "distance_mm"  # the recorded distance by default, as a track folder's groundtruth.csv names it


@dataclass(frozen=True, eq=False)
class TrackCsv:
    data: LandmarkLog  # geometry "track", one landmark (the wall), continuous commands
    truth_mm: np.ndarray | None  # the recorded distance on the step grid (NaN outside its rows' span)
    distance_reading: str  # the reading in mm, whose unit the state takes
    t0_s: float  # the file's clock at step 0
    sources: dict[str, str]  # sensact's column name -> the file's
    summary: JsonObject

    def summary_line(self) -> str:
        s = self.summary
        line = (
            f"{s['rows']} rows -> {self.data.n_steps} steps of {self.data.dt_s:.4g} s; commands "
            f"{', '.join(self.data.command_names)} from {s['command_rows']} rows (the longest gap, held: "
            f"{s['longest_command_gap_s']:.3g} s); kept {s['kept']} of {s['reading_rows']} rows with a reading, "
            f"dropped {s['dropped_outside_commands']} outside the commands' span"
        )
        per = ", ".join(f"{name} {n}" for name, n in s["readings_per_channel"].items())
        line += f" (readings: {per})"
        if self.truth_mm is not None:
            line += (
                f"; the recorded distance covers {100.0 * float(np.isfinite(self.truth_mm).mean()):.0f} % of the steps"
            )
        return line


def named_columns(
    given: tuple[str, ...], sources: dict[str, str], option: str, what: str = "column", path: Path | None = None
) -> tuple[str, ...]:
    """The sensact names of the columns an option names, each by its name in the file or sensact's
    (``sonar_m`` or ``sonar_mm``); ``sources`` maps the sensact names of the columns it may name (``what``)
    to the file's."""
    by_file = {v: k for k, v in sources.items()}
    out = []
    for name in given:
        col = by_file.get(name.strip(), name.strip() if name.strip() in sources else None)
        if col is None:
            raise LogFormatError(
                f"{option} {name}: no such {what}; found {', '.join(sources.values())}.",
                file=path,
                field=option if path is None else name,
                fix=f"give {option} a {what}'s name as the file's header writes it.",
            )
        out.append(col)
    return tuple(out)


def _columns(
    path: Path,
    sources: dict[str, str],
    commands: tuple[str, ...],
    readings: tuple[str, ...],
    distance: str | None,
) -> tuple[tuple[str, ...], tuple[str, ...], str | None]:
    """The command, reading and recorded-distance columns: as given, else by the defaults (module docstring)."""
    found = ", ".join(v for k, v in sources.items() if k != "t_s")
    if distance is not None:
        truth: str | None = named_columns((distance,), sources, "--distance", path=path)[0]
    else:
        truth = DISTANCE_COLUMN if DISTANCE_COLUMN in sources else None
    cmds = named_columns(commands, sources, "--command", path=path)
    if not cmds:
        cmds = tuple(c for c in sources if c.endswith("_mm_s"))
        if len(cmds) != 1:
            raise LogFormatError(
                (
                    f"{len(cmds)} columns are speeds ({', '.join(sources[c] for c in cmds)})"
                    if cmds
                    else "no column is a speed"
                )
                + f"; found {found}.",
                file=path,
                field="--command",
                fix="name the velocity command column with --command (a _m_s, _cm_s or _mm_s suffix gives its "
                "unit; another unit, e.g. a motor's percent, is kept as it is).",
            )
    used = {"t_s", *cmds, *((truth,) if truth else ())}
    reads = named_columns(readings, sources, "--reading", path=path) or tuple(c for c in sources if c not in used)
    clash = [c for c in reads if c in used]
    if clash or not reads:
        raise LogFormatError(
            f"{sources[clash[0]]} is read as a command or as the recorded distance, not a reading."
            if clash
            else f"no reading columns besides the time, the commands and the recorded distance; found {found}.",
            file=path,
            field=sources[clash[0]] if clash else "--reading",
            fix="name each sensor's column with --reading (the recorded distance, for scoring only, with --distance).",
        )
    return cmds, reads, truth


def _distance_reading(path: Path, reads: tuple[str, ...], sources: dict[str, str]) -> str:
    """The first reading in a distance unit: EM's state takes its unit (sec. 4.4.3: a 1-D state has no
    absolute scale but the one a sensor reads), in which the other readings' windows are given."""
    for r in reads:
        if r.endswith("_mm"):
            return r
    raise LogFormatError(
        f"none of the readings ({', '.join(sources[r] for r in reads)}) is in a distance unit: EM's state takes "
        "a distance sensor's unit (mm), in which the other sensors' windows are given.",
        file=path,
        field="--reading",
        fix="give a distance sensor's column (sonar, lidar, a wheel odometer's distance) a _m, _cm or _mm suffix; one "
        "with none cannot be learned by `sensact learn em`.",
    )


MAX_RANGE_MM = 100_000.0  # a range in mm beyond 100 m is no 1-D robot's: another unit (micrometres, a scaled column)


def read_track_csv(
    path: str | Path,
    *,
    commands: tuple[str, ...] = (),
    readings: tuple[str, ...] = (),
    distance: str | None = None,
    dt_s: float | None = None,
) -> TrackCsv:
    """The file (module docstring) as a track ``LandmarkLog`` on a fixed step: ``dt_s``, by default the
    median spacing of the rows that hold a reading."""
    path = Path(path)
    table, sources = table_and_sources(
        path, ("t_s",), "the 1-D robot's CSV", "t_s, a command and readings", command="convert track"
    )
    t_all = table["t_s"]
    bad = np.flatnonzero(~np.isfinite(t_all))
    if bad.size:
        raise LogFormatError(
            f"row {bad[0] + 2} has no time.", file=path, field=sources["t_s"], fix="give every row a time."
        )
    cmds, reads, truth_col = _columns(path, sources, commands, readings, distance)
    distance_reading = _distance_reading(path, reads, sources)
    order = np.argsort(t_all, kind="stable")
    t = t_all[order]
    values = np.column_stack([table[r][order] for r in reads])
    read = np.any(np.isfinite(values), axis=1)
    for j, r in enumerate(reads):
        col = values[:, j][np.isfinite(values[:, j])]
        if col.size == 0:
            raise LogFormatError(
                f"the {sources[r]} column holds no reading.",
                file=path,
                field=sources[r],
                fix="fill it where the sensor read, or leave it out (--reading).",
            )
        if r.endswith("_mm") and not 0 <= float(np.median(col)) <= MAX_RANGE_MM:  # a length, converted to mm
            raise LogFormatError(
                f"{sources[r]}'s readings have a median of {float(np.median(col)):.4g} mm: a 1-D robot's range "
                f"finder reads 0 to {MAX_RANGE_MM / 1000:g} m.",
                file=path,
                field=sources[r],
                fix="write the column in the unit its name says (mm), or name it for its own unit.",
            )
    if dt_s is None:
        spacing = np.diff(t[read])
        spacing = spacing[spacing > 0]
        dt_s = float(np.median(spacing)) if spacing.size else 0.0
        if dt_s > MAX_DEFAULT_STEP_S:
            raise LogFormatError(
                f"the readings are {dt_s:.4g} s apart (the median), no sensor's rate.",
                file=path,
                field=sources["t_s"],
                fix="write the times in seconds (t_ms for milliseconds), or give the step with --dt.",
            )
    if not (np.isfinite(dt_s) and dt_s > 0):
        raise LogFormatError(
            f"dt = {dt_s} is not a step.", file=path, field="--dt", fix="give a step in seconds with --dt, e.g. 0.05."
        )
    cmd_values = np.column_stack([table[c][order] for c in cmds])
    has_cmd = np.all(np.isfinite(cmd_values), axis=1)
    if has_cmd.sum() < 1 or t[has_cmd][0] >= t[-1]:
        raise LogFormatError(
            "no command is in force over the log: a command cell is needed on a row before the last.",
            file=path,
            field=sources[cmds[0]],
            fix="fill the command column at least where each command was sent.",
        )
    # the commands are held to the last row: a robot that logs its command only when it changes
    t_held = np.append(t[has_cmd], t[-1])
    if (t[-1] - t_held[0]) / dt_s > MAX_STEPS:
        raise LogFormatError(
            f"the log spans {t[-1] - t_held[0]:.4g} s, more than {MAX_STEPS:,} steps of {dt_s:.3g} s.",
            file=path,
            field=sources["t_s"],
            fix="if the times are not seconds, name the column t_ms, t_us or t_ns; else give a larger --dt.",
        )
    t0, held = held_on_grid(t_held, np.vstack([cmd_values[has_cmd], cmd_values[has_cmd][-1:]]), dt_s)
    T = len(held)
    step, inside = nearest_steps(t, t0, dt_s, T)
    keep = read & inside
    if not keep.any():
        raise LogFormatError(
            "no reading was logged while a command was in force.",
            file=path,
            field=sources[reads[0]],
            fix="give the readings and the commands times on one clock.",
        )
    sel = np.flatnonzero(keep)  # sorted by time, so by step
    data = LandmarkLog.continuous_track(dt_s, cmds, held, step[sel], values[sel], reads, str(path))
    truth_mm = None
    if truth_col is not None:
        recorded = np.isfinite(table[truth_col][order])
        if recorded.sum() < 2:
            raise LogFormatError(
                f"the recorded distance has {int(recorded.sum())} values: two or more are interpolated onto the steps.",
                file=path,
                field=sources[truth_col],
                fix="fill the column where the distance was recorded, or drop it (it is only scored against).",
            )
        grid = t0 + np.arange(T) * dt_s
        tr, vr = t[recorded], table[truth_col][order][recorded]
        refuse_scrambled_path(path, vr, sources[truth_col])
        # a step within half a step of the recorded span takes its end value, as its readings are on it
        near = (grid >= tr[0] - 0.5 * dt_s) & (grid <= tr[-1] + 0.5 * dt_s)
        truth_mm = np.where(near, np.interp(grid, tr, vr), np.nan)
    summary = {
        "rows": len(t),
        "command_rows": int(has_cmd.sum()),
        "longest_command_gap_s": float(np.max(np.diff(t_held), initial=0.0)),
        "reading_rows": int(read.sum()),
        "kept": int(keep.sum()),
        "dropped_outside_commands": int((read & ~inside).sum()),
        "readings_per_channel": {sources[r]: int(np.isfinite(values[sel, j]).sum()) for j, r in enumerate(reads)},
    }
    return TrackCsv(data, truth_mm, distance_reading, t0, sources, summary)
