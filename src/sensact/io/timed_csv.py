"""A robot's own timed CSV files as an EM log (``sensact convert csv``).

A robot's records are rarely on one clock tick: commands are sent when the controller decides, a camera
reads when it has a frame, motion capture samples at its own rate. Four CSV files with a header row,
times in seconds on one clock, in any order, become a planar ``LandmarkLog`` on a fixed step (by
default the commands' median interval):

* ``commands.csv``: ``t_s`` and one column per command (e.g. ``v_m_s``, ``omega_rad_s``), a row whenever
  a command was sent. Each is held until the next row (a zero-order hold) on the grid from the first
  row's time to the last's.
* ``sightings.csv``: ``t_s``, ``landmark_id``, one column per reading (e.g. ``range_m``; an empty cell
  when that sensor did not read) and optionally ``bearing_rad`` (counterclockwise from the robot's
  forward axis). Each row goes to the nearest step. Rows naming a landmark not in ``landmarks.csv``
  (another robot, a false detection), outside the commands' span or with nothing read are dropped and
  counted.
* ``landmarks.csv``: ``id``, ``x``, ``y``: the map. An id is a number or a name (``post_A``, ``tag17``);
  ``4`` and ``4.0`` are the same landmark, and the log keeps each id as the landmark's name.
* ``truth.csv`` (optional, for scoring only): ``t_s``, ``x``, ``y`` and optionally ``theta``, interpolated
  onto the grid. ``theta`` is the usual robotics heading (ROS REP 103, MRCLAM: 0 facing world +x,
  counterclockwise, the robot driving along its own +x) and is turned into sensact's frame; without it
  the truth's heading is NaN and the scores that need it are skipped (``score_against_positions``).

Units follow the column names' suffixes: ``_m`` and ``_m_s`` become ``_mm`` and ``_mm_s`` (times 1000:
EM's defaults are in mm; ``_cm`` and ``_cm_s`` times 10), ``_deg`` and ``_deg_s`` become ``_rad`` and
``_rad_s``; other names are kept as they are, in their own units. A time column may be ``t_ms``,
``t_us`` or ``t_ns`` instead of ``t_s``.
Bearings mostly beyond a whole turn are refused as degrees, and times that cannot be seconds;
``unit_checks.unit_doubts`` names a range or a speed whose size disagrees with the map's by orders of
magnitude (metres and millimetres swapped).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.csvtable import landmark_labels, read_numeric_csv, refuse_apart, refuse_repeated
from sensact.io.resample import HEADING_OFFSET_RAD, held_on_grid, nearest_steps, pose_truth_on_grid
from sensact.io.unit_checks import refuse_degrees_as_radians, truth_heading_doubt
from sensact.limits import MAX_STEPS
from sensact.logs.landmark_log import LandmarkLog
from sensact.records import JsonObject

# a column name's unit suffix -> sensact's suffix and factor, the longer suffixes first
UNIT_SUFFIXES = (
    ("_m_s", "_mm_s", 1000.0),
    ("_m", "_mm", 1000.0),
    ("_cm_s", "_mm_s", 10.0),
    ("_cm", "_mm", 10.0),
    ("_deg_s", "_rad_s", np.pi / 180.0),
    ("_deg", "_rad", np.pi / 180.0),
)
# the time column in other units (a ROS bag's stamps are nanoseconds) -> seconds; other columns keep _ms
TIME_COLUMNS = {"t_ms": 1e-3, "t_us": 1e-6, "t_ns": 1e-9}
MAX_DEFAULT_STEP_S = 2.0  # commands further apart than this (the median) are times in another unit, not a rate
MIN_TRUTH_GAP_S = 0.1  # truth samples further apart than this (or five of their periods) leave a gap
# times a clock in seconds cannot read: after the year 5000 on a 1970 clock, so ms, us or ns under t_s
MAX_CLOCK_S = 1e11


def in_sensact_units(name: str, values: np.ndarray) -> tuple[str, np.ndarray]:
    """A column renamed and scaled by its unit suffix (``range_m`` -> ``range_mm``, times 1000)."""
    if name in TIME_COLUMNS:
        return "t_s", values * TIME_COLUMNS[name]
    for suffix, target, factor in UNIT_SUFFIXES:
        if name.endswith(suffix):
            return name[: -len(suffix)] + target, values * factor
    return name, values


def _table(
    path: Path, required: tuple[str, ...], what: str, example: str, labels: tuple[str, ...] = ()
) -> dict[str, np.ndarray]:
    return table_and_sources(path, required, what, example, labels)[0]


def table_and_sources(
    path: Path,
    required: tuple[str, ...],
    what: str,
    example: str,
    labels: tuple[str, ...] = (),
    command: str = "convert csv",
) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """The file's columns in sensact's units, by sensact's names, and the name each had in the file.
    ``command``: the `sensact` command whose section of docs/cli-reference.md describes the file."""
    if not path.is_file():
        raise LogFormatError(
            f"{what} not found.", file=path, fix=f"give a CSV file of {example} (docs/cli-reference.md, {command})."
        )
    raw = read_numeric_csv(path, what=what, labels=labels)
    table: dict[str, np.ndarray] = {}
    sources: dict[str, str] = {}
    for name, values in raw.items():
        new, scaled = in_sensact_units(name, values)
        if new in table:
            raise LogFormatError(
                f"two columns mean {new} ({name} and another in other units).",
                file=path,
                field=name,
                fix="keep one of them.",
            )
        table[new], sources[new] = scaled, name
    if "t_s" in table:
        _refuse_a_clock_in_other_units(path, table["t_s"])
        refuse_repeated(path, raw)  # rows out of order are sorted (a robot's threads log so); twice, refused
    missing = [c for c in required if c not in table]
    if missing:
        raise LogFormatError(
            f"missing column {missing[0]}; found {', '.join(raw)}.",
            file=path,
            field=missing[0],
            fix=f"{what} needs {example} (a _m suffix for metres, _cm for centimetres, _deg for degrees"
            + ("; t_ms, t_us or t_ns for other units of time" if missing[0] == "t_s" else "")
            + f"; docs/cli-reference.md, {command})"
            + _rostopic_hint(raw),
        )
    return table, sources


def _rostopic_hint(raw: dict[str, np.ndarray]) -> str:
    """What to rename in ROS 1's ``rostopic echo -p`` output (``%time`` in nanoseconds, ``field.*``), the
    export a ROS user most likely has; the fields are not mapped by guess, as a Twist's six would be."""
    if "%time" not in raw and not any(name.startswith("field.") for name in raw):
        return "."
    twist = " (a cmd_vel Twist's field.linear.x is v_m_s, field.angular.z omega_rad_s; drop the others)"
    return f"; this is `rostopic echo -p` output: rename %time to t_ns and the field.* columns{twist}."


