"""Has the robot changed? The learned model's filter over a new log, its innovations into a change test.

Sec. 4.4.3 relearns after the robot's motors degrade; it does not say when to. Here the EKF of sec. 2.4
runs with the learned model over a new log (``innovations``) and each reading's standardized innovation
becomes a score, N(0, 1) while the model holds: through the model's own predictive distribution (the
probability integral transform, so a Student-t channel's heavy tails stay in the model), clipped at
``clip`` so that a handful of gross misreadings cannot make a change. The scores feed one stream per

* **sensor channel** (each reading channel, and the bearing): its score. A changed sensor shifts it.
* **action component** (each velocity of the action model): the scores weighted by their sensitivity to a
  gain on that velocity, carried through the filter (``innovations``: a slower robot leaves the
  filter's predictions ahead of its sightings, in a pattern the sensitivity predicts); a sign flip turns
  them into one score whose mean moves when that velocity changes (the locally most powerful score).

``core/changepoint.py`` turns each stream into a sequential test (binned, scaled by its long-run spread,
two-sided CUSUM, persistence to the end of the log). The change is the first confirmed crossing of any
stream; its stream says which model changed.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from sensact.core.changepoint import (
    binned,
    confirm_quantile,
    cusum_crossings,
    cusum_path,
    cusum_threshold,
    long_run_scale,
)
from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig
from sensact.learn.em.estep import innovations
from sensact.learn.em.uses.consistency import normal_scores
from sensact.learn.em.uses.place import localize
from sensact.limits import steps_problem
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel


@dataclass(frozen=True)
class MonitorConfig:
    """The change test's settings; every field has the default the docs (monitor.md) measured with."""

    false_alarm: float = 0.01  # probability of any alarm on a log where nothing changed (all streams)
    bin_s: float = 1.0  # the scores are summed over bins of this many seconds
    batch_s: float = 30.0  # the long-run spread is read from sums over this many seconds
    reference: float = 0.5  # CUSUM's k, in bin standard deviations: half the shift it is quickest to find
    clip: float = 3.0  # a score's largest magnitude (a robust CUSUM)

    def __post_init__(self) -> None:
        bad = self.problems()
        if bad:
            raise ValueError("; ".join(bad))

    def problems(self) -> list[str]:
        out = []
        if not 0.0 < self.false_alarm < 1.0:
            out.append("false_alarm must be between 0 and 1")
        if not self.bin_s > 0.0:
            out.append("bin_s must be > 0")
        if not self.batch_s >= self.bin_s:
            out.append("batch_s must be at least bin_s")
        if not self.reference > 0.0:
            out.append("reference must be > 0")
        if not self.clip > 0.0:
            out.append("clip must be > 0")
        return out


@dataclass(frozen=True)
class Event:
    """A CUSUM crossing on one stream: when it crossed, where its shift began, which way, and how far the
    bins from there to the end of the log still sit off zero (standard deviations of their mean)."""

    alarm_s: float
    change_s: float
    direction: int  # +1: the scores rose; for an action stream, the robot is slower than the model says
    persists_sigma: float

    def to_dict(self) -> dict[str, float | int]:
        return {
            "alarm_s": self.alarm_s,
            "change_s": self.change_s,
            "direction": self.direction,
            "persists_sigma": self.persists_sigma,
        }


@dataclass(frozen=True, eq=False)
class Stream:
    name: str  # "action:v_y_mm_s", "sensor:range_mm", "sensor:bearing"
    model: str  # "action" or "sensor"
    scale: float  # the bins' long-run standard deviation
    threshold: float  # CUSUM's h, in scaled bins
    change: Event | None
    episodes: tuple[Event, ...]
    bins: np.ndarray = field(repr=False)  # scaled bin scores, NaN where none
    statistic: np.ndarray = field(repr=False)  # the CUSUM over the whole log (no restarts), for figures

    def to_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "model": self.model,
            "scale": self.scale,
            "threshold": self.threshold,
            "max_statistic": float(np.max(self.statistic)) if self.statistic.size else 0.0,
            "change": None if self.change is None else self.change.to_dict(),
            "episodes": [e.to_dict() for e in self.episodes],
        }


@dataclass(frozen=True, eq=False)
class MonitorResult:
    streams: tuple[Stream, ...]
    config: MonitorConfig
    duration_s: float
    dt_s: float
    filter_ok: bool

    @property
    def change(self) -> tuple[Stream, Event] | None:
        """The change, if any stream confirmed one: put down to the stream whose shift persists most
        strongly (a slower robot moves the sensor's innovations too, but far less than its action's),
        flagged at the earliest confirmed alarm of any stream, begun at the earliest change point."""
        found = [(s, s.change) for s in self.streams if s.change is not None]
        if not found:
            return None
        stream, strongest = max(found, key=lambda se: se[1].persists_sigma)
        alarm = min(e.alarm_s for _, e in found)
        began = min(e.change_s for _, e in found)
        return stream, replace(strongest, alarm_s=alarm, change_s=min(began, alarm))

    def change_dict(self) -> dict[str, object] | None:
        """The change as monitor.json's ``change`` holds it (``stream``, ``model``, the event, ``delay_s``)."""
        found = self.change
        if found is None:
            return None
        s, e = found
        return {"stream": s.name, "model": s.model, **e.to_dict(), "delay_s": e.alarm_s - e.change_s}

    def change_step(self) -> int | None:
        """The step the change began at, for relearning from it."""
        c = self.change
        return None if c is None else round(c[1].change_s / self.dt_s)


