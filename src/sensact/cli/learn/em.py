"""``sensact learn em``: chapter 4's EM on a log folder or a Turtlebot CSV, from the thesis's poor guess or
from a learned model (``--start-from``), and on the log's halves (``--halves``)."""

from __future__ import annotations

from functools import cache, singledispatch
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.markup import escape

from sensact.cli.base import (
    ConfigOpt,
    EMLogArg,
    ForceOpt,
    SchedulerOpt,
    SetOpt,
    UncertaintyOpt,
    WorkersOpt,
    check_out_file,
    console,
    finish,
    friendly,
    learn_app,
    print_tables,
    progress_bar,
    write_result,
)
from sensact.cli.scores import print_em_model, print_scores
from sensact.outputs import EM_MODEL
from sensact.records import JsonObject

if TYPE_CHECKING:  # numpy is imported where a command needs it, so that --help stays quick
    import numpy as np


def _still_climbing(loglik: np.ndarray, best: int, max_iterations: int, patience: int, raced: int) -> str:
    """What a fit stopped at the cap tells the user: patience never ran out, so the likelihood may still
    rise; how much it rose lately says whether more iterations are worth their time."""
    window = min(patience, loglik.size // 2)
    lately = (
        f"the best log-likelihood rose by {loglik[best] - loglik[: loglik.size - window].max():.1f} "
        f"in the last {window} iterations"
        if window >= 1
        else "too few iterations to tell how fast it was rising"
    )
    return (
        f"[yellow]EM reached max_iterations ({max_iterations}"
        + (f", the start race's {raced} included" if raced > 0 else "")  # they count toward the cap
        + f") before {patience} iterations passed without a new best[/]: {lately}. The model given is the best "
        f"so far; to let EM run on, raise the cap (--set max_iterations={2 * max_iterations})."
    )


def learn_and_compare_halves(res: Any, data: Any, cfg: Any, figure: Path | None = None, title: str = "") -> JsonObject:
    """`learn em --halves`: each half of ``data`` learned on from ``res``'s model (learn/em/uses/split_halves.py),
    the three compared (evaluate/halves.py), printed and, given a ``figure`` path, drawn there; what the
    model JSON keeps of it."""
    from sensact.cli.scores import halves_rows
    from sensact.evaluate.halves import compare_halves
    from sensact.learn.em.uses.split_halves import learn_halves

    console.print("--halves: each half of the log learned on from this model, placed on it as `localize` does")
    with progress_bar() as progress:
        fits = learn_halves(
            res.model,
            data,
            cfg,
            progress=progress,
            on_iteration=lambda half, it, ll, best, since: progress(
                f"EM on the {half}: log-likelihood {ll:.1f} (best {best:.1f})", it + 1, None
            ),
        )
    cmp = compare_halves(res.model, fits[0].result.model, fits[1].result.model, res.posteriors, data)
    print_tables(
        [
            (
                "the log's halves, each learned on from the whole log's model (evaluate/halves.py)",
                ["", *[h.name for h in fits], "whole log", "halves differ by"],
                halves_rows(cmp, fits, data),
            )
        ]
    )
    for h in fits:
        if h.result.best_iteration == 0:  # EM keeps its most likely model, and none it learned beat its start
            console.print(
                f"the {h.name} kept the whole log's model: EM found none more likely on it, so the two do not differ"
            )
    if figure is not None:
        from sensact.report.figures_halves import figure_halves

        halves = [(h.name, h.result.model) for h in fits]
        console.print(f"wrote {figure_halves(res.model, halves, data, cmp, figure, title)}")
    return {
        "comparison": cmp,
        "fits": [
            {
                "half": h.name,
                "steps": list(h.steps),
                "placed": h.placed.start,
                "summary": h.result.summary(),
                "model": h.result.model.to_dict(),
            }
            for h in fits
        ],
    }


def _describe_fit(res: Any, cfg: Any) -> None:
    """How EM stopped and what its searches, gates and restarts did on the way."""
    from sensact.records import to_json
    from sensact.report.tables_real import kept_run_cell, restart_runs_cell

    console.print(
        f"stopped: [bold]{res.stop_reason}[/] after {res.iterations} iterations ({res.seconds:.1f} s); "
        f"best log-likelihood {res.loglik_best:.1f} at iteration {res.best_iteration}"
        + (f"; {res.n_pruned} observations pruned" if res.n_pruned else "")
        + (
            f" ({res.n_pruned_when_freed} when the robust readings took over: bearing more than "
            f"{cfg.thesis.prune_rad_per_step:g} rad off the smoothed path; prune_when_freed)"
            if res.n_pruned_when_freed
            else ""
        )
    )
    if res.mount is not None and res.model.geometry.has_heading:
        console.print(f"sensor mount: {res.mount.describe()}", highlight=False)
    learned = res.model.landmarks
    if learned is not None:
        held, placed = int(learned.held.sum()), int((learned.placed & ~learned.held).sum())
        console.print(
            f"landmark map: {placed} of {int((~learned.held).sum())} positions learned and placed"
            + (f", {held} given and held" if held else "")
            + f"; {learned.frame} (model.json's map; export --format landmarks)",
            highlight=False,
        )
    if res.start_moved:
        first, again = res.start_moved.loglik
        console.print(
            f"runs from the given start and from where EM moved it: log-likelihood {first:.1f} and {again:.1f}; "
            f"kept the {'second' if res.start_moved.kept == 'again' else 'first'}"
        )
    if res.turned_to_face_forward:
        console.print(
            "the sensor reads no bearing, so a robot driving backward while facing the other way reads the same: "
            "EM ended so, and the model is reported turned by pi, driving forward (the same likelihood; "
            'docs/em-real.md, section 2, "A sensor without bearings")',
            markup=False,
        )
    if res.n_pruned_when_freed and not cfg.robust.joint_student_t and res.model.sensor.student_t_params:
        console.print(
            "[yellow]sightings that far off are misread barcodes;[/] a misread one whose bearing happens to fit "
            "still counts in bearing. If there are many, --set joint_student_t=true lets its range discount the "
            "whole sighting (docs/em-real.md, section 2)."
        )
    race = res.start_search.race if res.start_search else None
    if res.stop_reason == "max_iterations":
        raced = race.winner_iterations if race else 0
        console.print(
            _still_climbing(
                res.loglik_history, res.best_iteration, cfg.thesis.max_iterations, cfg.thesis.patience, raced
            )
        )
    if res.start_search:
        x, y, th = res.start_search.prior_mean
        which = f" (candidate {race.winner} of {len(race.rounds[0])} won the race)" if race else ""
        console.print(f"start pose chosen: x {x:.0f} mm, y {y:.0f} mm, heading {th:.3f} rad{which}")
    for r in res.ridge or []:
        console.print(
            f"ridge search at iteration {r.iteration}: path and f moved {r.shift_mm:+.0f} mm forward, "
            f"log-likelihood {r.loglik_before:.1f} -> {r.loglik_after:.1f} ({r.forward_passes} forward passes)"
        )
    for r in res.delay_search or []:
        console.print(
            f"delay search at iteration {r.iteration}: command delay {r.delay_from} -> {r.delay_to} steps, "
            f"log-likelihood {r.loglik_before:.1f} -> {r.loglik_after:.1f} ({r.forward_passes} forward passes)"
        )
    if res.restarts:
        runs = to_json(res.restarts)
        console.print(
            f"runs by start sigma, log-likelihood on the sightings all kept: {restart_runs_cell(runs)}; "
            f"kept the most likely, {kept_run_cell(runs)}"
        )


@learn_app.command("em")
@friendly
def learn_em_cmd(
    log: EMLogArg,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Write the learned model here (JSON), the learning history (.history.npz), the smoothed path "
            "(.path.npz) and a figure of the fit (.png) beside it; with recorded poses, also the figures against "
            "them (OUT_actions.png, ...), for a Turtlebot CSV with a range column OUT_against_range.png, and with "
            "--halves OUT_halves.png.",
        ),
    ] = None,
    bins: Annotated[int, typer.Option(help="Actions to bin continuous 1-D commands into.")] = 21,
    start_from: Annotated[
        Path | None,
        typer.Option(
            "--start-from",
            help="Start EM from this learned model (a model.json of `learn em`: another robot of the same kind, or "
            "this one before a change) instead of the thesis's poor guess. It places the robot on the log first, as "
            "`sensact localize` does, and the settings it was learned with are the ones --config and --set override.",
        ),
    ] = None,
    halves: Annotated[
        bool,
        typer.Option(
            "--halves",
            help="Then learn each half of the log on from the whole log's model and compare the three: parameters "
            "the log pins down come out alike from both halves (no ground truth needed; about as long again). On "
            "an odometry-IMU-GNSS log each half is learned alone, compared in combined sd, and the first half's "
            "model is scored on the second.",
        ),
    ] = False,
    preset: Annotated[
        str | None,
        typer.Option(
            "--preset",
            help="Start from this preset's settings instead of the log folder's em_config.yaml: "
            "aibo_field (the thesis's), differential_drive_camera, range_only_anchors or track_1d "
            "(docs/em-real.md); --config and --set override it.",
        ),
    ] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
    report: Annotated[
        bool, typer.Option("--report/--no-report", help="Write OUT.report.html beside it (needs --out).")
    ] = True,
    uncertainty: UncertaintyOpt = None,
    workers: WorkersOpt = 1,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Learn the action model, sensor functions f and noise sigmas by EM (ch. 4).

    The settings: --preset, or else the settings file `convert` wrote into the log folder (em_config.yaml,
    which names its preset), or a Turtlebot's for a CSV, or the thesis's; --config and --set override
    them. Ctrl-C stops early and still writes the most likely model so far.

    On a wheels-and-2-D-lidar folder (`convert bag` of a bag with /scan, or `simulate diffdrive --set
    sensor=lidar2d`) it learns the wheels' radii, the axle, the lidar's mount and the noise instead, with error
    bars, and takes none of the EM options (docs/lidar2d.md).

    On an odometry-IMU-GNSS folder (`convert bag` of a bag with nav_msgs/Odometry and sensor_msgs/Imu, or
    `simulate outdoor`) it learns the odometry's gains, the gyro's bias, scale, noise and clock, the IMU's
    mount, and GNSS's lever arm, noise and heading, with error bars (docs/inertial.md)."""
    check_out_file(out, others={"--start-from": start_from}, kind=EM_MODEL, force=force)
    from sensact.app.log_kinds import refuse_options

    given = {"--start-from": start_from, "--halves": halves, "--preset": preset, "--set": set_, "--config": config,
             "--uncertainty": uncertainty}  # fmt: skip
    refuse_options(log, given)  # what this kind of log does not take, before any work
    asked = None
    if uncertainty is not None:  # before the fit: a request that cannot run is refused before the work it follows
        from sensact.app.uncertainty import ErrorBars

        asked = ErrorBars.parse(uncertainty)
        if asked.replicates is not None:
            from sensact.engine import check_engine

            check_engine(workers, scheduler)
    from sensact.app import calibrate, open_log, save_calibration

    opened = open_log(log, bins=bins)
    console.print(opened.describe(), highlight=False)
    for note in opened.notes:
        console.print(note, highlight=False)
    for doubt in opened.doubts():
        console.print(f"[yellow]warning:[/] {escape(doubt)}", highlight=False)
    with progress_bar() as progress:
        events = _events(opened, preset, progress)
        cal = calibrate(opened, preset, config, sets=set_ or (), start_from=start_from, events=events)
    show_calibration(cal)
    if out is not None:
        saved = save_calibration(cal, out, report=report)
        console.print("wrote " + ", ".join(str(p) for p in saved.written))
        for line in saved.not_drawn:
            console.print(f"[yellow]warning: a figure was not drawn:[/] {escape(line)}", highlight=False)
        if saved.removed_halves is not None and not halves:
            console.print(f"removed {saved.removed_halves}, an earlier run's --halves figure")
        if saved.removed:
            console.print(
                "removed what an earlier run at this --out drew against a truth this log does not have: "
                + ", ".join(str(p) for p in saved.removed)
            )
    if cal.interrupted:  # the most likely model so far is written; nothing more to do with it
        finish(interrupted=True)
    if asked is not None:  # after the model is written, so that stopping the error bars loses nothing of it
        cal = _error_bars(cal, asked, workers, scheduler)
        if out is not None:
            save_calibration(cal, out, report=report)
            console.print(f"wrote {out} again, with the error bars" + (" (and the report)" if report else ""))
    if halves:  # after the model is written, so that stopping the halves loses nothing of it
        from sensact.app.log_kinds import halves_of

        kind_halves = halves_of(cal)
        if kind_halves is None:
            _halves(cal, out)
        else:
            with progress_bar() as progress:
                doc = kind_halves(cal, progress)
            _show_inertial_halves(doc)
            if out is not None:
                write_result(out, cal.to_json() | {"halves": doc}, EM_MODEL)
                console.print(f"wrote {out} again, with the halves")
    finish(cal.health)


