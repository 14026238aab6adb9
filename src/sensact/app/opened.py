"""What the log kinds whose readers refuse what they doubt share once opened (``app.log_kinds``): the path,
its name, and no notes or doubts to print before the fit."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True, eq=False)
class OpenedFolder:
    path: Path

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def notes(self) -> tuple[str, ...]:
        return ()

    def doubts(self) -> tuple[str, ...]:
        return ()  # the reader refuses what it doubts
