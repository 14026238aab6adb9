"""The landmark logs EM reads (``open_landmark_log``; ``app.log_kinds`` is the door every path goes
through): a log folder (planar, range-only or 1-D, with its settings file and its truth) or a Turtlebot
CSV; and a learned model.json read, and refused in one line on a log it could not have been learned from
(another geometry, other commands or readings, another step)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensact.errors import ConfigError, LogFormatError
from sensact.io.landmark_folder import LandmarkLogFile
from sensact.learn.em.config import EMConfig
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.records import JsonObject
from sensact.reprs import compact_repr

SETTINGS_FILE = "em_config.yaml"  # the EM settings `convert` and `simulate` write into a log folder
# what a 1-D fit is scored against, as its score line names it
RANGE_COLUMN = "range"  # a Turtlebot CSV's column
RECORDED_DISTANCE = "the recorded distance"  # a track folder's groundtruth.csv distance_mm


@dataclass(frozen=True)
class KindSettings:
    """The EM settings a log of its kind starts from when nothing else names any: a preset put on the
    log's columns (a Turtlebot CSV's: track_1d on the channels it has)."""

    config: EMConfig
    preset: str
    origin: str  # for the user


@dataclass(frozen=True, eq=False)
class OpenedLandmarkLog:
    """A landmark log as EM reads it (a log folder: planar, range-only or 1-D; or a Turtlebot CSV), and what
    came with it."""

    __repr__ = compact_repr  # a line, never the arrays

    path: Path
    data: LandmarkLog
    folder: LandmarkLogFile | None  # a log folder's meta.json and truth; None for a Turtlebot CSV
    # a Turtlebot CSV's range column, or a track folder's recorded distance (mm per step), to score against
    recorded_distance_mm: np.ndarray | None
    bins: int  # actions continuous 1-D commands were binned into
    defaults: KindSettings | None = None  # None: a settings file beside the log, else the thesis's
    notes: tuple[str, ...] = ()  # what to tell the user of this log before a fit
    no_truth: str | None = None  # why the log cannot be scored, when its kind would say so

    @property
    def settings_file(self) -> Path | None:
        """The settings `convert` or `simulate` wrote beside the log, if any."""
        beside = self.path / SETTINGS_FILE
        return beside if self.folder is not None and beside.is_file() else None

    @property
    def scored_against(self) -> str:
        """What a 1-D fit is scored against, as its score line names it."""
        return RECORDED_DISTANCE if self.folder is not None else RANGE_COLUMN

    @property
    def name(self) -> str:
        """The log as figures' titles name it."""
        return self.folder.title(self.path) if self.folder is not None else Path(self.data.source).name

    def doubts(self) -> tuple[str, ...]:
        """What the log shows before a fit that may waste it: a column in the wrong unit, one command
        throughout (a 1-D log's action model's slope then rests on the few steps at others)."""
        from sensact.evaluate.measured import one_command_doubt
        from sensact.io.unit_checks import unit_doubts

        out = []
        if self.folder is not None:
            out += [f"{doubt} (in {self.path})" for doubt in unit_doubts(self.data, self.folder.truth_poses())]
        data = self.data
        if data.geometry.state_is_range and data.step_commands is not None:
            out.append(one_command_doubt(data.step_commands[:, 0], data.source, data.command_names[0]))
        return tuple(d for d in out if d is not None)

    def describe(self) -> str:
        """One line: what the log holds."""
        data, lf = self.data, self.folder
        commands = (
            f"continuous commands ({', '.join(data.command_names)})"
            if data.is_continuous
            else f"{data.n_actions} actions"
        )
        return (
            f"{data.source}: {data.geometry} log, {data.n_steps} steps of {data.dt_s:.4g} s, "
            f"{data.n_observations} observations, {commands}" + (f" ({lf.note})" if lf is not None and lf.note else "")
        )


def _check_bins(bins: int) -> None:
    from sensact.limits import MAX_BINS

    if not 2 <= bins <= MAX_BINS:
        raise ConfigError(
            f"--bins {bins:,}: continuous commands are binned into 2 to {MAX_BINS:,} actions.",
            field="--bins",
            fix="give 21 (the default) or another count in that range.",
        )


