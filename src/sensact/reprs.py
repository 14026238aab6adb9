"""Short ``repr``s for result types (a few lines, never their arrays): what a result is and how good, as a
person at a Python prompt wants to see it. ``print(cal)`` should not scroll 100 kB of numbers past."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

MAX_CHARS = 600  # a result's repr at the most


def brief(value: Any, depth: int = 0) -> str:
    """One value in a few characters: an array as its shape, a record as its class, a long list as its length."""
    if isinstance(value, np.ndarray):
        return f"array{value.shape}"
    if isinstance(value, float | np.floating):
        return f"{float(value):.6g}"
    if isinstance(value, str):
        return repr(value if len(value) <= 60 else value[:57] + "...")
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return f"{type(value).__name__}(...)" if depth else compact_repr(value, depth + 1)
    if isinstance(value, list | tuple):
        if len(value) > 4 or depth:
            return f"[{len(value)} items]"
        return "[" + ", ".join(brief(v, depth + 1) for v in value) + "]"
    if isinstance(value, dict):
        return f"{{{len(value)} keys}}"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def compact_repr(obj: Any, depth: int = 0) -> str:
    """``Class(field=value, ...)`` of a dataclass, each value ``brief``, the whole at most ``MAX_CHARS``."""
    parts = [f"{f.name}={brief(getattr(obj, f.name), depth + 1)}" for f in dataclasses.fields(obj) if f.repr]
    text = f"{type(obj).__name__}({', '.join(parts)})"
    return text if len(text) <= MAX_CHARS else text[: MAX_CHARS - 4] + "...)"
