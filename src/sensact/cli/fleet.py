"""``sensact fleet``: a fleet's logs calibrated at once on a Dask cluster (docs/howto-fleet.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from sensact.cli.base import (
    PLAIN,
    ConfigOpt,
    SchedulerOpt,
    SetOpt,
    UncertaintyOpt,
    app,
    console,
    err_console,
    friendly,
    print_tables,
    progress_bar,
    write_result,
)

fleet_app = typer.Typer(
    **PLAIN,
    help="Calibrate a fleet's logs at once on a Dask cluster, and score every model on every log.",
    no_args_is_help=True,
)
app.add_typer(fleet_app, name="fleet")

# exit codes (docs/howto-fleet.md): every log learned; some failed (the others written, fleet.json says which)
EXIT_SOME_FAILED = 3


@fleet_app.command("learn")
@friendly
def fleet_learn_cmd(
    logs: Annotated[
        list[Path],
        typer.Argument(help="Log folders or Turtlebot CSVs, one robot's run each.", metavar="LOG"),
    ],
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            help="A folder: each log's model at OUT/NAME/model.json (with what `learn em --out` writes beside it), "
            "OUT/fleet.json (each log's outcome and the cross-scores) and OUT/fleet.png.",
        ),
    ],
    workers: Annotated[
        int | None,
        typer.Option(
            "--workers",
            help="Worker processes of the LocalCluster started on this machine (default: one per core); 1 runs "
            "the logs here, one after another, without Dask.",
        ),
    ] = None,
    scheduler: SchedulerOpt = None,
    threads_per_worker: Annotated[
        int | None,
        typer.Option(
            "--threads-per-worker",
            help="Threads of each LocalCluster worker (default 1), or of this process with --workers 1 (default: "
            "its cores); numpy's, numba's and the start race's threads are sized to it. On a --scheduler's "
            "cluster, each worker's own (dask worker --nthreads).",
        ),
    ] = None,
    preset: Annotated[str | None, typer.Option("--preset", help="As `learn em --preset`, for every log.")] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
    report: Annotated[bool, typer.Option("--report/--no-report", help="Write a report page beside each model.")] = True,
    uncertainty: UncertaintyOpt = None,
    cross_scores: Annotated[
        bool,
        typer.Option(
            "--cross-scores/--no-cross-scores",
            help="Then score every model on every log, as `evaluate fleet` does, on the same cluster.",
        ),
    ] = True,
    shared_map: Annotated[
        bool,
        typer.Option(
            "--shared-map",
            help="Robots in one room whose logs give no map: learn one map from every log together, with each "
            "robot's own models; written as OUT/map.json.",
        ),
    ] = False,
) -> None:
    """Calibrate every log as `learn em LOG --out OUT/NAME/model.json` would, a job per log on Dask.

    Each log's model is the one `learn em` learns on it alone (the same file, its timing aside). A log that
    fails is reported, in the table and in fleet.json, and the others go on; the exit code is then 3 (2 when
    every log failed on bad input). Needs the fleet extra (pip install 'sensact[fleet]') unless --workers 1.

    --shared-map: each log is learned alone first (OUT/alone/NAME/model.json), the learned maps are laid on
    the first log's and merged, each robot learns its models again on that map (OUT/NAME/model.json), and
    their sightings together move the map once more (OUT/map.json; docs/map.md, "Several robots in one room")."""
    from rich.markup import escape

    from sensact.app.fleet import FleetEvents, LearnOptions, fleet_names, learn_fleet, log_name
    from sensact.engine import open_engine

    logs = list(dict.fromkeys(logs))  # a log given twice is learned once
    _refuse_out(out)
    existed = out.exists()
    names = fleet_names(logs, log_name)
    _refuse_out_over_logs(out, logs, names)
    from sensact.app.uncertainty import ErrorBars

    asked = None if uncertainty is None else ErrorBars.parse(uncertainty)
    options = LearnOptions(preset, config, tuple(set_ or ()), report, asked)
    with open_engine(workers, scheduler, threads_per_worker) as engine:
        console.print(f"{len(logs)} log{'s' * (len(logs) > 1)} ({', '.join(names)}) on {engine.where}")
        with progress_bar() as rows:
            bar = rows.bar
            overall = bar.add_task("fleet: logs learned", total=len(logs))
            task = [bar.add_task(f"{g}: waiting for a worker", total=None) for g in names]
            scoring: dict[int, Any] = {}

            def learning(i: int, desc: str, done: int, total: int | None) -> None:
                bar.update(task[i], description=escape(f"{names[i]}: {desc}"), completed=done, total=total)

            def learned(i: int, outcome: Any) -> None:
                desc = escape(f"{names[i]}: {_outcome_cell(outcome)}")
                bar.update(task[i], description=desc, completed=1, total=1)
                bar.advance(overall)

            def scored(i: int, desc: str, done: int, total: int | None) -> None:
                if i not in scoring:
                    scoring[i] = bar.add_task("", total=total)
                bar.update(scoring[i], description=f"cross-scores on {desc}", completed=done, total=total)

            fleet_events = FleetEvents(learning=learning, learned=learned, scoring=scored)
            if shared_map:
                from sensact.app.shared_map import learn_fleet_shared_map

                run = learn_fleet_shared_map(engine, logs, out, options, fleet_events)
            else:
                run = learn_fleet(engine, logs, out, options, cross_scores=cross_scores, events=fleet_events)
    _print_run(run)
    if run.n_failed == len(run.outcomes):  # nothing learned: nothing written (the table above says why)
        if not existed and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        _fail(run)
    summary = out / "fleet.json"
    write_result(summary, run.to_json())
    written = [summary]
    if run.cross_scores is not None:
        from sensact.cli.evaluate import print_fleet
        from sensact.report.figures_fleet import figure_fleet

        print_fleet(run.cross_scores)
        written.append(figure_fleet(run.cross_scores, out / "fleet.png"))
    elif run.cross_scores_skipped:
        console.print(f"[yellow]cross-scores not taken:[/] {run.cross_scores_skipped}", highlight=False)
    if (out / "map.json").is_file() and shared_map:
        written.append(out / "map.json")
    console.print("wrote " + ", ".join(str(p) for p in written) + f" and each log's model under {out}")
    if run.speedup_at_most is not None:  # what the cluster bought, measured in this run
        console.print(
            f"wall {run.seconds:.1f} s, CPU {run.cpu_seconds:.1f} s in the jobs, whose own times sum to "
            f"{run.jobs_seconds:.1f} s: at most {run.speedup_at_most:.2f} times the same logs one after another at "
            "the same threads (a job beside another runs slower than alone; benchmarks/fleet_speedup.py measures it)"
        )

    flagged = [o for o in run.outcomes if getattr(o, "health", None) is not None and not o.health.ok]
    for o in flagged:
        console.print(
            f"[yellow]flagged:[/] {escape(o.log)}: " + "; ".join(f.code for f in o.health.flags), highlight=False
        )
    if run.n_failed:
        _fail(run)
    if flagged:  # every model written, some not to be trusted (docs/errors.md)
        raise typer.Exit(EXIT_SOME_FAILED)


def _fail(run: Any) -> None:
    """The one line a fleet with failed logs ends on, and its exit code (``_exit_code``)."""
    from rich.markup import escape

    from sensact.engine import Failed

    code = _exit_code(run)
    name, first = next((g, o) for g, o in zip(run.names, run.outcomes, strict=True) if isinstance(o, Failed))
    said = "" if run.n_failed == len(run.outcomes) else " (fleet.json says why)"
    err_console.print(
        f"{'error' if code == 2 else 'failed'}: {run.n_failed} of {len(run.outcomes)} logs could not be learned"
        f"{said}; the first, {escape(name)}: {escape(first.error)}",
        highlight=False,
        soft_wrap=True,
    )
    raise typer.Exit(code)


def _refuse_out(out: Path) -> None:
    from sensact.errors import ConfigError

    if out.exists() and not out.is_dir():
        raise ConfigError(
            f"{out} is a file, and the fleet's results are a folder of them.",
            field="--out",
            fix="give a folder (new or existing).",
        )


def _refuse_out_over_logs(out: Path, logs: list[Path], names: list[str]) -> None:
    """Each log's outputs go to OUT/NAME/: never into a log folder (the input's own files beside them, or
    written over), so --out is neither a log, nor inside one, nor the folder that holds a log of that name."""
    from sensact.errors import ConfigError

    root = out.resolve()
    for log, name in zip(logs, names, strict=True):
        src = log.resolve()
        if root == src or src in root.parents or (root / name).resolve() == src:
            raise ConfigError(
                f"--out {out} would put the fleet's results in the log {log}, one of its inputs.",
                field="--out",
                fix="give a folder outside the logs (e.g. a new one beside them).",
            )


def _outcome_cell(outcome: Any) -> str:
    from sensact.engine import Failed

    if isinstance(outcome, Failed):
        return "failed: " + outcome.error
    return f"{outcome.stop_reason} after {outcome.iterations} iterations"


def _exit_code(run: Any) -> int:
    """3 when some logs failed and the others were written (or all were written, some flagged); 2 when every
    log failed on bad input; 70 when every log failed and sensact was at fault for one (docs/howto-fleet.md)."""
    from sensact.engine import Failed

    if run.n_failed < len(run.outcomes):
        return EXIT_SOME_FAILED
    return 2 if all(o.bad_input for o in run.outcomes if isinstance(o, Failed)) else 70


def _print_run(run: Any) -> None:
    """A row per log: how EM ended, or why the log failed."""
    from rich.markup import escape

    from sensact.engine import Failed

    rows = []
    for g, o in zip(run.names, run.outcomes, strict=True):
        if isinstance(o, Failed):
            rows.append([f"[red]{escape(g)}[/]", "[red]failed[/]", "", "", "", escape(o.error)])
        else:
            ll, warned = f"{o.loglik_best:.1f}", escape("; ".join(o.warnings))
            rows.append([escape(g), o.stop_reason, str(o.iterations), ll, f"{o.seconds:.0f}", warned])
    title = (
        f"the fleet on {run.where}: {len(run.outcomes) - run.n_failed} of {len(run.outcomes)} logs learned "
        f"in {run.seconds:.0f} s"
    )
    print_tables([(title, ["log", "EM stopped", "iterations", "log-likelihood", "EM s", "warnings / error"], rows)])
