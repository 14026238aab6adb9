"""One figure for any EM fit, drawn from the fit alone (no ground truth): what `sensact learn em --out`
writes beside the model so that a user can judge a fit on a log nobody has measured.

Panels: the log-likelihood per iteration; each reading channel's readings against the smoothed distance
to the landmark, with the learned f over them; the smoothed path (planar: in the plane among the
landmarks; track: the distance against time), in SI units and the map's axes (``report.frames``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.core.pose_models import TRACK, sensor_distance
from sensact.report.figures1d import _save
from sensact.report.frames import MM, si


def _loglik_panel(ax: Any, res: Any) -> None:
    ll = res.loglik_history
    ax.plot(np.arange(ll.size), ll, lw=1, color="C0")
    ax.plot(res.best_iteration, ll[res.best_iteration], "*", ms=9, color="C3", label="best (the model written)")
    if 0 <= res.freed_at < ll.size:
        ax.plot(res.freed_at, ll[res.freed_at], "o", ms=5, color="k", label="held stage ends")
    searched = sorted({r.iteration for r in (res.ridge or []) + (res.delay_search or [])} & set(range(ll.size)))
    if searched:
        ax.plot(searched, ll[searched], "^", ms=5, color="C2", label="ridge / delay search")
    # the first iterations from a poor start are far below; show the climb that matters
    lo = np.percentile(ll, 5)
    span = max(ll.max() - lo, 1.0)
    ax.set_ylim(lo - 0.1 * span, ll.max() + 0.1 * span)
    ax.set(xlabel="EM iteration", ylabel="log P(O | C, λ)", title=f"log-likelihood ({res.stop_reason})")
    ax.legend(fontsize=7, loc="lower right")


def _channel_panel(ax: Any, res: Any, data: Any, j: int, col: int, dist: np.ndarray) -> None:
    ch = res.model.sensor.channels[j]
    reading = data.obs_readings[:, col]
    has = np.isfinite(reading)
    if ch.bearing_terms and data.obs_bearing_rad is not None:
        # readings with the learned bearing terms taken out scatter about f(d)
        b = np.nan_to_num(data.obs_bearing_rad)
        reading = reading - dist * ch.bearing_gain(b)
    w = res.posteriors.weights[:, j]
    used = has & (w > 0)
    # a robust channel's outliers stay in with a small Student-t weight
    low = used & (w < 0.5)
    name, k = si(ch.name)  # shown in SI: a range in mm as metres (a height in px stays px)
    d, y = dist * MM, reading * k
    ax.scatter(d[has & ~used], y[has & ~used], s=3, alpha=0.3, color="0.7", label="not used (pruned, robust, window)")
    ax.scatter(d[used & ~low], y[used & ~low], s=3, alpha=0.3, color="C0", label="used")
    if low.any():
        ax.scatter(d[low], y[low], s=3, alpha=0.3, color="C1", label="weight below 0.5 (robust)")
    lo, hi = (dist[used].min(), dist[used].max()) if used.any() else (dist[has].min(), dist[has].max())
    x = np.linspace(lo, hi, 200)
    ax.plot(x * MM, ch.function(x) * k, color="C3", lw=2, label=f"learned f, σ = {ch.sigma * k:.3g}")
    for edge in (ch.valid_min, ch.valid_max):
        if math.isfinite(edge):
            ax.axvline(edge * MM, color="k", ls=":", lw=1)
    if used.any():
        r = reading[used] * k
        pad = 0.15 * (np.percentile(r, 99.5) - np.percentile(r, 0.5))
        ax.set_ylim(np.percentile(r, 0.5) - pad, np.percentile(r, 99.5) + pad)
    extra = " − bearing terms" if ch.bearing_terms else ""
    ax.set(
        xlabel="smoothed distance to the landmark (m)", ylabel=f"{name}{extra}", title=f"{name}: f over the readings"
    )
    ax.legend(fontsize=7, markerscale=3)


def _path_panel(ax: Any, res: Any, data: Any) -> None:
    m = res.posteriors.mean_gamma
    t = np.arange(data.n_steps) * data.dt_s
    if data.mode == TRACK:
        ax.plot(t, m[:, 0] * MM, lw=0.8)
        ax.set(xlabel="time (s)", ylabel="smoothed distance (m)", title="smoothed state")
        return
    ax.plot(m[:, 0] * MM, m[:, 1] * MM, lw=0.6, label="smoothed path")
    ax.plot(m[0, 0] * MM, m[0, 1] * MM, "o", color="C2", label="start")
    ax.scatter(*(data.landmarks_xy * MM).T, marker="s", color="k", s=20, label="landmarks")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="map x (m)", ylabel="map y (m)", title="smoothed path")
    ax.legend(fontsize=7)


def figure_em_fit(res: Any, data: Any, path: Path, title: str) -> Path:
    """The fit's own evidence: the likelihood's climb, each f over its readings, the smoothed path."""
    assert res.posteriors is not None, "the fit's posteriors are needed"
    channels = res.model.sensor.channels
    cols = res.model.sensor.columns(data)
    dist = sensor_distance(
        res.posteriors.mean_gamma[data.obs_step],
        data.landmarks_xy[data.obs_landmark],
        res.model.sensor.mount.as_array(),
        data.mode,
    )
    n = len(channels) + 2
    ncol = min(n, 3)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.0 * nrow), squeeze=False)
    flat = axes.ravel()
    _loglik_panel(flat[0], res)
    for j, col in enumerate(cols):
        _channel_panel(flat[1 + j], res, data, j, col, dist)
    _path_panel(flat[len(channels) + 1], res, data)
    for ax in flat[n:]:
        ax.set_visible(False)
    for ax in flat[:n]:
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def _localized_path_panel(ax: Any, posteriors: Any, data: Any, truth: Any) -> None:
    """The smoothed path (a track: the distance with two sds about it against time) and, when the log has
    them, the recorded poses or distances, drawn in the model's own unit."""
    m = posteriors.mean_gamma
    t = np.arange(data.n_steps) * data.dt_s
    if data.mode == TRACK:
        sd = np.sqrt(posteriors.cov_gamma[:, 0, 0]) * MM
        d = m[:, 0] * MM
        ax.fill_between(t, d - 2 * sd, d + 2 * sd, color="C0", alpha=0.25, lw=0, label="± 2 sd")
        ax.plot(t, d, lw=0.8, color="C0", label="smoothed distance")
        if truth is not None:
            ax.plot(t, truth[0][:, 0] * MM, lw=0.8, color="k", ls="--", label="recorded")
        ax.set(xlabel="time (s)", ylabel="distance (m)", title="where the model puts the robot")
        ax.legend(fontsize=7)
        return
    if truth is not None:
        poses, valid = truth
        xy = np.where(valid[:, None], poses[:, :2], np.nan) * MM  # a gap in the truth stays a gap
        ax.plot(xy[:, 0], xy[:, 1], lw=0.6, color="k", ls="--", label="recorded poses")
    ax.plot(m[:, 0] * MM, m[:, 1] * MM, lw=0.6, color="C0", label="smoothed path")
    ax.plot(m[0, 0] * MM, m[0, 1] * MM, "o", color="C2", label="start found")
    ax.scatter(*(data.landmarks_xy * MM).T, marker="s", color="k", s=20, label="landmarks")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="map x (m)", ylabel="map y (m)", title="where the model puts the robot")
    ax.legend(fontsize=7)


