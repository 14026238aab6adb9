"""``sensact learn em``: chapter 4's EM on a log folder or a Turtlebot CSV, from the thesis's poor guess or
from a learned model (``--start-from``), and on the log's halves (``--halves``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from sensact.cli.base import (
    ConfigOpt,
    SetOpt,
    config_beside,
    console,
    friendly,
    layered_config,
    learn_app,
    print_tables,
    progress_bar,
    write_result,
    write_smoothed_path,
)
from sensact.cli.model_on_log import is_turtlebot_csv, read_em_log, scored_against
from sensact.cli.scores import evaluate_em, evaluate_turtlebot_em, print_em_model, warn_if_one_command

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


# the figures `learn em --out OUT.json` draws against a log's truth (OUT_<kind>.png): recorded poses
# (report.figures_real.write_robot) or a Turtlebot CSV's range column; one an earlier run at the same
# --out drew, and this run does not, is removed so that it cannot pass for this fit
TRUTH_FIGURES = ("actions", "range", "heading_noise", "bearing", "against_range")


def halves_figure(out: Path) -> Path:
    """Where `learn em --halves --out OUT.json` draws the halves: OUT_halves.png."""
    return out.with_name(f"{out.stem}_halves.png")


def _log_name(log: Path, data: Any, lf: Any) -> str:
    """The log as the figures' titles name it."""
    return lf.title(log) if lf is not None else Path(data.source).name


def learn_and_compare_halves(
    res: Any, data: Any, cfg: Any, figure: Path | None = None, title: str = ""
) -> dict[str, Any]:
    """`learn em --halves`: each half of ``data`` learned on from ``res``'s model (learn/em/halves.py),
    the three compared (evaluate/halves.py), printed and, given a ``figure`` path, drawn there; what the
    model JSON keeps of it."""
    from sensact.cli.scores import halves_rows
    from sensact.evaluate.halves import compare_halves
    from sensact.learn.em.halves import learn_halves

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


def _settings_and_log(
    log: Path, bins: int, start_from: Path | None, config: Path | None, set_: list[str] | None
) -> tuple[Any, Any, Any, Any, tuple[dict[str, Any], Any] | None]:
    """``(settings, data, log folder or None, recorded distance or None (a Turtlebot CSV's range column, a
    track folder's distance_mm), (model.json, model) or None)``:
    the settings layered on a base that is the start model's own, a Turtlebot's, or the folder's
    em_config.yaml, each said to the user."""
    from sensact.config import config_from_dict
    from sensact.learn.em import EMConfig

    if start_from is not None:  # the model's own settings, and the log read onto its step
        from sensact.cli.model_on_log import read_model_and_log

        start_doc, start_model, data, lf, recorded_distance = read_model_and_log(log, start_from, bins, use="start")
        learned = (start_doc.get("summary") or {}).get("config")
        base = None if learned is None else config_from_dict(EMConfig, learned, source=f"{start_from}: summary.config")
        if base is None and is_turtlebot_csv(log):
            from sensact.experiments.turtlebot_em import turtlebot_em_config

            base = turtlebot_em_config(data.reading_names)
        cfg = layered_config(EMConfig, config, set_, base=base)
        console.print(
            f"starting from {start_from} (learned on {start_doc.get('log', 'a log it does not name')}): its "
            + ("settings, " if learned is not None else "")
            + "parameters and the start it finds; --config and --set override the settings."
        )
        return cfg, data, lf, recorded_distance, (start_doc, start_model)
    if is_turtlebot_csv(log):  # a Turtlebot's settings, for the sensors it has
        from sensact.experiments.turtlebot_em import turtlebot_em_config
        from sensact.io.turtlebot import EM_READINGS

        data, lf, recorded_distance = read_em_log(log, bins)
        cfg = layered_config(EMConfig, config, set_, base=turtlebot_em_config(data.reading_names))
        absent = [r for r in EM_READINGS if r not in data.reading_names]
        console.print(
            "Turtlebot CSV: starting from the Turtlebot's EM settings (docs/em-real.md); --config and --set "
            "override them."
            + (f" Channels {', '.join(data.reading_names)} ({', '.join(absent)} not in the file)." if absent else "")
        )
        return cfg, data, lf, recorded_distance, None
    config = config_beside(log, "em_config.yaml", config)  # what `convert` or `simulate diffdrive` wrote
    cfg = layered_config(EMConfig, config, set_)  # bad settings are said before the log is read
    data, lf, recorded_distance = read_em_log(log, bins)
    from sensact.io.unit_checks import unit_doubts

    # a hand-written folder's column in the wrong unit, before a wasted fit
    for doubt in unit_doubts(data, lf.truth_poses() if lf is not None else None):
        console.print(f"[yellow]warning:[/] {doubt} (in {log})")
    return cfg, data, lf, recorded_distance, None


