"""A Turtlebot EM fit (``experiments/turtlebot_em.py``) scored against the log's recorded range.

Nothing fixes the unit of the 1-D state, so the evaluation maps the learned state to the true range with
the optimal scale and offset (as sec. 4.4.3 does) and compares:

* the action **gain**: the learned d(velocity)/d(command) after the scale, against the slope of the
  true velocity (from ``range`` over 1 s windows) on the command; not scored when the log spends
  ``ONE_COMMAND_SHARE`` of its steps at one command, where that slope rests on the few others;
* each **sensor**: over 100 mm bins of true distance inside the channel's window, the gap between the
  learned f and the median reading, turned into distance by f's slope, as an RMS percent of the span;
  ``bins_beyond_span`` counts the bins whose error exceeds the whole span, where f is nearly flat and the
  reading hardly tells the distance (an IR sensor past its useful range).

The helpers are shared with the figure (``report/figures_turtlebot_em.py``), so that it draws what is scored.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sensact.evaluate.bars import BarCheck, at_most, not_scored
from sensact.evaluate.measured import ONE_COMMAND_SHARE, dominant_command
from sensact.learn.em import EMResult
from sensact.learn.em.uses.place import Localized
from sensact.logs.landmark_log import LandmarkLog
from sensact.records import JsonObject

BIN_MM = 100.0  # the sensor scores' bins of true distance

NO_RANGE_COLUMN = "there is no range column"


def range_column_problem(truth_mm: np.ndarray | None) -> str | None:
    """Why a Turtlebot CSV's ``range`` column (per step, mm) cannot score a fit, or None when it can:
    ``NO_RANGE_COLUMN`` (a file without one reads as NaN throughout), or how many of its steps are empty
    (the scores need it at every step)."""
    if truth_mm is None or np.isnan(truth_mm).all():
        return NO_RANGE_COLUMN
    if not np.isfinite(truth_mm).all():
        return f"the range column has {int((~np.isfinite(truth_mm)).sum())} empty steps"
    return None


def windowed_velocities(data: LandmarkLog, truth_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The recorded range's velocity over 1-s windows (half overlapping) and each window's mean command:
    what the gain is scored against."""
    window = max(round(1.0 / data.dt_s), 1)
    idx = np.arange(0, len(truth_mm) - window, max(window // 2, 1))
    v_true = (truth_mm[idx + window] - truth_mm[idx]) / (window * data.dt_s)
    c = np.array([data.step_commands[i : i + window, 0].mean() for i in idx])
    return c, v_true


def state_map(x: np.ndarray, truth_mm: np.ndarray) -> tuple[float, float]:
    """``(a, b)``: the optimal affine map ``true range ~ a x + b`` of a smoothed state ``x`` (sec. 4.4.3)."""
    a, b = np.polyfit(x, truth_mm, 1)
    return float(a), float(b)


def state_map_summary(x: np.ndarray, truth_mm: np.ndarray) -> dict[str, float]:
    """``state_map`` with the spread left about it: the RMS (after the best offset) the scores report."""
    a, b = state_map(x, truth_mm)
    return {"scale": a, "offset_mm": b, "rms_mm": float(np.std(a * x + b - truth_mm))}


def learned_velocity_mm_s(res: EMResult | Localized, commands: np.ndarray, a: float) -> np.ndarray:
    """The learned mean velocity of the recorded range at each command, after the scale: the track state
    shrinks as the robot advances (``TRACK``), so the range moves at ``-a A(c)``."""
    action = res.model.action
    return -a * (action.features(np.asarray(commands, dtype=float).reshape(-1, 1)) @ action.coefficients)[:, 0]


def sensor_bins(
    channel: Any, readings: np.ndarray, d_obs: np.ndarray, a: float, b: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Over ``BIN_MM`` bins of true distance inside the channel's window (mapped onto the range by
    ``a, b``), with at least 5 readings: each bin's centre, its median reading, and the gap between the
    learned f and that median turned into distance by f's slope."""
    lo = max(channel.valid_min * a + b, d_obs.min()) if math.isfinite(channel.valid_min) else d_obs.min()
    hi = min(channel.valid_max * a + b, d_obs.max()) if math.isfinite(channel.valid_max) else d_obs.max()
    lo, hi = min(lo, hi), max(lo, hi)
    edges = np.arange(lo, hi + BIN_MM, BIN_MM)
    centers, medians, errs = [], [], []
    for e0, e1 in itertools.pairwise(edges):
        sel = (d_obs >= e0) & (d_obs < e1) & np.isfinite(readings)
        if sel.sum() < 5:
            continue
        dc = 0.5 * (e0 + e1)
        xs = (dc - b) / a
        med = float(np.median(readings[sel]))
        f, df = channel.function(xs), (channel.function(xs + 1.0) - channel.function(xs - 1.0)) / 2.0
        centers.append(dc)
        medians.append(med)
        errs.append(a * (f - med) / df if df else np.nan)
    return np.array(centers), np.array(medians), np.array(errs)


def score_turtlebot_em(res: EMResult | Localized, data: LandmarkLog, truth_mm: np.ndarray) -> JsonObject:
    """Gain and sensor errors after the optimal affine map of the learned state onto the true range; ``res``
    is a fit, or a model held and placed on another log (`evaluate log`)."""
    post = res.posteriors
    x = post.mean_gamma[:, 0]
    mapped = state_map_summary(x, truth_mm)
    a, b = mapped["scale"], mapped["offset_mm"]
    action = res.model.action
    gain_learned = -a * action.coefficients[1, 0]  # the track state shrinks as the robot advances
    c, v_true = windowed_velocities(data, truth_mm)
    # commands that never vary (or too few windows) give no true gain to score against
    gain_true = float(np.polyfit(c, v_true, 1)[0]) if c.size >= 2 and np.ptp(c) > 0 else float("nan")
    _, one_share = dominant_command(data.step_commands[:, 0])
    scored = one_share < ONE_COMMAND_SHARE
    out: JsonObject = {
        "state_map": mapped,
        "one_command_share": one_share,
        "gain_learned": float(gain_learned),
        "gain_true": gain_true,
        "gain_error_pct": 100.0 * abs(gain_learned / gain_true - 1.0) if scored else None,
        "delay_s": action.delay_steps * data.dt_s,
        "sensors": {},
    }
    d_obs = truth_mm[data.obs_step]
    for j, ch in enumerate(res.model.sensor.channels):
        readings = data.obs_readings[:, data.reading_names.index(ch.name)]
        centers, _, errs = sensor_bins(ch, readings, d_obs, a, b)
        span = float(np.ptp(centers)) if len(centers) > 1 else float("nan")
        rms = float(np.sqrt(np.nanmean(np.square(errs)))) if errs.size else float("nan")
        # an inverse confined to the window is never off by more than its span: a bin beyond that is one
        # where f is nearly flat and the gap over its slope unbounded (an IR sensor past its useful range)
        within = np.abs(errs) <= span if errs.size and np.isfinite(span) else np.ones(len(errs), dtype=bool)
        rms_within = float(np.sqrt(np.mean(np.square(errs[within])))) if within.any() else float("nan")
        out["sensors"][ch.name] = {
            "rms_mm": rms,
            "rms_pct_of_span": 100.0 * rms / span if span else float("nan"),
            "span_mm": span,
            "bins": len(centers),
            "bins_beyond_span": int((~within).sum()),
            "rms_pct_of_span_within": 100.0 * rms_within / span if span else float("nan"),  # without those
            "sigma": ch.sigma,
            "weight_used": int((post.weights[:, j] > 0).sum()),
        }
    return out


@dataclass(frozen=True)
class TurtlebotEMRun:
    """A fit (or a learned model held and placed on another log by ``learn.em.localize``: `evaluate log`),
    the log and the recorded range (mm per step) it is scored against."""

    data: LandmarkLog
    truth_mm: np.ndarray
    result: EMResult | Localized  # what is read: its model and posteriors


# the Turtlebot's bars (docs/em-real.md): the gain within 5 % of the truth's, one sensor within 3 % of the range
GAIN_BAR_PCT = 5.0


SENSOR_BAR_PCT = 3.0


def scorecard(summary: JsonObject, name: str | None = None) -> list[BarCheck]:
    """The Turtlebot's bars on ``run_turtlebot_em``'s summary: the gain, and the best-scored sensor. With
    ``name`` (a log beside the issue's ``training1.csv``) the keys and questions carry it."""
    sc = summary["score"]
    key, who = (f"turtlebot/{name}", f"Turtlebot {name}") if name else ("turtlebot", "Turtlebot")
    gain_q = f"{who}: action gain error"
    gain_bar = f"≤ {GAIN_BAR_PCT:.2f} %"
    if sc["gain_error_pct"] is None:
        gain = not_scored(f"{key}.gain", gain_q, gain_bar, "the log holds one command")
    else:
        gain = at_most(f"{key}.gain", gain_q, sc["gain_error_pct"], GAIN_BAR_PCT, "%")
    best, pct = best_sensor(sc)
    sensor_q = f"{who}: best sensor ({best}), % of its span" if best else f"{who}: best sensor, % of its span"
    sensor = at_most(f"{key}.sensor", sensor_q, float("nan") if pct is None else pct, SENSOR_BAR_PCT, "%")
    return [gain, sensor]


def best_sensor(score: JsonObject) -> tuple[str | None, float | None]:
    """The sensor of a ``score_turtlebot_em`` result whose error is the least % of its span, and that error;
    (None, None) when no sensor could be scored."""
    pcts = {k: v["rms_pct_of_span"] for k, v in score["sensors"].items() if np.isfinite(v["rms_pct_of_span"])}
    best = min(pcts, key=pcts.__getitem__, default=None)
    return best, None if best is None else float(pcts[best])
