"""`learn em --uncertainty B`: a calibration's error bars by the parametric bootstrap
(``learn.em.uncertainty``), each replicate a job of an engine (``sensact.engine``)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from sensact.app.calibrate import Calibration
from sensact.engine import Engine, Failed, InProcess, Job, OnDone, OnProgress
from sensact.errors import ConfigError
from sensact.learn.em.uses.error_bars import Uncertainty, f_distances, replicate, summarize


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
    if res.posteriors is None:
        raise ConfigError(
            f"EM stopped {res.stop_reason} without a smoothed path, so there is no fit to draw replicates from.",
            field="--uncertainty",
            fix="let EM run to convergence first (see the lines above), then ask for error bars.",
        )
    f_at = tuple(float(d) for d in f_distances(res.model, data, res.posteriors.mean_gamma))
    start = None if cal.start_from is None else cal.start_from.placed.model  # each replicate starts as the fit did
    jobs = [
        Job(replicate, (res.model, data, cal.config, seed + b, f_at, start), f"replicate-{seed + b}")
        for b in range(replicates)
    ]
    draws: list[Any] = (engine or InProcess()).run(jobs, isolate=True, on_progress=on_progress, on_done=on_done)
    lines = [d.error if isinstance(d, Failed) else d for d in draws]
    return replace(cal, uncertainty=summarize(res.model, lines, f_at, seed))


__all__ = ["Uncertainty", "bootstrap"]
