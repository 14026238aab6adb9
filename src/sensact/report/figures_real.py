"""Figures for EM on real robots: action curves against Vicon, the range function over the residual
scatter, the heading noise against Vicon's, and the log-likelihood per iteration."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.core.pose_models import landmark_distance
from sensact.models.polynomial import Polynomial1D
from sensact.report.figures1d import _save


def figure_action_curves(ml: Any, res: Any, score: dict[str, Any], path: Path, title: str) -> Path:
    """Forward speed against commanded v (omega = 0) and turn rate against commanded omega (v at its
    median), learned and From-Truth, over the commands the robot used."""
    act = res.model.action
    beta_ft = np.asarray(score["action"]["from_truth_coefficients"])
    c = ml.data.step_commands
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    v = np.linspace(c[:, 0].min(), c[:, 0].max(), 50)
    grid = np.column_stack([v, np.zeros_like(v)])
    axes[0].plot(v, act.features(grid) @ act.coefficients[:, 1], label="learned (EM)")
    axes[0].plot(v, act.features(grid) @ beta_ft[:, 1], "--", label="From-Truth (Vicon)")
    axes[0].plot(v, v, ":", color="0.5", label="command")
    axes[0].set(xlabel="commanded v (mm/s)", ylabel="forward velocity v_y (mm/s)", title=f"{title}: forward")
    w = np.linspace(c[:, 1].min(), c[:, 1].max(), 50)
    grid = np.column_stack([np.full_like(w, np.median(c[:, 0])), w])
    axes[1].plot(w, act.features(grid) @ act.coefficients[:, 2], label="learned (EM)")
    axes[1].plot(w, act.features(grid) @ beta_ft[:, 2], "--", label="From-Truth (Vicon)")
    axes[1].plot(w, w, ":", color="0.5", label="command")
    axes[1].set(xlabel="commanded omega (rad/s)", ylabel="turn rate v_theta (rad/s)", title=f"{title}: turning")
    for ax in axes:
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def figure_range_function(ml: Any, res: Any, score: dict[str, Any], path: Path, title: str) -> Path:
    """Readings against the Vicon distance, with the learned and From-Truth range functions. With bearing
    terms the readings are shown with the learned terms taken out, ``reading - d g(b)``, so that they
    scatter about f(d)."""
    from sensact.evaluate.landmark_truth import at_sensor

    d = ml.data
    poses, valid = ml.truth_poses()
    poses, ok = poses[d.obs_step], valid[d.obs_step]
    m = score.get("sensor_mount", {})
    mount = [m.get("lateral_mm", 0.0), m.get("forward_mm", 0.0), m.get("yaw_rad", 0.0)]
    dist = landmark_distance(at_sensor(poses[ok], mount), d.landmarks_xy[d.obs_landmark[ok]])
    chan = res.model.sensor.channels[0]
    reading = d.obs_readings[ok, 0] - dist * chan.bearing_gain(d.obs_bearing_rad[ok])
    f = chan.function
    f_ft = Polynomial1D.from_dict(score["range"]["from_truth_function"])
    x = np.linspace(dist.min(), dist.max(), 200)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    what = "sightings, learned bearing terms removed" if chan.bearing_terms else "sightings"
    ax.scatter(dist, reading, s=3, alpha=0.25, color="0.4", label=f"{what} (Vicon, at the fitted sensor pose)")
    ax.plot(x, f(x), lw=2, label="learned f (EM)")
    ax.plot(x, f_ft(x), "--", lw=2, label="From-Truth f")
    ax.set(xlabel="true distance (mm)", ylabel="range reading (mm)", title=f"{title}: range function")
    ax.set_ylim(0, np.percentile(reading, 99.5) * 1.1)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def figure_heading_noise(ml: Any, res: Any, score: dict[str, Any], path: Path, title: str) -> Path:
    """The truth's heading drift over each 1-s window against the window's turn rate, its RMS in bins,
    the truth's ``a + b |turn|`` fit, and the drift the learned Sigma_m allows over the same window."""
    from sensact.evaluate.landmark_truth import from_truth_windows, heading_drift

    d = ml.data
    window = round(score["window_s"] / d.dt_s)
    _, D_true, features = from_truth_windows(d, *ml.truth_poses(), res.model.action, window)
    beta = np.asarray(score["action"]["from_truth_coefficients"])
    turn, drift = heading_drift(features(round(score["action"]["from_truth_delay_s"] / d.dt_s)) @ beta, D_true, d.dt_s)
    a, b = score["truth_noise"]["heading_drift_variance_fit"]
    a_m, b_m = score["truth_noise"]["learned_heading_variance_per_step"]
    x = np.linspace(0.0, np.percentile(turn, 99), 100)
    edges = np.quantile(turn, np.linspace(0, 1, 11))
    which = np.clip(np.searchsorted(edges, turn, side="right") - 1, 0, 9)
    rms = [np.sqrt(np.mean(drift[which == k] ** 2)) for k in range(10)]
    mid = [np.median(turn[which == k]) for k in range(10)]
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ax.scatter(turn, np.abs(drift), s=3, alpha=0.2, color="0.5", label="|heading drift| per window (Vicon)")
    ax.plot(mid, rms, "o", color="k", label="its RMS in tenths of the windows")
    ax.plot(x, np.sqrt(np.maximum(a + b * x, 0.0)), "--", lw=2, label="Vicon: variance a + b |turn|")
    kind = "turning" if res.model.turn_var is not None else "shared"
    ax.plot(x, np.sqrt(window * (a_m + b_m * x)), lw=2, label=f"learned Sigma_m ({kind})")
    ax.set(
        xlabel="window's mean turn rate (rad/s)",
        ylabel=f"heading drift over {score['window_s']:.2g} s (rad)",
        title=f"{title}: heading noise",
    )
    ax.set_xlim(0, x[-1])
    ax.set_ylim(0, 3 * max(rms))
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def figure_loglik(results: dict[str, Any], path: Path) -> Path:
    """log P(O | C, lambda) against the iteration, one line per run; a dot where the held stage ends
    (from there the likelihood is the robust one, with Sigma_m and the bearing terms learned) and a
    triangle at each later ridge or delay search (learn/em/ridge.py, delay_search.py), whose move shows
    as the next step up."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, res in results.items():
        ll = res.loglik_history
        (line,) = ax.plot(np.arange(ll.size), ll - ll.max(), lw=1, label=name)
        if 0 <= res.freed_at < ll.size:
            ax.plot(res.freed_at, ll[res.freed_at] - ll.max(), "o", ms=4, color=line.get_color())
        searched = {r["iteration"] for r in (res.ridge or []) + (res.delay_search or [])}
        later = sorted(i for i in searched if res.freed_at < i < ll.size)
        if later:
            ax.plot(later, ll[later] - ll.max(), "^", ms=4, color=line.get_color())
    ax.set_yscale("symlog", linthresh=10)
    ax.set(
        xlabel="EM iteration after the start race (dot: held stage ends; triangle: a search)",
        ylabel="log-likelihood minus its best",
        title="EM on real robots",
    )
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def write_all(art: dict[str, Any], res: dict[str, Any], out: Path) -> list[Path]:
    paths = []
    runs = {}
    for key, (ml, r) in art.get("mrclam", {}).items():
        score = res["mrclam"][key]["score"]
        stem, name = f"real_mrclam_{key.replace('/', '_')}", key.replace("/", " ").replace("robot", "robot ")
        paths.append(figure_action_curves(ml, r, score, out / f"{stem}_actions.png", name))
        paths.append(figure_range_function(ml, r, score, out / f"{stem}_range.png", name))
        paths.append(figure_heading_noise(ml, r, score, out / f"{stem}_heading_noise.png", name))
        runs[f"MRCLAM {name}"] = r
    if "turtlebot" in art:
        runs["Turtlebot"] = art["turtlebot"]
    if runs:
        paths.append(figure_loglik(runs, out / "real_loglik.png"))
    return paths