def _refuse_table_on_continuous_commands(data: Any, cfg: Any, log: Path, lf: Any) -> None:
    """The thesis's action table needs discrete actions; a planar log of continuous commands needs a basis."""
    if not (data.is_continuous and cfg.action_basis == "table" and data.geometry == "planar"):
        return
    from sensact.errors import ConfigError

    beside = lf is not None and (log / "em_config.yaml").is_file()
    raise ConfigError(
        f"{data.source} has continuous commands, and the action model is the thesis's table of discrete actions.",
        field="action_basis",
        fix=(
            f"pass --config {log / 'em_config.yaml'} (the settings written beside the log)"
            if beside
            else "pass --set action_basis=affine (or cross, polynomial), or a --config with it (docs/em-real.md)"
        )
        + ".",
    )


def _run_em(data: Any, start: Any, cfg: Any) -> Any:
    """``fit_em`` with its progress, restarts and a moved start shown as they happen."""
    from sensact.learn.em import fit_em
    from sensact.learn.em.checks import describe_lost_fit

    if cfg.start_search_s > 0 and data.geometry == "planar":
        console.print(
            f"finding the start pose: a {cfg.start_search_grid_mm:g} mm grid scored on the first "
            f"{cfg.start_search_s:g} s, then EM from its {cfg.start_candidates} best, the better half kept every "
            f"{cfg.start_trial_iterations} iterations"
        )
    with progress_bar() as progress:
        return fit_em(
            data,
            start,
            cfg,
            progress=lambda it, ll, best, since: progress(  # it stops by patience: no end to show
                f"EM: log-likelihood {ll:.1f} (best {best:.1f}, {since} of {cfg.patience} iterations since)",
                it + 1,
                None,
            ),
            on_race=lambda done, planned: progress(
                f"start race: EM from each start, {cfg.start_trial_iterations} iterations a trial", done, planned
            ),
            on_restart=lambda k, turned, sigmas: console.print(
                f"[yellow]{describe_lost_fit(turned, advice=False)}[/] EM starts again with "
                + ", ".join(f"{name}'s start sigma {s:.4g}" for name, s in sigmas.items())
                + f" (restart {k} of at most {cfg.turn_restarts}; turn_restarts in --config)"
            ),
            on_start_moved=lambda mm, mean: console.print(
                f"EM moved the start {mm / 1000:.1f} m from start_prior_mean, to x {mean[0]:.0f} mm, "
                f"y {mean[1]:.0f} mm, heading {mean[2]:.3f} rad: a start that far off can find the path with a "
                'wrong turn model, so EM runs again from there (docs/em-real.md, section 2, "A sensor without '
                'bearings")',
                style="yellow",
                markup=False,
            ),
        )


