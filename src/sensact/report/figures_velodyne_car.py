"""Figures for chapter 5, drawn like the thesis's Figures 5.2 to 5.5, and the one `sensact learn car --out`
draws from a drive alone (``figure_car_fit``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.learn.scan_odometry import scan_points
from sensact.learn.velodyne_car_dynamics import motion_to_velocities
from sensact.report.figures1d import _save


def _revolution(log: Any, relative_rad: np.ndarray, at_s: float) -> np.ndarray:
    """(N, 2) points in (x_C, y_C) of the revolution that starts at ``at_s`` (the last whole one if later)."""
    per_rev = round(2 * np.pi / abs(log.omega_rad_s) * log.firing_hz)
    a = min(max(round(at_s * log.firing_hz), 0), max(len(log.rotation_rad) - per_rev, 0))
    return scan_points(
        log.rotation_rad[a : a + per_rev], log.distance_m[a : a + per_rev], log.vertical_rad, relative_rad
    )


def figure_5_2(log: Any, rel_rad: np.ndarray, t_s: float, dt_s: float, path: Path) -> Path:
    """Two scans dt apart, in the lidar frame (x_C, y_C)."""
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    for t, color in ((t_s, "C3"), (t_s + dt_s, "C0")):
        p = _revolution(log, rel_rad, t)
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


def _scan_panel(ax: Any, log: Any, relative_rad: np.ndarray, at_s: float, title: str, lim: float) -> None:
    p = _revolution(log, relative_rad, at_s)
    ax.scatter(p[:, 0], p[:, 1], s=0.2, color="k", alpha=0.5)
    ax.plot(0, 0, "x", color="C3", ms=8)
    ax.set(xlim=(-lim, lim), ylim=(-lim, lim), xlabel="x_C (m)", ylabel="y_C (m)", title=title)
    ax.set_aspect("equal")


def figure_car_fit(
    res: Any,
    log: Any,
    path: Path,
    title: str,
    reference: tuple[np.ndarray, str] | None = None,
    dt_s: float = 0.5,
) -> Path:
    """A drive's own evidence, with no ground truth: one revolution drawn with the learned laser angles and
    with every angle equal (what the lasers' spread of sec. 5.1 does to a scan), the learned angles by
    laser (beside ``reference``, e.g. a factory calibration shifted by the mount yaw), and the motion from
    scan matching (sec. 5.2) against the learned eqs. 5.3-5.5 run on the controls, when there are any."""
    fig, axes = plt.subplots(2, 3, figsize=(16, 9.5))
    mid_s = 0.5 * len(log.rotation_rad) / log.firing_hz
    # the axes' reach from a few thousand firings spread over the drive: the whole drive's returns are
    # 400 MB, and a mask and a float64 copy of them would triple it
    sample = log.distance_m[:: max(1, len(log.distance_m) // 4096)]
    d = sample[np.isfinite(sample) & (sample > 0)]
    lim = float(np.percentile(d, 90)) if d.size else 50.0
    rel = res.intrinsics.relative_rad
    _scan_panel(axes[0, 0], log, rel, mid_s, f"one revolution at {mid_s:.0f} s, learned angles", lim)
    _scan_panel(axes[0, 1], log, np.zeros_like(rel), mid_s, "the same revolution, every laser at one angle", lim)
    ax = axes[0, 2]
    order = np.argsort(log.vertical_rad)
    if reference is not None:
        ax.plot(np.degrees(reference[0][order]), "ko", ms=4, label=reference[1])
    ax.plot(
        np.degrees(res.laser_angles_rad[order]),
        "C0.-",
        label=f"learned θ_l + θ_b (C = {np.degrees(res.offset_rad):.2f}°)",
    )
    ax.set(xlabel="laser, by vertical angle", ylabel="horizontal angle (deg)", title="laser angles")
    ax.legend(fontsize=8)
    v, w, a = motion_to_velocities(res.odometry.motion, res.offset_rad, dt_s)
    t = res.odometry.times_s
    model = getattr(res, "model", None)
    pred = None
    if model is not None:
        K = len(res.actions) - 1
        pv, pa, pw = model.predict(res.actions[:K], res.speed_m_s[0], dt_s)
        pred = (res.interval_times_s[:K], pv, pw, pa)
    K = max(len(v) - 1, 0)  # the last interval's acceleration has no successor
    for ax, series, label, j in (
        (axes[1, 0], v, "forward velocity (m/s)", 1),
        (axes[1, 1], w, "angular velocity (rad/s)", 2),
        (axes[1, 2], a[:K], "acceleration (m/s²)", 3),
    ):
        ax.plot(t[: len(series)], series, "k", lw=1, label="scan matching")
        if pred is not None:
            ax.plot(pred[0], pred[j], "C0", lw=1, label="learned model on the controls")
        ax.set(xlabel="time (s)", ylabel=label)
        ax.legend(fontsize=8)
    if pred is None:
        axes[1, 0].set_title("no actions.csv: the motion scan matching found")
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)
