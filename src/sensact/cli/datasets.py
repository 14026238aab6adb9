"""``sensact convert`` and ``sensact evaluate``: a public dataset to a log folder, and a learned model
scored against the dataset's own ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from sensact.cli.base import EMModelOpt, console, convert_app, evaluate_app, friendly
from sensact.cli.scores import evaluate_em, print_truth_score

MRCLAM_CONFIG_HEADER = """The EM settings behind docs/em-real-results.md's MRCLAM results
(sensact.experiments.real.mrclam_config()), as the fields that differ from EMConfig's defaults.
Edit them for your robot (docs/em-real.md, section 2) and pass this file with --config;
--set overrides single fields."""
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
    """em_config.yaml's header for ``experiments.real.planar_config``'s settings on these commands (with
    ``range_only``, ``range_only_config``'s)."""
    from sensact.experiments.real import diffdrive_config
    from sensact.models.wheel_drive import wheel_pair

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
) -> None:
    """Write one MRCLAM robot as an EM log folder, with its EM settings in em_config.yaml.

    Commands are resampled with a zero-order hold; only landmark sightings are kept (range in mm and
    bearing); the landmark map goes into meta.json and Vicon into groundtruth.csv (for `sensact learn
    em` to score against; it is never learned from)."""
    from sensact.config import config_to_yaml
    from sensact.experiments.real import mrclam_config
    from sensact.io.atomic import write_text
    from sensact.io.landmark_log import write_landmark_log
    from sensact.io.mrclam import read_mrclam

    ml = read_mrclam(dataset, robot, dt_s=dt)
    console.print(ml.summary_line())
    if not ml.data.n_observations:
        console.print(
            f"[yellow]warning: robot {robot} sees no landmark, so `sensact learn em` has nothing to learn from "
            "this log; its odometry and Vicon are written all the same.[/]"
        )
    write_landmark_log(
        out,
        ml.data,
        t0_s=0.0,
        groundtruth=ml.groundtruth,
        meta_extra={"source": {"dataset": str(dataset), "robot": robot, "t0_s": ml.t0_s, "rows": ml.summary}},
    )
    cfg = out / "em_config.yaml"
    write_text(cfg, config_to_yaml(mrclam_config(), MRCLAM_CONFIG_HEADER))
    overview = _draw_overview(ml.data, ml.groundtruth, out, f"{dataset.name} robot {robot}")
    console.print(
        f"wrote {out}, its EM settings {cfg} and {overview}; learn with `sensact learn em {out} --config {cfg}`"
    )


def _draw_overview(data: Any, groundtruth: dict[str, Any] | None, out: Path, title: str) -> Path:
    """OUT/overview.png: the commands, the sightings over time and the map with the recorded path, to
    check a conversion by eye (mismatched clocks, a map in the wrong unit) before learning from it."""
    from sensact.report.figures_log import figure_log_overview

    return figure_log_overview(data, groundtruth, out / "overview.png", title)


