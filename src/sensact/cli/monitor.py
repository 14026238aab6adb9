"""``sensact monitor``: has the robot changed since its model was learned? (learn/em/uses/change_detect.py)"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from sensact.app.settings import layered_config
from sensact.cli.base import (
    ConfigOpt,
    EMLogArg,
    EMModelOpt,
    ForceOpt,
    SetOpt,
    app,
    check_out_file,
    console,
    finish,
    friendly,
    progress_bar,
    write_result,
)
from sensact.outputs import EM_MODEL, MONITOR


@app.command("monitor")
@friendly
def monitor_cmd(
    log: EMLogArg,
    model: EMModelOpt,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Write the test here (JSON: whether, when and which model changed; every stream's test) "
            "and its figure beside it (.png).",
        ),
    ] = None,
    relearn: Annotated[
        Path | None,
        typer.Option(
            "--relearn",
            help="When the robot changed, learn its models again from the change on, with the settings the model "
            "was learned with, and write them here (as learn em --out does).",
        ),
    ] = None,
    false_alarm: Annotated[
        float | None,
        typer.Option(help="Probability of any alarm on a log where nothing changed (default 0.01)."),
    ] = None,
    bin_s: Annotated[float | None, typer.Option("--bin-s", help="Seconds a bin of scores spans (default 1).")] = None,
    bins: Annotated[int, typer.Option(help="Actions to bin continuous 1-D commands into (as learn em's --bins).")] = 21,
    set_: SetOpt = None,
    config: ConfigOpt = None,
    force: ForceOpt = False,
) -> None:
    """Run a learned model's filter over a log and test its innovations for a change.

    Every reading channel (and the bearing) and every velocity of the action model is a stream of
    standardized innovations, tested by a two-sided CUSUM; a crossing whose shift lasts to the end of
    the log is a change, one that does not is an episode. Prints when the change began, when it was
    flagged and which model changed; with --relearn, learns the models again from the change on."""
    check_out_file(out, others={"--model": model}, kind=MONITOR, force=force)
    check_out_file(relearn, "--relearn", others={"--out": out, "--model": model}, kind=EM_MODEL, force=force)
    from sensact.app.monitor import monitor_log
    from sensact.health import Health
    from sensact.learn.em.uses.change_detect import MonitorConfig

    cfg = layered_config(MonitorConfig, config, set_, false_alarm=false_alarm, bin_s=bin_s)
    mon = monitor_log(log, model, cfg, bins=bins)
    res = mon.result
    for s in res.streams:
        peak = float(s.statistic.max()) / s.threshold if s.statistic.size else 0.0
        state = f"change at {s.change.alarm_s:.1f} s (began {s.change.change_s:.1f} s)" if s.change else "no change"
        extra = f", {len(s.episodes)} episode(s) that did not persist" if s.episodes else ""
        console.print(f"{s.name}: {state}; peak CUSUM {peak:.2f} of its threshold{extra}", highlight=False)
    found = res.change
    if found is None:
        console.print(f"no change: the model holds on {log} ({res.duration_s:.0f} s)", highlight=False)
    else:
        s, e = found
        console.print(
            f"changed: the {s.model} model ({s.name}); began at {e.change_s:.1f} s, flagged at {e.alarm_s:.1f} s "
            f"({e.alarm_s - e.change_s:.1f} s later)",
            highlight=False,
        )
    health = mon.health
    if out is not None:
        from sensact.report.figures_monitor import figure_monitor

        written = [write_result(out, mon.to_json(), MONITOR)]
        written.append(figure_monitor(res, out.with_suffix(".png"), f"{model.name} on {mon.log.name}"))
        console.print("wrote " + ", ".join(str(p) for p in written), highlight=False)
    if relearn is not None:
        if found is None:
            console.print("nothing changed: nothing relearned")
            finish(health)
            return
        from sensact.app.em import FitEvents
        from sensact.app.monitor import relearn as relearn_from_change
        from sensact.app.save import save_em_calibration

        began = found[1].change_s
        with progress_bar() as bar:
            events = FitEvents(
                on_iteration=lambda it, ll, best, since: bar(
                    f"relearning from {began:.0f} s: log-likelihood {ll:.1f} (best {best:.1f})", it + 1, None
                ),
                on_race=lambda done, planned: bar("relearning: start race", done, planned),
            )
            cal = relearn_from_change(mon, events)
        if cal is not None:
            save_em_calibration(cal, relearn)
            res2 = cal.result
            console.print(
                f"relearned from {began:.1f} s: {res2.stop_reason} after {res2.iterations} iterations; wrote {relearn}",
                highlight=False,
            )
            health = Health.of(*health.flags, *cal.diagnostics.health.flags)
    finish(health)
