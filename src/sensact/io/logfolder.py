"""The native log folder (docs/formats.md) for one-dimensional logs.

::

    run-001/
      meta.json          platform, units, columns, simulator seed and true models if simulated
      actions.csv        t_s, <command column>
      observations.csv   t_s, <sensor column(s)>
      groundtruth.csv    optional: t_s, <position column>, ...; used only for evaluation

``read_track_log`` also accepts a Turtlebot CSV file (see ``sensact.io.turtlebot``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from sensact.core.geometry import GEOMETRIES
from sensact.errors import LogFormatError
from sensact.io.atomic import write_json, write_text
from sensact.io.csvtable import read_numeric_csv
from sensact.io.jsonfile import read_json_object
from sensact.io.resample import step_count
from sensact.logs.track_log import TrackLog
from sensact.records import JsonObject

LOG_FORMAT = "sensact-log"
LOG_VERSION = 1


def _fmt(x: np.ndarray) -> list[str]:
    return ["" if not np.isfinite(v) else repr(float(v)) for v in x]


def _write_csv(path: Path, columns: dict[str, np.ndarray]) -> None:
    names = list(columns)
    cols = [_fmt(np.asarray(columns[n], dtype=float)) for n in names]
    lines = [",".join(names)] + [",".join(row) for row in zip(*cols, strict=True)]
    write_text(path, "\n".join(lines) + "\n")


def write_log_folder(
    folder: str | Path,
    *,
    meta: JsonObject,
    actions: dict[str, np.ndarray],
    observations: dict[str, np.ndarray],
    groundtruth: dict[str, np.ndarray] | None = None,
) -> Path:
    """Write a log folder. Each table's first column must be ``t_s``; observation rows with every
    sensor value missing are left out. Every file is written atomically; meta.json goes last, so a
    folder with meta.json is complete."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, table in (("actions", actions), ("observations", observations), ("groundtruth", groundtruth)):
        if table is not None and next(iter(table)) != "t_s":
            raise ValueError(f"{name}: the first column must be t_s")
    keep = np.zeros(len(observations["t_s"]), dtype=bool)
    for name, col in observations.items():
        if name != "t_s":
            keep |= np.isfinite(col)
    _write_csv(folder / "actions.csv", actions)
    _write_csv(folder / "observations.csv", {k: np.asarray(v)[keep] for k, v in observations.items()})
    if groundtruth is not None:
        _write_csv(folder / "groundtruth.csv", groundtruth)
    write_json(folder / "meta.json", {"format": LOG_FORMAT, "version": LOG_VERSION, **meta})
    return folder


def meta_kind(folder: str | Path) -> str | None:
    """The ``kind`` a log folder's meta.json names (a wheels-and-lidar folder's ``lidar2d``), None where it
    names none or cannot be read (the folder's own reader then says why)."""
    meta = Path(folder) / "meta.json"
    if not meta.is_file():
        return None
    try:
        kind = json.loads(meta.read_text(encoding="utf-8")).get("kind")
    except (OSError, ValueError, AttributeError, RecursionError):
        return None
    return kind if isinstance(kind, str) else None


def read_meta(folder: str | Path, example: str = "`sensact simulate track1d --out DIR`") -> JsonObject:
    """``example``: what writes a folder of the kind the caller reads, for the fix."""
    path = Path(folder) / "meta.json"
    missing = f"a log folder needs meta.json; {example} writes an example."
    meta = read_json_object(path, LogFormatError, "repair or rewrite meta.json.", missing)
    if meta.get("format") != LOG_FORMAT:
        raise LogFormatError(
            f"'format' is not {LOG_FORMAT!r}.",
            file=path,
            field="format",
            fix=f'add "format": "{LOG_FORMAT}" to meta.json.',
        )
    if meta.get("version", LOG_VERSION) != LOG_VERSION:
        raise LogFormatError(
            f"version {meta.get('version')!r} is not one this sensact reads ({LOG_VERSION}).",
            file=path,
            field="version",
            fix=f'write "version": {LOG_VERSION}, or convert the log again with this sensact.',
        )
    return meta


def refuse_a_car_log(meta: JsonObject, folder: Path) -> None:
    """A car log folder (its meta.json has a lidar section) given to EM or chapter 3's learner."""
    if isinstance(meta.get("lidar"), dict) and "geometry" not in meta and "action" not in meta:
        raise LogFormatError(
            "this is a car log folder (meta.json has a lidar section), which chapter 5's learner reads.",
            file=folder / "meta.json",
            field="lidar",
            fix=f"learn it with `sensact learn car {folder}`.",
        )