@convert_app.command("csv")
@friendly
def convert_csv(
    commands: Annotated[Path, typer.Option(help="t_s and one column per command, a row whenever one was sent.")],
    sightings: Annotated[Path, typer.Option(help="t_s, landmark_id, one column per reading, optional bearing_rad.")],
    landmarks: Annotated[Path, typer.Option(help="The map: id (a number or a name), x_m, y_m (or x_mm, y_mm).")],
    truth: Annotated[
        Path | None, typer.Option(help="Optional, for scoring only: t_s, x_m, y_m, theta_rad (0 facing +x).")
    ] = None,
    out: Annotated[Path, typer.Option("--out", help="The log folder to write.")] = Path("robot_log"),
    dt: Annotated[
        float, typer.Option(help="Step (s), 1/30 by default; commands are held between their rows.", show_default=False)
    ] = (1.0 / 30.0),
) -> None:
    """Write your robot's own timed CSV files as an EM log folder.

    Times in seconds on one clock, rows in any order. Commands are held until the next row on a fixed
    step, each sighting goes to the nearest step, truth is interpolated. Column suffixes give units:
    _m and _m_s become mm and mm/s, _deg and _deg_s radians. Sightings of landmarks the map does not
    list are dropped and counted. A robot with a range_m and bearing camera also gets em_config.yaml
    (MRCLAM's settings) to start from: a differential drive's when the commands are v_m_s, omega_rad_s
    or the wheel speeds left_m_s, right_m_s; on any other commands, as a legged robot's (v, v_left,
    omega), every velocity, sideways too, affine in every command. A robot with range_m alone (radio
    beacons) gets the same without the bearings, in which to set where it starts. See docs/em-real.md."""
    import numpy as np

    from sensact.io.landmark_log import write_landmark_log
    from sensact.io.timed_csv import read_timed_csv

    tl = read_timed_csv(commands, sightings, landmarks, truth, dt_s=dt)
    console.print(tl.summary_line())
    files = {"commands": str(commands), "sightings": str(sightings), "landmarks": str(landmarks)}
    write_landmark_log(
        out,
        tl.data,
        t0_s=0.0,
        groundtruth=tl.groundtruth,
        meta_extra={
            "source": {"files": files | ({"truth": str(truth)} if truth else {}), "t0_s": tl.t0_s, "rows": tl.summary}
        },
    )
    d = tl.data
    console.print(f"drew {_draw_overview(d, tl.groundtruth, out, out.resolve().name)}")
    from sensact.config import config_to_yaml
    from sensact.experiments.real import planar_config, range_only_config
    from sensact.io.atomic import write_text

    # MRCLAM's settings learn from a range-and-bearing camera, or without its bearings from a range sensor
    # (radio beacons); other readings need their own channels
    cfg = out / "em_config.yaml"
    kept = cfg.is_file()  # an earlier conversion's, or the user's own, or the start pose set in it: not ours to replace
    if d.reading_names == ("range_mm",) and np.isfinite(d.obs_bearing_rad).any():
        write_text(cfg, config_to_yaml(planar_config(d.command_names), config_header(d.command_names)))
        console.print(
            f"wrote {out} and {cfg} (MRCLAM's settings, a starting point for {_robot_kind(d.command_names)} with a "
            f"range-and-bearing camera); learn with `sensact learn em {out} --config {cfg}`"
        )
        return
    if d.reading_names == ("range_mm",) and not kept:
        settings = range_only_config(d.command_names, (0.0, 0.0, 0.0))
        start = ("start_prior_mean", "start_prior_sd")
        write_text(cfg, config_to_yaml(settings, config_header(d.command_names, range_only=True), start))
        console.print(
            f"wrote {out} and {cfg} (MRCLAM's settings without the bearings, a starting point for "
            f"{_robot_kind(d.command_names)} with a range-only sensor). The sightings have no bearings, so EM "
            f"cannot search for where the robot starts: set start_prior_mean in {cfg} to its start (x mm, y mm, "
            f"heading rad; heading 0 faces the map's +y; a start metres off costs a second run), then learn with "
            f"`sensact learn em {out} --config {cfg}`"
        )
        return
    console.print(
        f"wrote {out}; choose the model families for commands {', '.join(d.command_names)} and readings "
        f"{', '.join(d.reading_names)} in a YAML file (docs/em-real.md, section 2) and learn with "
        f"`sensact learn em {out} --config YOUR.yaml`"
    )
    if kept:
        console.print(
            f"[yellow]note:[/] {cfg} was there before and is left as it was; check that it "
            f"fits commands {', '.join(d.command_names)} before passing it to learn em"
        )


def _robot_kind(command_names: tuple[str, ...]) -> str:
    from sensact.experiments.real import diffdrive_config

    if diffdrive_config(command_names):
        return "a differential drive"
    return f"a robot that can side-step on commands {', '.join(command_names)}"


@evaluate_app.command("mrclam")
@friendly
def evaluate_mrclam_cmd(
    dataset: Annotated[Path, typer.Argument(help="An MRCLAM dataset folder, e.g. .../MRCLAM_Dataset6.")],
    model: EMModelOpt,
    robot: Annotated[int, typer.Option(help="Robot 1-5.")] = 1,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write the scores here (JSON), and four figures beside it (OUT_actions.png, ...)."),
    ] = None,
) -> None:
    """Score a learned MRCLAM model against Vicon, next to From-Truth.

    From-Truth is the same model families fitted directly to the ground truth. With --out, also draw
    the action curves, the range function, the heading noise and the bearing noise against Vicon's,
    as `reproduce real` does."""
    from sensact.evaluate.landmark_truth import score_against_truth
    from sensact.experiments.real import bar_checks
    from sensact.io.atomic import write_json
    from sensact.io.mrclam import read_mrclam

    doc, m = _read_em_model(model)
    ml = read_mrclam(dataset, robot, dt_s=float(doc.get("dt_s", 1.0 / 30.0)))
    learn = (
        f"sensact convert mrclam {dataset} --robot {robot} --out DIR, then "
        "sensact learn em DIR --config DIR/em_config.yaml"
    )
    refuse_model_for_log(doc, m, ml.data, model, f"{dataset} robot {robot}", learn)
    sc = score_against_truth(m, ml.data, *ml.truth_poses())
    sc["bars"] = bar_checks(sc)
    print_truth_score(sc)
    if out is not None:
        from sensact.report.figures_real import write_robot

        write_json(out, sc)
        figures = write_robot(ml, m, sc, out.with_suffix(""), f"robot {robot}")
        console.print("wrote " + ", ".join(str(p) for p in (out, *figures)))