def _refuse_a_clock_in_other_units(path: Path, t_s: np.ndarray) -> None:
    finite = np.abs(t_s[np.isfinite(t_s)])
    if not finite.size or finite.max() <= MAX_CLOCK_S:
        return
    # a Unix clock read now in ms is about 1.8e12, in us 1.8e15, in ns 1.8e18
    unit = "ms" if finite.max() < 1e14 else "us" if finite.max() < 1e17 else "ns"
    raise LogFormatError(
        f"times up to {finite.max():.4g} s would be thousands of years after 1970: they are not seconds, "
        f"most likely {unit}.",
        file=path,
        field="t_s",
        fix=f"name the time column t_{unit} if it is in {unit} (t_s, t_ms, t_us and t_ns are read).",
    )


def _finite(path: Path, table: dict[str, np.ndarray], columns: tuple[str, ...], fix: str) -> None:
    for c in columns:
        bad = np.flatnonzero(~np.isfinite(table[c]))
        if bad.size:
            raise LogFormatError(f"row {bad[0] + 2} has no value.", file=path, field=c, fix=fix)


@dataclass(frozen=True, eq=False)
class TimedLog:
    data: LandmarkLog
    t0_s: float  # the files' clock at step 0
    groundtruth: dict[str, np.ndarray] | None  # x_mm, y_mm, theta_rad (sensact frame), valid, on the step grid
    summary: JsonObject  # rows kept and dropped, by reason
    truth_doubt: str | None = None  # the truth's heading read against the way it moves (unit_checks)

    def summary_line(self) -> str:
        s = self.summary
        line = (
            f"{s['command_rows']} command rows -> {self.data.n_steps} steps of {self.data.dt_s:.4g} s (the longest "
            f"gap between rows, held: {s['longest_command_gap_s']:.3g} s); kept {s['kept']} of "
            f"{s['sighting_rows']} sightings"
            + (f"; {s['learned_landmarks']} landmarks' positions to learn" if s["learned_landmarks"] else "")
            + f"; dropped {s['dropped_unknown_landmark']} naming landmarks not on "
            f"the map{_ids(s['unknown_landmark_ids'])}, {s['dropped_outside_time']} outside the commands' "
            f"span, {s['dropped_nothing_read']} with nothing read"
        )
        if s["dropped_after_commands"]:  # a robot that logs a command only when it changes ends on its last change
            line += (
                f" ({s['dropped_after_commands']} after the last command row: a row at the log's end holds the last "
                "command to it)"
            )
        if self.groundtruth is not None:
            line += f"; truth covers {100.0 * float(np.mean(self.groundtruth['valid'])):.0f} % of the steps"
        return line


