"""The one progress event of the whole library: ``progress(description, done, total)``, ``total`` None when
not known. A long computation takes one as an optional callback; the CLI passes a rich progress bar with an
ETA, a library user passes nothing (or their own)."""

from __future__ import annotations

from collections.abc import Callable

Progress = Callable[[str, int, "int | None"], None]
