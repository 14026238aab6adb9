"""What the log kinds whose readers refuse what they doubt share once opened (``app.log_kinds``): the path,
its name, and no notes or doubts to print before the fit; and what those whose fit takes seconds (one
maximum-likelihood fit, no EM) share once fitted (``FittedInSeconds``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, Generic, Protocol, TypeVar

import numpy as np

from sensact.health import Health


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


class _Fit(Protocol):
    @property
    def params(self) -> np.ndarray: ...

    @property
    def sd(self) -> np.ndarray: ...


class _Result(Protocol):
    @property
    def fit(self) -> _Fit: ...


LogT = TypeVar("LogT")
ResultT = TypeVar("ResultT", bound=_Result)


@dataclass(frozen=True, eq=False)
class FittedInSeconds(Generic[LogT, ResultT]):
    """A calibration of seconds: the log, the learner's result (its ``fit``'s ``params`` and ``sd`` in
    ``PARAMETERS``' order), its health and the time it took."""

    PARAMETERS: ClassVar[tuple[str, ...]]
    log: LogT
    result: ResultT
    health: Health
    seconds: float

    @property
    def interrupted(self) -> bool:
        return False  # a fit of seconds: Ctrl-C ends the command

    @property
    def params(self) -> dict[str, float]:
        return dict(zip(self.PARAMETERS, map(float, self.result.fit.params), strict=True))

    @property
    def sds(self) -> dict[str, float]:
        return dict(zip(self.PARAMETERS, map(float, self.result.fit.sd), strict=True))
