"""Reading a log folder as EM's input (``sensact.logs.landmark_log.LandmarkLog``).

Two kinds of folder are understood:

* **landmark logs** (``meta.json`` has ``"geometry": "planar"`` or ``"track"``, as ``sensact simulate
  field2d`` and ``sensact convert mrclam`` write): a fixed step ``dt_s``; ``actions.csv`` holds ``t_s``
  and either an action index into ``meta.actions.table`` or, with ``meta.actions.columns``, continuous
  command columns (held until the next row); ``observations.csv`` holds ``t_s``, a landmark id from
  ``meta.landmarks``, one column per reading channel (``meta.observations.readings``, or the single
  ``height``) and optionally the bearing, under the column names ``meta.observations`` gives.
* **track** (``"platform": "track1d"``, as ``sensact simulate track1d`` writes): commands are numbers. When
  there are few distinct commands each becomes one action; otherwise they are binned into
  ``command_bins`` equal-width actions (EM learns a velocity per action, sec. 4.4.3).

Ground truth, if present, is returned separately and is only ever used for evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from sensact.core.geometry import GEOMETRIES, Geometry, geometry_named
from sensact.errors import LogFormatError
from sensact.io.csvtable import (
    MIN_OVERLAP,
    landmark_labels,
    read_numeric_csv,
    refuse_apart,
    refuse_repeated,
    refuse_unordered,
)
from sensact.io.logfolder import read_meta, read_track_log, refuse_a_car_log, write_log_folder
from sensact.io.unit_checks import refuse_degrees_as_radians, refuse_negative_ranges
from sensact.limits import steps_problem
from sensact.logs.landmark_log import LandmarkLog
from sensact.records import JsonObject

MAX_DISTINCT_COMMANDS = 64


@dataclass(frozen=True, eq=False)
class LandmarkLogFile:
    data: LandmarkLog
    meta: JsonObject
    groundtruth: dict[str, np.ndarray] | None  # columns on the log's step grid
    note: str = ""  # how the commands were turned into actions, for the user

    def title(self, folder: str | Path) -> str:
        """The name figures give the log: its folder's, and the dataset and robot it was converted from
        when meta.json's ``source`` says (``sensact convert mrclam`` writes them)."""
        src = self.meta.get("source")
        name = Path(folder).resolve().name  # "." names the folder it is
        if isinstance(src, dict) and src.get("dataset") and src.get("robot") is not None:
            return f"{name} ({Path(str(src['dataset'])).name} robot {src['robot']})"
        return name

    def truth_poses(self) -> tuple[np.ndarray, np.ndarray] | None:
        return truth_poses_of(self.groundtruth)

    @property
    def survey_xy(self) -> np.ndarray | None:
        """(L, 2) mm: the surveyed positions of a log whose map EM learns (meta.json's ``survey``, for
        scoring only, as groundtruth.csv), NaN where not surveyed; the given map where every position is
        given; None when neither."""
        if self.data.map_given.all():
            return self.data.landmarks_xy
        rows = self.meta.get("survey")
        if not rows:
            return None
        xy = np.full_like(self.data.landmarks_xy, np.nan)
        try:
            for row in rows:
                j = int(row["id"])
                if not 0 <= j < len(xy):
                    raise IndexError(f"id {j} is not a landmark of the map")
                xy[j] = float(row["x_mm"]), float(row["y_mm"])
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise LogFormatError(
                f"meta.json's survey is malformed ({exc}).",
                file=self.data.source,
                field="survey",
                fix='give "survey": [{"id": <the landmark\'s index in landmarks>, "x_mm": ..., "y_mm": ...}, ...], '
                "or drop it (it is only used to score).",
            ) from None
        return xy

    def truth_distance_mm(self) -> np.ndarray | None:
        """A 1-D robot's recorded distance on the step grid (``groundtruth.csv``'s ``distance_mm`` in a
        track folder of continuous commands), scored as a Turtlebot CSV's ``range`` column; else None."""
        gt = self.groundtruth
        if (
            gt is None
            or "distance_mm" not in gt
            or not self.data.geometry.state_is_range
            or not self.data.is_continuous
        ):
            return None
        return np.asarray(gt["distance_mm"], dtype=float)


