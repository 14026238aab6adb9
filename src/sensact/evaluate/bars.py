"""The bars a result must clear, each checked and said in words: what is measured, the bar, our value and
whether it clears. The experiments build them from the numbers in their own JSON (the thesis's result
tables, as the issues state them); the JSON keeps them as ``scorecard``, so that a results folder says in
one place what was cleared and what was missed, and the report and the command print the same words."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from typing import Any


@dataclasses.dataclass(frozen=True)
class BarCheck:
    """One bar. ``cleared`` is None when the quantity could not be scored on this run (``ours`` says why)."""

    key: str  # stable name within the experiment, e.g. "linear.sensor_rms_mm"
    quantity: str  # "A0 = linear: sensor RMS"
    bar: str  # "≤ 70.4 mm"
    ours: str  # "35.7 mm"
    cleared: bool | None

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> BarCheck:
        return cls(**{f.name: d[f.name] for f in dataclasses.fields(cls)})


def _num(x: float, digits: int) -> str:
    return f"{x:.{digits}f}" if math.isfinite(x) else "not measured"


def _value(x: float | None) -> float:
    return float("nan") if x is None else float(x)


def at_most(key: str, quantity: str, value: float, limit: float, unit: str = "", digits: int = 2) -> BarCheck:
    """``value <= limit``; a value that is NaN (not measured) misses."""
    u, v = (f" {unit}" if unit else ""), _value(value)
    return BarCheck(key, quantity, f"≤ {limit:.{digits}f}{u}", f"{_num(v, digits)}{u}", bool(v <= limit))


def within_factor(key: str, quantity: str, ratio: float, factor: float, digits: int = 2) -> BarCheck:
    """``1/factor <= ratio <= factor`` (a learned value against the truth's, as their ratio)."""
    r = _value(ratio)
    return BarCheck(
        key,
        quantity,
        f"{1 / factor:.{digits}f} to {factor:.{digits}f}",
        _num(r, digits),
        bool(1 / factor <= r <= factor),
    )


def not_scored(key: str, quantity: str, bar: str, why: str) -> BarCheck:
    return BarCheck(key, quantity, bar, f"not scored: {why}", None)


def checks_from_json(rows: Iterable[dict[str, Any]]) -> list[BarCheck]:
    return [BarCheck.from_dict(r) for r in rows]


def counts(checks: Sequence[BarCheck]) -> tuple[int, int]:
    """(cleared, scored): checks that could not be scored count in neither."""
    scored = [c for c in checks if c.cleared is not None]
    return sum(bool(c.cleared) for c in scored), len(scored)


def miss_text(c: BarCheck) -> str:
    return f"{c.quantity} {c.ours} (bar {c.bar})"


def verdict_line(checks: Sequence[BarCheck]) -> str:
    """ "bars: 11 of 12 cleared; missed: robot1: bearing sigma / truth's 0.56 (bar 0.67 to 1.50)"."""
    done, scored = counts(checks)
    line = f"bars: {done} of {scored} cleared"
    missed = [miss_text(c) for c in checks if c.cleared is False]
    if missed:
        line += "; missed: " + "; ".join(missed)
    unscored = sum(c.cleared is None for c in checks)
    if unscored:
        line += f"; {unscored} not scored on this run"
    return line