def _ids(ids: list[str]) -> str:
    more = ", ..." if len(ids) > 5 else ""
    return f" (ids {', '.join(ids[:5])}{more})" if ids else ""


def _id_order(label: str) -> tuple[int, float, str]:
    """Numbers by value first (``2`` before ``10``), then names."""
    try:
        return (0, float(label), "")
    except ValueError:
        return (1, 0.0, label)


def commands_step(path: Path, t_cmd: np.ndarray) -> float:
    """The step a robot's commands come at: the median interval between successive command rows (a
    controller's rate; repeated times left out)."""
    gaps = np.diff(t_cmd)
    gaps = gaps[gaps > 0]
    if gaps.size == 0:
        raise LogFormatError(
            "every command row has the same time, so there is no rate to step at.",
            file=path,
            field="t_s",
            fix="give the whole run's commands, or a step with --dt.",
        )
    step = float(np.median(gaps))
    if step > MAX_DEFAULT_STEP_S:
        raise LogFormatError(
            f"the command rows are {step:.4g} s apart (the median), no controller's rate: a step that long "
            "would hold each command for all of it.",
            file=path,
            field="t_s",
            fix="write the times in seconds (t_ms for milliseconds), or give the step with --dt.",
        )
    return step


def _read_commands(path: Path, dt_s: float | None) -> tuple[np.ndarray, tuple[str, ...], float, np.ndarray, float]:
    """commands.csv: its sorted times, the command names, the commands held on the step grid from t0, and
    the step (``dt_s``, or with None the commands' median interval)."""
    cmd = _table(path, ("t_s",), "commands.csv", "t_s and one column per command")
    names = tuple(c for c in cmd if c != "t_s")
    if not names:
        raise LogFormatError(
            "no command columns besides t_s.", file=path, fix="add one column per command, e.g. v_m_s,omega_rad_s."
        )
    _finite(path, cmd, ("t_s", *names), "every row needs a time and a value in each command column.")
    order = np.argsort(cmd["t_s"], kind="stable")
    t_cmd = cmd["t_s"][order]
    if dt_s is None:
        dt_s = commands_step(path, t_cmd)
    if t_cmd[-1] - t_cmd[0] < dt_s:
        raise LogFormatError(
            f"the commands span {t_cmd[-1] - t_cmd[0]:.3g} s, less than one step of {dt_s:.3g} s.",
            file=path,
            field="t_s",
            fix="give the whole run's commands, or a smaller --dt.",
        )
    steps = (t_cmd[-1] - t_cmd[0]) / dt_s
    if steps > MAX_STEPS:
        raise LogFormatError(
            f"the commands span {t_cmd[-1] - t_cmd[0]:.4g} s, {steps:.3g} steps of {dt_s:.3g} s: more than "
            f"{MAX_STEPS:,} steps, beyond what EM learns from in an hour.",
            file=path,
            field="t_s",
            fix="if the times are not seconds, name the column t_ms, t_us or t_ns; else give one run or a larger --dt.",
        )
    t0, held = held_on_grid(t_cmd, np.column_stack([cmd[c][order] for c in names]), dt_s)
    return t_cmd, names, t0, held, dt_s