def _read_em_model(model: Path) -> tuple[dict[str, Any], Any]:
    """A model.json `sensact learn em` wrote: the whole document (its ``dt_s`` too) and the model."""
    from sensact.errors import ModelFormatError
    from sensact.io.jsonfile import read_json_object
    from sensact.models.em_model import EMModel

    doc = read_json_object(model, ModelFormatError, "give the model.json `sensact learn em` wrote.")
    return doc, EMModel.from_dict(doc.get("model", doc), source=str(model))


def refuse_model_for_log(
    doc: dict[str, Any], m: Any, data: Any, model: Path, log: Path | str, learn: str | None = None, use: str = "scored"
) -> None:
    """A model scores (or runs, ``use``) only on a log it could have been learned from: the same geometry,
    commands (or number of actions), readings and step, since its delay is counted in steps. One line
    naming what differs; ``learn`` is the command that learns a model on ``log``."""
    import numpy as np

    from sensact.errors import ModelFormatError
    from sensact.models.action_table import ActionTable

    def refuse(what: str, field: str, fix: str) -> None:
        raise ModelFormatError(f"{what}, so it cannot be {use} on {log}.", file=model, field=field, fix=fix)

    learn = learn or f"sensact learn em {log}"
    verb = "score" if use == "scored" else "run"
    relearn = f"{verb} it on a log like the one it was learned from, or learn one on this log ({learn})."
    if m.geometry != data.geometry:
        refuse(f"the model is {m.geometry} and the log {data.geometry}", "geometry", relearn)
    if isinstance(m.action, ActionTable):
        if data.is_continuous or m.action.n_actions != data.n_actions:
            has = "continuous commands" if data.is_continuous else f"{data.n_actions} actions"
            refuse(f"the model has a table of {m.action.n_actions} actions and the log {has}", "action", relearn)
        if not np.allclose(m.action.commands, data.action_commands, rtol=1e-9, atol=1e-9):
            # a track log bins its own commands: the same count of actions can mean other commands
            refuse("the model's actions are other commands than the log's", "action.commands", relearn)
    elif tuple(m.action.command_names) != tuple(data.command_names):
        refuse(
            f"the model's commands are {', '.join(m.action.command_names)} and the log's "
            f"{', '.join(data.command_names) or 'discrete actions'}",
            "action.command_names",
            relearn,
        )
    missing = [ch.name for ch in m.sensor.channels if ch.name not in data.reading_names]
    if missing:
        refuse(f"the log has no reading {missing[0]} (it has {', '.join(data.reading_names)})", "sensor", relearn)
    if data.geometry == "planar" and not np.isfinite(data.obs_bearing_rad).any():
        bent = [ch.name for ch in m.sensor.channels if ch.bearing_terms]
        if bent:
            refuse(
                f"the model's {bent[0]} reads through its bearing terms and the log has no bearings",
                "sensor",
                relearn,
            )
    dt = doc.get("dt_s")
    if dt is not None and abs(float(dt) - data.dt_s) > 1e-9 * max(1.0, data.dt_s):
        refuse(
            f"the model was learned on steps of {float(dt):.6g} s and the log has {data.dt_s:.6g} s (the command "
            "delay is counted in steps)",
            "dt_s",
            f"convert the log again with --dt {float(dt):.10g}.",
        )


