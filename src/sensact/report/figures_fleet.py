"""A fleet's models scored on every robot's log (``app.fleet.score_fleet``) as grids, a row per
model and a column per log: against the truth, the translation and rotation ratios to From-Truth, the
range residual about the truth and the bearing sigma ratio; by the likelihood, with no truth, how far
each model falls below the log's most likely one; on Turtlebot CSVs, against the range column, the action
gain's error and the best sensor's. A pair that misses a bar is outlined in red, a robot's
own pair is written in bold: which models carry over is seen at a glance."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LogNorm, Normalize
from matplotlib.patches import Rectangle
from matplotlib.ticker import FuncFormatter

from sensact.records import JsonObject
from sensact.report.figures1d import _save
from sensact.report.tables_fleet import FLEET_BARS

# ratios are coloured on one scale about 1 (white), so that a figure of models that all carry over
# looks quiet and a miss stands out; the colour bar marks the bars (the fleet's ``bars``)
RATIO_SPAN = 2.0

# (cell key, title, number format, the part of the cell whose bars it shows)
PANELS = (
    ("translation_ratio", "translation RMS / From-Truth's", "{:.2f}", "translation"),
    ("rotation_ratio", "rotation RMS / From-Truth's", "{:.2f}", "rotation"),
    ("range_residual_rms_mm", "range residual about the truth (mm)", "{:.0f}", None),
    ("bearing_sigma_ratio", "bearing sigma / truth's residual", "{:.2f}", "bearing"),
)
# on Turtlebot CSVs, against the range column (``fleet["range"]``): the part names the bar (its cell's ``bars``)
RANGE_PANELS = (
    ("gain_error_pct", "action gain error, % of the range's\n(-: one command, not scored)", "{:.1f}", "gain"),
    ("best_sensor_pct", "best sensor's error, % of its span", "{:.2f}", "sensor"),
)
RANGE_BAR_KEY = {"gain_error_pct": "gain_pct_max", "best_sensor_pct": "sensor_pct_max"}
# by the likelihood, with no truth: each model's fall per sighting below the log's most likely (0 for it)
LIKELIHOOD_PANEL = (
    "below_best",
    "log-likelihood a sighting below the log's most likely\n(no ground truth)",
    "{:.3f}",
    None,
)


def figure_fleet(fleet: JsonObject, path: Path, title: str = "models on logs") -> Path:
    models, logs = fleet["models"], fleet["logs"]
    n_m, n_l = len(models), len(logs)
    panels = list(PANELS) if "cells" in fleet else []
    ranged = bool(fleet.get("range", {}).get("logs"))
    if ranged:
        panels += RANGE_PANELS
    if "likelihood" in fleet:
        panels.append(LIKELIHOOD_PANEL)
    cols = 1 if len(panels) == 1 else 2 if len(panels) == 4 else 3
    rows = -(-len(panels) // cols)
    w, h = max(3.2, 0.9 * n_l + 1.8), max(2.6, 0.6 * n_m + 1.4)
    fig, axes = plt.subplots(rows, cols, figsize=(cols * w, rows * h), squeeze=False)
    for ax, panel in zip(axes.ravel(), panels, strict=False):
        _panel(fig, ax, fleet, *panel)
    for ax in axes.ravel()[len(panels) :]:
        ax.axis("off")
    bars = "cells" in fleet or ranged
    what = "red outline, a bar missed; bold, a robot's own model" if bars else "bold, a robot's own model"
    fig.suptitle(f"{title}: {what}", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def _panel(fig: Any, ax: Any, fleet: JsonObject, key: str, name: str, fmt: str, part: str | None) -> None:
    models, logs, own = fleet["models"], fleet["logs"], fleet.get("own", {})
    on_range = key in RANGE_BAR_KEY
    if key == "below_best":
        cells = fleet["likelihood"]["cells"]
    elif on_range:  # only the CSVs whose range could score
        cells, logs = fleet["range"]["cells"], fleet["range"]["logs"]
    else:
        cells = fleet["cells"]
    grid = np.array([[np.nan if (v := cells[m][g][key]) is None else v for g in logs] for m in models], dtype=float)
    finite = grid[np.isfinite(grid)]
    if key.endswith("_ratio"):
        norm, cmap = LogNorm(1 / RATIO_SPAN, RATIO_SPAN, clip=True), "RdBu_r"
    elif key == "below_best":  # linear from 0, the most likely, so that models alike look alike
        norm, cmap = Normalize(0.0, max(float(finite.max()) if finite.size else 0.0, 1e-3)), "viridis"
    elif on_range:  # linear from 0 to past the bar, so that a pair within it looks dark
        bar_pct = fleet["range"]["bars"][RANGE_BAR_KEY[key]]
        norm, cmap = Normalize(0.0, max(float(finite.max()) if finite.size else 0.0, 2.0 * bar_pct)), "viridis"
    else:
        positive = grid[np.isfinite(grid) & (grid > 0)]
        lo = float(positive.min()) if positive.size else 1.0
        hi = float(positive.max()) if positive.size else 10.0
        norm, cmap = LogNorm(lo, max(hi, 1.01 * lo)), "viridis"
    im = ax.imshow(grid, cmap=cmap, norm=norm, aspect="auto")
    bar = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    if key.endswith("_ratio"):  # the bars' limits, where a model stops carrying over
        f, most = fleet["bars"]["sigma_factor"], fleet["bars"]["action_ratio_max"]
        bar.set_ticks(sorted({1 / RATIO_SPAN, 1 / f, 1.0, f, most, RATIO_SPAN}))
    elif on_range:
        bar.set_ticks(sorted({0.0, bar_pct, norm.vmax}))
    elif key != "below_best":
        bar.set_ticks(np.geomspace(norm.vmin, norm.vmax, 5))
    if key != "below_best" and not on_range:
        bar.ax.yaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:.2g}" if x < 10 else f"{x:.0f}"))
        bar.ax.yaxis.set_minor_formatter(FuncFormatter(lambda x, _: ""))
    if key == "range_residual_rms_mm":  # From-Truth's residual on each log, the floor a model could reach
        floor = [fleet["cells"][models[0]][g]["range_from_truth_rms_mm"] for g in logs]
        name += "\n(From-Truth's under each log)"
        labels = [f"{g}\n{f:.0f}" for g, f in zip(logs, floor, strict=True)]
    else:
        labels = list(logs)
    ax.set_xticks(range(len(logs)), labels, fontsize=8)
    ax.set_yticks(range(len(models)), models, fontsize=8)
    ax.set(xlabel="scored on the log of", ylabel="model learned on", title=name)
    for i, m in enumerate(models):
        for j, g in enumerate(logs):
            # a model that reads no bearing has no bearing bar (and no number: "-")
            if on_range:  # a gain not scored (one command) misses no bar
                miss = cells[m][g]["bars"].get(part) is False
            else:
                miss = part is not None and not all(cells[m][g]["bars"].get(b, True) for b in FLEET_BARS[part])
            text = fmt.format(grid[i, j]) if np.isfinite(grid[i, j]) else "-"
            if key == "best_sensor_pct" and np.isfinite(grid[i, j]):  # which sensor it is
                text += f"\n{cells[m][g]['best_sensor']}"
            ax.text(
                j,
                i,
                text,
                ha="center",
                va="center",
                fontsize=8,
                color="white" if _dark(im, grid[i, j]) else "black",
                fontweight="bold" if own.get(m) == g else "normal",
            )
            if miss:
                ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, ec="red", lw=2.5))


def _dark(im: Any, value: float) -> bool:
    """Whether a cell's colour is dark enough to need white text."""
    if not np.isfinite(value):
        return False
    r, g, b, _ = im.cmap(im.norm(value))
    return 0.299 * r + 0.587 * g + 0.114 * b < 0.5
