"""Reading numeric CSV tables with errors that name the file, the column or row, and the fix."""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.limits import value_problem


def read_csv_rows(path: Path) -> tuple[list[list[str]], bool]:
    """The rows of a CSV text file as a spreadsheet exports it, and whether its decimals are commas.

    A UTF-8 byte-order mark (Excel's "CSV UTF-8") is dropped. A header with no comma but a semicolon
    or a tab sets the delimiter; a semicolon-separated file is what a spreadsheet writes where the
    decimal mark is a comma, so its cells' commas are read as decimal points.
    """
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            text = handle.read()
        first = text.split("\n", 1)[0]
        delimiter = next((d for d in (",", ";", "\t") if d in first), ",")
        rows = list(csv.reader(io.StringIO(text, newline=""), delimiter=delimiter))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise LogFormatError(
            f"not a readable CSV text file ({exc}).",
            file=path,
            fix="give a text file (UTF-8) separated by commas, semicolons or tabs.",
        ) from exc
    return rows, delimiter == ";"


def _shifted(cell: str, origin: int) -> float:
    from decimal import Decimal, InvalidOperation

    try:
        return float(Decimal(cell) - origin)
    except InvalidOperation:
        raise ValueError(cell) from None


def time_origin(path: str | Path, column: str = "t_s") -> int:
    """The whole second a table's first ``column`` cell lies in, where it is an epoch's (beyond 1e5 s), else 0:
    the origin its log's times are read from (``read_numeric_csv``'s ``origin``)."""
    from decimal import Decimal, InvalidOperation

    try:
        with open(path, encoding="utf-8-sig", errors="replace") as f:
            lines = [f.readline(), f.readline()]
    except OSError:
        return 0
    sep = ";" if ";" in lines[0] else ","  # a semicolon table writes decimal commas
    header, row = ([c.strip() for c in line.split(sep)] for line in lines)
    if column not in header or len(row) != len(header):
        return 0
    cell = row[header.index(column)].replace(",", ".")
    try:
        first = Decimal(cell)
    except InvalidOperation:
        return 0
    return int(first.to_integral_value(rounding="ROUND_FLOOR")) if first.is_finite() and abs(first) > 100_000 else 0


def read_numeric_csv(
    path: str | Path,
    required: Sequence[str] = (),
    *,
    what: str = "table",
    labels: Sequence[str] = (),
    missing_fix: str = "rename the column or choose one that exists.",
    origin: Mapping[str, int] | None = None,
) -> dict[str, np.ndarray]:
    """All columns of a CSV with a header row, as float arrays keyed by column name.

    Empty cells become NaN. The columns named in ``labels`` (names such as a landmark's ``post_A``) are
    kept as stripped strings instead, an empty cell as "". A missing file, a missing required column (with
    ``missing_fix``), a short row or a non-numeric cell raises ``LogFormatError`` naming where and what to do.
    """
    path = Path(path)
    if not path.is_file():
        raise LogFormatError(
            f"{what} not found.",
            file=path,
            fix="check the path; a log folder holds meta.json, actions.csv and observations.csv.",
        )
    rows, decimal_comma = read_csv_rows(path)
    if not rows:
        raise LogFormatError("the file is empty.", file=path, fix="write a header row and at least one data row.")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in required if c not in header]
    if missing:
        raise LogFormatError(
            f"missing column(s) {', '.join(missing)}; found {', '.join(h or '<unnamed>' for h in header)}.",
            file=path,
            field=missing[0],
            fix=missing_fix,
        )
    body = [r for r in rows[1:] if any(cell.strip() for cell in r)]
    if not body:
        raise LogFormatError("no data rows.", file=path, fix="the file must have at least one row after the header.")
    out = np.full((len(body), len(header)), np.nan)
    text = [j for j, name in enumerate(header) if name and name in labels]
    # columns read as exact decimals less an integer (a Unix time less its log's first second): float64 holds
    # 1.7e9 s only to 2.4e-7 s, and a fit's differences in time would carry that
    shift = {j: origin[name] for j, name in enumerate(header) if origin and name in origin}
    for i, row in enumerate(body):
        if len(row) != len(header):
            raise LogFormatError(
                f"row {i + 2} has {len(row)} cells but the header has {len(header)}.",
                file=path,
                field=f"row {i + 2}",
                fix="make every row as long as the header"
                + (
                    " (a decimal comma splits a number in two: write a decimal point, or separate cells by semicolons)."
                    if len(row) > len(header) and not decimal_comma
                    else "."
                ),
            )
        for j, cell in enumerate(row):
            cell = cell.strip()
            if cell == "" or j in text:
                continue
            try:
                number = cell.replace(",", ".") if decimal_comma else cell
                out[i, j] = value = float(number) if j not in shift else _shifted(number, shift[j])
                if not np.isfinite(value):
                    raise LogFormatError(
                        f"row {i + 2}: {cell!r} is not a finite number.",
                        file=path,
                        field=header[j] or f"column {j + 1}",
                        fix="write finite numbers only (an empty cell for a missing value).",
                    )
            except ValueError:
                raise LogFormatError(
                    f"row {i + 2}: {cell!r} is not a number.",
                    file=path,
                    field=header[j] or f"column {j + 1}",
                    fix="write numbers only (use an empty cell for a missing value).",
                ) from None
    for j, name in enumerate(header):
        if j in text:
            continue
        if _is_time(name):  # a time is never missing: every row happened at one
            empty = np.flatnonzero(np.isnan(out[:, j]))
            if empty.size:
                raise LogFormatError(
                    f"row {empty[0] + 2} has no time.", file=path, field=name, fix="give every row its time."
                )
            continue
        problem = value_problem(out[:, j], "the column")
        if problem is not None:
            row = int(np.nanargmax(np.abs(out[:, j])))
            raise LogFormatError(
                f"row {row + 2}: {problem}.",
                file=path,
                field=name or f"column {j + 1}",
                fix="check the column's unit and the row's value.",
            )
    table: dict[str, np.ndarray] = {name: out[:, j] for j, name in enumerate(header) if name}
    for j in text:
        table[header[j]] = np.array([row[j].strip() for row in body], dtype=str)
    return table


