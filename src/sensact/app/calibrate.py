"""``calibrate(log, preset or config) -> its calibration``: what `sensact learn em DIR` does, callable from
Python, for every kind of log: the learner of the kind that opened ``log`` (``log_kinds``) runs on it, EM on
a landmark log (``em.calibrate_em``), the wheels-and-lidar fit on a lidar2d log (``lidar2d``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sensact.app.em import FitEvents
from sensact.app.log_kinds import CalibratedAny, learner, refuse_options


def calibrate(
    log: Any,
    preset: str | None = None,
    config: Any = None,
    *,
    sets: Sequence[str] = (),
    start_from: Path | None = None,
    events: FitEvents | None = None,
) -> CalibratedAny:
    """``log``'s models learned by its kind's learner, as `sensact learn em` learns them. Settings (``preset``,
    a settings YAML or an ``EMConfig`` as ``config``, ``sets``) and ``start_from`` (a learned model.json to
    start from) are EM's; a kind that takes none refuses them in one line. ``events`` hears of the work."""
    refuse_options(log, {"--preset": preset, "--config": config, "--set": tuple(sets), "--start-from": start_from})
    return learner(log)(log, preset, config, sets=sets, start_from=start_from, events=events)
