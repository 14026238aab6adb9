"""Reading a log folder as EM's input (``sensact.logs.landmark_log.LandmarkLog``).

Two kinds of folder are understood:

* **planar** (``meta.json`` has ``"geometry": "planar"``, as ``sensact simulate field2d`` writes): a fixed
  step ``dt_s``; ``actions.csv`` holds ``t_s`` and an action index into ``meta.actions.table``;
  ``observations.csv`` holds ``t_s``, a landmark id from ``meta.landmarks``, the beacon height and
  (optionally) the bearing, under the column names ``meta.observations`` gives.
* **track** (``"platform": "track1d"``, as ``sensact simulate track1d`` writes): commands are numbers. When
  there are few distinct commands each becomes one action; otherwise they are binned into
  ``command_bins`` equal-width actions (EM learns a velocity per action, sec. 4.4.3).

Ground truth, if present, is returned separately and is only ever used for evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.csvtable import read_numeric_csv
from sensact.io.logfolder import read_meta, read_track_log
from sensact.logs.landmark_log import LandmarkLog

MAX_DISTINCT_COMMANDS = 64


@dataclass(frozen=True, eq=False)
class LandmarkLogFile:
    data: LandmarkLog
    meta: dict[str, Any]
    groundtruth: dict[str, np.ndarray] | None  # columns on the log's step grid
    note: str = ""  # how the commands were turned into actions, for the user


def _steps(t: np.ndarray, t0: float, dt: float, path: Path, what: str) -> np.ndarray:
    k = np.rint((t - t0) / dt)
    bad = np.flatnonzero(np.abs(t - t0 - k * dt) > 0.25 * dt)
    if bad.size:
        raise LogFormatError(
            f"row {bad[0] + 2}: t_s = {t[bad[0]]} is not on the {dt} s step grid.",
            file=path / what,
            field="t_s",
            fix="resample the log onto multiples of meta.json's dt_s.",
        )
    return k.astype(np.int64)


def _planar(path: Path, meta: dict[str, Any]) -> LandmarkLogFile:
    mpath = path / "meta.json"
    try:
        dt = float(meta["dt_s"])
        act = meta["actions"]
        table = np.asarray(act["table"], dtype=float)
        names = tuple(act.get("names") or [f"c{j}" for j in range(table.shape[1])])
        marks = meta["landmarks"]
        ids = [int(m["id"]) for m in marks]
        xy = np.array([[float(m["x_mm"]), float(m["y_mm"])] for m in marks])
        cols = meta.get("observations", {})
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise LogFormatError(
            f"a planar log needs dt_s, actions.table and landmarks ({exc!r} is missing or malformed).",
            file=mpath,
            field=str(exc).strip("'"),
            fix='see docs/commands.md, "Log folders for EM"; `sensact simulate field2d --out DIR` writes an example.',
        ) from None
    a_col = act.get("column", "action_id")
    lm_col, h_col, b_col = cols.get("landmark", "landmark_id"), cols.get("height", "height_px"), cols.get("bearing")
    actions = read_numeric_csv(path / "actions.csv", ["t_s", a_col], what="actions.csv")
    t_a = actions["t_s"]
    if np.any(np.diff(t_a) <= 0):
        raise LogFormatError(
            "t_s must be strictly increasing.", file=path / "actions.csv", field="t_s", fix="sort and deduplicate."
        )
    steps_a = _steps(t_a, t_a[0], dt, path, "actions.csv")
    T = int(steps_a[-1]) + 1
    a_ids = actions[a_col]
    if np.any(~np.isfinite(a_ids)) or np.any((a_ids < 0) | (a_ids >= len(table))) or np.any(a_ids != np.rint(a_ids)):
        bad = int(
            np.flatnonzero(~np.isfinite(a_ids) | (a_ids < 0) | (a_ids >= len(table)) | (a_ids != np.rint(a_ids)))[0]
        )
        raise LogFormatError(
            f"row {bad + 2}: {a_ids[bad]} is not an action index 0..{len(table) - 1}.",
            file=path / "actions.csv",
            field=a_col,
            fix="each row's action must index meta.json's actions.table.",
        )
    act_grid = np.full(T, -1, dtype=np.int64)
    act_grid[steps_a] = a_ids.astype(np.int64)
    last = np.maximum.accumulate(np.where(act_grid >= 0, np.arange(T), 0))  # zero-order hold between rows
    act_grid = act_grid[last]
    need = ["t_s", lm_col, h_col] + ([b_col] if b_col else [])
    obs = read_numeric_csv(path / "observations.csv", need, what="observations.csv")
    steps_o = _steps(obs["t_s"], t_a[0], dt, path, "observations.csv")
    keep = (steps_o >= 0) & (steps_o < T)
    lm_raw = obs[lm_col]
    id_to_row = {v: j for j, v in enumerate(ids)}
    unknown = [x for x in np.unique(lm_raw[keep]) if x not in id_to_row]
    if unknown:
        raise LogFormatError(
            f"landmark id {unknown[0]:g} is not in meta.json's landmarks ({ids}).",
            file=path / "observations.csv",
            field=lm_col,
            fix="add the landmark's position to meta.json or drop its rows.",
        )
    order = np.argsort(steps_o[keep], kind="stable")
    data = LandmarkLog(
        "planar",
        dt,
        act_grid,
        table,
        names,
        steps_o[keep][order],
        np.array([id_to_row[x] for x in lm_raw[keep][order]], dtype=np.int64),
        obs[h_col][keep][order],
        obs[b_col][keep][order] if b_col else np.full(int(keep.sum()), np.nan),
        xy,
        tuple(str(m.get("name", m["id"])) for m in marks),
        str(path),
    )
    gt = None
    if (path / "groundtruth.csv").is_file():
        g = read_numeric_csv(path / "groundtruth.csv", ["t_s"], what="groundtruth.csv")
        gt = {k: np.interp(np.arange(T) * dt + t_a[0], g["t_s"], v) for k, v in g.items() if k != "t_s"}
    return LandmarkLogFile(data, meta, gt)


def _track(path: Path, command_bins: int) -> LandmarkLogFile:
    log = read_track_log(path)
    dt = np.diff(log.times_s)
    if np.ptp(dt) > 1e-6 * dt.mean():
        raise LogFormatError(
            "EM needs a fixed time step, but the rows are unevenly spaced.",
            file=path / "actions.csv",
            field="t_s",
            fix="resample actions and observations onto one step.",
        )
    c = log.commands
    distinct = np.unique(c)
    if distinct.size <= MAX_DISTINCT_COMMANDS:
        levels, actions = distinct, np.searchsorted(distinct, c)
        note = f"{distinct.size} distinct commands, one action each"
    else:
        edges = np.linspace(c.min(), c.max(), command_bins + 1)
        actions = np.clip(np.searchsorted(edges, c, side="right") - 1, 0, command_bins - 1)
        levels = 0.5 * (edges[:-1] + edges[1:])
        note = f"{distinct.size} distinct commands binned into {command_bins} actions (--bins)"
    seen = np.flatnonzero(np.isfinite(log.observations))
    name = f"command_{log.command_unit or 'unit'}"
    data = LandmarkLog.track(float(dt.mean()), actions, levels, name, seen, log.observations[seen], str(path))
    gt = None if log.true_position is None else {"distance": log.true_position}
    return LandmarkLogFile(data, log.meta, gt, note)


def read_landmark_log(path: str | Path, *, command_bins: int = 21) -> LandmarkLogFile:
    """Read a planar or track log folder for EM."""
    path = Path(path)
    if not path.is_dir():
        raise LogFormatError(
            "EM reads a log folder.", file=path, fix="give a folder with meta.json, actions.csv and observations.csv."
        )
    meta = read_meta(path)
    if meta.get("geometry") == "planar" or meta.get("platform") == "field2d":
        return _planar(path, meta)
    if meta.get("platform") == "track1d" or "action" in meta:
        return _track(path, command_bins)
    raise LogFormatError(
        "meta.json declares neither a planar log (geometry: planar) nor a 1-D track (platform: track1d).",
        file=path / "meta.json",
        field="geometry",
        fix='add "geometry": "planar" with actions.table and landmarks (docs/commands.md).',
    )
