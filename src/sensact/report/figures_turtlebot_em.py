"""EM in 1-D on a Turtlebot log, drawn against its recorded ``range`` after the optimal scale and offset
(sec. 4.4.3): what `sensact reproduce real` (``real_turtlebot_<log>.png``) and `sensact learn em` on a
Turtlebot CSV with a range column (``OUT_against_range.png``) write beside the numbers.

Panels: the action, the learned velocity of the range against the command over the recorded range's
1-s velocities (the windows the gain is scored on); then one per reading channel, its readings against
the true distance, the medians per 100-mm bin the score uses, and the learned f carried onto the range,
solid inside the channel's window and dotted outside it, where EM ignores the channel."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.evaluate.turtlebot_em import learned_velocity_mm_s, sensor_bins, windowed_velocities
from sensact.records import JsonObject
from sensact.report.figures1d import _save


def _action_panel(ax: Any, run: Any, score: JsonObject, a: float) -> None:
    c, v_true = windowed_velocities(run.data, run.truth_mm)
    ax.plot(c, v_true, ".", ms=3, alpha=0.4, color="0.5", label="recorded range, 1-s windows")
    grid = np.linspace(c.min(), c.max(), 100) if c.size else np.zeros(1)
    if c.size >= 2 and np.ptp(c) > 0:  # one command throughout draws no line through the truth
        slope, offset = np.polyfit(c, v_true, 1)
        ax.plot(
            grid, slope * grid + offset, "--", color="k", lw=1, label=f"truth's line (gain {score['gain_true']:.4f})"
        )
    err = score["gain_error_pct"]
    off = f", {err:.2f} % off" if err is not None else ", not scored: one command"
    ax.plot(
        grid,
        learned_velocity_mm_s(run.result, grid, a),
        "-",
        color="C3",
        lw=1.5,
        label=f"learned × scale (gain {score['gain_learned']:.4f}{off})",
    )
    ax.set(
        xlabel=f"{run.data.command_names[0]}",
        ylabel="velocity of the range (mm/s)",
        title=f"action (learned delay {score['delay_s']:.2f} s)",
    )
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)


def _sensor_panel(ax: Any, run: Any, channel: Any, s: JsonObject, a: float, b: float) -> None:
    data = run.data
    readings = data.obs_readings[:, data.reading_names.index(channel.name)]
    d_obs = run.truth_mm[data.obs_step]
    ok = np.isfinite(readings)
    ax.plot(d_obs[ok], readings[ok], ".", ms=2, alpha=0.25, color="0.5", label="readings")
    centers, medians, _ = sensor_bins(channel, readings, d_obs, a, b)
    if centers.size:
        ax.plot(centers, medians, "o", ms=3, color="k", label="median per 100 mm (scored)")
    lo = channel.valid_min * a + b if math.isfinite(channel.valid_min) else -math.inf
    hi = channel.valid_max * a + b if math.isfinite(channel.valid_max) else math.inf
    lo, hi = min(lo, hi), max(lo, hi)
    d = np.linspace(d_obs.min(), d_obs.max(), 400)
    f = channel.function((d - b) / a)
    inside = (d >= lo) & (d <= hi)
    ax.plot(d, np.where(inside, f, np.nan), "-", color="C3", lw=1.5, label="learned f, after the scale")
    ax.plot(d, np.where(inside, np.nan, f), ":", color="C3", lw=1, label="outside its window")
    if math.isfinite(lo) or math.isfinite(hi):
        ax.axvspan(max(lo, d[0]), min(hi, d[-1]), color="C2", alpha=0.08, lw=0)
    # the curve is drawn where the readings are: a cubic far outside them would flatten the scatter
    span = np.nanpercentile(readings[ok], [0.5, 99.5]) if ok.any() else np.array([0.0, 1.0])
    pad = 0.1 * max(span[1] - span[0], 1e-9)
    ax.set_ylim(span[0] - pad, span[1] + pad)
    pct = s.get("rms_pct_of_span")
    scored = (
        f"{pct:.2f} % of its {s['span_mm']:.0f} mm span" if pct is not None and math.isfinite(pct) else "not scored"
    )
    if s.get("bins_beyond_span"):  # where f is nearly flat: said apart, as the table says it
        flat = s["bins_beyond_span"]
        scored += f"\n({s['rms_pct_of_span_within']:.2f} % without its {flat} flat bin{'s' if flat > 1 else ''})"
    ax.set(xlabel="recorded range (mm)", ylabel="reading", title=f"{channel.name}: {scored}")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)


def figure_turtlebot_em(run: Any, score: JsonObject, path: Path, title: str) -> Path:
    """The action panel and one panel per reading channel, against the recorded range. ``run`` has the
    fit's ``data``, ``truth_mm`` and ``result`` (``experiments.turtlebot_em.TurtlebotEMRun``); ``score``
    is ``score_turtlebot_em``'s for it."""
    a, b = score["state_map"]["scale"], score["state_map"]["offset_mm"]  # the map the numbers were scored through
    channels = run.result.model.sensor.channels
    n = 1 + len(channels)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.8 * rows), squeeze=False)
    flat = axes.ravel()
    _action_panel(flat[0], run, score, a)
    for ax, ch in zip(flat[1:], channels, strict=False):
        _sensor_panel(ax, run, ch, score["sensors"][ch.name], a, b)
    for ax in flat[n:]:
        ax.set_axis_off()
    fig.suptitle(f"{title}: learned models against the recorded range (optimal scale {a:.3f}, offset {b:.0f} mm)")
    fig.tight_layout()
    return _save(fig, path)
