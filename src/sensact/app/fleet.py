"""One log of a fleet calibrated as a job of an engine (``sensact.engine``, issue 76): what `sensact learn
em LOG --out OUT` does, where a worker runs it, with what the fleet's summary keeps of it returned."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sensact.engine import Progress
from sensact.health import Health
from sensact.reprs import compact_repr


@dataclass(frozen=True)
class LearnOptions:
    """What `learn em` is given besides the log; every log of the fleet gets the same."""

    preset: str | None = None
    config: Path | None = None  # a settings YAML (where each worker can read it)
    sets: tuple[str, ...] = ()
    report: bool = True  # report.html beside each model
    uncertainty: int | None = None  # `--uncertainty B`: the bootstrap's replicates, run in the log's own job


@dataclass(frozen=True)
class Learned:
    """A log calibrated: where its model is and how EM ended (the model's JSON has the rest)."""

    __repr__ = compact_repr  # a line, never the arrays

    log: str
    model: str  # its model.json
    stop_reason: str
    iterations: int
    loglik_best: float
    n_used: int
    seconds: float  # EM's own time
    warnings: tuple[str, ...]  # the diagnostics' lines (``Diagnostics.warnings``)
    written: tuple[str, ...]
    health: Health = field(default_factory=Health)  # learn/em/health.py: flagged fits end the fleet with 3

    def to_dict(self) -> dict[str, Any]:
        return {
            "status": "learned",
            "log": self.log,
            "model": self.model,
            "stop_reason": self.stop_reason,
            "iterations": self.iterations,
            "loglik_best": self.loglik_best,
            "n_used": self.n_used,
            "seconds": self.seconds,
            "warnings": list(self.warnings),
            "written": list(self.written),
            "health": self.health.to_dict(),
        }


def learn_log(log: Path, out: Path, options: LearnOptions, *, progress: Progress | None = None) -> Learned:
    """``log`` calibrated and written at ``out`` exactly as `sensact learn em LOG --out OUT` writes it (with
    ``options.uncertainty``, as `learn em --uncertainty B` does: its replicates one after another here)."""
    from sensact.app.calibrate import FitEvents, calibrate
    from sensact.app.logs import open_log
    from sensact.app.save import save_calibration

    events = FitEvents()
    if progress is not None:
        show = progress
        events = FitEvents(
            progress=lambda it, ll, best, since: show(f"EM: log-likelihood {ll:.1f} (best {best:.1f})", it + 1, None),
            on_race=lambda done, planned: show("start race: EM from each start", done, planned),
            placing=show,
        )
    cal = calibrate(open_log(log), options.preset, options.config, sets=options.sets, events=events)
    out.parent.mkdir(parents=True, exist_ok=True)
    saved = save_calibration(cal, out, report=options.report)
    if options.uncertainty is not None:  # after the model is written, as `learn em --uncertainty` does
        from sensact.app.uncertainty import bootstrap

        done = [0]

        def replicated(i: int, outcome: Any) -> None:
            done[0] += 1
            if progress is not None:
                progress("bootstrap: replicates learned", done[0], options.uncertainty)

        cal = bootstrap(cal, options.uncertainty, on_done=replicated)
        saved = save_calibration(cal, out, report=options.report)
    res = cal.result
    return Learned(
        log=str(log),
        model=str(out),
        stop_reason=res.stop_reason,
        iterations=res.iterations,
        loglik_best=res.loglik_best,
        n_used=res.n_used,
        seconds=res.seconds,
        warnings=cal.diagnostics.warnings,
        written=tuple(str(p) for p in saved.written),
        health=cal.diagnostics.health,
    )
