"""`learn em --halves`'s figure: the models learned on the log's two halves against the whole log's, drawn
as differences so that what the log pins down lies on the zero line (``evaluate/halves.py`` gives the
same comparison as numbers).

Panels: for each velocity the action model moves, each half's predicted velocity minus the whole's at
every step's command, against the whole's; for each channel the log read, each half's f minus the
whole's over the distances its sightings were seen at, with the whole's sigma shaded for scale; and each
noise parameter as the half's over the whole's."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.evaluate.halves import GRID
from sensact.records import JsonObject
from sensact.report.figures1d import _save

_VELOCITY_WORDS = {
    "v_x_mm_s": "sideways velocity (mm/s)",
    "v_y_mm_s": "forward velocity (mm/s)",
    "v_theta_rad_s": "turn rate (rad/s)",
    "v_mm_s": "velocity (mm/s)",  # a track's
}
_HALF_STYLE = {"first half": "C0", "second half": "C1"}
_MOST_POINTS = 3000  # a long log's steps thinned for the scatter, evenly over the log


def _velocity_panel(ax: Any, name: str, whole: np.ndarray, halves: list[tuple[str, np.ndarray]]) -> None:
    every = max(1, whole.size // _MOST_POINTS)
    for half, v in halves:
        ax.scatter(whole[::every], (v - whole)[::every], s=3, alpha=0.4, color=_HALF_STYLE[half], label=half)
    ax.axhline(0.0, color="k", lw=1)
    word = _VELOCITY_WORDS.get(name, name)
    ax.set(xlabel=f"whole log's {word}", ylabel="half's minus whole's", title=f"{word.split(' (')[0]}, at each step")
    ax.legend(fontsize=7, markerscale=3)


def _channel_panel(ax: Any, j: int, span: tuple[float, float], whole: Any, halves: list[tuple[str, Any]]) -> None:
    ch = whole.sensor.channels[j]
    d = np.linspace(*span, GRID)
    ax.fill_between(d, -ch.sigma, ch.sigma, color="0.85", label=f"± whole's σ ({ch.sigma:.3g})")
    for half, m in halves:
        ax.plot(d, m.sensor.channels[j].function(d) - ch.function(d), color=_HALF_STYLE[half], lw=2, label=half)
    ax.axhline(0.0, color="k", lw=1)
    ax.set(
        xlabel="distance to the landmark (fitted path)",
        ylabel=f"half's f minus whole's ({ch.name})",
        title=f"{ch.name}: f over its sightings' distances",
    )
    ax.legend(fontsize=7)


def _noise_panel(ax: Any, noises: dict[str, dict[str, float]]) -> None:
    names = [k for k, v in noises["whole"].items() if v > 0]
    x = np.arange(len(names))
    width = 0.38
    for i, half in enumerate(("first", "second")):
        ratio = np.array([noises[half][k] / noises["whole"][k] for k in names])
        # bars from 1, the whole's own, so that a half's larger and smaller values point up and down
        ax.bar(
            x + (i - 0.5) * width,
            ratio - 1.0,
            width,
            bottom=1.0,
            color=_HALF_STYLE[f"{half} half"],
            label=f"{half} half",
        )
    ax.axhline(1.0, color="k", lw=1)
    ax.set_xticks(x, names, rotation=35, ha="right", fontsize=7)
    ax.set(ylabel="half's over whole's", title="noise parameters")
    ax.legend(fontsize=7)


def figure_halves(
    whole: Any, halves: list[tuple[str, Any]], data: Any, comparison: JsonObject, path: Path, title: str
) -> Path:
    """``halves``' models (``(name, model)``, "first half" and "second half") against ``whole``, learned
    on ``data``; ``comparison`` is ``compare_halves``' (its channels' spans and noise parameters)."""
    v_whole = whole.action.step_velocity(data)
    moving = [j for j in range(v_whole.shape[1]) if np.any(v_whole[:, j] != 0)]  # not a diff-drive's sideways
    v_halves = [(name, m.action.step_velocity(data)) for name, m in halves]
    spans = comparison["f"]["spans"]
    channels = [j for j, ch in enumerate(whole.sensor.channels) if ch.name in spans]
    n = len(moving) + len(channels) + 1
    ncol = min(n, 3)
    nrow = math.ceil(n / ncol)
    # constrained: the suptitle clear of the panels' titles
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.0 * nrow), squeeze=False, layout="constrained")
    flat = list(axes.ravel())
    names = whole.action.velocity_names
    for ax, j in zip(flat, moving, strict=False):
        _velocity_panel(ax, names[j], v_whole[:, j], [(name, v[:, j]) for name, v in v_halves])
    for ax, j in zip(flat[len(moving) :], channels, strict=False):
        _channel_panel(ax, j, tuple(spans[whole.sensor.channels[j].name]), whole, halves)
    _noise_panel(flat[n - 1], comparison["noise"])
    for ax in flat[n:]:
        ax.set_visible(False)
    for ax in flat[:n]:
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    return _save(fig, path)