def _describe_fit(res: Any, cfg: Any) -> None:
    """How EM stopped and what its searches, gates and restarts did on the way."""
    from sensact.report.tables_real import kept_run_cell, restart_runs_cell

    console.print(
        f"stopped: [bold]{res.stop_reason}[/] after {res.iterations} iterations ({res.seconds:.1f} s); "
        f"best log-likelihood {res.loglik_best:.1f} at iteration {res.best_iteration}"
        + (f"; {res.n_pruned} observations pruned" if res.n_pruned else "")
        + (
            f" ({res.n_pruned_when_freed} when the robust readings took over: bearing more than "
            f"{cfg.prune_rad_per_step:g} rad off the smoothed path; prune_when_freed)"
            if res.n_pruned_when_freed
            else ""
        )
    )
    if res.mount is not None and res.model.geometry == "planar":
        console.print(f"sensor mount: {res.mount.describe()}", highlight=False)
    if res.start_moved:
        first, again = res.start_moved["loglik"]
        console.print(
            f"runs from the given start and from where EM moved it: log-likelihood {first:.1f} and {again:.1f}; "
            f"kept the {'second' if res.start_moved['kept'] == 'again' else 'first'}"
        )
    if res.turned_to_face_forward:
        console.print(
            "the sensor reads no bearing, so a robot driving backward while facing the other way reads the same: "
            "EM ended so, and the model is reported turned by pi, driving forward (the same likelihood; "
            'docs/em-real.md, section 2, "A sensor without bearings")',
            markup=False,
        )
    if res.n_pruned_when_freed and not cfg.joint_student_t and res.model.sensor.student_t_params:
        console.print(
            "[yellow]sightings that far off are misread barcodes;[/] a misread one whose bearing happens to fit "
            "still counts in bearing. If there are many, --set joint_student_t=true lets its range discount the "
            "whole sighting (docs/em-real.md, section 2)."
        )
    race = (res.start_search or {}).get("race")
    if res.stop_reason == "max_iterations":
        raced = race["winner_iterations"] if race else 0
        console.print(_still_climbing(res.loglik_history, res.best_iteration, cfg.max_iterations, cfg.patience, raced))
    if res.start_search:
        x, y, th = res.start_search["prior_mean"]
        which = f" (candidate {race['winner']} of {len(race['rounds'][0])} won the race)" if race else ""
        console.print(f"start pose chosen: x {x:.0f} mm, y {y:.0f} mm, heading {th:.3f} rad{which}")
    for r in res.ridge or []:
        console.print(
            f"ridge search at iteration {r['iteration']}: path and f moved {r['shift_mm']:+.0f} mm forward, "
            f"log-likelihood {r['loglik_before']:.1f} -> {r['loglik_after']:.1f} ({r['forward_passes']} forward passes)"
        )
    for r in res.delay_search or []:
        console.print(
            f"delay search at iteration {r['iteration']}: command delay {r['delay_from']} -> {r['delay_to']} steps, "
            f"log-likelihood {r['loglik_before']:.1f} -> {r['loglik_after']:.1f} ({r['forward_passes']} forward passes)"
        )
    if res.restarts:
        console.print(
            f"runs by start sigma, log-likelihood on the sightings all kept: {restart_runs_cell(res.restarts)}; "
            f"kept the most likely, {kept_run_cell(res.restarts)}"
        )


