"""Measured models from a real log's ground truth, made the way sec. 3.3.2 measured the Aibo's.

* Sensor: the thesis parked the robot at known distances and averaged 100 readings. From a log with a
  true position we bin the positions and take the **median** reading per bin (robust to outliers such
  as the HC-SR04's).
* Action: the thesis timed each command over a known distance. We take every stretch where one
  command was held, drop its first ``settle_s`` (acceleration), and fit the slope of true position
  against time; stretches of the same command are averaged, weighted by their duration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MeasuredSensor:
    observations: np.ndarray  # median reading per bin
    positions: np.ndarray  # bin centres
    counts: np.ndarray


@dataclass(frozen=True)
class MeasuredAction:
    commands: np.ndarray
    velocities: np.ndarray
    seconds: np.ndarray  # time each command was observed in steady state


def measure_sensor(
    observations: np.ndarray,
    positions: np.ndarray,
    *,
    bin_width: float,
    window: tuple[float, float] = (-np.inf, np.inf),
    min_count: int = 20,
) -> MeasuredSensor:
    """Median reading per position bin; bins whose median reading is outside ``window`` (where the
    sensor is not invertible) are left out."""
    o = np.asarray(observations, dtype=float)
    x = np.asarray(positions, dtype=float)
    m = np.isfinite(o) & np.isfinite(x)
    o, x = o[m], x[m]
    if o.size == 0:
        return MeasuredSensor(np.empty(0), np.empty(0), np.empty(0, dtype=np.int64))
    edges = np.arange(np.floor(x.min() / bin_width) * bin_width, x.max() + bin_width, bin_width)
    idx = np.digitize(x, edges) - 1
    obs, pos, cnt = [], [], []
    for b in range(len(edges) - 1):
        sel = idx == b
        if sel.sum() >= min_count and window[0] <= np.median(o[sel]) <= window[1]:
            obs.append(np.median(o[sel]))
            pos.append(np.median(x[sel]))
            cnt.append(int(sel.sum()))
    return MeasuredSensor(np.array(obs), np.array(pos), np.array(cnt, dtype=np.int64))


def measure_action(
    times_s: np.ndarray,
    commands: np.ndarray,
    positions: np.ndarray,
    *,
    settle_s: float = 1.0,
    min_span_s: float = 2.0,
    sign: float = 1.0,
) -> MeasuredAction:
    """Timed velocity per held command; ``sign=-1`` when the command moves the position negative."""
    t = np.asarray(times_s, dtype=float)
    c = np.asarray(commands, dtype=float)
    x = np.asarray(positions, dtype=float)
    starts = np.r_[0, np.flatnonzero(np.diff(c) != 0) + 1]
    ends = np.r_[starts[1:], len(c)]
    acc: dict[float, list[tuple[float, float]]] = {}
    for s, e in zip(starts, ends, strict=True):
        sel = np.arange(s, e)
        sel = sel[t[sel] >= t[s] + settle_s]
        if sel.size < 3 or t[sel[-1]] - t[sel[0]] < min_span_s:
            continue
        slope = np.polyfit(t[sel], x[sel], 1)[0]
        acc.setdefault(float(c[s]), []).append((sign * slope, t[sel[-1]] - t[sel[0]]))
    cmds = np.array(sorted(acc))
    vel = np.array([np.average([v for v, _ in acc[k]], weights=[w for _, w in acc[k]]) for k in cmds])
    secs = np.array([sum(w for _, w in acc[k]) for k in cmds])
    return MeasuredAction(cmds, vel, secs)


# a log spending this share of its steps at one command measures one point of the action model
ONE_COMMAND_SHARE = 0.9


def dominant_command(commands: np.ndarray, tolerance: float = 0.02) -> tuple[float, float]:
    """The median command and the share of steps within ``tolerance`` of the largest command's size of
    it. Needs no ground truth: when the share reaches ``ONE_COMMAND_SHARE`` (turtlebot1d's
    calibration.csv: 0.98; training1.csv: 0.07) a slope of velocity on command rests on the few steps
    at other commands, mostly their accelerations, and is not a gain to score or to trust."""
    c = np.asarray(commands, dtype=float)
    c = c[np.isfinite(c)]
    if c.size == 0:
        return float("nan"), 0.0
    med = float(np.median(c))
    return med, float(np.mean(np.abs(c - med) <= tolerance * np.abs(c).max()))


def one_command_doubt(commands: np.ndarray, source: str, name: str, unit: str = "") -> str | None:
    """A line for a 1-D log that spends nearly all its steps at one command (``ONE_COMMAND_SHARE``): the action
    model's slope then rests on the few steps at others; None otherwise."""
    value, share = dominant_command(commands)
    if share < ONE_COMMAND_SHARE:
        return None
    command = f"{name} {value:g} {unit}".rstrip()
    return (
        f"{source} spends {100 * share:.0f} % of its steps at one command ({command}), so the action model's "
        "slope rests on the few steps at others and a gain against ground truth is not scored; for a model to "
        "trust, drive at two or more speeds, each for a few seconds."
    )


def first_reversal_s(times_s: np.ndarray, commands: np.ndarray, tolerance: float = 0.02) -> float | None:
    """Seconds into the log of the first command against the direction of the first one that moves (each
    beyond ``tolerance`` of the largest command's size), or None if the log never reverses. Needs no
    ground truth: chapter 3's learner sees one direction of travel until then."""
    c = np.asarray(commands, dtype=float)
    t = np.asarray(times_s, dtype=float)
    ok = np.isfinite(c)
    if not ok.any():
        return None
    moving = np.flatnonzero(ok & (np.abs(c) > tolerance * np.abs(c[ok]).max()))
    if moving.size == 0:
        return None
    back = moving[np.sign(c[moving]) != np.sign(c[moving[0]])]
    return None if back.size == 0 else float(t[back[0]] - t[0])
