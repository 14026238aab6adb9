"""``sensact learn bootstrap``: chapter 3's online learner (Algorithm 1) on a 1-D log."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from sensact.cli.base import ConfigOpt, SetOpt, console, friendly, layered_config, learn_app, progress_bar, write_result
from sensact.cli.scores import evaluate_log, warn_if_one_command


@learn_app.command("bootstrap")
@friendly
def learn_bootstrap_cmd(
    log: Annotated[Path, typer.Argument(help="A log folder, or a Turtlebot CSV file.")],
    a0: Annotated[str | None, typer.Option(help="Starting action model: linear, sign or constant.")] = None,
    sensor: Annotated[
        str | None, typer.Option(help="Observation column (default: the log's own; sonar1 for a Turtlebot CSV).")
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Write the learned models here (JSON), the history beside it (.npz) and a figure of the run (.png).",
        ),
    ] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Learn S(o) and A(c) from each other with Algorithm 1 (sec. 3.2.3).

    Prints the polynomials, and the scaled errors when the log carries ground truth."""
    from sensact.errors import ConfigError
    from sensact.io.atomic import write_npz
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
    cfg = layered_config(BootstrapConfig, config, set_, base=base, a0=a0)
    console.print(
        f"{data.source}: {len(data.times_s)} steps over {data.duration_s:.1f} s, "
        f"{data.n_observations} observations of {data.observation_name}"
    )
    warn_if_one_command(data.commands, data.source, "command", data.command_unit)
    with progress_bar() as progress:
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
    evaluation = evaluate_log(data, res, cfg)
    if out is not None:
        payload = {**res.to_dict(), "log": data.source, "evaluation": evaluation}
        write_result(out, payload)
        assert res.history is not None
        write_npz(out.with_suffix(".history.npz"), **res.history.arrays())
        from sensact.report.figures_bootstrap import figure_bootstrap_fit

        png = figure_bootstrap_fit(res, data, out.with_suffix(".png"), f"Algorithm 1 on {Path(data.source).name}")
        console.print(f"wrote {out}, {out.with_suffix('.history.npz')} and {png}")
