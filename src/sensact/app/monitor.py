"""`sensact monitor` as a function: a learned model's change test on a log, and relearning from the change."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sensact.app.em import Calibration, FitEvents, calibrate_em
from sensact.app.logs import OpenedLandmarkLog, learned_settings, read_model_and_log
from sensact.health import Health, filter_failed, learned_health
from sensact.learn.em.uses.change_detect import MonitorConfig, MonitorResult, monitor_placed
from sensact.learn.em.uses.place import learned_config
from sensact.models.em_model import EMModel
from sensact.records import JsonObject
from sensact.reprs import compact_repr


@dataclass(frozen=True, eq=False)
class Monitored:
    __repr__ = compact_repr  # a line, never the arrays
    log: OpenedLandmarkLog
    model_path: Path
    model_doc: JsonObject
    model: EMModel  # placed on the log (its prior_mean: where the robot started)
    result: MonitorResult
    seconds: float

    @property
    def health(self) -> Health:
        """The model's own flags when it was learned, and a filter that failed here."""
        return Health.of(*learned_health(self.model_doc).flags, filter_failed(self.result.filter_ok, "the change test"))

    def to_json(self) -> JsonObject:
        """monitor.json: ``changed``; ``change`` (``stream``, ``model``: "action" or "sensor", ``alarm_s``,
        ``change_s``, ``delay_s``, ``direction``, ``persists_sigma``) or null; every stream's test."""
        res = self.result
        change = res.change_dict()
        return {
            "health": self.health.to_dict(),
            "log": str(self.log.path),
            "model": str(self.model_path),
            "start": self.model.prior_mean.tolist(),
            "changed": change is not None,
            "change": change,
            "streams": [s.to_dict() for s in res.streams],
            "duration_s": res.duration_s,
            "filter_ok": res.filter_ok,
            "config": {k: getattr(res.config, k) for k in res.config.__dataclass_fields__},
            "seconds": self.seconds,
        }


def monitor_log(log: Path, model: Path, config: MonitorConfig | None = None, *, bins: int = 21) -> Monitored:
    """``model`` (a model.json of `learn em`) over ``log``: has the robot changed since it was learned?"""
    from sensact.app.log_kinds import refuse_other_kinds

    refuse_other_kinds(log, "monitor")
    doc, m, opened = read_model_and_log(log, model, bins, use="run")
    t0 = time.perf_counter()
    settings = learned_config((doc.get("summary") or {}).get("config"), str(model))
    placed, res = monitor_placed(m, opened.data, settings, config)
    return Monitored(opened, model, doc, placed, res, time.perf_counter() - t0)


def after_step(log: OpenedLandmarkLog, step: int) -> OpenedLandmarkLog:
    """The log from ``step`` on, its truth too, as a log of its own."""
    data = log.data.slice_steps(step, log.data.n_steps)
    folder = log.folder
    if folder is not None:
        gt = folder.groundtruth
        cut = None if gt is None else {k: np.asarray(v)[step:] for k, v in gt.items()}
        folder = replace(folder, data=data, groundtruth=cut)
    rec = None if log.recorded_distance_mm is None else log.recorded_distance_mm[step:]
    return replace(log, data=data, folder=folder, recorded_distance_mm=rec)


def relearn(mon: Monitored, events: FitEvents | None = None) -> Calibration | None:
    """EM again on the log from the change on, with the settings the model was learned with (its JSON's
    ``summary.config``; the log's own when it has none). None when nothing changed."""
    step = mon.result.change_step()
    if step is None:
        return None
    part = after_step(mon.log, step)
    settings = learned_settings(mon.model_doc, str(mon.model_path))
    return calibrate_em(part, config=settings, events=events)