def _halves(cal: Any, out: Path | None) -> None:
    """`learn em --halves`: each half learned on from the whole log's model, compared, and written beside it."""
    res = cal.result
    if res.posteriors is None:
        console.print(f"--halves: not run, EM stopped {res.stop_reason} without a smoothed path to compare on")
        return
    from sensact.app.save import halves_figure

    figure = None if out is None else halves_figure(out)
    title = f"{cal.log.name}: halves against the whole"
    halves_doc = learn_and_compare_halves(res, cal.log.data, cal.config, figure, title)
    if out is not None:
        write_result(out, cal.to_json() | {"halves": halves_doc}, EM_MODEL)
        console.print(f"wrote {out} again, with the halves")


def show_calibration(cal: Any) -> None:
    """A calibration on the console, by the function registered for its type (each kind's learner returns
    its own)."""
    _register_shows()
    _shown(cal)


@singledispatch
def _shown(cal: Any) -> None:
    raise TypeError(f"no way to show a {type(cal).__name__}")


@cache
def _register_shows() -> None:
    """Registered when first used, so that the app is imported only when a command runs (``--help`` stays quick)."""
    from sensact.app import Calibration, Lidar2DCalibration
    from sensact.app.car import CarCalibration
    from sensact.app.inertial import InertialCalibration
    from sensact.app.intervals import IntervalsCalibration

    _shown.register(Calibration, _show_em)
    _shown.register(Lidar2DCalibration, _show_lidar2d)
    _shown.register(CarCalibration, _show_car)
    _shown.register(InertialCalibration, _show_inertial)
    _shown.register(IntervalsCalibration, _show_intervals)


