"""Chapter 4's EM in 1-D on the real Turtlebot (turtlebot1d), with several sensors at once.

The robot drives toward and away from a wall; the state is its distance (mm). The action model is
affine in ``velocity_command`` (with a learned command delay), the sensors are sonar1 (robust:
Student-t, since the HC-SR04 is wrong about 14 % of the time) and the four IR sensors, each valid only
within its datasheet distance window (an IR curve folds back below its minimum range, so outside the
window a reading says nothing). Nothing fixes the unit of the 1-D state, so the evaluation maps the
learned state to the true range with the optimal scale and offset (as sec. 4.4.3 does) and compares:

* the action **gain**: the learned d(velocity)/d(command) after the scale, against the slope of the
  true velocity (from ``range`` over 1 s windows) on the command; not scored when the log spends
  ``ONE_COMMAND_SHARE`` of its steps at one command, where that slope rests on the few others;
* each **sensor**: over 100 mm bins of true distance inside the channel's window, the gap between the
  learned f and the median reading, turned into distance by f's slope, as an RMS percent of the span;
  ``bins_beyond_span`` counts the bins whose error exceeds the whole span, where f is nearly flat and the
  reading hardly tells the distance (an IR sensor past its useful range).

The chapter-3 online learner's numbers on the same file are reported beside it.
"""

from __future__ import annotations

import itertools
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from sensact.config import config_to_dict
from sensact.errors import LogFormatError
from sensact.evaluate.bars import BarCheck, at_most, not_scored
from sensact.evaluate.measured import ONE_COMMAND_SHARE, dominant_command
from sensact.io.turtlebot import EM_READINGS, SPEC_RANGE_M, read_turtlebot_landmark_log
from sensact.learn.em import EMConfig, EMResult, fit_em
from sensact.learn.em.config import ChannelConfig
from sensact.logs.landmark_log import LandmarkLog


def turtlebot_em_config(readings: tuple[str, ...] = EM_READINGS) -> EMConfig:
    """The model a user would choose from the datasheets: every channel a cubic from a poor line;
    the IR channels valid within their datasheet ranges; sonar1 robust. ``readings``: the columns a
    file has (sonar1 and any of the IR sensors)."""
    chans = [
        # a sonar reads a distance: its poor start is a wrong scale and offset, not a wrong unit, so that the
        # state is in mm and the IR windows mean what the datasheets say
        ChannelConfig("sonar1", 3, 100.0, 0.8, 300.0, robust="student_t", robust_param=4.0),
    ]
    for name in (r for r in EM_READINGS[1:] if r in readings):
        lo, hi = SPEC_RANGE_M[name]
        chans.append(ChannelConfig(name, 3, 1.5, -0.0002, 1.0, lo * 1000.0, hi * 1000.0))
    return EMConfig(
        action_basis="affine",
        action_delay_max_s=0.5,
        motion_noise="shared",
        channels=tuple(chans),
        max_iterations=1000,
    )


BIN_MM = 100.0  # the sensor scores' bins of true distance