def open_turtlebot_csv(path: Path, *, bins: int = 21, dt_s: float | None = None) -> OpenedLandmarkLog:
    """A Turtlebot CSV read as EM reads it (on ``dt_s``, or its median step; its range column kept to score
    against), with the Turtlebot's settings to start from."""
    from sensact.io.turtlebot import EM_READINGS, read_turtlebot_landmark_log
    from sensact.presets import turtlebot_em_config

    _check_bins(bins)
    if path.suffix.lower() != ".csv":
        raise LogFormatError(
            "EM reads a log folder or a Turtlebot CSV file.",
            file=path,
            fix="give a folder with meta.json, actions.csv and observations.csv (sensact convert mrclam "
            "writes one), or a .csv with the Turtlebot's columns.",
        )
    data, truth = read_turtlebot_landmark_log(path, dt_s)
    names = data.reading_names
    absent = [r for r in EM_READINGS if r not in names]
    defaults = KindSettings(
        turtlebot_em_config(names),
        "track_1d",
        "Turtlebot CSV: the Turtlebot's EM settings (preset track_1d, on the channels it has)",
    )
    return OpenedLandmarkLog(
        path,
        data,
        None,
        truth,
        bins,
        defaults,
        (f"Channels {', '.join(names)} ({', '.join(absent)} not in the file).",) if absent else (),
        "no range column: nothing to score against (the model is learned from the readings alone)."
        if np.isnan(truth).all()
        else None,
    )


def open_landmark_folder(path: Path, *, bins: int = 21, command_levels: np.ndarray | None = None) -> OpenedLandmarkLog:
    """A log folder read as EM reads it: continuous commands of a track1d folder binned into ``bins``
    actions (or onto ``command_levels``); a track folder's recorded distance from groundtruth.csv's
    ``distance_mm``."""
    from sensact.io.landmark_folder import read_landmark_log

    _check_bins(bins)
    lf = read_landmark_log(path, command_bins=bins, command_levels=command_levels)
    return OpenedLandmarkLog(path, lf.data, lf, lf.truth_distance_mm(), bins)


def open_landmark_log(
    path: str | Path, *, bins: int = 21, dt_s: float | None = None, command_levels: np.ndarray | None = None
) -> OpenedLandmarkLog:
    """What ``path`` is, read as EM reads it: a Turtlebot CSV (``open_turtlebot_csv``) or a log folder
    (``open_landmark_folder``). Anything else is one line."""
    log = Path(path)
    if log.is_file():
        return open_turtlebot_csv(log, bins=bins, dt_s=dt_s)
    return open_landmark_folder(log, bins=bins, command_levels=command_levels)


MODEL_STEP_S = (1e-6, 1e6)  # a log's step: beyond these, not seconds (or a number written by hand)


def model_step(doc: JsonObject, source: Path) -> float:
    """A model.json's ``dt_s``, checked: the step its commands' delay and its noise per step are counted in."""
    from sensact.errors import ModelFormatError

    dt = doc.get("dt_s")
    lo, hi = MODEL_STEP_S
    if not (isinstance(dt, int | float) and not isinstance(dt, bool) and lo <= dt <= hi):
        raise ModelFormatError(
            f"dt_s is {dt!r}, not a step in seconds ({lo:g} to {hi:g}).",
            file=source,
            field="dt_s",
            fix="rewrite it with `sensact learn em`.",
        )
    return float(dt)


def read_em_model(model: Path) -> tuple[JsonObject, EMModel]:
    """A model.json `sensact learn em` wrote: the whole document (its ``dt_s`` too) and the model."""
    from sensact.errors import ModelFormatError
    from sensact.io.jsonfile import read_json_object

    doc = read_json_object(model, ModelFormatError, "give the model.json `sensact learn em` wrote.")
    if doc.get("dt_s") is not None:
        model_step(doc, model)
    refuse_newer(doc, model)
    learned_settings(doc, str(model))  # its settings, every field checked as it is read
    return doc, EMModel.from_dict(doc.get("model", doc), source=str(model))