def _show_em(cal: Any) -> None:
    """EM's fit: how it stopped, the model, its warnings and its scores."""
    res, cfg = cal.result, cal.config
    _describe_fit(res, cfg)
    print_em_model(res.model)
    for line in cal.diagnostics.warnings:
        console.print(f"[yellow]warning:[/] {line}", highlight=False)
    print_scores(cal.scores, cal.log)


def _show_intervals(cal: Any) -> None:
    """The wheels and the mount from given intervals, with error bars, beside Censi et al.'s closed form."""
    from sensact.app.intervals import rows

    title = f"the wheels and the lidar from {cal.log.n} intervals (docs/lidar2d.md)"
    print_tables([(title, ["", "learned", "sd", "Censi et al."], rows(cal))])
    for note in cal.result.notes:
        console.print(f"[yellow]note:[/] {note}", highlight=False)
    ev = cal.evaluation()
    if ev:
        console.print(
            "against the simulator's truth: "
            + ", ".join(f"{k} {v['error']:+.3g} ({v['error_sd']:+.2f} sd)" for k, v in ev.items()),
            highlight=False,
        )


def _show_lidar2d(cal: Any) -> None:
    """The wheels, the mount and the noise, with error bars (docs/lidar2d.md)."""
    doc = cal.to_json()
    print_tables([lidar2d_table(doc)])
    _notes_and_truth(doc)


