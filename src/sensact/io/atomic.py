"""Atomic writes: a temporary file in the same folder, then ``os.replace``, so an interrupted run never
leaves a half-written model or result."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np


def _process_umask() -> int:
    mask = os.umask(0)  # reading the umask means setting it; put it straight back
    os.umask(mask)
    return mask


# mkstemp makes its file private (0600); a written result gets the mode any new file of the user's gets
_FILE_MODE = 0o666 & ~_process_umask()


def _atomic(path: str | Path, mode: str, write: Callable[[IO[Any]], None]) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, mode) as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_stream(path: str | Path, write: Callable[[IO[Any]], None]) -> Path:
    """Write a large binary file in pieces (``write(handle)``), atomically."""
    return _atomic(path, "wb", write)


def write_text(path: str | Path, text: str) -> Path:
    return _atomic(path, "w", lambda h: h.write(text))


def write_bytes(path: str | Path, data: bytes) -> Path:
    return _atomic(path, "wb", lambda h: h.write(data))


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")


def write_json(path: str | Path, data: Any) -> Path:
    """Pretty JSON; non-finite floats are written as null so that every JSON reader accepts the file."""
    text = json.dumps(_finite_or_null(data), indent=2, default=_jsonable, allow_nan=False)
    return write_text(path, text + "\n")


def _finite_or_null(obj: Any) -> Any:
    if isinstance(obj, float | np.floating):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite_or_null(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _finite_or_null(obj.tolist())
    return obj


def write_npz(path: str | Path, **arrays: np.ndarray) -> Path:
    """Compressed ``.npz`` of plain numeric arrays; readers must use ``allow_pickle=False``."""
    for name, arr in arrays.items():
        if np.asarray(arr).dtype == object:
            raise TypeError(f"array {name!r} has dtype object; only numeric arrays are written")
    return _atomic(path, "wb", lambda h: np.savez_compressed(h, **arrays))
