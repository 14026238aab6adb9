"""Typed records across layers, JSON only at the edge (typed results, docs/design.md).

What a fit, a search or a score reports travels between packages as a frozen dataclass; ``to_json`` is the
one writer that turns any of them (nested, in lists and tuples, with numpy values) into the JSON object a
file holds, its keys the fields' names in their order. A field whose ``metadata`` has ``omit=value`` is
left out of the JSON when it equals that value (a key that appears only when it says something).

``JsonObject`` names what is read from or written to a JSON file, and nothing else: a document whose
keys a user or a script reads, not a record passed between packages.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

JsonObject = dict[str, Any]
_NO_OMIT = object()


def omit_when(value: Any, **kwargs: Any) -> Any:
    """A dataclass field left out of ``to_json``'s object when it equals ``value``."""
    return dataclasses.field(metadata={"omit": value}, **kwargs)


def to_json(value: Any) -> Any:
    """``value`` as JSON data: dataclasses as objects of their fields, tuples as lists, numpy as numbers, and
    anything with a ``json_value()`` as that (a geometry names itself)."""
    named = getattr(value, "json_value", None)
    if callable(named) and not isinstance(value, type):
        return named()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        if hasattr(value, "to_dict"):
            return value.to_dict()
        out = {}
        for f in dataclasses.fields(value):
            v = getattr(value, f.name)
            omit = f.metadata.get("omit", _NO_OMIT)
            if omit is not _NO_OMIT and (v is omit or v == omit):
                continue
            out[f.name] = to_json(v)
        return out
    if isinstance(value, dict):
        return {k: to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return value
