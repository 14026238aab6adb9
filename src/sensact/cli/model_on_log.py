"""A learned model and the log it is used on: the log EM reads (a folder or a Turtlebot CSV), `learn em`'s
model.json read, and a model that could not have been learned from the log (another geometry, other commands
or readings, another step) refused in one line before `evaluate` scores it, `localize` runs it or `learn em
--start-from` starts from it."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def is_turtlebot_csv(log: Path) -> bool:
    """Whether EM reads ``log`` as a Turtlebot CSV (``read_em_log``), not as a log folder."""
    return log.is_file() and log.suffix.lower() == ".csv"


def scored_against(log: Path) -> str:
    """What a 1-D log's fit is scored against, as its score line names it: a Turtlebot CSV's range column,
    or a track folder's recorded distance."""
    from sensact.cli.scores import RANGE_COLUMN, RECORDED_DISTANCE

    return RANGE_COLUMN if is_turtlebot_csv(log) else RECORDED_DISTANCE


def read_em_log(log: Path, bins: int, dt_s: float | None = None) -> tuple[Any, Any, Any]:
    """What EM reads: ``(data, the log folder, its recorded distance or None)`` from a folder (continuous
    commands of a track1d folder binned into ``bins`` actions; the distance of a track folder of continuous
    commands whose groundtruth.csv has ``distance_mm``), or ``(data, None, its range column)`` from a
    Turtlebot CSV (on ``dt_s``, or its median step); anything else is one line. The distance and the range
    column are scored alike (``evaluate.turtlebot_em``)."""
    if is_turtlebot_csv(log):
        from sensact.io.turtlebot import read_turtlebot_landmark_log

        data, truth = read_turtlebot_landmark_log(log, dt_s)
        return data, None, truth
    if log.is_file():
        from sensact.errors import LogFormatError

        raise LogFormatError(
            "EM reads a log folder or a Turtlebot CSV file.",
            file=log,
            fix="give a folder with meta.json, actions.csv and observations.csv (sensact convert mrclam "
            "writes one), or a .csv with the Turtlebot's columns.",
        )
    from sensact.io.landmark_log import read_landmark_log

    lf = read_landmark_log(log, command_bins=bins)
    return lf.data, lf, lf.truth_distance_mm()


def read_log_on_model_step(log: Path, doc: dict[str, Any], bins: int) -> tuple[Any, Any, Any]:
    """``read_em_log`` with a Turtlebot CSV read onto the step of the model ``doc`` (its model.json),
    whatever the CSV's own median step; a folder's steps are its own."""
    dt = doc.get("dt_s")
    return read_em_log(log, bins, None if dt is None else float(dt))


def read_em_model(model: Path) -> tuple[dict[str, Any], Any]:
    """A model.json `sensact learn em` wrote: the whole document (its ``dt_s`` too) and the model."""
    from sensact.errors import ModelFormatError
    from sensact.io.jsonfile import read_json_object
    from sensact.models.em_model import EMModel

    doc = read_json_object(model, ModelFormatError, "give the model.json `sensact learn em` wrote.")
    return doc, EMModel.from_dict(doc.get("model", doc), source=str(model))


def refuse_model_for_log(
    doc: dict[str, Any], m: Any, data: Any, model: Path, log: Path | str, learn: str | None = None, use: str = "scored"
) -> None:
    """A model scores (or runs, or starts EM: ``use`` "scored", "run" or "start") only on a log it could have
    been learned from: the same geometry, commands (or number of actions), readings and step, since its delay
    is counted in steps. One line naming what differs; ``learn`` is the command that learns a model on ``log``."""
    import numpy as np

    from sensact.errors import ModelFormatError
    from sensact.models.action_table import ActionTable

    cannot = "EM cannot start from it" if use == "start" else f"it cannot be {use}"

    def refuse(what: str, field: str, fix: str) -> None:
        raise ModelFormatError(f"{what}, so {cannot} on {log}.", file=model, field=field, fix=fix)

    learn = learn or f"sensact learn em {log}"
    relearn = (
        f"start from a model learned on a log like this one, or from the thesis's start ({learn} without --start-from)."
        if use == "start"
        else f"{'score' if use == 'scored' else 'run'} it on a log like the one it was learned from, or learn one "
        f"on this log ({learn})."
    )
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


def read_model_and_log(log: Path, model: Path, bins: int, use: str) -> tuple[dict[str, Any], Any, Any, Any, Any]:
    """``(model.json, the model, the log's data, its folder or None, the recorded distance or None: a Turtlebot
    CSV's range column or a track folder's distance_mm)``,
    the log read onto the model's step; a model that does not fit the log is refused in one line (``use``:
    "run", "scored" or "start")."""
    doc, m = read_em_model(model)
    data, lf, truth_mm = read_log_on_model_step(log, doc, bins)
    refuse_model_for_log(doc, m, data, model, log, use=use)
    return doc, m, data, lf, truth_mm
