"""``sensact learn bootstrap``: chapter 3's online learner (Algorithm 1) on a 1-D log."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from sensact.app.settings import layered_config
from sensact.cli.base import (
    ConfigOpt,
    ForceOpt,
    SetOpt,
    check_out_file,
    config_beside,
    console,
    finish,
    friendly,
    learn_app,
    progress_bar,
    write_result,
)
from sensact.cli.scores import warn_if_one_command
from sensact.outputs import BOOTSTRAP_MODEL
from sensact.records import JsonObject


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
    report: Annotated[
        bool, typer.Option("--report/--no-report", help="Write OUT.report.html beside it (needs --out).")
    ] = True,
    force: ForceOpt = False,
) -> None:
    """Learn S(o) and A(c) from each other with Algorithm 1 (sec. 3.2.3).

    Prints the polynomials, and the scaled errors when the log carries ground truth."""
    check_out_file(out, kind=BOOTSTRAP_MODEL, force=force)
    from sensact.errors import ConfigError
    from sensact.io.atomic import write_npz
    from sensact.io.logfolder import read_track_log
    from sensact.learn.bootstrap import BootstrapConfig, bootstrap_health, learn_bootstrap

    if a0 is not None and a0 not in ("linear", "sign", "constant"):
        raise ConfigError(f"unknown starting model {a0!r}.", field="--a0", fix="use linear, sign or constant.")
    data = read_track_log(log, sensor=sensor)
    base = None
    if data.meta.get("platform") == "turtlebot1d":
        from sensact.presets import learner_for

        base = learner_for(data.observation_name)
        console.print(
            "Turtlebot log: starting from the turtlebot settings (docs/bootstrap.md); --config and --set override them."
        )
    config = config_beside(log, "bootstrap_config.yaml", config)  # what `convert track` wrote
    cfg = layered_config(BootstrapConfig, config, set_, base=base, a0=a0)
    console.print(
        f"{data.source}: {len(data.times_s)} steps over {data.duration_s:.1f} s, "
        f"{data.n_observations} observations of {data.observation_name}"
    )
    warn_if_one_command(data.commands, data.source, "command", data.command_unit)
    start = _clock_start(data, log)
    warnings = [w for w in (_warn_if_one_way_at_takeover(data, cfg, start),) if w]
    with progress_bar() as progress:
        res = learn_bootstrap(
            data.times_s,
            data.commands,
            data.observations,
            cfg,
            units=(data.command_unit, data.observation_unit, "w"),
            progress=progress,
        )
    console.print(
        f"status: [bold]{res.status}[/]"
        + (f" at {res.diverged_at_s:.1f} s" if res.diverged_at_s else "")
        + (" after the first command" if res.diverged_at_s and start > 0.0 else "")
        + (f"; {res.n_gated} observations gated as outliers" if res.n_gated else "")
    )
    console.print("  " + res.sensor.describe("S"))
    console.print("  " + res.action.describe("A"))
    from sensact.app.bootstrap import score_bootstrap

    scored = score_bootstrap(data, res, cfg)
    evaluation = None
    if scored is not None:
        evaluation, line = scored
        console.print(line, highlight=False)
    health = bootstrap_health(res, data.commands, data.observations, data.times_s)
    if out is not None:
        payload = {**res.to_dict(), "log": data.source, "evaluation": evaluation, "health": health.to_dict()}
        write_result(out, payload, BOOTSTRAP_MODEL)
        assert res.history is not None
        write_npz(out.with_suffix(".history.npz"), **res.history.arrays())
        from sensact.report.figures_bootstrap import figure_bootstrap_fit

        png = figure_bootstrap_fit(res, data, out.with_suffix(".png"), f"Algorithm 1 on {Path(data.source).name}")
        written = [out, out.with_suffix(".history.npz"), png]
        if report:
            from sensact.app.report import simple_report

            if res.status != "ok":
                warnings.append(
                    f"Algorithm 1 ended {res.status}" + (f" at {res.diverged_at_s:.1f} s" if res.diverged_at_s else "")
                )
            numbers = {"status": res.status, "sensor S": res.sensor.describe("S"), "action A": res.action.describe("A")}
            numbers |= {"gated observations": res.n_gated} | _flat(evaluation)
            lead = f"Chapter 3's Algorithm 1 on {data.source}; the models are {out.name}."
            figures = [(png, "the learned S and A over the log")]
            written.append(
                simple_report(out, f"sensact calibration: {Path(data.source).name}", lead, numbers, warnings, figures)
            )
        console.print("wrote " + ", ".join(str(p) for p in written))
    finish(health)


def _clock_start(data: Any, log: Path) -> float:
    """Seconds into the log where Algorithm 1's clock starts, the first non-zero command, said when the robot
    was held still before it; a log never commanded is refused."""
    from sensact.errors import LogFormatError
    from sensact.learn.bootstrap import first_command_s

    start = first_command_s(data.times_s, data.commands)
    if start is None:
        raise LogFormatError(
            "every command is zero, so the readings say nothing about what a command does.",
            file=log,
            field=(data.meta.get("action") or {}).get("column", "velocity_command"),
            fix="learn from a log in which the robot is driven toward and away from what its sensor reads (sec. 3.3).",
        )
    if start > 0.0:
        console.print(
            f"the robot is first commanded {start:.1f} s into the log: Algorithm 1's clock starts there, and the "
            "readings before it are not learned from (held still, they would all be taught one place)."
        )
    return start


def _warn_if_one_way_at_takeover(data: Any, cfg: Any, start: float) -> str | None:
    """Say so when A_t takes over from A0 (at 2 t_start after the clock ``start``, Algorithm 1 line 3) before
    the robot has been commanded both ways: fitted to one direction of travel, the pair of models can settle
    far off (on turtlebot1d's training1.csv, first commanded at 3.3 s and first reversing at 84 s, t_start_s = 40
    learns S 11 % of the span off, 45 learns it 2.0 % off)."""
    from sensact.evaluate.measured import first_reversal_s

    takeover = start + 2.0 * cfg.t_start_s
    reverse = first_reversal_s(data.times_s, data.commands)
    if reverse is not None and reverse <= takeover:
        return None
    until = "in the whole log" if reverse is None else f"until {reverse:.1f} s"
    after = f"{start:.0f} s + " if start > 0.0 else ""
    fix = (
        "drive it both ways (toward and away from what its sensor reads, sec. 3.3)"
        if reverse is None
        else f"pass --set t_start_s=T with {after}2 T past {reverse:.0f} s, by some seconds of driving back"
    )
    at = (
        f"2 t_start_s = {2.0 * cfg.t_start_s:g} s after the first command ({takeover:.1f} s into the log)"
        if start > 0.0
        else f"2 t_start_s = {takeover:g} s into the log"
    )
    line = (
        f"A_t takes over from A0 at {at}, and {until} the robot is commanded one way only, so the two models are "
        f"first fitted to one direction of travel and can settle far off; {fix} (docs/bootstrap.md)."
    )
    console.print(f"[yellow]warning[/]: {line}")
    return line


def _flat(doc: Any, prefix: str = "") -> JsonObject:
    """A nested evaluation as one row per number (``sensor.rms_mm``)."""
    if not isinstance(doc, dict):
        return {prefix: doc} if prefix and not isinstance(doc, list) else {}
    out: JsonObject = {}
    for k, v in doc.items():
        out |= _flat(v, f"{prefix}.{k}" if prefix else str(k))
    return out
