"""``sensact evaluate``: a learned model scored against a log's own ground truth (MRCLAM's Vicon, a log
folder's recorded poses or simulated model, a Turtlebot CSV's range column), and a fleet's models on each
other's logs."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from sensact.app.logs import read_em_model, refuse_model_for_log
from sensact.cli.base import (
    EMModelOpt,
    ForceOpt,
    SchedulerOpt,
    WorkersOpt,
    check_out_file,
    console,
    evaluate_app,
    friendly,
    write_result,
)
from sensact.cli.scores import print_scores, print_truth_score
from sensact.outputs import EVALUATION, FLEET_EVALUATION
from sensact.records import JsonObject


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
    force: ForceOpt = False,
) -> None:
    """Score a learned MRCLAM model against Vicon, next to From-Truth.

    From-Truth is the same model families fitted directly to the ground truth. With --out, also draw
    the action curves, the range function, the heading noise and the bearing noise against Vicon's,
    as `reproduce real` does."""
    check_out_file(out, others={"--model": model}, kind=EVALUATION, force=force)
    from sensact.evaluate.bars import bar_checks
    from sensact.evaluate.landmark_truth import score_against_truth
    from sensact.io.mrclam import read_mrclam

    doc, m = read_em_model(model)
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

        write_result(out, sc, EVALUATION)
        figures = write_robot(ml, m, sc, out.with_suffix(""), f"robot {robot}")
        console.print("wrote " + ", ".join(str(p) for p in (out, *figures)))


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
    force: ForceOpt = False,
) -> None:
    """Score a model learned on one log against another log's ground truth, next to From-Truth.

    The check that a model holds beyond the log it was learned from: learn on one run, score on the
    next. The same table, bars and figures as `learn em` prints for a log with ground truth, with
    From-Truth fitted on this log; the model must share the log's commands, readings and step. On a
    Turtlebot CSV the robot is first placed by the E-step with the model held (as `sensact localize`),
    and the model is scored against the range column as `learn em` scores it. On a log folder too the robot
    is placed first, and its path scored (evaluation.path.median_mm). Whatever the truth, the model's
    consistency: per reading type, the share of the filter's one-step-ahead innovations inside the model's
    90 % interval (consistency.range.coverage90, .bearing; 0.90 when its sigma is honest) and their mean
    normalized square (nis_mean, 1 when honest)."""
    check_out_file(out, others={"--model": model}, kind=EVALUATION, force=force)
    # a track folder's continuous commands are binned as `learn em`'s default bins them (a Turtlebot
    # CSV's are read as they are)
    from sensact.app.log_kinds import kind_of, open_log, refuse_other_kinds
    from sensact.app.logs import read_model_and_log
    from sensact.errors import LogFormatError

    kind = kind_of(log)
    if kind.evaluate is not None:  # a kind that scores its own models (an odometry-IMU-GNSS log's consistency)
        from sensact.app.export import read_model_doc

        result = kind.evaluate(open_log(log), read_model_doc(model), model)
        for sensor, c in result["consistency"].items():
            console.print(
                f"{sensor}: coverage90 {c['coverage90']:.3f}, nis_mean {c['nis_mean']:.3f} ({c['n']} innovations)",
                highlight=False,
            )
        if out is not None:
            write_result(out, result, EVALUATION)
            console.print(f"wrote {out}")
        return
    refuse_other_kinds(log, "evaluate log")
    doc, m, opened = read_model_and_log(log, model, bins=21, use="scored")
    lf, truth_mm = opened.folder, opened.recorded_distance_mm
    if truth_mm is not None:  # a Turtlebot CSV, or a track folder with a recorded distance
        _evaluate_on_range_column(doc, m, opened, model, out)
        return
    console.print(f"{model} on {lf.title(log)}: {lf.data.n_steps} steps, {lf.data.n_observations} observations")
    from sensact.app.scores import Scores, score_model
    from sensact.cli.localize import consistency_on, place_robot

    # another run starts elsewhere: the robot is placed first (as `localize`), and its path scored too
    loc, per_learned = place_robot(doc, m, opened.data, model, None, None, None)
    held = consistency_on(loc.model, opened.data)
    scores = score_model(opened, m, path=loc.posteriors.mean_gamma, fit=loc)
    print_scores(scores, opened)
    if not isinstance(scores, Scores):
        raise LogFormatError(
            "has no ground truth to score against.",
            file=log / "groundtruth.csv",
            fix="add groundtruth.csv with t_s, x_mm, y_mm, theta_rad (convert csv --truth writes it).",
        )
    sc = scores.evaluation
    if out is not None:
        placed = {"start": loc.start, "loglik_per_sighting": loc.loglik_per_sighting}
        placed |= {"loglik_per_sighting_learned": per_learned}
        # the path as a model.json's evaluation.path names it, the consistency as localize's
        write_result(out, sc | placed | {"evaluation": {"path": sc.get("path")}, "consistency": held}, EVALUATION)
        written = [out]
        if sc.get("truth_noise"):  # scored against recorded poses (with their heading): the figures too
            from sensact.report.figures_real import write_robot

            written += write_robot(lf, m, sc, out.with_suffix(""), lf.title(log), truth="ground truth")
        console.print("wrote " + ", ".join(str(p) for p in written))


def _evaluate_on_range_column(doc: JsonObject, m: Any, opened: Any, model: Path, out: Path | None) -> None:
    """`evaluate log` on a Turtlebot CSV: the state has no unit of its own, so the model is scored through the
    optimal map of the path it places onto the recorded range (sec. 4.4.3), fitted on this log."""

    import numpy as np

    from sensact.app.scores import Scores, score_model
    from sensact.cli.localize import consistency_on, place_robot
    from sensact.errors import LogFormatError
    from sensact.evaluate.turtlebot_em import range_column_problem

    data, truth_mm, log = opened.data, opened.recorded_distance_mm, opened.path
    problem = range_column_problem(truth_mm)
    if problem and log.is_dir():  # a track folder's distance_mm, empty on the grid only next to an empty cell
        raise LogFormatError(
            f"groundtruth.csv's distance_mm is empty at {int((~np.isfinite(truth_mm)).sum())} steps, and the scores "
            "need the recorded distance at every step.",
            file=log / "groundtruth.csv",
            field="distance_mm",
            fix="fill every distance_mm cell (or drop those rows); `sensact localize` runs the model without scores.",
        )
    if problem:
        raise LogFormatError(
            f"{problem} to score against, and the scores need the range at every step.",
            file=log,
            field="range",
            fix="score on a CSV with the range at every step (calibration.csv, training*.csv); `sensact localize` "
            "runs the model on one without it.",
        )
    loc, per_learned = place_robot(doc, m, data, model, None, None, None)
    held = consistency_on(loc.model, data)
    scores = score_model(opened, m, fit=loc)
    print_scores(scores, opened)
    if out is None or not isinstance(scores, Scores):
        return
    sc = scores.evaluation
    from sensact.evaluate.turtlebot_em import TurtlebotEMRun
    from sensact.report.figures_turtlebot_em import figure_turtlebot_em

    doc_out = {
        "log": data.source,
        "model": str(model),
        "loglik_per_sighting": loc.loglik_per_sighting,
        "loglik_per_sighting_learned": per_learned,
        "start": loc.start,
        "evaluation": sc,
        "consistency": held,
    }
    path = out.with_name(f"{out.stem}_against_range.png")
    run = TurtlebotEMRun(data, truth_mm, loc)
    written = [write_result(out, doc_out, EVALUATION)]
    written.append(figure_turtlebot_em(run, sc, path, f"{model.name} on {log.name}"))
    console.print("wrote " + ", ".join(str(p) for p in written))


@evaluate_app.command("fleet")
@friendly
def evaluate_fleet_cmd(
    logs: Annotated[
        list[Path],
        typer.Argument(
            help="Log folders, with or without ground truth (groundtruth.csv with poses), or Turtlebot CSVs, with "
            "or without their range column.",
            metavar="LOG",
        ),
    ],
    model: Annotated[
        list[Path], typer.Option("--model", help="A model.json written by `sensact learn em`; repeat for each model.")
    ],
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write the scores here (JSON), and the grids beside it (OUT.png)."),
    ] = None,
    workers: WorkersOpt = 1,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Score every model on every log: does one robot's model serve the others of its kind?

    For a fleet of robots of one kind, each with a log and a model learned on it. Without ground truth,
    each model is placed on each log by the E-step alone (as `sensact localize` places it) and the table
    gives its log-likelihood a sighting and how far it falls below the log's most likely model. When every
    log has recorded poses, each pair is also scored as `sensact evaluate log` scores it, against that
    log's ground truth with From-Truth fitted on that log: the translation and rotation RMS over
    From-Truth's, the range function's residual about the truth and the bearing sigma over the truth's. On
    Turtlebot CSVs with their range column, each placed model is also scored against the range as
    `evaluate log` scores it: the action gain's error and the best sensor's, in % of its span. A pair is
    a robot's own when the model was learned on that log. Every model must share the logs' commands,
    readings and step (a Turtlebot CSV is read onto each model's own step)."""
    check_out_file(out, kind=FLEET_EVALUATION, force=force)
    from sensact.app.fleet import fleet_names, log_name, score_fleet_on
    from sensact.cli.base import progress_bar
    from sensact.engine import open_engine

    logs, model = list(dict.fromkeys(logs)), list(dict.fromkeys(model))  # a folder or file given twice counts once
    n_m, n_l = len(model), len(logs)
    with open_engine(workers, scheduler) as engine:
        names = fleet_names(logs, log_name)
        console.print(
            f"{n_m} model{'s' * (n_m > 1)} on {n_l} log{'s' * (n_l > 1)} ({', '.join(names)}), on {engine.where}"
        )
        with progress_bar() as progress:

            def on_progress(i: int, desc: str, done: int, total: int | None) -> None:
                progress(f"{names[i]}: {desc}", done, total)

            fleet = score_fleet_on(engine, model, logs, on_progress=on_progress)
    print_fleet(fleet)
    if out is not None:
        from sensact.report.figures_fleet import figure_fleet

        write_result(out, fleet, FLEET_EVALUATION)
        figure = figure_fleet(fleet, out.with_suffix(".png"))
        console.print(f"wrote {out} and {figure}")