def _notes_and_truth(doc: JsonObject) -> None:
    """A scan route's notes, and each learned number against the simulator's truth (its error, in sd where known)."""
    for note in doc["fit"]["notes"]:
        console.print(f"[yellow]note:[/] {note}", highlight=False)
    ev = doc.get("evaluation")
    if ev:
        console.print(
            "against the simulator's truth: "
            + ", ".join(
                f"{k} {v['error']:+.3g}" + (f" ({v['error_sd']:+.2f} sd)" if "error_sd" in v else "")
                for k, v in ev.items()
                if "error" in v
            ),
            highlight=False,
        )


def _show_car(cal: Any) -> None:
    """The VESC's numbers, the wheelbase, the delays and the mount, with error bars (docs/ackermann.md)."""
    doc = cal.to_json()
    rows = [
        [f"{group}.{key}", f"{node[key]:.6g}" if node[key] is not None else "", f"{node[key + '_sd']:.2g}"]
        for group, node in (("vesc", doc["vesc"]), ("car", doc["car"]), ("lidar.mount", doc["lidar"]["mount"]))
        for key in node
        if f"{key}_sd" in node
    ]
    print_tables([("the car and its lidar (docs/ackermann.md)", ["", "learned", "sd"], rows)])
    ahead = doc["car"]["straight_ahead"]
    if ahead is not None:
        console.print(
            f"the log's yaml commands straight ahead, and the wheels point {ahead['wheel_angle_deg']:+.2f} deg "
            f"(sd {ahead['wheel_angle_deg_sd']:.2f}; positive: left)",
            highlight=False,
        )
    _notes_and_truth(doc)


