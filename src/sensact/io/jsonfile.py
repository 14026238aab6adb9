"""Reading a JSON file that must hold one object (a log's meta.json, a learned model.json), with the
one-line errors of ``sensact.errors``: not found, not JSON, not an object."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from sensact.errors import SensactError


def read_json_object(path: str | Path, error: type[SensactError], fix: str, missing_fix: str | None = None) -> dict:
    """The object in ``path``; ``error`` is raised with ``fix`` (``missing_fix`` when the file is absent)."""
    path = Path(path)
    if not path.is_file():
        raise error(f"{path.name} not found.", file=path, fix=missing_fix or fix)
    try:
        doc: Any = json.loads(path.read_text(encoding="utf-8-sig"))  # a hand-written file may start with a BOM
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        where = f" (line {exc.lineno})" if isinstance(exc, json.JSONDecodeError) else ""
        raise error(f"not valid JSON{where}.", file=path, fix=fix) from None
    if not isinstance(doc, dict):
        raise error(f"not a JSON object (it holds a {type(doc).__name__}).", file=path, fix=fix)
    return doc
