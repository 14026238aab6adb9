"""The figures of a calibration's report that `figure_em_fit` does not draw, from the fit alone (the truth's
path drawn when the log has one): each channel's residuals about the smoothed path (histogram against the
model's noise, and their autocorrelation in time), the learned action model against the commands, and
the smoothed path over the recorded one."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.core.pose_models import PLANAR, landmark_bearing, relative_displacement, sensor_distance, sensor_poses
from sensact.report.figures1d import _save
from sensact.report.frames import LABEL, MM, REP_ORDER, si, velocity_rep

MAX_LAG = 20
WINDOW_S = 1.0  # velocities are compared over windows this long: one step's is mostly noise


def standardized_residuals(res: Any, data: Any) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each channel's (and the bearing's) residual about the smoothed path over its sigma, with the step of
    each, for the sightings EM used (weight above 0), in time order."""
    model, post = res.model, res.posteriors
    poses = post.mean_gamma[data.obs_step]
    mount = model.sensor.mount.as_array()
    dist = sensor_distance(poses, data.landmarks_xy[data.obs_landmark], mount, data.mode)
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for j, col in enumerate(model.sensor.columns(data)):
        ch = model.sensor.channels[j]
        reading = data.obs_readings[:, col]
        pred = ch.function(dist)
        if ch.bearing_terms and data.obs_bearing_rad is not None:
            pred = pred + dist * ch.bearing_gain(np.nan_to_num(data.obs_bearing_rad))
        used = np.isfinite(reading) & (post.weights[:, j] > 0)
        out[ch.name] = ((reading[used] - pred[used]) / ch.sigma, data.obs_step[used])
    sigma_b = model.sensor.sigma_bearing_rad
    if data.mode == PLANAR and data.obs_bearing_rad is not None and sigma_b:
        at = sensor_poses(poses, mount)
        r = np.angle(np.exp(1j * (data.obs_bearing_rad - landmark_bearing(at, data.landmarks_xy[data.obs_landmark]))))
        ok = np.isfinite(r)
        out["bearing"] = (r[ok] / sigma_b, data.obs_step[ok])
    return out


def autocorrelation(x: np.ndarray, max_lag: int = MAX_LAG) -> np.ndarray:
    """The sample autocorrelation at lags 1..max_lag (NaN where too short)."""
    x = np.asarray(x, dtype=float) - np.mean(x)
    var = float(x @ x)
    return np.array(
        [float(x[k:] @ x[:-k]) / var if 0 < k < x.size and var > 0 else np.nan for k in range(1, max_lag + 1)]
    )


def noise_laws(model: Any) -> dict[str, tuple[str, float]]:
    """Each reading's noise law over its sigma as the model has it: ("none", 0) is N(0, 1), ("student_t",
    nu) a Student-t of nu degrees of freedom (a gate's readings are Gaussian inside it)."""
    laws = {ch.name: (ch.robust, ch.robust_param) for ch in model.sensor.channels}
    return laws | {"bearing": (model.sensor.bearing_robust, model.sensor.bearing_robust_param)}


def figure_residuals(res: Any, data: Any, path: Path, title: str) -> Path:
    """A row per channel: the standardized residuals' histogram over the model's noise law (N(0, 1), or
    the Student-t of a robust reading), and their autocorrelation by lag in sightings (a band of 2/sqrt(n)
    about 0 is what independent errors stay within)."""
    from scipy.stats import t as student_t

    resid = standardized_residuals(res, data)
    laws = noise_laws(res.model)
    n = max(len(resid), 1)
    fig, axes = plt.subplots(n, 2, figsize=(10.0, 3.0 * n), squeeze=False)
    z = np.linspace(-5, 5, 201)
    for (name, (r, _)), (ax_h, ax_a) in zip(resid.items(), axes, strict=False):
        ax_h.hist(np.clip(r, -5, 5), bins=60, range=(-5, 5), density=True, color="C0", alpha=0.7)
        kind, nu = laws.get(name, ("none", 0.0))
        if kind == "student_t":
            ax_h.plot(z, student_t.pdf(z, nu), color="C3", label=f"Student-t, {nu:g} dof: the model's noise")
        else:
            ax_h.plot(z, np.exp(-0.5 * z**2) / np.sqrt(2 * np.pi), color="C3", label="N(0, 1): the model's noise")
        ax_h.set(
            xlabel=f"{si(name)[0]} residual / learned sigma",
            ylabel="density",
            title=f"{si(name)[0]}: {r.size} residuals",
        )
        ax_h.legend(fontsize=7)
        ac = autocorrelation(r)
        lags = np.arange(1, ac.size + 1)
        ax_a.bar(lags, ac, color="C0")
        band = 2 / np.sqrt(max(r.size, 1))
        ax_a.axhspan(-band, band, color="0.85", zorder=0, label="independent errors (95 %)")
        ax_a.set(xlabel="lag (sightings)", ylabel="autocorrelation", title=f"{name}: correlated errors", ylim=(-1, 1))
        ax_a.legend(fontsize=7)
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def _windowed(x: np.ndarray, k: int) -> np.ndarray:
    n = x.shape[0] // k
    return x[: n * k].reshape(n, k, *x.shape[1:]).mean(axis=1)