def _is_time(name: str) -> bool:
    """A clock's column (bounded by the step limit instead: a Unix time in ns is 1.7e18)."""
    low = name.strip().lower()
    return low in ("t", "t_s", "t_ns") or "time" in low or "stamp" in low


def landmark_labels(path: Path, cells: np.ndarray, column: str, fix: str) -> np.ndarray:
    """Each landmark id as one spelling, so that the files that name a landmark match: a whole number
    without its decimals (``4.0`` is landmark ``4``), another number as Python writes it, a name as
    written. An empty id is refused naming its row (counted with the header as row 1)."""
    out = []
    for i, cell in enumerate(cells):
        if not cell:
            raise LogFormatError(f"row {i + 2} has no value.", file=path, field=column, fix=fix)
        try:
            number = float(cell)
        except ValueError:
            out.append(str(cell))
            continue
        if not np.isfinite(number):
            out.append(str(cell))
        else:
            out.append(str(int(number)) if number.is_integer() else repr(number))
    return np.array(out, dtype=str)


MIN_OVERLAP = 0.5  # the share of a file's rows that must fall within the commands' span


def refuse_unordered(path: Path, t: np.ndarray, *, strict: bool) -> None:
    """Times must rise (``strict``) or never fall: a shuffled, reversed or doubled file is refused."""
    d = np.diff(t)
    bad = np.flatnonzero(d <= 0 if strict else d < 0)
    if bad.size:
        i = int(bad[0])
        raise LogFormatError(
            f"row {i + 3}: t_s = {t[i + 1]:g} after {t[i]:g}; times must "
            + ("rise from row to row." if strict else "never fall from row to row."),
            file=path,
            field="t_s",
            fix="sort the rows by time and drop repeated rows.",
        )


def refuse_apart(
    path: Path, t: np.ndarray, inside: np.ndarray, t0: float, t1: float, span: str = "the commands in actions.csv"
) -> None:
    """Refuse a file whose clock does not overlap ``span``'s (most rows outside it, ``t0`` to ``t1`` s):
    another clock's zero, another unit, or another log's file."""
    if t.size and inside.mean() < MIN_OVERLAP:
        raise LogFormatError(
            f"{np.count_nonzero(~inside)} of {t.size} rows fall outside the span of {span} ({t0:g} to {t1:g} s; "
            f"these run {np.min(t):g} to {np.max(t):g} s).",
            file=path,
            field="t_s",
            fix="write both on one clock, in seconds.",
        )


MAX_REPEATED = 0.05  # the share of rows that may repeat an earlier one exactly (sensors that read alike at once)


def refuse_repeated(path: Path, table: dict[str, np.ndarray]) -> None:
    """A file whose rows repeat earlier ones exactly, more than now and then, is a duplicated stream (a
    mirrored port, a file appended to itself): refused. A rare repeat is two records that read alike."""
    columns = list(table.values())
    seen: set[tuple[object, ...]] = set()
    repeats: list[int] = []
    for i, row in enumerate(zip(*columns, strict=True)):
        key = tuple("" if isinstance(x, float) and x != x else x for x in row)  # NaN never equals itself
        if key in seen:
            repeats.append(i)
        seen.add(key)
    n = len(columns[0]) if columns else 0
    if len(repeats) >= 2 and len(repeats) > MAX_REPEATED * n:
        raise LogFormatError(
            f"{len(repeats)} of {n} rows repeat an earlier row exactly (the first: row {repeats[0] + 2}).",
            file=path,
            field="t_s",
            fix="drop the repeated rows (a record is logged once).",
        )
