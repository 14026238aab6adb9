"""The error hierarchy: every bad input becomes one line naming the file, the field and the fix.

The CLI prints ``str(error)`` and exits non-zero; it shows a traceback only with ``--debug``. Its exit
codes (docs/cli-reference.md) are the constants below.
"""

from __future__ import annotations

from os import PathLike

EXIT_OK = 0
EXIT_BAD_INPUT = 2  # a SensactError: the file, the field and the fix on one line
EXIT_FLAGGED = 3  # the result is written, but flagged: it did not converge, or it is degenerate (``health``)
EXIT_INTERNAL = 70  # an unexpected exception (BSD's EX_SOFTWARE): one line, and --debug for the traceback
EXIT_INTERRUPTED = 130  # Ctrl-C or SIGTERM; what was finished is on disk, whole


class SensactError(Exception):
    """Base class. ``str()`` is a single line: ``<file>: <field>: <problem> Fix: <fix>``."""

    def __init__(
        self,
        problem: str,
        *,
        file: str | PathLike[str] | None = None,
        field: str | None = None,
        fix: str | None = None,
    ) -> None:
        self.problem = problem
        self.file = None if file is None else str(file)
        self.field = field
        self.fix = fix
        super().__init__(self._line())

    def _line(self) -> str:
        parts = [p for p in (self.file, self.field) if p]
        head = ": ".join(parts)
        text = f"{head}: {self.problem}" if head else self.problem
        if self.fix:
            text = f"{text} Fix: {self.fix}"
        return " ".join(text.split())


class ConfigError(SensactError, ValueError):
    """A configuration field, YAML file or ``--set`` override is invalid, or does not suit the log it is
    used on. Also a ``ValueError``, which is what a library caller expects from a bad argument."""


class LogFormatError(SensactError):
    """A log file is missing, truncated, or has a bad column or value."""


class ModelFormatError(SensactError):
    """A model JSON file does not describe a model of the expected kind."""
