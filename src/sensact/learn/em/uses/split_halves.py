"""The log's two halves, each learned on from the whole log's model: how closely the log pins its model
down, with no ground truth (beyond the thesis; only when asked, `learn em --halves`).

A model learned without ground truth can still be checked against the log itself. Each half of the run
is learned by EM from the whole log's model (``warm_start.start_from_model``: placed on the half by the
E-step, nothing held), and the halves' models are compared with each other and with the whole's
(``evaluate/halves.py``). Parameters the log pins down come out alike from both halves; one that differs
from half to half is set by little of the log, or changed during it (a floor, a battery, a knock to the
camera).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig
from sensact.learn.em.fit import EMResult, fit_em
from sensact.learn.em.uses.place import Localized
from sensact.learn.em.uses.warm_start import start_from_model
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.progress import Progress
from sensact.reprs import compact_repr

HALF_NAMES = ("first half", "second half")


@dataclass(frozen=True)
class HalfFit:
    __repr__ = compact_repr  # a line, never the arrays
    name: str  # "first half" or "second half"
    steps: tuple[int, int]  # the log's steps start:stop
    data: LandmarkLog
    placed: Localized  # where the whole log's model put the robot at the half's start
    result: EMResult


def half_steps(n_steps: int) -> list[tuple[int, int]]:
    """The steps of each half: ``[0, n // 2)`` and ``[n // 2, n)``."""
    mid = n_steps // 2
    return [(0, mid), (mid, n_steps)]


def learn_halves(
    model: EMModel,
    data: LandmarkLog,
    config: EMConfig,
    *,
    progress: Progress | None = None,
    on_iteration: Callable[[str, int, float, float, int], Any] | None = None,
) -> list[HalfFit]:
    """Each half of ``data`` learned by EM from ``model`` (the whole log's), with ``config``'s settings.
    ``on_iteration(half, iteration, loglik, best, since)`` follows each fit. A half without a sighting
    cannot be learned and is refused, naming it."""
    fits = []
    for name, (a, b) in zip(HALF_NAMES, half_steps(data.n_steps), strict=True):
        part = data.slice_steps(a, b)
        if part.n_observations == 0:
            raise ConfigError(
                f"{data.source}: the {name} (steps {a}:{b}) has no sighting to learn from.",
                field="--halves",
                fix="check the halves on a log with sightings throughout, or leave --halves out.",
            )
        placed, cfg = start_from_model(model, part, config, progress, source="the whole log's model")
        res = fit_em(
            part,
            placed.model,
            cfg,
            on_iteration=None
            if on_iteration is None
            else lambda it, ll, best, since, n=name: on_iteration(n, it, ll, best, since),
        )
        fits.append(HalfFit(name, (a, b), part, placed, res))
    return fits