def _windowed_velocity(x: np.ndarray, dt: float, window: int) -> tuple[np.ndarray, np.ndarray]:
    idx = np.arange(0, len(x) - window, max(window // 2, 1))
    return idx, (x[idx + window] - x[idx]) / (window * dt)


def score_turtlebot_em(res: EMResult, data: LandmarkLog, truth_mm: np.ndarray) -> dict[str, Any]:
    """Gain and sensor errors after the optimal affine map of the learned state onto the true range."""
    post = res.posteriors
    x = post.mean_gamma[:, 0]
    a, b = np.polyfit(x, truth_mm, 1)  # true range ~ a x + b
    action = res.model.action
    gain_learned = -a * action.coefficients[1, 0]  # the track state shrinks as the robot advances
    window = max(round(1.0 / data.dt_s), 1)
    idx, v_true = _windowed_velocity(truth_mm, data.dt_s, window)
    c = np.array([data.step_commands[i : i + window, 0].mean() for i in idx])
    gain_true = float(np.polyfit(c, v_true, 1)[0])
    _, one_share = dominant_command(data.step_commands[:, 0])
    scored = one_share < ONE_COMMAND_SHARE
    out: dict[str, Any] = {
        "state_map": {"scale": float(a), "offset_mm": float(b), "rms_mm": float(np.std(a * x + b - truth_mm))},
        "one_command_share": one_share,
        "gain_learned": float(gain_learned),
        "gain_true": gain_true,
        "gain_error_pct": 100.0 * abs(gain_learned / gain_true - 1.0) if scored else None,
        "delay_s": action.delay_steps * data.dt_s,
        "sensors": {},
    }
    d_obs = truth_mm[data.obs_step]
    for j, ch in enumerate(res.model.sensor.channels):
        col = data.reading_names.index(ch.name)
        lo = max(ch.valid_min * a + b, d_obs.min()) if math.isfinite(ch.valid_min) else d_obs.min()
        hi = min(ch.valid_max * a + b, d_obs.max()) if math.isfinite(ch.valid_max) else d_obs.max()
        lo, hi = min(lo, hi), max(lo, hi)
        edges = np.arange(lo, hi + BIN_MM, BIN_MM)
        errs, centers = [], []
        for e0, e1 in itertools.pairwise(edges):
            sel = (d_obs >= e0) & (d_obs < e1) & np.isfinite(data.obs_readings[:, col])
            if sel.sum() < 5:
                continue
            dc = 0.5 * (e0 + e1)
            xs = (dc - b) / a
            med = float(np.median(data.obs_readings[sel, col]))
            f, df = ch.function(xs), (ch.function(xs + 1.0) - ch.function(xs - 1.0)) / 2.0
            errs.append(a * (f - med) / df if df else np.nan)
            centers.append(dc)
        span = float(np.ptp(centers)) if len(centers) > 1 else float("nan")
        rms = float(np.sqrt(np.nanmean(np.square(errs)))) if errs else float("nan")
        # an inverse confined to the window is never off by more than its span: a bin beyond that is one
        # where f is nearly flat and the gap over its slope unbounded (an IR sensor past its useful range)
        within = np.abs(errs) <= span if errs and np.isfinite(span) else np.ones(len(errs), dtype=bool)
        rms_within = float(np.sqrt(np.mean(np.square(np.asarray(errs)[within])))) if within.any() else float("nan")
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


# issue 5's Turtlebot bars: the gain within 5 % of the truth's, one sensor within 3 % of the range
GAIN_BAR_PCT = 5.0
SENSOR_BAR_PCT = 3.0


def scorecard(summary: dict[str, Any], name: str | None = None) -> list[BarCheck]:
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
    pcts = {k: v["rms_pct_of_span"] for k, v in sc["sensors"].items() if np.isfinite(v["rms_pct_of_span"])}
    best = min(pcts, key=pcts.__getitem__, default=None)
    sensor_q = f"{who}: best sensor ({best}), % of its span" if best else f"{who}: best sensor, % of its span"
    sensor = at_most(f"{key}.sensor", sensor_q, pcts.get(best, float("nan")), SENSOR_BAR_PCT, "%")
    return [gain, sensor]


def run_turtlebot_em(csv_path: str | Path, config: EMConfig | None = None) -> tuple[dict[str, Any], EMResult]:
    t0 = time.perf_counter()
    data, truth = read_turtlebot_landmark_log(csv_path)
    if not np.isfinite(truth).any():  # checked before the fit: without it nothing can be scored
        raise LogFormatError(
            "the log has no recorded range to score the learned models against.",
            file=csv_path,
            field="range",
            fix="add the range column (m), or learn from the log with `sensact learn em FILE` (no scores).",
        )
    cfg = config or turtlebot_em_config(data.reading_names)
    res = fit_em(data, None, cfg)
    score = score_turtlebot_em(res, data, truth)
    summary: dict[str, Any] = {
        "file": str(csv_path),
        "steps": data.n_steps,
        "dt_s": data.dt_s,
        "em": res.summary() | {"config": config_to_dict(cfg)},
        "score": score,
        "seconds": time.perf_counter() - t0,
    }
    gain, sensor = scorecard(summary)
    summary["bars"] = {"gain_within_5pct": gain.cleared, "a_sensor_within_3pct": sensor.cleared}
    return summary, res