def _show_inertial(cal: Any) -> None:
    """Every learned number with its sd, the flags aside (docs/inertial.md)."""
    rows = [
        [key, f"{e.value:.6g}", "" if e.sd is None else f"{e.sd:.2g}"]
        for key, e in cal.result.estimates.items()
        if e.value is not None
    ]
    print_tables([("wheel odometry, IMU and GNSS (docs/inertial.md)", ["", "learned", "sd"], rows)])
    not_learned = [key for key, e in cal.result.estimates.items() if e.value is None]
    if not_learned:
        console.print(f"[yellow]note:[/] the log has no GNSS: not learned: {', '.join(not_learned)}", highlight=False)
    ev = cal.evaluation()
    if ev:
        console.print(
            "against the simulator's truth: "
            + ", ".join(
                f"{k} {v['error']:+.3g}" + ("" if v["error_sd"] is None else f" ({v['error_sd']:+.2f} sd)")
                for k, v in ev.items()
            ),
            highlight=False,
        )


def _show_inertial_halves(doc: JsonObject) -> None:
    """Each half's numbers, their difference in combined sd, and the first half's model on the second."""
    first, second, z = doc["first_half"], doc["second_half"], doc["differ_sd"]
    rows = [
        [
            key + (" (the run's)" if key in doc["run_keys"] else ""),
            *(f"{h[key]['value']:.6g} +- {h[key]['sd']:.2g}" for h in (first, second)),
            f"{z[key]:+.2f}" if z[key] is not None else "",
        ]
        for key in z
    ]
    title = f"the log's halves, each learned alone (cut at {doc['cut_s']:.0f} s)"
    print_tables([(title, ["", "first half", "second half", "differ (sd)"], rows)])
    verdict = "agree" if doc["agree_within_3sd"] else f"disagree most in {doc['worst']}"
    cons = doc["first_on_second"]["consistency"]
    console.print(
        f"the robot's constants {verdict} within 3 combined sd; the first half's model on the second: "
        + ", ".join(f"{s} coverage90 {c['coverage90']:.3f}" for s, c in cons.items() if c["coverage90"] is not None)
        + " (0.90 when its noise is honest)",
        highlight=False,
    )


