"""Figures for chapter 5, drawn like the thesis's Figures 5.2 to 5.5."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.learn.scan_odometry import scan_points
from sensact.report.figures1d import _save


def figure_5_2(log: Any, rel_rad: np.ndarray, t_s: float, dt_s: float, path: Path) -> Path:
    """Two scans dt apart, in the lidar frame (x_C, y_C)."""
    per_rev = round(2 * np.pi / abs(log.omega_rad_s) * log.firing_hz)
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    for t, color in ((t_s, "C3"), (t_s + dt_s, "C0")):
        a = round(t * log.firing_hz)
        p = scan_points(log.rotation_rad[a : a + per_rev], log.distance_m[a : a + per_rev], log.vertical_rad, rel_rad)
        ax.scatter(p[:, 0], p[:, 1], s=0.3, color=color, label=f"scan at {t:.1f} s")
    ax.plot(0, 0, "kx", ms=10)
    ax.set(xlabel="x_C (m)", ylabel="y_C (m)", title="two consecutive scans (points > 1 m below the sensor dropped)")
    ax.set_aspect("equal")
    ax.legend(markerscale=20)
    return _save(fig, path)


def figure_5_3(learned_rad: np.ndarray, true_rad: np.ndarray, vertical_rad: np.ndarray, path: Path) -> Path:
    order = np.argsort(vertical_rad)
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(np.degrees(true_rad[order]), "ko", ms=4, label="true θ_l + θ_b")
    ax.plot(np.degrees(learned_rad[order]), "C0.-", label="learned")
    ax.set(xlabel="laser, by vertical angle", ylabel="horizontal angle (deg)", title="laser angles")
    ax.legend()
    return _save(fig, path)


def figure_5_4_5(times_s, truth, predicted, path: Path, window_s: tuple[float, float]) -> Path:
    """Accelerations, forward and angular velocities predicted from the actions, against the truth."""
    v, w, a = truth
    pv, pa, pw = predicted
    k = (times_s >= window_s[0]) & (times_s <= window_s[1])
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for ax, true, pred, label in (
        (axes[0], a, pa, "acceleration (m/s²)"),
        (axes[1], v, pv, "forward velocity (m/s)"),
        (axes[2], w, pw, "angular velocity (rad/s)"),
    ):
        ax.plot(times_s[k], true[k], "k", label="truth (Applanix-like)")
        ax.plot(times_s[k], pred[k], "C0", label="learned model on the actions")
        ax.set_ylabel(label)
    axes[0].legend()
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    return _save(fig, path)