def print_fleet(fleet: JsonObject) -> None:
    """The fleet's tables (a missed bar in red, a robot's own pair in bold) and what they say."""
    from sensact.cli.base import print_tables
    from sensact.report.tables_fleet import (
        fleet_likelihood_lines,
        fleet_likelihood_table,
        fleet_lines,
        fleet_range_lines,
        fleet_range_table,
        fleet_table,
    )

    miss, own = (lambda s: f"[red]{s}[/]"), (lambda s: f"[bold]{s}[/]")
    if "cells" in fleet:
        print_tables([fleet_table(fleet, miss=miss, own=own)])
        for line in fleet_lines(fleet):
            console.print(line)
    for log, doubt in fleet.get("truth_heading_doubts", {}).items():
        console.print(f"[yellow]warning:[/] {log}: {doubt}", highlight=False)
    rng = fleet.get("range", {})
    # a Turtlebot CSV has no poses by its nature: it is scored against its range column instead
    unposed = [
        g for g in fleet.get("no_truth", []) if g not in rng.get("logs", []) and g not in rng.get("no_range", {})
    ]
    if unposed:
        console.print(
            f"not scored against ground truth: {', '.join(unposed)} "
            f"{'has' if len(unposed) == 1 else 'have'} no recorded poses on continuous commands "
            "(groundtruth.csv with t_s, x_mm, y_mm, theta_rad; `convert csv --truth` writes it)"
        )
    if rng.get("logs"):
        print_tables([fleet_range_table(fleet, miss=miss, own=own)])
    for line in fleet_range_lines(fleet):
        console.print(line)
    if "likelihood" in fleet:
        print_tables([fleet_likelihood_table(fleet, own=lambda s: f"[bold]{s}[/]")])
        for line in fleet_likelihood_lines(fleet):
            console.print(line)