def _write_fit(
    out: Path, doc: dict[str, Any], res: Any, data: Any, log: Path, lf: Any, recorded_distance: Any, halves: bool
) -> None:
    """The model JSON, its history and path, the figure of the fit and those against the log's truth; a
    figure that an earlier run at this --out drew, against a truth this log does not have or of its
    halves (``halves``: this run draws its own after them), is removed."""
    from sensact.io.atomic import write_npz

    write_result(out, doc)
    write_npz(
        out.with_suffix(".history.npz"),
        loglik=res.loglik_history,
        velocities=res.velocity_history,
        sigmas=res.sigma_history,
    )
    written = [out, out.with_suffix(".history.npz")]
    name = _log_name(log, data, lf)
    m, evaluation = res.model, doc["evaluation"]
    if res.posteriors is not None:
        from sensact.report.figures_fit import figure_em_fit

        written.append(write_smoothed_path(out.with_suffix(".path.npz"), res.posteriors, data))
        written.append(figure_em_fit(res, data, out.with_suffix(".png"), f"EM on {name}"))
    if evaluation is not None and evaluation.get("truth_noise"):  # scored against recorded poses
        from sensact.report.figures_real import write_robot

        written += write_robot(lf, m, evaluation, out.with_suffix(""), name, res.posteriors, truth="ground truth")
    elif evaluation is not None and recorded_distance is not None:  # scored against a recorded distance
        from sensact.experiments.turtlebot_em import TurtlebotEMRun
        from sensact.report.figures_turtlebot_em import figure_turtlebot_em

        run = TurtlebotEMRun(data, recorded_distance, res)
        path = out.with_name(f"{out.stem}_against_range.png")
        written.append(figure_turtlebot_em(run, evaluation, path, f"EM on {name}"))
    console.print("wrote " + ", ".join(str(p) for p in written))
    earlier = halves_figure(out)
    if earlier.exists():  # an earlier run's --halves: this run's, if any, is drawn after the halves
        earlier.unlink()
        if not halves:
            console.print(f"removed {earlier}, an earlier run's --halves figure")
    stale = [
        p for kind in TRUTH_FIGURES if (p := out.with_name(f"{out.stem}_{kind}.png")).exists() and p not in written
    ]
    for p in stale:
        p.unlink()
    if stale:
        console.print(
            "removed what an earlier run at this --out drew against a truth this log does not have: "
            + ", ".join(str(p) for p in stale)
        )


def _describe_log(data: Any, lf: Any) -> None:
    console.print(
        f"{data.source}: {data.geometry} log, {data.n_steps} steps of {data.dt_s:.4g} s, "
        f"{data.n_observations} observations, "
        + (
            f"continuous commands ({', '.join(data.command_names)})"
            if data.is_continuous
            else f"{data.n_actions} actions"
        )
        + (f" ({lf.note})" if lf is not None and lf.note else "")
    )


def _starting_model(data: Any, cfg: Any, start_doc_model: Any, start_from: Path | None) -> tuple[Any, Any, Any]:
    """Sec. 4.4.1's poor start, or with ``--start-from`` the learned model placed on this log
    (``learn/em/warm_start.py``): the model EM starts from, the placement (None without one) and the
    settings EM runs with."""
    if start_doc_model is None:
        from sensact.learn.em import initial_model

        return initial_model(data, cfg), None, cfg
    from sensact.cli.localize import describe_placement
    from sensact.learn.em.warm_start import start_from_model

    start_doc, start_model = start_doc_model
    with progress_bar() as progress:
        placed, cfg = start_from_model(start_model, data, cfg, progress, source=str(start_from))
    describe_placement(placed, start_doc.get("summary") or {}, data)
    return placed.model, placed, cfg


def _warn_of_a_doubtful_fit(res: Any, data: Any, cfg: Any) -> tuple[list[dict[str, Any]], Any, dict[str, Any]]:
    """Signs, without ground truth, that EM lost the robot, a side-stepping robot held to no sideways
    mean, correlated reading errors and a gate that dropped many sightings (``learn/em/checks.py``): each
    printed, and returned for the JSON."""
    from sensact.learn.em.checks import (
        describe_correlated,
        describe_held_sideways,
        describe_lost_fit,
        describe_pruned,
        held_sideways_noise,
        lost_fit_signs,
        residual_autocorrelation,
    )

    signs = []
    autocorrelation: dict[str, Any] = {}
    if res.posteriors is not None:
        signs = lost_fit_signs(res.model, res.posteriors, data, res.loglik_history, res.best_iteration)
        if signs:
            console.print(f"[yellow]{describe_lost_fit(signs)}[/]")
        autocorrelation = residual_autocorrelation(res.model, res.posteriors, data)
        for line in describe_correlated(autocorrelation):
            console.print(f"[yellow]warning:[/] {line}", highlight=False)
    pruned = describe_pruned(res.pruned_fraction)
    if pruned:
        console.print(f"[yellow]warning:[/] {pruned}", highlight=False)
    held = held_sideways_noise(res.model, cfg.motion_noise)
    if held:
        console.print(describe_held_sideways(held), style="yellow", markup=False)  # it quotes a YAML list
    return signs, held, autocorrelation