@evaluate_app.command("log")
@friendly
def evaluate_log_cmd(
    log: Annotated[
        Path,
        typer.Argument(
            help="A log folder with its ground truth (groundtruth.csv with poses), or a Turtlebot CSV with its "
            "range column."
        ),
    ],
    model: EMModelOpt,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Write the scores here (JSON), and the figures beside it (OUT_actions.png, ...; for a Turtlebot "
            "CSV OUT_against_range.png).",
        ),
    ] = None,
) -> None:
    """Score a model learned on one log against another log's ground truth, next to From-Truth.

    The check that a model holds beyond the log it was learned from: learn on one run, score on the
    next. The same table, bars and figures as `learn em` prints for a log with ground truth, with
    From-Truth fitted on this log; the model must share the log's commands, readings and step. On a
    Turtlebot CSV the robot is first placed by the E-step with the model held (as `sensact localize`),
    and the model is scored against the range column as `learn em` scores it."""
    from sensact.errors import LogFormatError
    from sensact.io.atomic import write_json
    from sensact.io.landmark_log import read_landmark_log

    if log.is_file():
        _evaluate_on_range_column(log, model, out)
        return
    doc, m = _read_em_model(model)
    lf = read_landmark_log(log)
    refuse_model_for_log(doc, m, lf.data, model, log)
    console.print(f"{model} on {lf.title(log)}: {lf.data.n_steps} steps, {lf.data.n_observations} observations")
    sc = evaluate_em(lf, m)
    if sc is None:
        raise LogFormatError(
            "has no ground truth to score against.",
            file=log / "groundtruth.csv",
            fix="add groundtruth.csv with t_s, x_mm, y_mm, theta_rad (convert csv --truth writes it).",
        )
    if out is not None:
        write_json(out, sc)
        written = [out]
        if "truth_noise" in sc:  # scored against recorded poses: the figures too
            from sensact.report.figures_real import write_robot

            written += write_robot(lf, m, sc, out.with_suffix(""), lf.title(log), truth="ground truth")
        console.print("wrote " + ", ".join(str(p) for p in written))


def _evaluate_on_range_column(log: Path, model: Path, out: Path | None) -> None:
    """`evaluate log` on a Turtlebot CSV: the state has no unit of its own, so the model is scored through the
    optimal map of the path it places onto the recorded range (sec. 4.4.3), fitted on this log."""
    import numpy as np

    from sensact.cli.localize import place_robot, read_model_and_log
    from sensact.cli.scores import evaluate_turtlebot_em
    from sensact.errors import LogFormatError
    from sensact.io.atomic import write_json

    doc, m, data, _, truth_mm = read_model_and_log(log, model, 21, use="scored")
    if truth_mm is None or not np.isfinite(truth_mm).any():
        raise LogFormatError(
            "has no range column to score against.",
            file=log,
            field="range",
            fix="score on a CSV with the range column (calibration.csv, training*.csv); `sensact localize` runs "
            "the model on one without it.",
        )
    if not np.isfinite(truth_mm).all():
        raise LogFormatError(
            f"{int((~np.isfinite(truth_mm)).sum())} steps have no range, and the scores need it at every step.",
            file=log,
            field="range",
            fix="score on a stretch of the log with the range at every step.",
        )
    loc, per_learned = place_robot(doc, m, data, model, None, None, None)
    sc = evaluate_turtlebot_em(loc, data, truth_mm)
    if out is None or sc is None:
        return
    from sensact.experiments.turtlebot_em import TurtlebotEMRun
    from sensact.report.figures_turtlebot_em import figure_turtlebot_em

    doc_out = {
        "log": data.source,
        "model": str(model),
        "loglik_per_sighting": loc.loglik_per_sighting,
        "loglik_per_sighting_learned": per_learned,
        "start": loc.start,
        "evaluation": sc,
    }
    path = out.with_name(f"{out.stem}_against_range.png")
    run = TurtlebotEMRun(data, truth_mm, loc)
    written = [write_json(out, doc_out), figure_turtlebot_em(run, sc, path, f"{model.name} on {log.name}")]
    console.print("wrote " + ", ".join(str(p) for p in written))


def learned_on_log(doc: dict[str, Any], log: Path) -> bool:
    """Whether model.json says it was learned on ``log``: ``learn em`` records the folder as it was given, so
    a relative one matches the end of the log's full path (it may have been run from another folder)."""
    recorded = doc.get("log")
    if not recorded:
        return False
    path, full = Path(str(recorded)), log.resolve()
    parts = tuple(q for q in path.parts if q != ".")
    if path.is_absolute() or not parts or ".." in parts:  # "." or "../x" name a folder only from where it ran
        return path.resolve() == full
    return full.parts[-len(parts) :] == parts