def truth_poses_of(gt: dict[str, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray] | None:
    """Ground truth's ``(T, 3)`` poses on the step grid and where they are valid (every step when it has
    no ``valid`` column, as a hand-written groundtruth.csv), or None without ``x_mm``, ``y_mm`` and
    ``theta_rad``."""
    if gt is None or not {"x_mm", "y_mm", "theta_rad"} <= set(gt):
        return None
    poses = np.column_stack([gt["x_mm"], gt["y_mm"], gt["theta_rad"]])
    return poses, (gt["valid"] > 0.5 if "valid" in gt else np.ones(len(poses), dtype=bool))


def _steps(t: np.ndarray, t0: float, dt: float, path: Path, what: str) -> np.ndarray:
    k = np.rint((t - t0) / dt)
    bad = np.flatnonzero(np.abs(t - t0 - k * dt) > 0.25 * dt)
    if bad.size:
        raise LogFormatError(
            f"row {bad[0] + 2}: t_s = {t[bad[0]]} is not on the {dt} s step grid.",
            file=path / what,
            field="t_s",
            fix="resample the log onto multiples of meta.json's dt_s (`sensact convert csv` does it from timed CSVs).",
        )
    return k.astype(np.int64)


def _commands_on_grid(
    path: Path, act: JsonObject, dt: float, n_table: int
) -> tuple[np.ndarray, np.ndarray | None, float, int]:
    """Action indices (discrete) or command rows (continuous) on the step grid, held until the next row."""
    continuous = "columns" in act
    cols = list(act["columns"]) if continuous else [act.get("column", "action_id")]
    actions = read_numeric_csv(path / "actions.csv", ["t_s", *cols], what="actions.csv")
    t_a = actions["t_s"]
    if np.any(np.diff(t_a) <= 0):
        raise LogFormatError(
            "t_s must be strictly increasing.", file=path / "actions.csv", field="t_s", fix="sort and deduplicate."
        )
    too_long = steps_problem((t_a[-1] - t_a[0]) / dt + 1, "the commands' span")
    if too_long is not None:
        raise LogFormatError(f"{too_long}.", file=path / "actions.csv", field="t_s", fix="check the times in t_s.")
    steps_a = _steps(t_a, t_a[0], dt, path, "actions.csv")
    T = int(steps_a[-1]) + 1
    filled = np.zeros(T, dtype=bool)
    filled[steps_a] = True
    last = np.maximum.accumulate(np.where(filled, np.arange(T), 0))  # zero-order hold between rows
    rows = np.searchsorted(steps_a, last)
    if continuous:
        values = np.column_stack([actions[c] for c in cols])
        bad = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
        if bad.size:
            raise LogFormatError(
                f"row {bad[0] + 2}: a command is empty or not finite.",
                file=path / "actions.csv",
                field=cols[int(np.flatnonzero(~np.isfinite(values[bad[0]]))[0])],
                fix="every row needs a value in each command column.",
            )
        return np.full(T, -1, dtype=np.int64), values[rows], float(t_a[0]), T
    a_ids = actions[cols[0]]
    wrong = ~np.isfinite(a_ids) | (a_ids < 0) | (a_ids >= n_table) | (a_ids != np.rint(a_ids))
    if wrong.any():
        bad = int(np.flatnonzero(wrong)[0])
        raise LogFormatError(
            f"row {bad + 2}: {a_ids[bad]} is not an action index 0..{n_table - 1}.",
            file=path / "actions.csv",
            field=cols[0],
            fix="each row's action must index meta.json's actions.table.",
        )
    return a_ids.astype(np.int64)[rows], None, float(t_a[0]), T


def _map_ids(mpath: Path, raw: list[str]) -> list[str]:
    """meta.json's landmark ids, each spelled once (``landmark_labels``); an empty or repeated id is refused."""
    fix = "give each landmark in meta.json its own id, a number or a name."
    for j, cell in enumerate(raw):
        if not cell:
            raise LogFormatError(f"landmark {j + 1} has no id.", file=mpath, field="landmarks.id", fix=fix)
    ids = [str(x) for x in landmark_labels(mpath, np.array(raw, dtype=str), "landmarks.id", fix)]
    twice = sorted({x for x in ids if ids.count(x) > 1})
    if twice:
        raise LogFormatError(
            f"landmark id {twice[0]} appears more than once.", file=mpath, field="landmarks.id", fix=fix
        )
    return ids


class _MetaParts(NamedTuple):
    """What a landmark log's meta.json says: the step, the actions, the map and the observation columns."""

    dt: float
    actions: JsonObject
    table: np.ndarray  # discrete actions' velocities; zero rows for command columns
    names: tuple[str, ...]  # the command (or action table) columns
    marks: list[JsonObject]
    raw_ids: list[str]
    xy: np.ndarray
    columns: JsonObject  # meta.json's "observations"


def _meta_parts(mpath: Path, meta: JsonObject, geometry: Geometry) -> _MetaParts:
    """meta.json's parts, each missing or malformed one named in one line."""
    part = "dt_s"  # the part of meta.json being read, for the error
    try:
        dt = float(meta["dt_s"])
        part = "actions"
        act = meta["actions"]
        if "columns" in act:
            table = np.zeros((0, len(act["columns"])))
            names = tuple(str(c) for c in act["columns"])
        else:
            table = np.asarray(act["table"], dtype=float)
            names = tuple(act.get("names") or [f"c{j}" for j in range(table.shape[1])])
        part = "landmarks"
        # a track's state is the range to its one beacon: no map to read
        beacon = [{"id": 0, "x_mm": 0, "y_mm": 0}]
        marks = meta.get("landmarks", beacon) if geometry.state_is_range else meta["landmarks"]
        raw_ids = [str(m["id"]).strip() if m["id"] is not None else "" for m in marks]
        # a position nobody surveyed is null: EM learns it (docs/map.md)
        xy = np.array([[_mm_or_nan(m["x_mm"]), _mm_or_nan(m["y_mm"])] for m in marks])
        part = "observations"
        cols = meta.get("observations", {})
        if not isinstance(cols, dict):
            raise TypeError(f"an object naming the columns, not {type(cols).__name__}")
        part = "truth"
        if not isinstance(meta.get("truth", {}) or {}, dict):
            raise TypeError(f"the simulated truth is an object, not {type(meta['truth']).__name__}")
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        what = f"{exc} is missing" if isinstance(exc, KeyError) else f"malformed ({exc})"
        raise LogFormatError(
            f"a landmark log needs dt_s, actions (a table or command columns) and landmarks (id, x_mm, y_mm); "
            f"{part}: {what}.",
            file=mpath,
            field=part,
            fix='see docs/formats.md, "Log folders for EM"; `sensact simulate field2d --out DIR` writes an example.',
        ) from None
    if "columns" in act and not names:
        raise LogFormatError(
            "actions.columns is empty: EM needs at least one command column.",
            file=mpath,
            field="actions.columns",
            fix='name the command columns of actions.csv, e.g. ["v_mm_s", "omega_rad_s"].',
        )
    half = np.isfinite(xy).any(axis=1) & ~np.isfinite(xy).all(axis=1) if xy.size else np.zeros(0, dtype=bool)
    odd = [j for j, m in enumerate(marks) if any(_not_a_number(m[k]) for k in ("x_mm", "y_mm"))]
    if half.any() or odd:
        bad = int(np.flatnonzero(half)[0]) if half.any() else odd[0]
        raise LogFormatError(
            f"landmark {raw_ids[bad] or bad + 1}'s position is not finite.",
            file=mpath,
            field="landmarks.x_mm / y_mm",
            fix="give a landmark a finite x_mm and y_mm, or null for both when nobody surveyed it (EM learns it).",
        )
    given = xy[np.isfinite(xy).all(axis=1)] if xy.size else xy
    if len(given) >= 3 and np.ptp(given, axis=0).max() == 0:  # a map of one point: a copy gone wrong, not a survey
        raise LogFormatError(
            f"all {len(given)} landmarks given are at one point ({given[0, 0]:g}, {given[0, 1]:g}) mm.",
            file=mpath,
            field="landmarks.x_mm / y_mm",
            fix="give each landmark its own surveyed position, or null for those nobody surveyed (EM learns them).",
        )
    if not (np.isfinite(dt) and dt > 0):
        raise LogFormatError(
            f"dt_s is {meta['dt_s']!r}; the fixed step must be a positive number of seconds.",
            file=mpath,
            field="dt_s",
            fix="set dt_s to the step the CSVs' t_s are on (e.g. 0.0333 for 30 Hz).",
        )
    return _MetaParts(dt, act, table, names, marks, raw_ids, xy, cols)


def _mm_or_nan(v: Any) -> float:
    """A landmark coordinate: null is a position nobody surveyed (NaN; EM learns it)."""
    return np.nan if v is None else float(v)


def _not_a_number(v: Any) -> bool:
    return v is not None and not np.isfinite(float(v))


class _Sightings(NamedTuple):
    """observations.csv's rows within the commands' span, in step order."""

    steps: np.ndarray
    landmarks: np.ndarray  # row in the map
    readings: np.ndarray  # one column per reading
    bearings: np.ndarray  # NaN when the log has none
    names: tuple[str, ...]  # the reading columns


def _sightings(
    path: Path, geometry: Geometry, cols: JsonObject, ids: list[str], t0: float, dt: float, T: int
) -> _Sightings:
    """observations.csv on the step grid: rows outside the commands' ``T`` steps dropped, every landmark id
    in the map (``ids``), bearings in radians."""
    lm_col, b_col = cols.get("landmark", "landmark_id"), cols.get("bearing")
    readings = list(cols.get("readings") or [cols.get("height", "height_px")])
    need = ["t_s", *readings] + ([b_col] if b_col else []) + ([] if geometry.state_is_range else [lm_col])
    # a landmark id may be a name (``post_A``), spelled as `convert csv` spells it (a track's column too)
    obs = read_numeric_csv(path / "observations.csv", need, what="observations.csv", labels=(lm_col,))
    refuse_unordered(path / "observations.csv", obs["t_s"], strict=False)
    steps_o = np.rint((obs["t_s"] - t0) / dt)
    keep = (steps_o >= 0) & (steps_o < T)
    refuse_apart(path / "observations.csv", obs["t_s"], keep, t0, t0 + (T - 1) * dt)
    steps_o = _steps(obs["t_s"], t0, dt, path, "observations.csv")
    fix_obs = "give each sighting the id of a landmark in meta.json."
    lm_raw = (
        landmark_labels(path / "observations.csv", obs[lm_col], lm_col, fix_obs)
        if lm_col in obs
        else np.full(steps_o.size, ids[0])
    )
    refuse_repeated(path / "observations.csv", obs)
    id_to_row = {v: j for j, v in enumerate(ids)}
    unknown = [x for x in np.unique(lm_raw[keep]) if x not in id_to_row]
    if unknown:
        raise LogFormatError(
            f"landmark id {unknown[0]} is not in meta.json's landmarks ({', '.join(ids)}).",
            file=path / "observations.csv",
            field=lm_col,
            fix="add the landmark's position to meta.json or drop its rows.",
        )
    for r in readings:
        if r.startswith("range") or r.endswith("height_px"):
            refuse_negative_ranges(path / "observations.csv", obs[r][keep], r)
    if b_col:
        refuse_degrees_as_radians(
            path / "observations.csv", obs[b_col], b_col, f"write {b_col} in radians (counterclockwise from forward)."
        )
    order = np.argsort(steps_o[keep], kind="stable")
    return _Sightings(
        steps_o[keep][order],
        np.array([id_to_row[x] for x in lm_raw[keep][order]], dtype=np.int64),
        np.column_stack([obs[r][keep][order] for r in readings]),
        obs[b_col][keep][order] if b_col else np.full(int(keep.sum()), np.nan),
        tuple(readings),
    )


def _planar(path: Path, meta: JsonObject) -> LandmarkLogFile:
    """A landmark log folder (planar, or a track declared with ``"geometry": "track"``)."""
    mpath = path / "meta.json"
    try:
        geometry = geometry_named(meta.get("geometry", "planar"))
    except ValueError as exc:
        fix = 'use "geometry": "planar" or "track".'
        raise LogFormatError(f"{exc}.", file=mpath, field="geometry", fix=fix) from None
    mp = _meta_parts(mpath, meta, geometry)
    ids = _map_ids(mpath, mp.raw_ids)
    act_grid, cmd_grid, t0, T = _commands_on_grid(path, mp.actions, mp.dt, len(mp.table))
    seen = _sightings(path, geometry, mp.columns, ids, t0, mp.dt, T)
    data = _log_or_refuse(
        path,
        geometry,
        mp.dt,
        act_grid,
        mp.table,
        mp.names,
        seen.steps,
        seen.landmarks,
        seen.readings,
        seen.bearings,
        mp.xy,
        tuple(str(m.get("name", m["id"])) for m in mp.marks),
        str(path),
        seen.names,
        cmd_grid,
    )
    gt = None
    if (path / "groundtruth.csv").is_file():
        g = read_numeric_csv(path / "groundtruth.csv", ["t_s"], what="groundtruth.csv")
        refuse_bad_truth(path / "groundtruth.csv", g, t0, t0 + (T - 1) * mp.dt)
        gt = {k: np.interp(np.arange(T) * mp.dt + t0, g["t_s"], v) for k, v in g.items() if k != "t_s"}
    folder = LandmarkLogFile(data, meta, gt)
    _ = folder.survey_xy  # a malformed survey is refused with the rest of the folder, before any learning
    return folder


def _track(path: Path, command_bins: int, command_levels: np.ndarray | None = None) -> LandmarkLogFile:
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
    given = None if command_levels is None else np.asarray(command_levels, dtype=float)
    tol = 1e-9 * max(1.0, float(np.abs(given).max())) if given is not None else 0.0
    if given is not None and distinct.size <= MAX_DISTINCT_COMMANDS:
        near = np.abs(distinct[:, None] - given[None, :]) <= tol
        if near.any(axis=1).all():  # discrete commands, each one of a learned table's actions
            levels, actions = given, np.argmax(near, axis=1)[np.searchsorted(distinct, c)]
            return _track_file(
                path, log, dt, actions, levels, f"{distinct.size} distinct commands, the model's actions"
            )
    if given is not None and distinct.size > MAX_DISTINCT_COMMANDS and _within(c, given):
        # continuous commands onto a learned table's bins (equal widths: the nearest centre is the bin), so
        # that a model learned on one log runs on the next, whose commands span a little more or less
        levels, actions = given, np.argmin(np.abs(c[:, None] - given[None, :]), axis=1)
        note = f"{distinct.size} distinct commands binned onto the model's {given.size} actions"
    elif distinct.size <= MAX_DISTINCT_COMMANDS:
        levels, actions = distinct, np.searchsorted(distinct, c)
        note = f"{distinct.size} distinct commands, one action each"
    else:
        edges = np.linspace(c.min(), c.max(), command_bins + 1)
        actions = np.clip(np.searchsorted(edges, c, side="right") - 1, 0, command_bins - 1)
        levels = 0.5 * (edges[:-1] + edges[1:])
        note = f"{distinct.size} distinct commands binned into {command_bins} actions (--bins)"
    return _track_file(path, log, dt, actions, levels, note)


def _within(commands: np.ndarray, levels: np.ndarray) -> bool:
    """Whether every command lies within the actions' span, widened by one action's spacing past either
    end (a model learned on commands like these: a command a little past it goes to the end action);
    else the log keeps its own actions, and a model of others is refused."""
    if levels.size < 2:
        return False
    reach = 1.5 * float(np.median(np.diff(np.sort(levels))))  # half a bin to the edge, then one bin more
    return bool(commands.min() >= levels.min() - reach and commands.max() <= levels.max() + reach)


def _track_file(
    path: Path, log: Any, dt: np.ndarray, actions: np.ndarray, levels: np.ndarray, note: str
) -> LandmarkLogFile:
    seen = np.flatnonzero(np.isfinite(log.observations))
    name = f"command_{log.command_unit or 'unit'}"
    data = LandmarkLog.track(float(dt.mean()), actions, levels, name, seen, log.observations[seen], str(path))
    gt = None if log.true_position is None else {"distance": log.true_position}
    return LandmarkLogFile(data, log.meta, gt, note)


def read_landmark_log(
    path: str | Path, *, command_bins: int = 21, command_levels: np.ndarray | None = None
) -> LandmarkLogFile:
    """Read a planar or track log folder for EM. A track's continuous commands are binned into
    ``command_bins`` equal actions over their span, or onto ``command_levels`` (a learned table's)."""
    path = Path(path)
    if not path.is_dir():
        raise LogFormatError(
            "not a log folder: " + ("this is a file." if path.exists() else "not found."),
            file=path,
            fix="give a folder with meta.json, actions.csv and observations.csv (`convert csv`, `convert mrclam` or "
            "`simulate` writes one).",
        )
    meta = read_meta(path, example="`sensact simulate field2d --out DIR` (or `sensact convert mrclam`)")
    if meta.get("geometry") in GEOMETRIES or meta.get("platform") == "field2d":
        return _planar(path, meta)
    if meta.get("platform") == "track1d" or "action" in meta:
        return _track(path, command_bins, command_levels)
    refuse_a_car_log(meta, path)
    raise LogFormatError(
        "meta.json declares neither a planar log (geometry: planar) nor a 1-D track (platform: track1d).",
        file=path / "meta.json",
        field="geometry",
        fix='add "geometry": "planar" with actions.table and landmarks (docs/cli-reference.md).',
    )


def write_landmark_log(
    folder: str | Path,
    data: LandmarkLog,
    *,
    t0_s: float = 0.0,
    groundtruth: dict[str, np.ndarray] | None = None,
    meta_extra: JsonObject | None = None,
    survey_xy: np.ndarray | None = None,
) -> Path:
    """Write ``data`` as a landmark log folder that ``read_landmark_log`` reads back exactly.

    ``groundtruth`` columns (on the step grid) go to groundtruth.csv, for evaluation only; so does
    ``survey_xy`` ((L, 2) mm, NaN where not surveyed), the surveyed map of a log whose map EM learns
    (meta.json's ``survey``).
    """
    times = t0_s + np.arange(data.n_steps) * data.dt_s
    if data.is_continuous:
        act_meta: JsonObject = {
            "columns": list(data.command_names),
            "meaning": "continuous commands, in force until the next row",
        }
        actions = {"t_s": times, **{c: data.step_commands[:, j] for j, c in enumerate(data.command_names)}}
    else:
        act_meta = {"column": "action_id", "names": list(data.command_names), "table": data.action_commands.tolist()}
        actions = {"t_s": times, "action_id": data.actions.astype(float)}
    obs: dict[str, np.ndarray] = {"t_s": times[data.obs_step], "landmark_id": data.obs_landmark.astype(float)}
    obs.update({r: data.obs_readings[:, j] for j, r in enumerate(data.reading_names)})
    cols: JsonObject = {"landmark": "landmark_id", "readings": list(data.reading_names)}
    if data.geometry.has_heading and np.isfinite(data.obs_bearing_rad).any():  # a range-only sensor's log has none
        obs["bearing_rad"] = data.obs_bearing_rad
        cols["bearing"] = "bearing_rad"
    names = data.landmark_names or tuple(str(j) for j in range(len(data.landmarks_xy)))
    meta = {
        "geometry": data.geometry.name,
        "dt_s": data.dt_s,
        "actions": act_meta,
        "landmarks": [
            {"id": j, "name": name, "x_mm": _mm_or_null(x), "y_mm": _mm_or_null(y)}
            for j, (name, (x, y)) in enumerate(zip(names, data.landmarks_xy, strict=True))
        ],
        **({} if survey_xy is None else {"survey": _survey_rows(survey_xy)}),
        "observations": cols,
        **(meta_extra or {}),
    }
    gt = None if groundtruth is None else {"t_s": times, **groundtruth}
    return write_log_folder(folder, meta=meta, actions=actions, observations=obs, groundtruth=gt)


def _mm_or_null(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def _survey_rows(xy: np.ndarray) -> list[JsonObject]:
    return [
        {"id": j, "x_mm": float(x), "y_mm": float(y)}
        for j, (x, y) in enumerate(np.asarray(xy))
        if np.isfinite([x, y]).all()
    ]


def refuse_bad_truth(path: Path, g: dict[str, np.ndarray], t0: float, t1: float) -> None:
    """Ground truth is scored against: its times rise, its poses are all there, and it covers the commands'
    span on their clock."""
    refuse_unordered(path, g["t_s"], strict=True)
    poses = [name for name in g if name != "t_s"]  # a gap is a time the truth was not recorded
    if poses and not any(np.isfinite(g[name]).any() for name in poses):
        raise LogFormatError(
            "no row holds a pose: the truth is empty.",
            file=path,
            field=", ".join(poses),
            fix="fill it, or drop the file.",
        )
    t = g["t_s"]
    overlap = min(t1, float(t[-1])) - max(t0, float(t[0]))
    if overlap < MIN_OVERLAP * (t1 - t0):
        raise LogFormatError(
            f"it runs {t[0]:g} to {t[-1]:g} s, and the commands {t0:g} to {t1:g} s: less than half of them overlap.",
            file=path,
            field="t_s",
            fix="write the truth's times on the commands' clock, in seconds.",
        )
    refuse_apart(path, t, (t >= t0 - 1.0) & (t <= t1 + 1.0), t0, t1)  # most of it on another clock, or scale


def _log_or_refuse(path: Path, *parts: Any) -> LandmarkLog:
    """The log, or its own checks' complaint (too few steps, mismatched shapes) as the folder's error."""
    try:
        return LandmarkLog(*parts)
    except ValueError as exc:
        raise LogFormatError(f"{exc}.", file=path, fix='see docs/formats.md, "Log folders for EM".') from None