@learn_app.command("em")
@friendly
def learn_em_cmd(
    log: Annotated[Path, typer.Argument(help="A log folder (planar or a 1-D track), or a Turtlebot CSV file.")],
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
            "the log pins down come out alike from both halves (no ground truth needed; about as long again).",
        ),
    ] = False,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Learn the action model, sensor functions f and noise sigmas by EM (ch. 4).

    Ctrl-C stops early and still writes the most likely model so far."""

    from sensact.learn.em.config import refuse_bearing_settings
    from sensact.models.wheel_drive import as_differential_drive

    cfg, data, lf, recorded_distance, start_doc_model = _settings_and_log(log, bins, start_from, config, set_)
    _describe_log(data, lf)
    _refuse_table_on_continuous_commands(data, cfg, log, lf)
    refuse_bearing_settings(cfg, data)  # before the starting model, which would fail on it
    if data.geometry == "track" and data.step_commands is not None:
        warn_if_one_command(data.step_commands[:, 0], data.source, data.command_names[0])
    start, placed, cfg = _starting_model(data, cfg, start_doc_model, start_from)
    res = _run_em(data, start, cfg)
    _describe_fit(res, cfg)
    m = res.model
    print_em_model(m)
    signs, held, autocorrelation = _warn_of_a_doubtful_fit(res, data, cfg)
    evaluation = (
        evaluate_em(lf, m, learned_here=True, path=None if res.posteriors is None else res.posteriors.mean_gamma)
        if lf is not None and recorded_distance is None
        else evaluate_turtlebot_em(res, data, recorded_distance, scored_against(log))
    )
    if evaluation is not None:
        evaluation["pruned_fraction"] = res.pruned_fraction
    doc = {
        "model": m.to_dict(),
        "summary": res.summary(),
        "log": data.source,
        "dt_s": data.dt_s,
        "evaluation": evaluation,
        # learn/em/checks.py: signs that EM lost the robot
        "range_function_turns": [t for t in signs if t["sign"] == "turns"],
        "range_function_bends": [t for t in signs if t["sign"] == "bends"],
        "em_unsettled": next((t for t in signs if t["sign"] == "unsettled"), None),
        "held_sideways_noise": held,  # ... and that a robot that side-steps is held to no sideways mean
        # the share of sightings the gates dropped, and each channel's residuals' lag-1 autocorrelation
        "pruned_fraction": res.pruned_fraction,
        "residual_lag1_autocorrelation": autocorrelation,
        "differential_drive": as_differential_drive(m.action),  # on wheel speeds: gain, axle, wheel ratio
        # --start-from: the model EM started from, and where it placed the robot (learn/em/warm_start.py)
        "start_from": None
        if placed is None
        else {
            "model": str(start_from),
            "placed": placed.start,
            "loglik_per_sighting": placed.loglik_per_sighting,
        },
        "halves": None,  # --halves: each half learned on from this model, and compared (below)
    }
    if out is not None:
        _write_fit(out, doc, res, data, log, lf, recorded_distance, halves)
    if halves:  # after the model is written, so that stopping the halves loses nothing of it
        if res.posteriors is None:
            console.print(f"--halves: not run, EM stopped {res.stop_reason} without a smoothed path to compare on")
            return
        figure = None if out is None else halves_figure(out)
        halves_doc = learn_and_compare_halves(
            res, data, cfg, figure, f"{_log_name(log, data, lf)}: halves against the whole"
        )
        if out is not None:
            write_result(out, doc | {"halves": halves_doc})
            console.print(f"wrote {out} again, with the halves")