def lidar2d_table(doc: JsonObject) -> tuple[str, list[str], list[list[str]]]:
    d, li, u = doc["drive"], doc["lidar"], doc["urdf"]
    um = u.get("lidar_mount") or {}
    rows = []
    if d.get("source") == "wheels":
        drive = [
            ("left wheel radius (mm)", d, "wheel_radius_left_mm", u.get("wheel_radius_mm")),
            ("right wheel radius (mm)", d, "wheel_radius_right_mm", u.get("wheel_radius_mm")),
            ("axle (mm)", d, "axle_mm", u.get("axle_mm")),
        ]
    else:  # /odom's or /cmd_vel's motion: the learned numbers are gains on its nominal wheels, not radii
        drive = [
            (f"forward gain (on {d['source']})", d, "gain_forward", None),
            (f"turn gain (on {d['source']})", d, "gain_turn", None),
        ]
    for label, node, key, guess in (
        *drive,
        ("lidar forward (mm)", li["mount"], "forward_mm", um.get("forward_mm")),
        ("lidar left (mm)", li["mount"], "left_mm", um.get("left_mm")),
        ("lidar yaw (rad)", li["mount"], "yaw_rad", um.get("yaw_rad")),
        ("wheels' delay (s)", d, "delay_s", None),
        ("range noise sd (mm)", li, "range_sigma_mm", None),
    ):
        rows.append([label, f"{node[key]:.6g}", f"{node[key + '_sd']:.2g}", "" if guess is None else f"{guess:.6g}"])
    return ("the wheels and the lidar (docs/lidar2d.md)", ["", "learned", "sd", "URDF"], rows)


def _error_bars(cal: Any, asked: Any, workers: int | None, scheduler: str | None) -> Any:
    """`--uncertainty`: the error bars asked for (a bootstrap's replicates on the engine asked for), and their
    table."""
    from rich.markup import escape

    from sensact.app.uncertainty import bootstrap, information

    if asked.replicates is None:
        console.print("--uncertainty information: the likelihood's curvature, and the noise's profiles")
        cal = information(cal)
        title = "error bars: 90 % intervals from the likelihood (learn/em/uses/information.py)"
    else:
        from sensact.engine import open_engine

        replicates = asked.replicates
        with open_engine(workers, scheduler) as engine:
            console.print(f"--uncertainty {replicates}: a parametric bootstrap on {engine.where}")
            with progress_bar() as progress:
                done = [0]

                def on_done(i: int, outcome: Any) -> None:
                    done[0] += 1
                    progress("bootstrap: replicates learned", done[0], replicates)

                cal = bootstrap(
                    cal, replicates, engine, on_progress=lambda i, d, k, n: progress(d, k, n), on_done=on_done
                )
        u = cal.uncertainty
        title = (
            f"error bars: {u.used} of {u.replicates} replicates learned, 90 % intervals (learn/em/uses/error_bars.py)"
        )
    u = cal.uncertainty
    rows = [[escape(p.name), f"{p.value:.5g}", _se(p), _interval(p)] for p in u.parameters]
    print_tables([(title, ["parameter", "value", "standard error", "90 % interval"], rows)])
    for line in u.failed:
        console.print(f"[yellow]a replicate failed:[/] {escape(line)}", highlight=False)
    return cal