def learned_settings(doc: JsonObject, source: str) -> Any:  # -> EMConfig | None
    """The settings a learned model was learned with (its model.json's ``summary.config``), if it says."""
    from sensact.config import config_from_dict
    from sensact.learn.em.config import EMConfig, upgrade_settings

    summary = doc.get("summary") or {}
    learned = summary.get("config") if isinstance(summary, dict) else None
    if learned is None:
        return None
    if not isinstance(learned, dict):
        from sensact.errors import ModelFormatError

        raise ModelFormatError(
            f"summary.config is {type(learned).__name__}, not the settings' object.",
            file=source,
            field="summary.config",
            fix="give a model.json written by `sensact learn em` (or drop summary.config to start from the preset).",
        )
    return config_from_dict(EMConfig, upgrade_settings(learned), source=f"{source}: summary.config")


def _version(text: str) -> tuple[int, ...] | None:
    parts = text.split("+")[0].split(".")
    return tuple(int(p) for p in parts) if all(p.isdigit() for p in parts) else None


def refuse_newer(doc: JsonObject, path: Path) -> None:
    """A model written by a newer sensact may mean what this one cannot read: refused, naming both versions."""
    from sensact import __version__
    from sensact.errors import ModelFormatError

    written = doc.get("sensact_version")
    if written is None:
        return
    theirs, ours = (_version(written) if isinstance(written, str) else None), _version(__version__)
    if theirs is None or (ours is not None and theirs > ours):
        raise ModelFormatError(
            f"written by sensact {written!r}, {'not a version' if theirs is None else 'newer than this one'} "
            f"({__version__}).",
            file=path,
            field="sensact_version",
            fix="read it with the sensact that wrote it, or learn the model again with this one.",
        )


def refuse_model_for_log(
    doc: JsonObject, m: Any, data: Any, model: Path, log: Path | str, learn: str | None = None, use: str = "scored"
) -> None:
    """A model scores (or runs, or starts EM: ``use`` "scored", "run" or "start") only on a log it could have
    been learned from: the same geometry, commands (or number of actions), readings and step, since its delay
    is counted in steps. One line naming what differs; ``learn`` is the command that learns a model on ``log``."""
    from sensact.errors import ModelFormatError

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
    mismatch = m.action.mismatch(data)
    if mismatch is not None:
        refuse(*mismatch, relearn)
    missing = [ch.name for ch in m.sensor.channels if ch.name not in data.reading_names]
    if missing:
        refuse(f"the log has no reading {missing[0]} (it has {', '.join(data.reading_names)})", "sensor", relearn)
    if data.geometry.has_heading and not np.isfinite(data.obs_bearing_rad).any():
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


def read_model_and_log(log: Path, model: Path, bins: int, use: str) -> tuple[JsonObject, EMModel, OpenedLandmarkLog]:
    """``(model.json, the model, the log)``, the log read onto the model's step; a model that does not fit the
    log is refused in one line (``use``: "run", "scored" or "start")."""
    doc, m = read_em_model(model)
    dt = doc.get("dt_s")
    # a track's continuous commands go onto the model's own actions, not the bins of this log's span
    binned = m.action.binned_commands
    levels = binned[:, 0] if m.geometry.state_is_range and binned is not None else None
    opened = open_landmark_log(log, bins=bins, dt_s=None if dt is None else float(dt), command_levels=levels)
    refuse_model_for_log(doc, m, opened.data, model, log, use=use)
    from sensact.io.unit_checks import range_unit_doubt

    doubt = range_unit_doubt(opened.data)
    if doubt is not None:  # `learn em` learns an f in any unit; a model learned in mm cannot read this log
        raise LogFormatError(
            f"{doubt}.",
            file=log,
            field="range_mm",
            fix="write the ranges in millimetres (a range in metres as range_m, which is read x1000).",
        )
    return doc, m, opened


def data_root() -> Path:
    """Where the real-data folder is: ``$SENSACT_DATA``, else ``../shared/data`` from the working directory."""
    env = os.environ.get("SENSACT_DATA")
    return Path(env) if env else Path("..") / "shared" / "data"
