"""Is a learned model's noise honest on a run it was not learned on? (docs/uncertainty.md)

The filter of sec. 2.4 runs with the model held over a log (``estep.innovations``: one step ahead, the
forward pass, not the smoother, so that no reading is scored by a path it helped place). Under the model,
each reading's standardized innovation follows the channel's predictive law: N(0, 1), or Student-t's where
the channel is robust. Through that law's CDF and N(0, 1)'s inverse (the probability integral transform)
every score is N(0, 1) while the model holds, whatever the law, and two numbers per reading type say
whether its sigma is right:

- ``coverage90``: the share of readings inside the model's 90 % predictive interval (0.90 when honest; a
  sigma too small gives less, one too large more);
- ``nis_mean``: the mean squared score, the normalized innovation squared (1 when honest).

The truth's residual cannot decide a sigma where the truth is itself uncertain (a Vicon heading, time-aligned
by interpolation); these need no truth at all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import norm
from scipy.stats import t as student_t

from sensact.learn.em.estep import innovations
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.records import JsonObject

INTERVAL = 0.90
Z90 = float(norm.ppf(0.5 + INTERVAL / 2.0))  # 1.645: the 90 % interval's half-width in N(0, 1)
UNITS = ("_mm", "_m", "_cm", "_px", "_rad", "_deg", "_v")  # stripped from a channel's name for its key


def normal_scores(z: np.ndarray, kind: str, param: float) -> np.ndarray:
    """Standardized innovations through the channel's predictive law to N(0, 1) (NaN stays NaN)."""
    z = np.asarray(z, dtype=float)
    if kind == "student_t":
        return norm.ppf(np.clip(student_t.cdf(z, param), 1e-15, 1.0 - 1e-15))
    return z


@dataclass(frozen=True)
class ReadingConsistency:
    n: int  # readings scored
    coverage90: float  # share inside the model's 90 % predictive interval (NaN with none)
    nis_mean: float  # mean squared normal score

    def to_dict(self) -> JsonObject:
        return {"n": self.n, "coverage90": self.coverage90, "nis_mean": self.nis_mean}


@dataclass(frozen=True)
class Consistency:
    """Per reading type (``range``, ``bearing``, ...): how its one-step-ahead innovations sit in the model's
    predictive law; ``filter_ok`` False when the filter failed (then nothing is scored)."""

    readings: dict[str, ReadingConsistency]
    filter_ok: bool

    def to_dict(self) -> JsonObject:
        return {name: r.to_dict() for name, r in self.readings.items()} | {"filter_ok": self.filter_ok}


def reading_key(name: str) -> str:
    """``range_mm`` -> ``range``: the reading type, whatever its unit."""
    for unit in UNITS:
        if name.endswith(unit) and len(name) > len(unit):
            return name[: -len(unit)]
    return name


def consistency(model: EMModel, data: LandmarkLog) -> Consistency:
    """``model``'s filter over ``data`` (the robot placed on it already: its ``prior_mean`` is where it
    starts), each reading type's innovations scored against its predictive law (module docstring)."""
    inn = innovations(model, data)
    sensor = model.sensor
    kinds = [(ch.robust, ch.robust_param) for ch in sensor.channels] + [
        (sensor.bearing_robust, sensor.bearing_robust_param)
    ]
    names = [reading_key(ch.name) for ch in sensor.channels] + ["bearing"]
    out: dict[str, ReadingConsistency] = {}
    for c, (name, (kind, param)) in enumerate(zip(names, kinds, strict=True)):
        u = normal_scores(inn.z[:, c], kind, param) if inn.ok else np.zeros(0)
        u = u[np.isfinite(u)]
        if c == len(sensor.channels) and not u.size:
            continue  # a sensor that reads no bearing
        out[name] = ReadingConsistency(
            int(u.size),
            float(np.mean(np.abs(u) <= Z90)) if u.size else float("nan"),
            float(np.mean(u**2)) if u.size else float("nan"),
        )
    return Consistency(out, inn.ok)
