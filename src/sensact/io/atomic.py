"""Atomic writes: a temporary file in the same folder, then ``os.replace``, so an interrupted run never
leaves a half-written model or result."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np

from sensact.records import to_json


def _process_umask() -> int:
    mask = os.umask(0)  # reading the umask means setting it; put it straight back
    os.umask(mask)
    return mask


# mkstemp makes its file private (0600); a written result gets the mode any new file of the user's gets
_FILE_MODE = 0o666 & ~_process_umask()


def _atomic(path: str | Path, mode: str, write: Callable[[IO[Any]], None], kind: str) -> Path:
    path = Path(path)
    if path.exists() and not path.is_file():  # the rename would replace a folder's name or a device (/dev/full)
        from sensact.errors import SensactError

        raise SensactError(
            "is not a regular file (a folder, a device or a pipe), and writing here would replace it.",
            file=path,
            fix="give the path of a regular file, or a new one.",
        )
    _claim(path, kind)
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


_claims: dict[Path, str] | None = None  # path -> the first writer's kind, while a command runs (one_run)


@contextmanager
def one_run() -> Iterator[None]:
    """While a command runs: a file it wrote may be written again by the same kind of writer (a model
    rewritten with its error bars), never by another (its figure over the model)."""
    global _claims
    outer, _claims = _claims, {}
    try:
        yield
    finally:
        _claims = outer


def _claim(path: Path, kind: str) -> None:
    if _claims is None:
        return
    key = path.resolve()
    first = _claims.setdefault(key, kind)
    if first != kind:
        from sensact.errors import SensactError

        raise SensactError(
            "this command wrote another of its outputs here already, and this one would overwrite it.",
            file=path,
            fix="give each output its own path (a model's --out ends in .json).",
        )


def write_stream(path: str | Path, write: Callable[[IO[Any]], None]) -> Path:
    """Write a large binary file in pieces (``write(handle)``), atomically."""
    return _atomic(path, "wb", write, "stream")


def write_text(path: str | Path, text: str, kind: str = "text") -> Path:
    return _atomic(path, "w", lambda h: h.write(text), kind)


def write_bytes(path: str | Path, data: bytes) -> Path:
    return _atomic(path, "wb", lambda h: h.write(data), "bytes")


def _jsonable(obj: Any) -> Any:
    """What ``json`` cannot write itself: numpy values, paths and records (``records.to_json``), and what names
    itself in JSON (a geometry, by its name)."""
    out = to_json(obj)
    if out is not obj:
        return out
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")


def write_json(path: str | Path, data: Any) -> Path:
    """Pretty JSON; non-finite floats are written as null so that every JSON reader accepts the file."""
    text = json.dumps(_finite_or_null(data), indent=2, default=_jsonable, allow_nan=False)
    return write_text(path, text + "\n", "json")


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
    return _atomic(path, "wb", lambda h: np.savez_compressed(h, **arrays), "npz")


@contextmanager
def nothing_half_written(folder: str | Path) -> Iterator[Path]:
    """A block that writes several files into ``folder``: if it fails (or is interrupted), what it added is
    removed (the folder itself when it made it), and what was there before is left as it was (each file is
    replaced atomically, so it is either the old one or the new)."""
    folder = Path(folder)
    before = {p for p in folder.rglob("*")} if folder.exists() else None
    try:
        yield folder
    except BaseException:
        if before is None:
            import shutil

            shutil.rmtree(folder, ignore_errors=True)
        elif folder.is_dir():
            for p in sorted(folder.rglob("*"), key=lambda q: len(q.parts), reverse=True):  # the deepest first
                if p in before:
                    continue
                if p.is_dir() and not p.is_symlink():
                    p.rmdir()
                else:
                    p.unlink(missing_ok=True)
        raise