def figure_localized(loc: Any, data: Any, path: Path, title: str, truth: Any = None) -> Path:
    """`sensact localize`'s figure (``learn/em/uses/place.Localized``): the path, and each learned f, held,
    over this log's readings against the smoothed distance, so that a model that does not fit the log
    shows. ``truth``: ``(poses, valid)`` on a planar log, ``(distances (T, 1), None)`` on a track."""
    channels = loc.model.sensor.channels
    cols = loc.model.sensor.columns(data)
    post = loc.posteriors
    dist = sensor_distance(
        post.mean_gamma[data.obs_step],
        data.landmarks_xy[data.obs_landmark],
        loc.model.sensor.mount.as_array(),
        data.mode,
    )
    n = len(channels) + 1
    ncol = min(n, 3)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.0 * nrow), squeeze=False)
    flat = axes.ravel()
    _localized_path_panel(flat[0], post, data, truth)
    for j, col in enumerate(cols):
        _channel_panel(flat[1 + j], loc, data, j, col, dist)
    for ax in flat[n:]:
        ax.set_visible(False)
    for ax in flat[:n]:
        ax.grid(alpha=0.3)
    fig.suptitle(f"{title}: log-likelihood {loc.loglik_per_sighting:.3f} a sighting")
    fig.tight_layout()
    return _save(fig, path)