def _column(meta: JsonObject, key: str, path: Path) -> tuple[str, str]:
    try:
        spec = meta[key]
        return str(spec["column"]), str(spec.get("unit", ""))
    except (KeyError, TypeError):
        raise LogFormatError(
            f"meta.json has no {key}.column.",
            file=path / "meta.json",
            field=key,
            fix=f'add "{key}": {{"column": "<name in the csv>", "unit": "..."}}.',
        ) from None


def read_track_log(path: str | Path, sensor: str | None = None) -> TrackLog:
    """Read a 1-D log folder, or a Turtlebot CSV file, onto one time grid.

    ``sensor`` picks the observation column; by default the one meta.json names (or sonar1 for a
    Turtlebot file).
    """
    path = Path(path)
    if path.is_file() and path.suffix.lower() == ".csv":
        from sensact.io.turtlebot import read_turtlebot_csv

        return read_turtlebot_csv(path, sensor=sensor or "sonar1")
    if not path.is_dir():
        raise LogFormatError(
            "not a log folder or CSV file.",
            file=path,
            fix="give a folder with meta.json, actions.csv and observations.csv, or a Turtlebot CSV.",
        )
    meta = read_meta(path)
    refuse_a_car_log(meta, path)
    if "geometry" in meta and "action" not in meta:
        track = getattr(GEOMETRIES.get(meta["geometry"]), "state_is_range", False)
        raise LogFormatError(
            f"this is a log folder for EM (geometry: {meta['geometry']}) without chapter 3's action and sensor "
            "columns; chapter 3's learner reads a 1-D log with one command and one sensor.",
            file=path / "meta.json",
            field="geometry",
            fix=f"learn it with `sensact learn em {path}`"
            + (
                ", or write it again with `sensact convert track`, which names both for chapter 3 too"
                if track
                else "; `sensact learn bootstrap` reads a Turtlebot CSV, a `sensact convert track` folder or a "
                "`sensact simulate track1d` folder"
            )
            + ".",
        )
    cmd_col, cmd_unit = _column(meta, "action", path)
    obs_col, obs_unit = _column(meta, "sensor", path)
    if sensor is not None:
        obs_col, obs_unit = sensor, meta.get("units", {}).get(sensor, "")
    actions = read_numeric_csv(path / "actions.csv", ["t_s", cmd_col], what="actions.csv")
    obs = read_numeric_csv(path / "observations.csv", ["t_s", obs_col], what="observations.csv")
    t_a, c = actions["t_s"], actions[cmd_col]
    if np.any(~np.isfinite(t_a)) or np.any(np.diff(t_a) <= 0) or t_a.size < 2:
        raise LogFormatError(
            f"t_s must be finite and strictly increasing, over at least two rows (it has {t_a.size}).",
            file=path / "actions.csv",
            field="t_s",
            fix="sort the rows by time and remove duplicates; a log needs at least two steps.",
        )
    if np.any(~np.isfinite(c)):
        bad = int(np.flatnonzero(~np.isfinite(c))[0]) + 2
        raise LogFormatError(
            f"row {bad} has no command.",
            file=path / "actions.csv",
            field=cmd_col,
            fix="every action row needs a command value.",
        )
    t_o, o = obs["t_s"], obs[obs_col]
    if obs_col.startswith("range") or obs_col.endswith("height_px"):
        from sensact.io.unit_checks import refuse_negative_ranges

        refuse_negative_ranges(path / "observations.csv", o, obs_col)
    ok = np.isfinite(t_o) & np.isfinite(o) & (t_o >= t_a[0])
    t_o, o = t_o[ok], o[ok]
    if t_o.size == 0:
        raise LogFormatError(
            f"no reading of {obs_col} from the first action row's time on.",
            file=path / "observations.csv",
            field=obs_col,
            fix="give a log whose sensor read something, on the same clock as actions.csv.",
        )
    times = np.union1d(t_a, t_o)
    # chapter 3's learner steps at the commands' rate: bounded before it allocates (sensact.limits)
    step_count(times[-1] - times[0], float(np.median(np.diff(t_a))), str(path / "observations.csv"), "t_s")
    commands = c[np.searchsorted(t_a, times, side="right") - 1]
    observations = np.full(len(times), np.nan)
    observations[np.searchsorted(times, t_o)] = o
    true_pos, pos_unit = None, ""
    gt_spec = meta.get("groundtruth")
    if gt_spec and (path / "groundtruth.csv").is_file():
        col = gt_spec["column"]
        gt = read_numeric_csv(path / "groundtruth.csv", ["t_s", col], what="groundtruth.csv")
        true_pos = np.interp(times, gt["t_s"], gt[col])
        pos_unit = gt_spec.get("unit", "")
    return TrackLog(times, commands, observations, cmd_unit, obs_col, obs_unit, str(path), meta, true_pos, pos_unit)
