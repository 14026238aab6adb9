"""A converted log at a glance, before anything is learned from it: the commands over time, when each
landmark was seen, and the map with the recorded path. Two clocks that do not match, a map in the wrong
unit or a robot that drives out of its landmarks' sight show here before they show as a poor model."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.report.figures1d import _save

MAX_COMMAND_PANELS = 3
MAX_NAMED_LANDMARKS = 30
MIN_MAP_HALF_MM = 1000.0  # a map of one landmark still shows a room around it


def figure_log_overview(data: Any, groundtruth: dict[str, np.ndarray] | None, path: Path, title: str) -> Path:
    """``data`` a planar ``LandmarkLog`` with continuous commands; ``groundtruth`` its x_mm, y_mm (and
    valid) on the step grid, or None."""
    t = np.arange(data.n_steps) * data.dt_s
    names = data.command_names[:MAX_COMMAND_PANELS]
    fig = plt.figure(figsize=(13, 2.2 * (len(names) + 1) + 0.6))
    grid = fig.add_gridspec(len(names) + 1, 2, width_ratios=(1.7, 1.0))
    axes = [fig.add_subplot(grid[j, 0]) for j in range(len(names) + 1)]
    for j, (ax, name) in enumerate(zip(axes, names, strict=False)):
        ax.plot(t, data.step_commands[:, j], lw=0.6, drawstyle="steps-post")
        ax.set(ylabel=name, title=f"{title}: commands, held between their rows" if j == 0 else None)
    seen = axes[-1]
    n_marks = len(data.landmarks_xy)
    seen.plot(data.obs_step * data.dt_s, data.obs_landmark, "|", ms=6, alpha=0.6)
    seen.set(xlabel="time from the first command (s)", ylabel="landmark", title=f"{data.obs_step.size} sightings")
    if n_marks <= MAX_NAMED_LANDMARKS and data.landmark_names:
        seen.set_yticks(range(n_marks), data.landmark_names, fontsize=7)
    for ax in axes:
        ax.set_xlim(t[0], t[-1])
        ax.grid(alpha=0.3)
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    world = fig.add_subplot(grid[:, 1])
    xy = data.landmarks_xy
    counts = np.bincount(data.obs_landmark, minlength=n_marks)
    world.scatter(xy[:, 0], xy[:, 1], marker="^", s=60, c="tab:red", label="landmarks (how often seen)", zorder=3)
    for j, (x, y) in enumerate(xy):
        name = data.landmark_names[j] if data.landmark_names else str(j)
        world.annotate(f"{name} ({counts[j]})", (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    if groundtruth is not None:
        ok = groundtruth.get("valid", np.ones(data.n_steps)) > 0.5
        x = np.where(ok, groundtruth["x_mm"], np.nan)  # a gap in the truth stays a gap
        y = np.where(ok, groundtruth["y_mm"], np.nan)
        world.plot(x, y, lw=0.6, color="tab:blue", label=f"recorded path ({100 * ok.mean():.0f} % of the steps)")
        start = int(np.argmax(ok)) if ok.any() else 0
        world.plot(x[start], y[start], "o", color="tab:green", label="path start")
    world.set(xlabel="x (mm)", ylabel="y (mm)", title="map" + (" and recorded path" if groundtruth is not None else ""))
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    if groundtruth is not None and ok.any():
        lo = np.fmin(lo, [np.nanmin(x), np.nanmin(y)])
        hi = np.fmax(hi, [np.nanmax(x), np.nanmax(y)])
    mid, half = 0.5 * (lo + hi), np.maximum(0.55 * (hi - lo), MIN_MAP_HALF_MM)
    world.update_datalim([mid - half, mid + half])  # the equal aspect then widens the shorter side
    world.autoscale_view()
    world.set_aspect("equal", adjustable="datalim")
    world.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=2)  # clear of the map
    world.grid(alpha=0.3)
    return _save(fig, path)


def figure_track_overview(
    data: Any, truth_mm: np.ndarray | None, distance_reading: str, path: Path, title: str
) -> Path:
    """A 1-D robot's converted log (``data`` a track ``LandmarkLog``): the commands and each reading over
    time (left), and each reading against the distance it was read at (right): the recorded distance
    where there is one, else (for the other readings) the distance sensor's reading on the same row. The
    right column shows where a sensor says something about the distance (an IR curve folds back below its
    range) and so where its validity window belongs."""
    t = np.arange(data.n_steps) * data.dt_s
    names = data.command_names[:MAX_COMMAND_PANELS]
    rows = len(names) + len(data.reading_names)
    fig = plt.figure(figsize=(13, 1.9 * rows + 0.8))
    grid = fig.add_gridspec(rows, 2, width_ratios=(1.7, 1.0))
    left = [fig.add_subplot(grid[j, 0]) for j in range(rows)]
    for j, (ax, name) in enumerate(zip(left, names, strict=False)):
        ax.plot(t, data.step_commands[:, j], lw=0.6, drawstyle="steps-post")
        ax.set(ylabel=name, title=f"{title}: commands, held between their rows" if j == 0 else None)
    obs_t = data.obs_step * data.dt_s
    for j, (ax, r) in enumerate(zip(left[len(names) :], data.reading_names, strict=True)):
        ax.plot(obs_t, data.obs_readings[:, j], ".", ms=1.5)
        if r == distance_reading and truth_mm is not None:
            ax.plot(t, truth_mm, lw=0.8, color="tab:green", label="recorded distance (mm)")
            ax.legend(fontsize=7, loc="upper right")
        ax.set(ylabel=r)
    for ax in left:
        ax.set_xlim(t[0], t[-1])
        ax.grid(alpha=0.3)
    for ax in left[:-1]:
        ax.tick_params(labelbottom=False)
    left[-1].set(xlabel="time from the first command (s)")
    d = data.reading_names.index(distance_reading)
    if truth_mm is not None:
        x, against = truth_mm[data.obs_step], "the recorded distance (mm)"
        panels = list(range(len(data.reading_names)))  # the distance sensor's lost echoes show too
    else:
        x, against = data.obs_readings[:, d], f"{distance_reading} on the same row"
        panels = [j for j in range(len(data.reading_names)) if j != d]
    for k, j in enumerate(panels):
        ax = fig.add_subplot(grid[k * rows // len(panels) : (k + 1) * rows // len(panels), 1])
        ax.plot(x, data.obs_readings[:, j], ".", ms=1.5, alpha=0.5)
        ax.set(ylabel=data.reading_names[j], title=f"each reading against {against}" if k == 0 else None)
        ax.grid(alpha=0.3)
        if k == len(panels) - 1:
            ax.set(xlabel=against)
    return _save(fig, path)