def fleet_names(paths: list[Path], name: Any) -> list[str]:
    """Short, distinct names for the table: ``name(path)`` (a folder's or a file's own name), or the path as
    given where two would share one."""
    short = [name(p) for p in paths]
    return [str(p) if short.count(s) > 1 else s for p, s in zip(paths, short, strict=True)]


@evaluate_app.command("fleet")
@friendly
def evaluate_fleet_cmd(
    logs: Annotated[
        list[Path],
        typer.Argument(help="Log folders, with or without ground truth (groundtruth.csv with poses).", metavar="DIR"),
    ],
    model: Annotated[
        list[Path], typer.Option("--model", help="A model.json written by `sensact learn em`; repeat for each model.")
    ],
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write the scores here (JSON), and the grids beside it (OUT.png)."),
    ] = None,
) -> None:
    """Score every model on every log: does one robot's model serve the others of its kind?

    For a fleet of robots of one kind, each with a log and a model learned on it. Without ground truth,
    each model is placed on each log by the E-step alone (as `sensact localize` places it) and the table
    gives its log-likelihood a sighting and how far it falls below the log's most likely model. When every
    log has recorded poses, each pair is also scored as `sensact evaluate log` scores it, against that
    log's ground truth with From-Truth fitted on that log: the translation and rotation RMS over
    From-Truth's, the range function's residual about the truth and the bearing sigma over the truth's. A
    pair is a robot's own when the model was learned on that log. Every model must share the logs'
    commands, readings and step."""
    from sensact.cli.base import progress_bar
    from sensact.experiments.fleet import score_fleet
    from sensact.io.atomic import write_json
    from sensact.io.landmark_log import read_landmark_log
    from sensact.learn.em.localize import learned_config

    models, configs, own = {}, {}, {}
    logs, model = list(dict.fromkeys(logs)), list(dict.fromkeys(model))  # a folder or file given twice counts once
    read = {p: read_landmark_log(p) for p in logs}
    log_names = dict(zip(logs, fleet_names(logs, lambda p: p.resolve().name), strict=True))
    for path, name in zip(model, fleet_names(model, lambda p: p.stem), strict=True):
        doc, m = _read_em_model(path)
        for log, lf in read.items():
            refuse_model_for_log(doc, m, lf.data, path, log)
        models[name] = m
        configs[name] = learned_config((doc.get("summary") or {}).get("config"), str(path))
        for log in logs:
            if learned_on_log(doc, log):
                own[name] = log_names[log]
    n_m, n_l = len(models), len(read)
    console.print(
        f"{n_m} model{'s' * (n_m > 1)} on {n_l} log{'s' * (n_l > 1)}: "
        + ", ".join(lf.title(p) for p, lf in read.items())
    )
    with progress_bar() as progress:
        fleet = score_fleet(models, {log_names[p]: lf for p, lf in read.items()}, own, progress, configs)
    print_fleet(fleet)
    if out is not None:
        from sensact.report.figures_fleet import figure_fleet

        write_json(out, fleet)
        figure = figure_fleet(fleet, out.with_suffix(".png"))
        console.print(f"wrote {out} and {figure}")


def print_fleet(fleet: dict[str, Any]) -> None:
    """The fleet's tables (a missed bar in red, a robot's own pair in bold) and what they say."""
    from sensact.cli.base import print_tables
    from sensact.report.tables import fleet_likelihood_lines, fleet_likelihood_table, fleet_lines, fleet_table

    if "cells" in fleet:
        print_tables([fleet_table(fleet, miss=lambda s: f"[red]{s}[/]", own=lambda s: f"[bold]{s}[/]")])
        for line in fleet_lines(fleet):
            console.print(line)
    else:
        console.print(
            f"not scored against ground truth: {', '.join(fleet['no_truth'])} "
            f"{'has' if len(fleet['no_truth']) == 1 else 'have'} no recorded poses on continuous commands "
            "(groundtruth.csv with t_s, x_mm, y_mm, theta_rad; `convert csv --truth` writes it)"
        )
    if "likelihood" in fleet:
        print_tables([fleet_likelihood_table(fleet, own=lambda s: f"[bold]{s}[/]")])
        for line in fleet_likelihood_lines(fleet):
            console.print(line)
