"""``sensact convert``: a public dataset, or a robot's own timed CSVs, to an EM log folder with its EM
settings (em_config.yaml)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer

from sensact.cli.base import console, convert_app, friendly
from sensact.records import JsonObject

MRCLAM_CONFIG_HEADER = """The EM settings `sensact learn em` reads from this folder: a preset shipped with sensact
(`sensact learn em --help` lists them; differential_drive_camera is behind docs/em-real.md's
MRCLAM results), put on this log's commands, and the fields below it that differ from it.
Edit them for your robot (docs/em-real.md, section 2); --set overrides single fields."""
WHEELS_CONFIG_NOTE = """
On wheel speeds ({left}, {right}) the forward speed is the wheels' mean, so it depends on their
sum alone, ({left}+{right}), as MRCLAM's depends on v_mm_s alone."""
FREE_MOTION_NOTE = """
These commands are not a differential drive's (v_mm_s, omega_rad_s, or its wheels, left_X, right_X):
  {names}
so every velocity, sideways too, is affine in every command, as for a robot that can side-step
(a legged one): MRCLAM's action_zero_mean and action_inputs are left out. If yours cannot
side-step, add action_zero_mean: [v_x_mm_s] (docs/em-real.md, section 2)."""


RANGE_ONLY_NOTE = """
The sensor reads ranges alone (no bearing column), so the range channel has no bearing terms and no
bearing settings are set. Nor can EM search for the start pose, which it scores by the bearings:
start_prior_mean is where the robot starts (x mm, y mm, heading rad; heading 0 faces the map's +y,
counterclockwise), within start_prior_sd; when EM moves it metres, it runs again from there. The
turn rate depends on the turn command alone (omega_rad_s, or on wheel speeds their difference), which
ranges cannot show (docs/em-real.md, section 2, "A sensor without bearings")."""


def config_header(command_names: tuple[str, ...], range_only: bool = False) -> str:
    """em_config.yaml's header for ``presets.planar_config``'s settings on these commands (with
    ``range_only``, ``range_only_config``'s)."""
    from sensact.models.wheel_drive import wheel_pair
    from sensact.presets import diffdrive_config

    pair = wheel_pair(command_names)
    if diffdrive_config(command_names) is None:
        head = MRCLAM_CONFIG_HEADER + FREE_MOTION_NOTE.format(names=", ".join(command_names))
    else:
        head = MRCLAM_CONFIG_HEADER + ("" if pair is None else WHEELS_CONFIG_NOTE.format(left=pair[0], right=pair[1]))
    return head + (RANGE_ONLY_NOTE if range_only else "")


@convert_app.command("mrclam")
@friendly
def convert_mrclam(
    dataset: Annotated[Path, typer.Argument(help="An MRCLAM dataset folder, e.g. .../MRCLAM_Dataset6.")],
    robot: Annotated[int, typer.Option(help="Robot 1-5.")] = 1,
    out: Annotated[Path, typer.Option("--out", help="The log folder to write.")] = Path("mrclam_log"),
    dt: Annotated[
        float, typer.Option(help="Step (s), 1/30 by default; commands are held between their rows.", show_default=False)
    ] = (1.0 / 30.0),
    no_map: Annotated[
        bool,
        typer.Option(
            "--no-map", help="Leave the surveyed map out: EM learns the landmarks' positions (kept for scoring only)."
        ),
    ] = False,
) -> None:
    """Write one MRCLAM robot as an EM log folder, with its EM settings in em_config.yaml.

    Commands are resampled with a zero-order hold; only landmark sightings are kept (range in mm and
    bearing); the landmark map goes into meta.json and Vicon into groundtruth.csv (for `sensact learn
    em` to score against; it is never learned from). With --no-map the map's positions are left out
    (null) and `learn em` learns them; the survey is kept in meta.json's ``survey`` for scoring only."""
    import numpy as np

    from sensact.io.atomic import write_text
    from sensact.io.landmark_folder import write_landmark_log
    from sensact.io.mrclam import read_mrclam
    from sensact.presets import mrclam_config, settings_yaml

    ml = read_mrclam(dataset, robot, dt_s=dt)
    console.print(ml.summary_line())
    if not ml.data.n_observations:
        console.print(
            f"[yellow]warning: robot {robot} sees no landmark, so `sensact learn em` has nothing to learn from "
            "this log; its odometry and Vicon are written all the same.[/]"
        )
    data, survey = ml.data, None
    if no_map:
        survey, data = data.landmarks_xy, data.with_landmarks(np.full_like(data.landmarks_xy, np.nan))
    write_landmark_log(
        out,
        data,
        t0_s=0.0,
        groundtruth=ml.groundtruth,
        meta_extra={"source": {"dataset": str(dataset), "robot": robot, "t0_s": ml.t0_s, "rows": ml.summary}},
        survey_xy=survey,
    )
    cfg = out / "em_config.yaml"
    write_text(cfg, settings_yaml("differential_drive_camera", mrclam_config(), ml.data, MRCLAM_CONFIG_HEADER))
    overview = _draw_overview(ml.data, ml.groundtruth, out, f"{dataset.name} robot {robot}")
    console.print(
        f"wrote {out}, its EM settings {cfg} (preset differential_drive_camera) and {overview}; learn with "
        f"`sensact learn em {out}`"
    )


