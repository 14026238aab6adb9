"""``sensact localize``: a learned model put to use on another log (learn/em/uses/place.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

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
from sensact.outputs import LOCALIZATION
from sensact.records import JsonObject


def _parse_start(text: str | None, n: int) -> Any:
    if text is None:
        return None
    import numpy as np

    from sensact.errors import ConfigError

    what = "X_MM,Y_MM,HEADING_RAD or X_MM,Y_MM" if n == 3 else "DISTANCE"
    counts = (3, 2) if n == 3 else (n,)
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in counts or not all(np.isfinite(values)):
        many = " or ".join(str(c) for c in sorted(counts))
        raise ConfigError(
            f"--start {text!r} is not {many} number{'s' if n > 1 else ''}.",
            field="--start",
            fix=f"give --start {what}.",
        )
    return np.array(values)


FAR_START_MM = 100_000.0  # a start this far from every landmark (100 m) is a number in the wrong unit


def _refuse_far_start(start: Any, data: Any) -> None:
    """A given start within ``FAR_START_MM`` of the map's nearest landmark (a track's: of its beacon, at 0)."""
    if start is None:
        return
    import numpy as np

    from sensact.errors import ConfigError

    if data.geometry.has_heading:
        lm = data.landmarks_xy[np.isfinite(data.landmarks_xy).all(axis=1)]
        far = float(np.min(np.hypot(*(lm - start[:2]).T))) if len(lm) else 0.0
    else:
        far = abs(float(start[0]))
    if far > FAR_START_MM:
        raise ConfigError(
            f"--start is {far / 1000:.4g} m from the nearest landmark, over {FAR_START_MM / 1000:g} m: is it in mm?",
            field="--start",
            fix="give the start in mm (and rad), in the map's frame.",
        )


def _truth_scores(
    loc: Any, poses: Any, truth_mm: Any, learned_map: dict[str, float] | None, dt_s: float
) -> JsonObject | None:
    """The path against recorded ``(poses, valid)`` (planar) or the range column (a Turtlebot CSV), for
    evaluation only. ``learned_map``: the scale and offset fitted on the log the model was learned from (its
    JSON's ``evaluation.state_map``), carried over as a user who measured them once would."""
    import numpy as np

    mean = loc.posteriors.mean_gamma
    if poses is not None:
        from sensact.evaluate.landmark_truth import path_offset
        from sensact.io.unit_checks import groundtruth_heading_doubt

        off = path_offset(mean, *poses)
        console.print(
            f"smoothed path off the recorded poses: median {off['median_mm']:.0f} mm "
            f"(forward {off['forward_median_mm']:+.0f} mm, right {off['right_median_mm']:+.0f} mm)"
        )
        doubt = groundtruth_heading_doubt(*poses, dt_s)
        if doubt:  # the split into forward and right reads the recorded heading
            console.print(f"[yellow]warning:[/] {doubt}", highlight=False)
        return {"path": off}
    from sensact.cli.scores import range_column_scoreable

    if not range_column_scoreable(truth_mm, None):
        return None
    from sensact.evaluate.turtlebot_em import state_map_summary

    x = mean[:, 0]
    mapped = state_map_summary(x, truth_mm)
    a, b = mapped["scale"], mapped["offset_mm"]
    out: JsonObject = {"rms_mm": float(np.sqrt(np.mean((x - truth_mm) ** 2))), "state_map": mapped}
    line = (
        f"smoothed distance against the range column: RMS {out['rms_mm']:.1f} (the state read as mm); "
        f"{out['state_map']['rms_mm']:.1f} mm after the optimal scale {a:.3f} and offset {b:.0f} mm"
    )
    if learned_map:
        a0, b0 = learned_map["scale"], learned_map["offset_mm"]
        out["rms_mm_learned_map"] = float(np.sqrt(np.mean((a0 * x + b0 - truth_mm) ** 2)))
        line += (
            f"; {out['rms_mm_learned_map']:.1f} mm after the scale {a0:.3f} and offset {b0:.0f} mm fitted on "
            "the log the model was learned from"
        )
    console.print(line)
    return out


def place_robot(
    doc: JsonObject, m: Any, data: Any, model: Path, config: Path | None, set_: list[str] | None, start: Any
) -> tuple[Any, float | None]:
    """``app.localize.place_robot`` with a progress bar; prints the start and the log-likelihood a sighting
    beside the one on the log it was learned from, which it returns with the run."""
    from sensact.app.localize import place_robot as placed

    console.print(
        f"{model} on {data.source}: {data.n_steps} steps of {data.dt_s:.4g} s, {data.n_observations} observations"
    )
    with progress_bar() as progress:
        loc = placed(doc, m, data, model, config, set_, start, progress)
    return loc, describe_placement(loc, doc.get("summary") or {}, data)


def consistency_on(placed: Any, data: Any) -> JsonObject:
    """The placed model's innovations on ``data`` against its predictive law (docs/uncertainty.md), printed a line per
    reading type, as the JSON's ``consistency``."""
    from sensact.learn.em.uses.consistency import INTERVAL, consistency

    held = consistency(placed, data)
    for name, r in held.readings.items():
        console.print(
            f"consistency, {name}: {100 * r.coverage90:.1f} % of {r.n} readings inside the model's "
            f"{100 * INTERVAL:.0f} % interval, NIS mean {r.nis_mean:.3f} (honest: {100 * INTERVAL:.0f} % and 1)"
        )
    return held.to_dict()


def describe_placement(loc: Any, summary: JsonObject, data: Any) -> float | None:
    """Where ``localize`` put the robot and how well the model fits the log: its log-likelihood a sighting
    beside the one on the log it was learned from (``summary``, its model.json's), which it returns."""
    import numpy as np

    m = loc.model
    post = loc.posteriors
    chosen = ", ".join(f"{v:.4g}" for v in loc.model.prior_mean)
    tried = len(loc.start["candidates"])
    how = "given" if loc.start["how"] == "given" else f"from {loc.start['how']} ({tried} tried, the most likely kept)"
    console.print(f"start: ({chosen}), {how}")
    line = (
        f"log-likelihood {post.loglik:.1f} on {post.n_used} of {data.n_observations} sightings: "
        f"{loc.loglik_per_sighting:.3f} a sighting"
    )
    best, used = summary.get("loglik_best"), summary.get("n_used")
    per_learned = best / used if best is not None and used else None
    if per_learned is not None:
        line += f" (on the log it was learned from, {per_learned:.3f}"
        if m.sensor.reads_bearing and not np.isfinite(data.obs_bearing_rad).any():
            line += ", where each sighting read a bearing too: not comparable"
        line += ")"
    console.print(line)
    if not post.ok:
        console.print("[yellow]the filter lost positive definiteness: the path is not to be trusted.[/]")
    return per_learned


@app.command("localize")
@friendly
def localize_cmd(
    log: EMLogArg,
    model: EMModelOpt,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Write the run here (JSON: the start, the log-likelihood, the consistency of the model's innovations "
            "as `evaluate log` gives it, the scores against any ground truth), "
            "the smoothed path beside it (.path.npz) and a figure (.png).",
        ),
    ] = None,
    start: Annotated[
        str | None,
        typer.Option(
            help="Where the robot starts, X_MM,Y_MM,HEADING_RAD, or X_MM,Y_MM with the heading searched for (a "
            "track: DISTANCE); searched for if not given."
        ),
    ] = None,
    bins: Annotated[int, typer.Option(help="Actions to bin continuous 1-D commands into (as learn em's --bins).")] = 21,
    set_: SetOpt = None,
    config: ConfigOpt = None,
    force: ForceOpt = False,
) -> None:
    """Place the robot in a log with a learned model: the E-step alone, nothing learned.

    The settings are the ones the model was learned with (its JSON's summary.config); --config and --set
    override them. Only the start search, the start's spread and the first-iteration gate are used."""
    check_out_file(out, others={"--model": model}, kind=LOCALIZATION, force=force)
    import numpy as np

    from sensact.app.log_kinds import refuse_other_kinds
    from sensact.app.logs import read_model_and_log
    from sensact.app.save import write_smoothed_path
    from sensact.health import Health, filter_failed, learned_health

    refuse_other_kinds(log, "localize")
    doc, m, opened = read_model_and_log(log, model, bins, use="run")
    data, lf, truth_mm = opened.data, opened.folder, opened.recorded_distance_mm
    poses = lf.truth_poses() if lf is not None else None
    given = _parse_start(start, m.prior_mean.size)
    _refuse_far_start(given, data)
    loc, per_learned = place_robot(doc, m, data, model, config, set_, given)
    post = loc.posteriors
    scores = _truth_scores(loc, poses, truth_mm, (doc.get("evaluation") or {}).get("state_map"), data.dt_s)
    held = consistency_on(loc.model, data)
    health = Health.of(*learned_health(doc).flags, filter_failed(post.ok, "the path"))
    if out is not None:
        write_result(
            out,
            {
                "health": health.to_dict(),
                "log": data.source,
                "model": str(model),
                "start": loc.start,
                "loglik": post.loglik,
                "n_used": post.n_used,
                "n_observations": data.n_observations,
                "loglik_per_sighting": loc.loglik_per_sighting,
                "loglik_per_sighting_learned": per_learned,
                "filter_ok": post.ok,
                "truth": scores,
                "consistency": held,
            },
            LOCALIZATION,
        )
        from sensact.report.figures_fit import figure_localized

        written = [out, write_smoothed_path(out.with_suffix(".path.npz"), post, data)]
        recorded = truth_mm is not None and bool(np.isfinite(truth_mm).any())  # test.csv has no range
        truth_path = (truth_mm.reshape(-1, 1), None) if recorded else poses
        name = lf.title(log) if lf is not None else Path(data.source).name
        written.append(
            figure_localized(loc, data, out.with_suffix(".png"), f"{Path(model).name} on {name}", truth_path)
        )
        console.print("wrote " + ", ".join(str(p) for p in written))
    finish(health)