def figure_actions(res: Any, data: Any, path: Path, title: str) -> Path:
    """Each velocity EM moves the robot by, against the command that drives it most: the smoothed path's
    (over 1 s windows) and the learned action model's, A(c), on the same windows."""
    model, post = res.model, res.posteriors
    action = model.action
    names = action.velocity_names
    if data.step_commands is None or not hasattr(action, "step_features"):
        fig, ax = plt.subplots(figsize=(5, 2))
        ax.text(0.5, 0.5, "an action table: no commands to draw against", ha="center", va="center")
        ax.set_axis_off()
        return _save(fig, path)
    predicted = action.step_features(data.step_commands) @ action.coefficients  # (T, n) per second
    m = post.mean_gamma
    moved = relative_displacement(m[:-1], m[1:], data.mode) / data.dt_s  # robot frame, per second
    if data.mode == PLANAR:
        moved[:, 2] = np.angle(np.exp(1j * moved[:, 2] * data.dt_s)) / data.dt_s
    k = max(1, round(WINDOW_S / data.dt_s))
    smoothed, pred = _windowed(moved, k), _windowed(predicted[:-1], k)
    cmds = _windowed(data.step_commands[:-1], k)
    rep = [velocity_rep(n) for n in names]  # REP 103 and SI, as the page's table and the exports
    order = sorted(range(len(names)), key=lambda i: REP_ORDER.index(rep[i][0]) if rep[i][0] in REP_ORDER else i)
    fig, axes = plt.subplots(1, len(names), figsize=(4.6 * len(names), 3.8), squeeze=False)
    for i, ax in zip(order, axes[0], strict=True):
        spread = np.abs(np.corrcoef(np.column_stack([cmds, pred[:, i]]).T)[-1, :-1]) if pred[:, i].std() > 0 else None
        c = int(np.nanargmax(spread)) if spread is not None and np.isfinite(spread).any() else 0
        (name, k), (command, kc) = rep[i], si(data.command_names[c])
        ax.scatter(cmds[:, c] * kc, smoothed[:, i] * k, s=4, alpha=0.4, color="C0", label="smoothed path")
        ax.scatter(cmds[:, c] * kc, pred[:, i] * k, s=4, alpha=0.6, color="C3", label="learned A(c)")
        ax.set(xlabel=command, ylabel=name, title=f"{name} against {command}")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, markerscale=3)
    fig.suptitle(f"{title} ({LABEL})")
    fig.tight_layout()
    return _save(fig, path)


def figure_path_over_truth(res: Any, data: Any, truth: np.ndarray, valid: np.ndarray, path: Path, title: str) -> Path:
    """The smoothed path over the recorded one (planar), or the state against the recorded distance."""
    m = res.posteriors.mean_gamma
    fig, ax = plt.subplots(figsize=(6.5, 5.5))
    if data.mode == PLANAR:
        tr = np.where(valid[:, None], truth[:, :2], np.nan) * MM
        ax.plot(tr[:, 0], tr[:, 1], color="k", lw=1.2, label="recorded (truth)")
        ax.plot(m[:, 0] * MM, m[:, 1] * MM, color="C0", lw=0.8, label="EM's smoothed path")
        ax.scatter(*(data.landmarks_xy * MM).T, marker="s", color="C2", s=20, label="landmarks")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set(xlabel="map x (m)", ylabel="map y (m)")
    else:
        t = np.arange(data.n_steps) * data.dt_s
        ax.plot(t, np.where(valid, truth[:, 0], np.nan) * MM, color="k", lw=1.2, label="recorded distance")
        ax.plot(t, m[:, 0] * MM, color="C0", lw=0.8, label="EM's smoothed state")
        ax.set(xlabel="time (s)", ylabel="distance (m)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    return _save(fig, path)


def figure_landmark_map(
    learned: Any,
    names: tuple[str, ...],
    path_xy: np.ndarray | None,
    survey: np.ndarray | None,
    alignment: Any,
    out: Path,
    title: str,
) -> Path:
    """The map EM learned (docs/map.md): each placed landmark with its 2-sd ellipse and name, EM's path, and
    the survey when the log has one, the learned map laid on it by the best rigid alignment (no scale)."""
    from matplotlib.patches import Ellipse

    xy, angle = learned.xy, 0.0
    if alignment is not None:
        xy, angle = alignment.points(xy), alignment.rotation_rad
        path_xy = None if path_xy is None else alignment.points(path_xy)
    fig, ax = plt.subplots(figsize=(6.5, 5.5))
    if path_xy is not None:
        ax.plot(*(path_xy * MM).T, color="0.6", lw=0.6, label="EM's smoothed path")
    if survey is not None:
        ax.scatter(*(survey * MM).T, marker="x", color="k", s=40, label="surveyed (never learned from)")
    placed = learned.placed & np.isfinite(xy).all(axis=1)
    ax.scatter(*(xy[placed] * MM).T, marker="s", color="C2", s=18, label="learned (2-sd ellipses)")
    for j in np.flatnonzero(placed):
        sx, sy = np.nan_to_num(learned.sd[j], nan=0.0)
        ax.add_patch(
            Ellipse(xy[j] * MM, 4 * sx * MM, 4 * sy * MM, angle=np.degrees(angle), fill=False, color="C2", lw=0.8)
        )
        ax.annotate(names[j], xy[j] * MM, fontsize=6, xytext=(3, 3), textcoords="offset points")
    if (~placed).any():
        ax.set_title(f"{title}\nnot placed: {', '.join(names[j] for j in np.flatnonzero(~placed))}", fontsize=9)
    else:
        ax.set_title(title)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="map x (m)", ylabel="map y (m)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, out)
