"""Figures for chapter 4, drawn like the thesis's Figures 4.2 to 4.7."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.evaluate.em import fit_distance_map
from sensact.evaluate.track1d import DISTANCE_GRID_MM
from sensact.report.figures1d import _save


def figure_learning_curve(
    trial: Any, velocity_rms: np.ndarray | None, path: Path, title: str, thesis: dict[str, float] | None = None
) -> Path:
    """Figures 4.2 / 4.4: log-likelihood per iteration and, when the truth is known, velocity RMS."""
    res = trial.result
    it = np.arange(res.iterations)
    panels = 2 if velocity_rms is not None else 1
    fig, axes = plt.subplots(1, panels, figsize=(6 * panels, 3.8), squeeze=False)
    ax = axes[0, 0]
    ax.plot(it, res.loglik_history, lw=1)
    ax.axvline(res.best_iteration, color="0.5", ls=":", label=f"best, iteration {res.best_iteration}")
    lo = np.percentile(res.loglik_history, 2)
    ax.set_ylim(lo - 0.05 * abs(lo), res.loglik_history.max() + 0.02 * abs(lo))
    ax.set(xlabel="EM iteration", ylabel="log P(O | C, λ)", title=f"{title}: log-likelihood")
    ax.legend(loc="lower right", fontsize=8)
    if velocity_rms is not None:
        ax = axes[0, 1]
        ax.plot(it, velocity_rms[:, 0], label="v_x")
        ax.plot(it, velocity_rms[:, 1], label="v_y")
        if thesis:
            ax.axhline(thesis["vx_rms_mm_s"], color="C0", ls="--", lw=0.8, label="thesis v_x")
            ax.axhline(thesis["vy_rms_mm_s"], color="C1", ls="--", lw=0.8, label="thesis v_y")
        ax.set_yscale("log")
        ax.set(xlabel="EM iteration", ylabel="RMS error (mm/s)", title="velocity error against the truth")
        ax2 = ax.twinx()
        ax2.plot(it, velocity_rms[:, 2], color="C2", lw=0.8, label="v_θ (rad/s)")
        ax2.set_yscale("log")
        ax2.set_ylabel("v_θ RMS (rad/s)")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def figure_sensor(
    start: Any, learned: Any, true_height: Any, path: Path, title: str, d_range: tuple[float, float] = (1275, 4175)
) -> Path:
    """Figures 4.3 / 4.5: the starting, learned and true beacon-height functions f(d)."""
    d = np.linspace(*d_range, 200)
    fig, ax = plt.subplots(figsize=(6.5, 4))
    ax.plot(d, true_height(d), "k", lw=2.5, alpha=0.4, label="true f")
    ax.plot(d, learned(d), "C0", label="learned f")
    ax.plot(d, start(d), "C3--", label="starting f")
    ax.set(xlabel="distance to beacon (mm)", ylabel="beacon height (px)", title=title)
    ax.legend()
    fig.tight_layout()
    return _save(fig, path)


def figure_track(
    model: Any,
    true_velocities: np.ndarray,
    true_height: Any,
    commands: np.ndarray,
    path: Path,
    title: str,
    stale: Any = None,
) -> Path:
    """Figures 4.6 / 4.7: learned 1-D sensor and action models after the optimal scale, against the truth."""
    d = np.asarray(DISTANCE_GRID_MM, dtype=float)
    dmap = fit_distance_map(model.sensor.height, true_height, d)
    dd = np.linspace(d.min(), d.max(), 200)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    a1.plot(d, true_height(d), "ko", ms=4, label="true")
    a1.plot(dd, model.sensor.height(dmap.scale * dd + dmap.offset), "C0", label="learned (optimally mapped)")
    a1.set(xlabel="distance (mm)", ylabel="beacon height (px)", title=f"{title}: sensor model")
    a1.legend()
    for m, style, name in ((model, "C0", "learned"), (stale, "C3--", "stale (before the change)")):
        if m is None:
            continue
        v = m.action.velocities[:, 0]
        k = float(v @ true_velocities / (v @ v))
        a2.plot(commands, k * v, style, marker=".", label=f"{name}, scaled")
    a2.plot(commands, true_velocities, "ko", ms=4, label="true")
    a2.set(xlabel="attempted a_y", ylabel="velocity (mm/s)", title=f"{title}: action model")
    a2.legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)