def _survey_on(data: Any, survey: Path) -> Any:
    """The surveyed positions (mm) of ``data``'s landmarks, NaN where the survey does not list one."""
    import numpy as np

    from sensact.io.timed_csv import read_landmarks

    xy, ids = read_landmarks(survey)
    row = {str(v): j for j, v in enumerate(ids)}
    names = data.landmark_names
    return np.array([xy[row[n]] if n in row else (np.nan, np.nan) for n in names], dtype=float).reshape(-1, 2)


def _draw_overview(data: Any, groundtruth: JsonObject | None, out: Path, title: str) -> Path:
    """OUT/overview.png: the commands, the sightings over time and the map with the recorded path, to
    check a conversion by eye (mismatched clocks, a map in the wrong unit) before learning from it."""
    from sensact.report.figures_log import figure_log_overview

    return figure_log_overview(data, groundtruth, out / "overview.png", title)


@convert_app.command("csv")
@friendly
def convert_csv(
    commands: Annotated[Path, typer.Option(help="t_s and one column per command, a row whenever one was sent.")],
    sightings: Annotated[Path, typer.Option(help="t_s, landmark_id, one column per reading, optional bearing_rad.")],
    landmarks: Annotated[
        Path | None,
        typer.Option(
            help="The map: id (a number or a name), x_m, y_m (or x_mm, y_mm). Optional: EM learns the positions "
            "it does not give."
        ),
    ] = None,
    truth: Annotated[
        Path | None,
        typer.Option(help="Optional, for scoring only: t_s, x_m, y_m, theta_rad (0 facing +x, counterclockwise)."),
    ] = None,
    survey: Annotated[
        Path | None,
        typer.Option(
            help="Optional, for scoring a learned map only: id, x_m, y_m, as --landmarks (never learned from)."
        ),
    ] = None,
    learn_unlisted: Annotated[
        bool,
        typer.Option(
            "--learn-unlisted",
            help="A partial --landmarks map: learn the positions of the landmarks it does not list (seen 20 times "
            "or more) instead of dropping their sightings.",
        ),
    ] = False,
    out: Annotated[Path, typer.Option("--out", help="The log folder to write.")] = Path("robot_log"),
    dt: Annotated[
        float | None,
        typer.Option(
            help="Step (s); by default the commands' median interval (the controller's rate). Commands are held "
            "between their rows.",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Write your robot's own timed CSV files as an EM log folder.

    Times in seconds on one clock, rows in any order. Commands are held until the next row on a fixed
    step, each sighting goes to the nearest step, truth is interpolated. A spreadsheet's export reads as
    written (a byte-order mark, tabs, or semicolons with decimal commas). Column suffixes give units: _m
    and _m_s (or _cm and _cm_s) become mm and mm/s, _deg and _deg_s radians; a column whose numbers show
    another unit (bearings in degrees, times in ms) is refused, and a range or speed off the map's size, a
    turn rate over a turn a second, or a truth heading that points off the way the truth moves warned about.
    Without --landmarks, `learn em` learns every landmark's position with the models (the robot's start
    fixes the map's frame: the origin, facing +x), so every id in the sightings must be a landmark that
    stays put (drop other robots' ids). Sightings of landmarks the map does not list are dropped and
    counted; with --learn-unlisted (a partial map) those seen 20 times or more are learned instead, the
    listed ones held. A robot with a range_m and
    bearing camera also gets em_config.yaml (MRCLAM's settings) to start from: a differential drive's
    when the commands are v_m_s, omega_rad_s or the wheel speeds left_m_s, right_m_s; on any other
    commands, as a legged robot's (v, v_left, omega), every velocity, sideways too, affine in every
    command. A robot with range_m alone (radio beacons) gets the same without the bearings, in which to
    set where it starts. See docs/em-real.md."""
    import numpy as np

    from sensact.io.landmark_folder import truth_poses_of, write_landmark_log
    from sensact.io.timed_csv import read_timed_csv
    from sensact.io.unit_checks import unit_doubts

    tl = read_timed_csv(commands, sightings, landmarks, truth, dt_s=dt, learn_unlisted=learn_unlisted)
    console.print(tl.summary_line())
    for doubt in unit_doubts(tl.data, truth_poses_of(tl.groundtruth)):
        console.print(f"[yellow]warning:[/] {doubt}")
    if tl.truth_doubt:  # scoring only, so the log is written; the scores against it would be off
        console.print(f"[yellow]warning:[/] {truth}: {tl.truth_doubt}", highlight=False)
    files = {"commands": str(commands), "sightings": str(sightings)}
    files |= {k: str(v) for k, v in (("landmarks", landmarks), ("survey", survey)) if v is not None}
    write_landmark_log(
        out,
        tl.data,
        t0_s=0.0,
        groundtruth=tl.groundtruth,
        survey_xy=None if survey is None else _survey_on(tl.data, survey),
        meta_extra={
            "source": {"files": files | ({"truth": str(truth)} if truth else {}), "t0_s": tl.t0_s, "rows": tl.summary}
        },
    )
    d = tl.data
    console.print(f"drew {_draw_overview(d, tl.groundtruth, out, out.resolve().name)}")
    from sensact.io.atomic import write_text
    from sensact.presets import planar_config, range_only_config, settings_yaml

    # MRCLAM's settings learn from a range-and-bearing camera, or without its bearings from a range sensor
    # (radio beacons); other readings need their own channels
    cfg = out / "em_config.yaml"
    kept = cfg.is_file()  # an earlier conversion's, or the user's own, or the start pose set in it: not ours to replace
    if d.reading_names == ("range_mm",) and np.isfinite(d.obs_bearing_rad).any():
        settings = planar_config(d.command_names)
        write_text(cfg, settings_yaml("differential_drive_camera", settings, d, config_header(d.command_names)))
        console.print(
            f"wrote {out} and {cfg} (preset differential_drive_camera, a starting point for "
            f"{_robot_kind(d.command_names)} with a range-and-bearing camera); learn with `sensact learn em {out}`"
        )
        return
    if d.reading_names == ("range_mm",) and not kept:
        settings = range_only_config(d.command_names, (0.0, 0.0, 0.0))
        start = ("thesis.start_prior_mean", "thesis.start_prior_sd")
        header = config_header(d.command_names, range_only=True)
        write_text(cfg, settings_yaml("range_only_anchors", settings, d, header, start))
        console.print(
            f"wrote {out} and {cfg} (preset range_only_anchors, a starting point for "
            f"{_robot_kind(d.command_names)} with a range-only sensor). The sightings have no bearings, so EM "
            f"cannot search for where the robot starts: set start_prior_mean in {cfg} to its start (x mm, y mm, "
            f"heading rad; heading 0 faces the map's +y; a start metres off costs a second run), then learn with "
            f"`sensact learn em {out}`"
        )
        return
    console.print(
        f"wrote {out}; choose the model families for commands {', '.join(d.command_names)} and readings "
        f"{', '.join(d.reading_names)} in a YAML file, starting from a preset (`preset: NAME` on its first line; "
        f"docs/em-real.md, section 2), and learn with `sensact learn em {out} --config YOUR.yaml`"
    )
    if kept:
        console.print(
            f"[yellow]note:[/] {cfg} was there before and is left as it was; check that it "
            f"fits commands {', '.join(d.command_names)} before passing it to learn em"
        )


def _robot_kind(command_names: tuple[str, ...]) -> str:
    from sensact.presets import diffdrive_config

    if diffdrive_config(command_names):
        return "a differential drive"
    return f"a robot that can side-step on commands {', '.join(command_names)}"


TRACK_CONFIG_HEADER = """The EM settings `sensact learn em` reads from this folder: the track_1d preset
(the Turtlebot's; docs/em-real.md, section 2) for this 1-D robot's readings, and the fields below
it that differ from it: an affine action model with a learned command delay and motion noise;
{distance} reads the distance (its mm are the state's, which the windows are in) from a poor
straight line, every other reading from a flat line that says nothing of the distance.
Edit them for your robot; --set overrides single fields."""


BOOTSTRAP_CONFIG_HEADER = """Chapter 3's learner (Algorithm 1: `sensact learn bootstrap DIR`) on {distance}, as the
fields that differ from the thesis's: the Turtlebot's (docs/bootstrap.md, "The Turtlebot"), an affine
action model and t_start_s = 60 s. A_t takes over from A0 at 2 t_start_s, which must come after the
robot has driven both ways.{gate}
Edit them for your robot and pass this file with --config; --set overrides single fields."""


def _chapter3_meta(d: Any, distance_reading: str, has_truth: bool) -> JsonObject:
    """meta.json's keys through which `learn bootstrap` reads the folder as a 1-D log (one command, the
    distance reading, the recorded distance); none for several commands, which chapter 3 cannot learn."""
    if len(d.command_names) != 1:
        return {}
    (command,) = d.command_names
    meta: JsonObject = {
        "action": {"column": command, "unit": "mm/s" if command.endswith("_mm_s") else ""},
        "sensor": {"column": distance_reading, "unit": "mm"},
        "units": {r: "mm" if r.endswith("_mm") else "" for r in d.reading_names},
    }
    if has_truth:
        meta["groundtruth"] = {"column": "distance_mm", "unit": "mm"}
    return meta


def _parse_windows(items: list[str], known: dict[str, str]) -> dict[str, tuple[float, float]]:
    """``NAME=MIN:MAX`` (mm; an end left empty is open) by sensact's reading name."""
    from sensact.errors import LogFormatError
    from sensact.io.track_csv import named_columns

    out = {}
    for item in items:
        name, _, span = item.partition("=")
        (col,) = named_columns((name,), known, "--window", "reading")
        lo, colon, hi = span.partition(":")
        try:
            low, high = float(lo) if lo.strip() else -math.inf, float(hi) if hi.strip() else math.inf
        except ValueError:
            low = high = math.nan
        if not colon or not low < high:
            raise LogFormatError(
                f"--window {item!r} is not a window of distances.",
                field="--window",
                fix="write --window NAME=MIN_MM:MAX_MM with MIN below MAX (an end left empty is open, e.g. "
                "ir_volts=100:).",
            )
        out[col] = (low, high)
    return out


@convert_app.command("track")
@friendly
def convert_track(
    csv: Annotated[
        Path, typer.Argument(help="The 1-D robot's CSV: t_s, its command, its readings, optional distance_m.")
    ],
    out: Annotated[Path, typer.Option("--out", help="The track log folder to write.")] = Path("track_log"),
    command: Annotated[
        list[str] | None,
        typer.Option(
            metavar="COLUMN",
            help="A velocity command column (repeat for several); by default the one column in m/s, cm/s or mm/s.",
        ),
    ] = None,
    reading: Annotated[
        list[str] | None,
        typer.Option(
            metavar="COLUMN",
            help="A sensor's column (repeat for each); by default every other column. One must be in m or mm.",
        ),
    ] = None,
    distance: Annotated[
        str | None,
        typer.Option(
            metavar="COLUMN",
            help="The recorded distance, for scoring only; by default distance_m or distance_mm if there is one.",
        ),
    ] = None,
    window: Annotated[
        list[str] | None,
        typer.Option(
            metavar="NAME=MIN_MM:MAX_MM",
            help="The distances (mm) where a reading is valid (an IR sensor's range; an end left empty is open).",
        ),
    ] = None,
    robust: Annotated[
        list[str] | None,
        typer.Option(
            metavar="COLUMN",
            help="A reading read with a Student-t, for a sensor that is sometimes far wrong (a sonar).",
        ),
    ] = None,
    dt: Annotated[
        float | None, typer.Option(help="Step (s); by default the median spacing of the rows with a reading.")
    ] = None,
) -> None:
    """Write a 1-D robot's own CSV as a track log folder, with its EM settings in em_config.yaml.

    One file with a header row: a time (t_s, or t_ms, t_us, t_ns), the velocity command (held from each
    row that has it), one column per sensor (each row's readings at the nearest step; an empty cell where a
    sensor did not read) and, to score against, the recorded distance. Column suffixes give units as in
    `convert csv` (_m and _m_s, or _cm and _cm_s, become mm and mm/s; other columns keep theirs, an IR
    sensor's volts). One reading must be a distance (_m, _cm or _mm): the state takes its unit.
    em_config.yaml holds the Turtlebot's settings for these readings, with --window and --robust;
    overview.png draws each reading against the distance, to choose the windows by. With one command,
    bootstrap_config.yaml holds chapter 3's settings for the distance reading, for `learn bootstrap DIR`.
    See docs/em-real.md, section 1."""
    import numpy as np

    from sensact.config import config_to_yaml
    from sensact.io.atomic import write_text
    from sensact.io.landmark_folder import write_landmark_log
    from sensact.io.track_csv import named_columns, read_track_csv
    from sensact.presets import settings_yaml, track_em_config, track_learner
    from sensact.report.figures_log import figure_track_overview

    tc = read_track_csv(csv, commands=tuple(command or ()), readings=tuple(reading or ()), distance=distance, dt_s=dt)
    console.print(tc.summary_line())
    d = tc.data
    reads = {r: tc.sources[r] for r in d.reading_names}
    windows = _parse_windows(window or [], reads)
    robust_cols = named_columns(tuple(robust or ()), reads, "--robust", "reading")
    truth = None if tc.truth_mm is None else {"distance_mm": tc.truth_mm}
    if tc.truth_mm is not None and not np.isfinite(tc.truth_mm).all():
        console.print(
            f"[yellow]warning:[/] the recorded distance does not cover {int((~np.isfinite(tc.truth_mm)).sum())} of the "
            f"{d.n_steps} steps, and a fit is scored only against one on every step: give it on the first and last "
            "rows."
        )
    files = {"csv": str(csv)}
    chapter3 = _chapter3_meta(d, tc.distance_reading, truth is not None)
    source = {"files": files, "t0_s": tc.t0_s, "columns": tc.sources, "rows": tc.summary}
    write_landmark_log(out, d, groundtruth=truth, meta_extra={**chapter3, "source": source})
    cfg = out / "em_config.yaml"
    settings = track_em_config(d, tc.distance_reading, windows, robust_cols)
    header = TRACK_CONFIG_HEADER.format(distance=tc.distance_reading)
    write_text(cfg, settings_yaml("track_1d", settings, d, header))
    learners = f"learn with `sensact learn em {out}`"
    if chapter3:
        robust_distance = tc.distance_reading in robust_cols
        gate = (
            "\nAn outlier gate (3 running RMS innovations), as the reading is robust (--robust)."
            if robust_distance
            else ""
        )
        header = BOOTSTRAP_CONFIG_HEADER.format(distance=tc.distance_reading, gate=gate)
        write_text(out / "bootstrap_config.yaml", config_to_yaml(track_learner(robust_distance), header))
        learners += f" (or chapter 3's learner: `sensact learn bootstrap {out}`, settings in bootstrap_config.yaml)"
    overview = figure_track_overview(d, tc.truth_mm, tc.distance_reading, out / "overview.png", out.resolve().name)
    console.print(
        f"wrote {out}, its EM settings {cfg} and {overview}; {learners}"
        + ("" if truth is None else "; each is scored against the recorded distance")
    )


@convert_app.command("intervals")
@friendly
def convert_intervals(
    intervals: Annotated[
        Path,
        typer.Argument(
            help="Censi et al.'s tuples (one JSON object a line: T, phi_l, phi_r, sm), or a CSV of T_s, "
            "phi_l_rad_s, phi_r_rad_s, sm_x_m, sm_y_m, sm_theta_rad."
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="The intervals log folder to write.")] = Path("intervals_log"),
) -> None:
    """Write the scan-matched intervals Censi et al.'s calibration tool or OdomLaserCalibraTool holds as a log
    folder, for `sensact learn em OUT`: the wheels' radii, the axle and the lidar's mount, with error bars,
    as the scan route learns them after its own matching (docs/lidar2d.md).

    Each interval: its length T (s), the left and right wheels' angular velocities over it (rad/s, constant
    within it; the radii come out in mm per rad), and the scan matcher's displacement of the lidar over it, in
    the lidar's own frame at the interval's start (x forward, y left; metres and radians). A file ending in
    .csv is read as the CSV, any other as the JSON lines."""
    from sensact.io.atomic import nothing_half_written
    from sensact.io.intervals import read_intervals_file, write_intervals_log

    log = read_intervals_file(intervals)
    with nothing_half_written(out):
        write_intervals_log(out, log)
    console.print(
        f"wrote {out}: {log.n} intervals over {float(log.t_s.sum()):.1f} s; learn with `sensact learn em {out}`",
        highlight=False,
    )
