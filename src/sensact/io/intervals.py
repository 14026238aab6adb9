"""Intervals in (docs/lidar2d.md, "Intervals from Censi et al.'s tool"): Censi et al.'s tuple format (one JSON
object a line, ``{"T": s, "phi_l": rad/s, "phi_r": rad/s, "sm": [x_m, y_m, theta_rad]}``, as their calibration
tool and OdomLaserCalibraTool write it) or a CSV of the same columns, read into an ``IntervalsLog``; and the log
folder ``convert intervals`` writes::

    run/
      meta.json       "kind": "intervals", the source, the truth if simulated
      intervals.csv   T_s, phi_l_rad_s, phi_r_rad_s, sm_x_m, sm_y_m, sm_theta_rad
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.atomic import write_json, write_text
from sensact.io.csvtable import read_numeric_csv
from sensact.io.jsonfile import read_json_object
from sensact.logs.intervals_log import IntervalsLog

KIND = "intervals"
TABLE = "intervals.csv"
COLUMNS = ["T_s", "phi_l_rad_s", "phi_r_rad_s", "sm_x_m", "sm_y_m", "sm_theta_rad"]
MAX_T_S = 60.0  # an interval longer than a minute is no scan matcher's
MAX_RATE_RAD_S = 1000.0  # a wheel's angular velocity beyond any ground robot's
MAX_SM_M = 100.0
MIN_INTERVALS = 10


def _checked(path: Path, values: np.ndarray, rows: list[int]) -> np.ndarray:
    """(n, 6) in COLUMNS' order, refused in one line where a value is not finite or beyond any robot's."""
    limits = [MAX_T_S, MAX_RATE_RAD_S, MAX_RATE_RAD_S, MAX_SM_M, MAX_SM_M, 2 * math.pi]
    for k, (name, limit) in enumerate(zip(COLUMNS, limits, strict=True)):
        v = values[:, k]
        bad = ~np.isfinite(v) | (np.abs(v) > limit) | ((v <= 0) if k == 0 else False)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise LogFormatError(
                f"interval {rows[i]}'s {name} is {float(v[i])!r}: " + ("not a length in (0, 60] s." if k == 0 else
                f"not a finite number within {limit:g}."),
                file=path,
                field=name,
                fix="T in seconds; phi_l and phi_r the wheels' angular velocities in rad/s; sm in metres and radians.",
            )  # fmt: skip
    if len(values) < MIN_INTERVALS:
        raise LogFormatError(
            f"only {len(values)} intervals.", file=path, fix=f"give {MIN_INTERVALS} or more, turning both ways."
        )
    return values


def _objects(text: str) -> list[tuple[int, object]]:
    """The JSON values of ``text`` in order, each with its line: one a line, or run together as the authors' own
    whole-set files are (each third's tuples appended to the last without a line break); blank lines and
    ``#`` comments skipped. ValueError names the line where a value does not parse."""
    decoder, out, at = json.JSONDecoder(), [], 0
    while True:
        while at < len(text) and (text[at].isspace() or text[at] == "#"):
            if text[at] == "#":  # a comment runs to the line's end
                end = text.find("\n", at)
                at = len(text) if end < 0 else end
            else:
                at += 1
        if at >= len(text):
            return out
        line = text.count("\n", 0, at) + 1
        try:
            doc, at = decoder.raw_decode(text, at)
        except (ValueError, RecursionError):
            raise ValueError(line) from None
        out.append((line, doc))


def read_censi(path: Path) -> IntervalsLog:
    """Censi et al.'s tuples, JSON objects one a line or run together (``_objects``); a tuple their tool marked
    ``mark_as_outlier`` is kept (sensact finds its own outliers)."""
    fix = "one JSON object a line, as Censi et al.'s tool writes them, or a CSV of " + ", ".join(COLUMNS) + "."
    with open(path, encoding="utf-8", errors="replace") as f:
        text = f.read()
    rows, values, not_tuple = [], [], "is not a tuple {T, phi_l, phi_r, sm: [x, y, theta]}."
    try:
        docs = _objects(text)
    except ValueError as e:
        raise LogFormatError(f"line {e.args[0]} {not_tuple}", file=path, fix=fix) from None
    for k, doc in docs:
        try:
            sm = doc["sm"]  # type: ignore[index]
            if len(sm) < 3:
                raise ValueError
            values.append([float(doc["T"]), float(doc["phi_l"]), float(doc["phi_r"]), *map(float, sm[:3])])  # type: ignore[index]
        except (ValueError, KeyError, TypeError, IndexError):
            raise LogFormatError(f"line {k} {not_tuple}", file=path, fix=fix) from None
        rows.append(k)
    arr = _checked(path, np.array(values, dtype=float).reshape(-1, 6), rows)
    return IntervalsLog(str(path), arr[:, 0], arr[:, 1:3], arr[:, 3:6])


def read_intervals_csv(path: Path) -> IntervalsLog:
    table = read_numeric_csv(path, COLUMNS, what="intervals")
    arr = np.column_stack([table[c] for c in COLUMNS])
    arr = _checked(path, arr, list(range(2, len(arr) + 2)))
    return IntervalsLog(str(path), arr[:, 0], arr[:, 1:3], arr[:, 3:6])


def read_intervals_file(path: Path) -> IntervalsLog:
    """A CSV (by its ``.csv`` suffix) or Censi et al.'s JSON lines (any other)."""
    path = Path(path)
    if not path.is_file():
        raise LogFormatError("not found.", file=path, fix="give Censi et al.'s tuples (JSON lines) or a CSV of them.")
    return read_intervals_csv(path) if path.suffix.lower() == ".csv" else read_censi(path)


def write_intervals_log(folder: Path, log: IntervalsLog) -> Path:
    """``log`` as a folder; meta.json last, so that a folder with meta.json is whole."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    arr = np.column_stack([log.t_s, log.phi_rad_s, log.sm_m])
    write_text(folder / TABLE, "\n".join([",".join(COLUMNS), *(",".join(map(repr, r)) for r in arr.tolist())]) + "\n")
    meta = {"format": "sensact-log", "version": 1, "kind": KIND, "source": log.source}
    write_json(folder / "meta.json", meta | ({"truth": log.truth} if log.truth is not None else {}))
    return folder


def read_intervals_log(folder: Path) -> IntervalsLog:
    folder = Path(folder)
    meta = read_json_object(folder / "meta.json", LogFormatError, "write it with `sensact convert intervals`.")
    log = read_intervals_csv(folder / TABLE)
    truth = meta.get("truth")
    return IntervalsLog(
        str(meta.get("source", folder)), log.t_s, log.phi_rad_s, log.sm_m, truth if isinstance(truth, dict) else None
    )
