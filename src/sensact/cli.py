"""The ``sensact`` command. The only place that configures logging or draws progress bars.

Heavy modules (numba kernels, matplotlib) are imported inside the commands so that ``sensact --help``
stays instant.
"""

from __future__ import annotations

import functools
import logging
import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.table import Table

from sensact.errors import SensactError

app = typer.Typer(
    name="sensact",
    help="Learn a mobile robot's action and sensor models from its own logs, with no ground truth "
    "(Stronger 2008). Start with `sensact reproduce`; see docs/commands.md.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
simulate_app = typer.Typer(help="Write a simulated log folder (with its ground truth).", no_args_is_help=True)
learn_app = typer.Typer(help="Learn models from a log.", no_args_is_help=True)
app.add_typer(simulate_app, name="simulate")
app.add_typer(learn_app, name="learn")

# rich falls back to 80 columns when output is not a terminal; the result tables need more
console = Console(width=None if sys.stdout.isatty() else 160)
err_console = Console(stderr=True, width=None if sys.stderr.isatty() else 160)
_state = {"debug": False}
F = TypeVar("F", bound=Callable[..., Any])

SetOpt = Annotated[
    list[str] | None, typer.Option("--set", help="Override a config field: --set name=value (repeatable).")
]
ConfigOpt = Annotated[Path | None, typer.Option("--config", help="YAML file of config fields.")]


def _friendly(fn: F) -> F:
    """Bad input becomes one line and exit code 2; ``--debug`` shows the traceback instead."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except SensactError as exc:
            if _state["debug"]:
                raise
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None
        except KeyboardInterrupt:
            err_console.print("interrupted; files already written are complete (atomic writes).")
            raise typer.Exit(130) from None

    return wrapper  # type: ignore[return-value]


@app.callback()
def _main(
    debug: Annotated[bool, typer.Option("--debug", help="Show full tracebacks.")] = False,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Log library messages.")] = False,
) -> None:
    _state["debug"] = debug
    logging.basicConfig(level=logging.DEBUG if verbose else logging.WARNING, format="%(name)s: %(message)s")


@contextmanager
def _progress() -> Iterator[Callable[[str, int, int], None]]:
    """A rich progress bar fed by the library's ``progress(description, done, total)`` callbacks."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    tasks: dict[str, Any] = {}
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=err_console,
        transient=False,
        disable=not err_console.is_terminal,
    ) as bar:

        def update(desc: str, done: int, total: int) -> None:
            if desc not in tasks:
                tasks[desc] = bar.add_task(desc, total=total)
            bar.update(tasks[desc], completed=done, total=total)

        yield update


def _print_tables(tables: list[tuple[str, list[str], list[list[str]]]]) -> None:
    for title, headers, rows in tables:
        t = Table(title=title, title_justify="left")
        for h in headers:
            t.add_column(h)
        for r in rows:
            t.add_row(*r)
        console.print(t)


def _config(cls: type, config: Path | None, sets: list[str] | None, base: Any = None, **flags: Any) -> Any:
    """``base`` or defaults < ``--config`` YAML < ``--set`` < explicit flags."""
    import dataclasses

    from sensact.config import build_config

    cfg = build_config(cls, config, sets or [], base=base)
    flags = {k: v for k, v in flags.items() if v is not None}
    return dataclasses.replace(cfg, **flags) if flags else cfg


# ---- simulate -------------------------------------------------------------------------------------------