def _se(p: Any) -> str:
    if p.held:
        return "held"
    return "unbounded" if p.se is None else f"{p.se:.3g}"


def _interval(p: Any) -> str:
    """``lo to hi``; an open end is said so (a standard deviation's open lower end is 0)."""
    if p.interval is None:
        return ""
    lo, hi = p.interval
    low = "no bound" if lo is None else f"{lo:.5g}" + (" (open)" if p.open_ended[0] else "")
    return f"{low} to " + ("no bound" if hi is None else f"{hi:.5g}")


def _events(opened: Any, preset: str | None, show: Any) -> Any:
    """What the CLI shows as a calibration goes: the settings, the placement, EM's progress, restarts."""
    from sensact.app import FitEvents
    from sensact.learn.em.checks.lost_signs import describe_lost_fit
    from sensact.learn.em.progress import ConvergenceEta

    cfg_of: JsonObject = {}  # the settings, once read

    def on_settings(settings: Any) -> None:
        cfg = cfg_of["cfg"] = settings.config
        if preset is not None:
            console.print(f"settings: preset {preset}; --config and --set override it.")
        elif opened.settings_file is not None and settings.base == str(opened.settings_file):
            console.print(
                f"settings: {settings.base}, written beside the log (preset {settings.preset}); --config replaces "
                "them, --set overrides them.",
                highlight=False,
            )
        elif settings.base != "the thesis's defaults":
            console.print(f"settings: {settings.base}; --config and --set override them.", highlight=False)
        if cfg.search.start_s is not None and opened.data.geometry.has_heading and not cfg.search.warm_start:
            console.print(
                f"finding the start pose: a {cfg.search.start_grid_mm:g} mm grid scored on the first "
                f"{cfg.search.start_s:g} s, then EM from its {cfg.search.start_candidates} best, the better half kept "
                f"every {cfg.search.start_trial_iterations} iterations"
            )

    def on_placed(start: Any) -> None:
        from sensact.cli.localize import describe_placement

        console.print(
            f"starting from {start.path} (learned on {start.document.get('log', 'a log it does not name')}): "
            "its settings, parameters and the start it finds; --config and --set override the settings."
        )
        describe_placement(start.placed, start.document.get("summary") or {}, start.log.data)

    eta = ConvergenceEta()

    def on_iteration(it: int, ll: float, best: float, since: int) -> None:  # its end projected from its convergence
        thesis = cfg_of["cfg"].thesis
        total = eta.total(it, best, since, thesis.patience, thesis.max_iterations)
        show(f"EM: log-likelihood {ll:.1f} (best {best:.1f}, {since} of {thesis.patience} since)", it + 1, total)

    return FitEvents(
        progress=show,
        on_iteration=on_iteration,
        on_race=lambda done, planned: show(
            f"start race: EM from each start, {cfg_of['cfg'].search.start_trial_iterations} iterations a trial",
            done,
            planned,
        ),
        on_restart=lambda k, turned, sigmas: console.print(
            f"[yellow]{describe_lost_fit(turned, advice=False)}[/] EM starts again with "
            + ", ".join(f"{name}'s start sigma {s:.4g}" for name, s in sigmas.items())
            + f" (restart {k} of at most {cfg_of['cfg'].search.turn_restarts}; turn_restarts in --config)"
        ),
        on_start_moved=lambda mm, mean: console.print(
            f"EM moved the start {mm / 1000:.1f} m from start_prior_mean, to x {mean[0]:.0f} mm, "
            f"y {mean[1]:.0f} mm, heading {mean[2]:.3f} rad: a start that far off can find the path with a "
            'wrong turn model, so EM runs again from there (docs/em-real.md, section 2, "A sensor without '
            'bearings")',
            style="yellow",
            markup=False,
        ),
        on_placed=on_placed,
        on_settings=on_settings,
    )
