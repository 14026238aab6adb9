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
        # a hand-written file may start with a BOM; NaN and Infinity are not JSON (Python's json reads them)
        doc: Any = json.loads(path.read_text(encoding="utf-8-sig"), parse_constant=_not_json)
    except _NonFinite as exc:
        raise error(f"{exc} is not a JSON number (a missing value is null).", file=path, fix=fix) from None
    except RecursionError:
        raise error("nested too deeply to be a sensact file.", file=path, fix=fix) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        where = f" (line {exc.lineno})" if isinstance(exc, json.JSONDecodeError) else ""
        raise error(f"not valid JSON{where}.", file=path, fix=fix) from None
    if not isinstance(doc, dict):
        raise error(f"not a JSON object (it holds a {type(doc).__name__}).", file=path, fix=fix)
    return doc


class _NonFinite(ValueError):
    pass


def _not_json(name: str) -> Any:
    raise _NonFinite(name)