def _scores(z: np.ndarray, kind: str, param: float, clip: float) -> np.ndarray:
    """Standardized innovations through the channel's predictive distribution to N(0, 1), clipped."""
    return np.clip(normal_scores(z, kind, param), -clip, clip)


def _events(
    bins: np.ndarray, h: float, k: float, confirm: float, width_s: float, settle: int
) -> tuple[Event | None, tuple]:
    crossings = cusum_crossings(bins, h, k, confirm, settle)
    ev = [Event((c.alarm + 1) * width_s, c.start * width_s, c.sign, c.persists) for c in crossings]
    if crossings and crossings[-1].confirmed:
        return ev[-1], tuple(ev[:-1])
    return None, tuple(ev)


def monitor(model: EMModel, data: LandmarkLog, config: MonitorConfig | None = None) -> MonitorResult:
    """Run ``model``'s filter over ``data`` and test every stream for a change (module docstring)."""
    cfg = config or MonitorConfig()
    too_many = steps_problem(data.n_steps * data.dt_s / cfg.bin_s, f"bins of {cfg.bin_s:g} s over the log")
    if too_many is not None:  # checked before the filter runs and before any bin is allocated
        raise ConfigError(f"{too_many}.", field="bin_s", fix="give --bin-s in seconds, e.g. 1 (the default).")
    inn = innovations(model, data)
    sensor = model.sensor
    C = len(sensor.channels)
    kinds = [ch.robust for ch in sensor.channels] + [sensor.bearing_robust]
    params = [ch.robust_param for ch in sensor.channels] + [sensor.bearing_robust_param]
    u = np.column_stack([_scores(inn.z[:, c], kinds[c], params[c], cfg.clip) for c in range(C + 1)])
    t_obs = data.obs_step * data.dt_s
    duration = data.n_steps * data.dt_s
    names = [f"sensor:{ch.name}" for ch in sensor.channels] + ["sensor:bearing"]
    raw: list[tuple[str, str, np.ndarray]] = []
    seen = np.isfinite(u)
    for c in range(C + 1):
        f = seen[:, c]
        if f.any():
            raw.append((names[c], "sensor", binned(u[f, c], np.ones(int(f.sum())), t_obs[f], cfg.bin_s, duration)))
    times = np.broadcast_to(t_obs[:, None], u.shape)[seen]
    for a, vname in enumerate(model.action.velocity_names):
        w = inn.sensitivity[:, :, a][seen]
        if not np.any(w != 0.0):
            continue  # a velocity the model holds at zero (or the log never moves): nothing to test
        raw.append((f"action:{vname}", "action", binned(u[seen] * np.sign(w), np.abs(w), times, cfg.bin_s, duration)))
    tests = max(len(raw), 1)
    batch = max(1, round(cfg.batch_s / cfg.bin_s))
    first = _tested(raw, [long_run_scale(b, batch) for _, _, b in raw], tests, cfg)
    result = MonitorResult(first, cfg, duration, data.dt_s, inn.ok)
    found = result.change
    if found is None:
        return result
    # the spread a stream has while the model holds is the spread before the change: read again from the
    # bins before it, the test sharpens its alarm; what it confirms stands only if the first test's did
    before = round(found[1].change_s / cfg.bin_s)
    again = _tested(raw, [long_run_scale(b[:before], batch) for _, _, b in raw], tests, cfg)
    sharper = MonitorResult(again, cfg, duration, data.dt_s, inn.ok)
    return sharper if sharper.change is not None else result


def _tested(raw: list[tuple[str, str, np.ndarray]], scales: list[float], tests: int, cfg: MonitorConfig) -> tuple:
    """Each stream's bins, divided by its scale, through the CUSUM and the persistence test."""
    confirm = confirm_quantile(tests, cfg.false_alarm)
    streams = []
    for (name, kind, b), scale in zip(raw, scales, strict=True):
        scaled = b / scale
        h = cusum_threshold(int(np.isfinite(b).sum()), tests, cfg.false_alarm, cfg.reference)
        change, episodes = _events(scaled, h, cfg.reference, confirm, cfg.bin_s, round(cfg.batch_s / cfg.bin_s))
        streams.append(Stream(name, kind, scale, h, change, episodes, scaled, cusum_path(scaled, cfg.reference)))
    return tuple(streams)


def monitor_placed(
    model: EMModel, data: LandmarkLog, settings: EMConfig | None = None, config: MonitorConfig | None = None
) -> tuple[EMModel, MonitorResult]:
    """The robot placed on ``data`` first, as `localize` places it under ``settings`` (the ones the model was
    learned with): a new log starts elsewhere than the one the model was learned on, and where it starts is
    no part of the robot. Returns the placed model and ``monitor``'s result."""
    placed = localize(model, data, settings).model
    return placed, monitor(placed, data, config)
