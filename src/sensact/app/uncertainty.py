"""`learn em --uncertainty information|B`: a calibration's error bars from the likelihood's curvature and
profiles (``learn.em.uses.information``, no refits), or by the parametric bootstrap
(``learn.em.uses.error_bars``), each replicate a job of an engine (``sensact.engine``)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from sensact.app.em import Calibration
from sensact.engine import Engine, Failed, InProcess, Job, OnDone, OnProgress
from sensact.errors import ConfigError
from sensact.learn.em.uses.error_bars import Uncertainty, f_distances, replicate, summarize

INFORMATION = "information"


@dataclass(frozen=True)
class ErrorBars:
    """What `--uncertainty` asked for: ``replicates`` None is the observed information (and profiles), a
    count is a parametric bootstrap of that many replicates."""

    replicates: int | None = None

    @classmethod
    def parse(cls, text: str) -> ErrorBars:
        """``information`` or a replicate count; anything else refused in one line."""
        if text.strip().lower() == INFORMATION:
            return cls(None)
        try:
            replicates = int(text)
        except ValueError:
            raise ConfigError(
                f"--uncertainty {text!r} is neither 'information' nor a number of bootstrap replicates.",
                field="--uncertainty",
                fix="give --uncertainty information (no refits), or --uncertainty 20 for a 20-replicate bootstrap.",
            ) from None
        refuse_replicates(replicates)
        return cls(replicates)


def refuse_replicates(replicates: int) -> None:
    """``--uncertainty B`` checked before any work: at least 2 replicates, at most ``limits.MAX_TRIALS``."""
    from sensact.limits import MAX_TRIALS

    if replicates < 2:
        raise ConfigError(
            f"--uncertainty {replicates}: a standard error needs at least 2 replicates.",
            field="--uncertainty",
            fix="give 20 or more (each replicate is a fit as long as the first).",
        )
    if replicates > MAX_TRIALS:
        raise ConfigError(
            f"--uncertainty {replicates:,} is over the limit of {MAX_TRIALS:,} replicates, each a fit as long as the "
            "first.",
            field="--uncertainty",
            fix="give 20 to 200 (SENSACT_MAX_TRIALS raises the limit).",
        )


def _fitted(cal: Calibration) -> tuple[float, ...]:
    """The distances f is read at; a fit without a smoothed path is refused in one line."""
    res, data = cal.result, cal.log.data
    if res.posteriors is None:
        raise ConfigError(
            f"EM stopped {res.stop_reason} without a smoothed path, so there is no fit to give error bars to.",
            field="--uncertainty",
            fix="let EM run to convergence first (see the lines above), then ask for error bars.",
        )
    return tuple(float(d) for d in f_distances(res.model, data, res.posteriors.mean_gamma))


def information(cal: Calibration) -> Calibration:
    """``cal`` with its ``uncertainty`` from the observed information and the variances' profiles."""
    from sensact.learn.em.uses.information import information_intervals

    f_at = _fitted(cal)
    mount = cal.result.mount
    return replace(
        cal,
        uncertainty=information_intervals(cal.result.model, cal.log.data, f_at, None if mount is None else mount.free),
    )


def error_bars(cal: Calibration, asked: ErrorBars, engine: Engine | None = None, **kwargs: Any) -> Calibration:
    """``cal`` with the error bars ``asked`` for (a bootstrap's replicates on ``engine``)."""
    if asked.replicates is None:
        return information(cal)
    return bootstrap(cal, asked.replicates, engine, **kwargs)


def bootstrap(
    cal: Calibration,
    replicates: int,
    engine: Engine | None = None,
    *,
    seed: int = 0,
    on_progress: OnProgress | None = None,
    on_done: OnDone | None = None,
) -> Calibration:
    """``cal`` with its ``uncertainty``: ``replicates`` logs drawn from its model (replicate b with seed
    ``seed + b``), each learned again as the log was, on ``engine`` (here, one after another, by default)."""
    refuse_replicates(replicates)
    res, data = cal.result, cal.log.data
    f_at = _fitted(cal)
    start = None if cal.start_from is None else cal.start_from.placed.model  # each replicate starts as the fit did
    jobs = [
        Job(replicate, (res.model, data, cal.config, seed + b, f_at, start), f"replicate-{seed + b}")
        for b in range(replicates)
    ]
    draws: list[Any] = (engine or InProcess()).run(jobs, isolate=True, on_progress=on_progress, on_done=on_done)
    lines = [d.error if isinstance(d, Failed) else d for d in draws]
    return replace(cal, uncertainty=summarize(res.model, lines, f_at, seed))


__all__ = ["ErrorBars", "Uncertainty", "bootstrap", "error_bars", "information"]