@simulate_app.command("track1d")
@_friendly
def simulate_track1d(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write.")],
    seconds: Annotated[float | None, typer.Option(help="Length of the log (default 150).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Simulate the chapter-3 Aibo walking toward and away from a beacon (sec. 3.3)."""
    from sensact.io.logfolder import write_log_folder
    from sensact.sim.track1d import Track1DConfig, log_tables, simulate_track

    cfg = _config(Track1DConfig, config, set_, seconds=seconds, seed=seed)
    run = simulate_track(cfg)
    write_log_folder(out, **log_tables(run))
    n_obs = int((run.heights_px == run.heights_px).sum())
    console.print(
        f"wrote {out}: {len(run.times_s)} steps, {n_obs} observations, "
        f"distance {run.distance_mm.min():.0f}-{run.distance_mm.max():.0f} mm (seed {cfg.seed})"
    )


# ---- learn ----------------------------------------------------------------------------------------------


@learn_app.command("bootstrap")
@_friendly
def learn_bootstrap_cmd(
    log: Annotated[Path, typer.Argument(help="A log folder, or a Turtlebot CSV file.")],
    a0: Annotated[str | None, typer.Option(help="Starting action model: linear, sign or constant.")] = None,
    sensor: Annotated[
        str | None, typer.Option(help="Observation column (default: the log's own; sonar1 for a Turtlebot CSV).")
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write the learned models here (JSON) and the history beside it (.npz)."),
    ] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Learn S(o) and A(c) from each other with Algorithm 1 (sec. 3.2.3). Prints the polynomials, and
    the scaled errors when the log carries ground truth."""
    from sensact.errors import ConfigError
    from sensact.io.atomic import write_json, write_npz
    from sensact.io.logfolder import read_track_log
    from sensact.learn.bootstrap import BootstrapConfig, learn_bootstrap

    if a0 is not None and a0 not in ("linear", "sign", "constant"):
        raise ConfigError(f"unknown starting model {a0!r}.", field="--a0", fix="use linear, sign or constant.")
    data = read_track_log(log, sensor=sensor)
    base = None
    if data.meta.get("platform") == "turtlebot1d":
        from sensact.experiments.turtlebot import learner_for

        base = learner_for(data.observation_name)
        console.print(
            "Turtlebot log: starting from the turtlebot settings (docs/bootstrap.md); --config and --set override them."
        )
    cfg = _config(BootstrapConfig, config, set_, base=base, a0=a0)
    console.print(
        f"{data.source}: {len(data.times_s)} steps over {data.duration_s:.1f} s, "
        f"{data.n_observations} observations of {data.observation_name}"
    )
    with _progress() as progress:
        res = learn_bootstrap(
            data.times_s,
            data.commands,
            data.observations,
            cfg,
            units=(data.command_unit, data.observation_unit, "w"),
            progress=lambda d, n: progress("Algorithm 1", d, n),
        )
    console.print(
        f"status: [bold]{res.status}[/]"
        + (f" at {res.diverged_at_s:.1f} s" if res.diverged_at_s else "")
        + (f"; {res.n_gated} observations gated as outliers" if res.n_gated else "")
    )
    console.print("  " + res.sensor.describe("S"))
    console.print("  " + res.action.describe("A"))
    evaluation = _evaluate_log(data, res, cfg)
    if out is not None:
        payload = {**res.to_dict(), "log": data.source, "evaluation": evaluation}
        write_json(out, payload)
        assert res.history is not None
        write_npz(out.with_suffix(".history.npz"), **res.history.arrays())
        console.print(f"wrote {out} and {out.with_suffix('.history.npz')}")


def _evaluate_log(data: Any, res: Any, cfg: Any) -> dict[str, Any] | None:
    """Scaled errors against the log's ground truth, if it has any (never used for learning)."""
    if "truth" in data.meta:
        from sensact.evaluate.track1d import score_track_models
        from sensact.sim.track1d import TrackTruth

        sc = score_track_models(res.sensor, res.action, TrackTruth.from_dict(data.meta["truth"]))
        console.print(
            f"vs truth (measured grid of sec. 3.3.2): sensor RMS {sc.sensor_rms:.1f} mm "
            f"(best cubic {sc.sensor_best_rms:.1f}), action RMS {sc.action_rms:.1f} mm/s "
            f"(best quartic {sc.action_best_rms:.1f}), consistency {sc.consistency:.3f}"
        )
        return sc.to_dict()
    if data.true_position is not None:
        from sensact.experiments.turtlebot import evaluate_real

        run = evaluate_real(data, res, cfg)
        sc = run.score
        console.print(
            f"vs ground truth: sensor RMS {sc.sensor_rms:.4g} {data.position_unit} "
            f"(best {sc.sensor_best_rms:.4g}), action RMS {sc.action_rms:.4g} {data.position_unit}/s, "
            f"gain {run.learned_gain:.4f} (truth {run.true_gain:.4f}), consistency {sc.consistency:.3f}"
        )
        return {**sc.to_dict(), "learned_gain": run.learned_gain, "true_gain": run.true_gain}
    return None


# ---- reproduce ------------------------------------------------------------------------------------------

EXPERIMENTS = ("track1d", "turtlebot")


def _data_dir(data: Path | None) -> Path:
    if data is not None:
        return data
    env = os.environ.get("SENSACT_DATA")
    return Path(env) if env else Path("..") / "shared" / "data"


@app.command()
@_friendly
def reproduce(
    experiment: Annotated[str | None, typer.Argument(help=f"One of {', '.join(EXPERIMENTS)}; default: all.")] = None,
    out: Annotated[Path, typer.Option("--out", help="Results folder.")] = Path("results"),
    trials: Annotated[int, typer.Option(help="Trials per row (the thesis used 15).")] = 15,
    seed: Annotated[int, typer.Option(help="Seed of the first trial.")] = 0,
    data: Annotated[
        Path | None, typer.Option(help="Real-data folder (default $SENSACT_DATA or ../shared/data).")
    ] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Run the thesis's experiments and write RESULTS/<experiment>.json, tables and figures."""
    from sensact.errors import ConfigError

    if experiment is not None and experiment not in EXPERIMENTS:
        raise ConfigError(
            f"unknown experiment {experiment!r}.",
            field="EXPERIMENT",
            fix=f"choose one of {', '.join(EXPERIMENTS)}, or none for all.",
        )
    todo = [experiment] if experiment else list(EXPERIMENTS)
    if "track1d" in todo:
        _reproduce_track1d(out, trials, seed, set_, config)
    if "turtlebot" in todo:
        csv = _data_dir(data) / "turtlebot1d" / "training1.csv"
        if not csv.is_file():
            if experiment == "turtlebot":
                raise SensactError(
                    "Turtlebot data not found.",
                    file=csv,
                    fix="pass --data DIR (the folder holding turtlebot1d/) or set SENSACT_DATA.",
                )
            console.print(f"skipping turtlebot: {csv} not found (pass --data DIR to include it)")
        else:
            _reproduce_turtlebot(out, csv)


def _reproduce_track1d(out: Path, trials: int, seed: int, set_: list[str] | None, config: Path | None) -> None:
    from sensact.config import config_from_dict, load_yaml_mapping, parse_overrides
    from sensact.experiments.track1d import Track1DExperiment, run_track1d
    from sensact.io.atomic import write_json, write_npz, write_text
    from sensact.learn.bootstrap import BootstrapConfig
    from sensact.report import figures1d
    from sensact.report.tables import to_markdown, track1d_tables
    from sensact.sim.track1d import Track1DConfig

    # --set / --config fields go to the learner or the simulator, whichever has the field
    fields = {**(load_yaml_mapping(config) if config else {}), **parse_overrides(set_ or [])}
    learner_fields = {k: v for k, v in fields.items() if k in BootstrapConfig.__dataclass_fields__}
    sim_fields = {k: v for k, v in fields.items() if k not in learner_fields}
    exp = Track1DExperiment(
        trials=trials,
        degree_trials=trials,
        seed=seed,
        learner=config_from_dict(BootstrapConfig, learner_fields, source="--set/--config"),
        simulator=config_from_dict(Track1DConfig, sim_fields, source="--set/--config"),
    )
    with _progress() as progress:
        res, art = run_track1d(exp, progress)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "track1d.json", res)
    tables = track1d_tables(res)
    write_text(out / "track1d.md", to_markdown(tables))
    _print_tables(tables)
    linear = art["trials"].get("linear") or next(iter(art["trials"].values()))
    figures1d.figure_3_7(linear[0], out / "fig3_7_location_estimates.png")
    figures1d.figure_3_8(linear[0], out / "fig3_8_learned_vs_measured.png")
    first = next(iter(res["rows"].values()))
    figures1d.figure_3_9(
        art["curves"],
        {"sensor": first["sensor_best_rms_mm"], "action": first["action_best_rms_mm_s"]},
        out / "fig3_9_learning_curves.png",
    )
    figures1d.figure_degree(art["degree_trials"], out / "fig_degree_selection.png")
    write_npz(
        out / "track1d_curves.npz",
        **{
            f"{row}_{name}": arr
            for row, c in art["curves"].items()
            for name, arr in zip(("t_s", "sensor_rms_mm", "action_rms_mm_s"), c, strict=True)
        },
    )
    console.print(f"wrote {out / 'track1d.json'}, {out / 'track1d.md'} and figures in {out} ({res['seconds']:.1f} s)")


def _reproduce_turtlebot(out: Path, csv: Path) -> None:
    from sensact.experiments.turtlebot import run_turtlebot
    from sensact.io.atomic import write_json, write_text
    from sensact.report.figures1d import figure_real
    from sensact.report.tables import to_markdown, turtlebot_tables

    res, runs = run_turtlebot(csv)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "turtlebot.json", res)
    tables = turtlebot_tables(res)
    write_text(out / "turtlebot.md", to_markdown(tables))
    _print_tables(tables)
    figure_real(runs, out / "turtlebot_models.png")
    console.print(f"wrote {out / 'turtlebot.json'} and {out / 'turtlebot_models.png'}")


def main() -> None:
    """Console-script entry point."""
    try:
        app()
    except SensactError as exc:  # raised outside a command, e.g. while parsing
        if _state["debug"]:
            raise
        err_console.print(f"error: {exc}")
        sys.exit(2)


if __name__ == "__main__":
    main()