def read_landmarks(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """landmarks.csv: the map (mm) and each landmark's id, one row each."""
    lm = _table(path, ("id", "x_mm", "y_mm"), "landmarks.csv", "id, x_m (or x_mm) and y_m (or y_mm)", labels=("id",))
    fix_lm = "every landmark needs an id and a position."
    _finite(path, lm, ("x_mm", "y_mm"), fix_lm)
    ids = landmark_labels(path, lm["id"], "id", fix_lm)
    dup = [str(i) for i, n in zip(*np.unique(ids, return_counts=True), strict=True) if n > 1]
    if dup:
        raise LogFormatError(
            f"landmark id {dup[0]} appears more than once.", file=path, field="id", fix="give each one row."
        )
    return np.column_stack([lm["x_mm"], lm["y_mm"]]), ids


MIN_SIGHTINGS_TO_LEARN = 20  # an unlisted landmark seen this often is one EM places (the map's bar)


def _map_with_unlisted(
    given: tuple[np.ndarray, np.ndarray] | None, seen_id: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The map's positions and ids, with a NaN row for each landmark EM learns: every one seen without a
    map; with one, those it does not list but the sightings name ``MIN_SIGHTINGS_TO_LEARN`` times or more."""
    xy, ids = given if given is not None else (np.zeros((0, 2)), np.array([], dtype=str))
    labels, counts = np.unique(seen_id[~np.isin(seen_id, ids)], return_counts=True)
    learned = [v for v, n in zip(labels, counts, strict=True) if given is None or n >= MIN_SIGHTINGS_TO_LEARN]
    learned = sorted(learned, key=lambda v: _id_order(str(v)))
    if not learned:
        return xy, ids
    return np.vstack([xy, np.full((len(learned), 2), np.nan)]), np.concatenate([ids.astype(str), np.array(learned)])


def _read_sightings(path: Path) -> tuple[np.ndarray, np.ndarray, tuple[str, ...], np.ndarray, np.ndarray | None]:
    """sightings.csv: each row's time, landmark id, reading names, readings and bearing (None: no bearing
    column)."""
    obs = _table(
        path,
        ("t_s", "landmark_id"),
        "sightings.csv",
        "t_s, landmark_id and one column per reading",
        labels=("landmark_id",),
    )
    fix_obs = "every sighting needs a time and the landmark's id."
    _finite(path, obs, ("t_s",), fix_obs)
    seen_id = landmark_labels(path, obs["landmark_id"], "landmark_id", fix_obs)
    bearing = obs.get("bearing_rad")
    if bearing is not None:
        refuse_degrees_as_radians(path, bearing, "bearing_rad", "name the column bearing_deg, or write radians.")
    readings = tuple(c for c in obs if c not in ("t_s", "landmark_id", "bearing_rad"))
    if not readings:
        raise LogFormatError(
            "no reading columns besides t_s, landmark_id and bearing_rad.",
            file=path,
            fix="add one column per reading, e.g. range_m (EM learns each reading's function of distance).",
        )
    return obs["t_s"], seen_id, readings, np.column_stack([obs[r] for r in readings]), bearing


def read_timed_csv(
    commands: str | Path,
    sightings: str | Path,
    landmarks: str | Path | None,
    truth: str | Path | None = None,
    *,
    dt_s: float | None = None,
    learn_unlisted: bool = False,
) -> TimedLog:
    """The four files (see the module docstring) as a planar, continuous-command ``LandmarkLog`` on a step
    of ``dt_s`` (None: the commands' median interval, the rate the robot's controller ran at).

    Without ``landmarks`` every landmark seen is one whose position EM learns (docs/map.md). With a map,
    sightings of landmarks it does not list (another robot, a false detection) are dropped and counted;
    with ``learn_unlisted`` (a partial map) an unlisted landmark seen ``MIN_SIGHTINGS_TO_LEARN`` times or
    more is learned instead, one seen fewer times still dropped."""
    commands, sightings = Path(commands), Path(sightings)
    if dt_s is not None and not (np.isfinite(dt_s) and dt_s > 0):
        raise LogFormatError(f"dt = {dt_s} is not a step.", field="dt", fix="give a step in seconds, e.g. 0.0333.")
    t_cmd, names, t0, held, dt_s = _read_commands(commands, dt_s)
    T = len(held)
    given = read_landmarks(Path(landmarks)) if landmarks is not None else None
    t_obs, seen_id, readings, values, bearing = _read_sightings(sightings)
    landmarks_mm, ids = given if given is not None and not learn_unlisted else _map_with_unlisted(given, seen_id)
    landmarks = Path(landmarks) if landmarks is not None else sightings
    step, inside = nearest_steps(t_obs, t0, dt_s, T)
    known = np.isin(seen_id, ids)
    read = np.any(np.isfinite(values), axis=1) | (np.isfinite(bearing) if bearing is not None else False)
    keep = known & inside & read
    refuse_apart(sightings, t_obs, inside, t_cmd[0], t_cmd[-1], f"the commands in {commands.name}")  # another clock
    if not keep.any():
        raise LogFormatError(
            f"none of the {len(keep)} sightings is kept ({int((~known).sum())} name landmarks not in "
            f"{landmarks.name}, {int((~inside).sum())} are outside the commands' span "
            f"{t_cmd[0]:.6g}-{t_cmd[-1]:.6g} s).",
            file=sightings,
            fix="give sightings.csv and commands.csv times on one clock, and landmark ids that landmarks.csv lists.",
        )
    sel = np.flatnonzero(keep)[np.lexsort((t_obs[keep], step[keep]))]  # by step, then by time
    row_of = {str(v): j for j, v in enumerate(ids)}
    data = LandmarkLog(
        "planar",
        dt_s,
        np.full(T, -1, dtype=np.int64),
        np.zeros((0, len(names))),
        names,
        step[sel],
        np.array([row_of[str(v)] for v in seen_id[sel]], dtype=np.int64),
        values[sel],
        bearing[sel] if bearing is not None else np.full(sel.size, np.nan),
        landmarks_mm,
        tuple(str(v) for v in ids),
        str(commands.parent),
        readings,
        held,
    )
    gt, truth_doubt = (None, None) if truth is None else _truth_on_grid(Path(truth), t0 + np.arange(T) * dt_s)
    summary: JsonObject = {
        "command_rows": len(t_cmd),
        "longest_command_gap_s": float(np.max(np.diff(t_cmd), initial=0.0)),
        "sighting_rows": len(keep),
        "kept": int(keep.sum()),
        "dropped_unknown_landmark": int((~known).sum()),
        "unknown_landmark_ids": sorted({str(v) for v in seen_id[~known]}, key=_id_order),
        "dropped_outside_time": int((known & ~inside).sum()),
        "dropped_after_commands": int((known & ~inside & (step > 0)).sum()),
        "dropped_nothing_read": int((known & inside & ~read).sum()),
        "learned_landmarks": int((~np.isfinite(landmarks_mm).all(axis=1)).sum()),
    }
    return TimedLog(data, t0, gt, summary, truth_doubt)


def _truth_on_grid(path: Path, grid: np.ndarray) -> tuple[dict[str, np.ndarray], str | None]:
    """The truth's poses on ``grid`` in sensact's frame, and a doubt about its heading, judged on the
    rows as written (degrees would be bent by the unwrapping before the grid)."""
    tr, sources = table_and_sources(path, ("t_s", "x_mm", "y_mm"), "truth.csv", "t_s, x_m, y_m and theta_rad")
    if "theta_rad" not in tr:  # positions alone (a UWB or GNSS truth): scored without heading
        _finite(path, tr, ("t_s", "x_mm", "y_mm"), "drop rows where the truth lost the robot.")
        if len(tr["t_s"]) < 2:
            raise LogFormatError("one row cannot be interpolated.", file=path, field="t_s", fix="give the whole run.")
        order = np.argsort(tr["t_s"], kind="stable")
        t = tr["t_s"][order]
        on_grid = pose_truth_on_grid(
            grid,
            t,
            tr["x_mm"][order],
            tr["y_mm"][order],
            np.zeros(t.size),
            max_gap_s=max(MIN_TRUTH_GAP_S, 5.0 * float(np.median(np.diff(t)))),
        )
        on_grid["theta_rad"] = np.full(grid.size, np.nan)
        return on_grid, None
    in_degrees = sources["theta_rad"] == "theta_deg"  # the warning's fix is then written in the file's degrees
    _finite(path, tr, ("t_s", "x_mm", "y_mm", "theta_rad"), "drop rows where the truth lost the robot.")
    if len(tr["t_s"]) < 2:
        raise LogFormatError("one row cannot be interpolated.", file=path, field="t_s", fix="give the whole run.")
    order = np.argsort(tr["t_s"], kind="stable")
    t = tr["t_s"][order]
    period = float(np.median(np.diff(t)))
    doubt = truth_heading_doubt(
        t,
        tr["x_mm"][order],
        tr["y_mm"][order],
        tr["theta_rad"][order],
        zero_rad=0.0,
        column=sources["theta_rad"],
        convention=f"{'degrees' if in_degrees else 'radians'}, counterclockwise, 0 facing +x (ROS REP 103)",
        in_degrees=in_degrees,
    )
    on_grid = pose_truth_on_grid(
        grid,
        t,
        tr["x_mm"][order],
        tr["y_mm"][order],
        tr["theta_rad"][order],
        max_gap_s=max(MIN_TRUTH_GAP_S, 5.0 * period),
        heading_offset_rad=HEADING_OFFSET_RAD,
    )
    return on_grid, doubt
