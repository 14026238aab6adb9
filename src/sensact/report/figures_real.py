"""Figures for EM on real robots: action curves against Vicon, the range function over the residual
scatter, the heading noise against Vicon's, the bearing noise against Vicon's, and the log-likelihood
per iteration. The legends name the ground truth ``truth``: Vicon on MRCLAM, "ground truth" for a log
folder's groundtruth.csv of unknown origin."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.core.pose_models import landmark_distance
from sensact.models.polynomial import Polynomial1D
from sensact.records import JsonObject
from sensact.report.figures1d import _save
from sensact.report.figures_turtlebot_em import figure_turtlebot_em
from sensact.report.frames import MM, si, velocity_rep


def _truth_at_sensor(ml: Any, score: JsonObject) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sightings with valid truth (a mask), Vicon's pose moved to the sensor mount the score fitted
    at each, and each one's landmark: what the sensor bars score against."""
    from sensact.core.pose_models import sensor_poses

    d = ml.data
    poses, valid = ml.truth_poses()
    ok = valid[d.obs_step] > 0
    m = score["sensor_mount"]["fitted_to_truth"] or {}  # None: no bearings to fit it by, the truth's origin
    mount = (m.get("forward_mm", 0.0), m.get("left_mm", 0.0), m.get("yaw_rad", 0.0))
    return ok, sensor_poses(poses[d.obs_step[ok]], mount), d.landmarks_xy[d.obs_landmark[ok]]


_VELOCITY_LABELS = {  # the panel's title word and its axis, in REP 103 and SI (report.frames)
    "v_x_mm_s": ("sideways velocity", "sideways velocity vy, + left (m/s)"),
    "v_y_mm_s": ("forward velocity", "forward velocity vx (m/s)"),
    "v_theta_rad_s": ("turn rate", "turn rate vyaw (rad/s)"),
}
# A command asks for a velocity outright only when it is the log's one command in that velocity's unit: a
# differential drive's v_mm_s is the forward speed it asks for, while two wheel speeds ask for none alone.
_ASKED_BY_UNIT = {"v_y_mm_s": "_mm_s", "v_theta_rad_s": "_rad_s"}


def action_panels(names: tuple[str, ...], beta_learned: np.ndarray, beta_truth: np.ndarray) -> list[int]:
    """The velocity components worth a row of panels: forward, turn, then sideways, each only where the
    learned model or From-Truth moves it (a component both hold at zero, as a differential drive's
    sideways one, shows nothing)."""
    first = ("v_y_mm_s", "v_theta_rad_s", "v_x_mm_s")
    order = sorted(range(len(names)), key=lambda j: first.index(names[j]) if names[j] in first else len(first))
    moving = np.any(beta_learned != 0, axis=0) | np.any(beta_truth != 0, axis=0)
    return [j for j in order if moving[j]]


def figure_action_curves(ml: Any, model: Any, score: JsonObject, path: Path, title: str, truth: str = "Vicon") -> Path:
    """Each velocity against each command, learned and From-Truth, over the range of that command the
    robot used, every other command held at its median over the log (a differential drive's turn
    command is then 0 and its forward one its cruising speed; a wheel the other wheel's usual speed).
    A row per velocity that moves, a column per command, whatever the commands are."""
    act = model.action
    beta_ft = np.asarray(score["action"]["from_truth_coefficients"])
    c = ml.data.step_commands
    commands = tuple(ml.data.command_names)
    velocities = tuple(act.velocity_names)
    rows = action_panels(velocities, act.coefficients, beta_ft)
    held = np.median(c, axis=0)
    fig, axes = plt.subplots(
        len(rows), len(commands), figsize=(4.2 * len(commands) + 0.6, 3.4 * len(rows)), squeeze=False, sharey="row"
    )  # a row shares its scale, so a command the velocity hardly depends on draws a flat line, not a zoomed one
    for r, j in enumerate(rows):
        unit = _ASKED_BY_UNIT.get(velocities[j])
        asking = [n for n in commands if unit and n.endswith(unit)]
        for i, name in enumerate(commands):
            ax = axes[r, i]
            x = np.linspace(c[:, i].min(), c[:, i].max(), 50)
            grid = np.tile(held, (x.size, 1))
            grid[:, i] = x
            (_, kv), (si_name, kc) = velocity_rep(velocities[j]), si(name)  # REP 103, SI
            ax.plot(x * kc, act.features(grid) @ act.coefficients[:, j] * kv, label="learned (EM)")
            ax.plot(x * kc, act.features(grid) @ beta_ft[:, j] * kv, "--", label=f"From-Truth ({truth})")
            if asking == [name]:
                ax.plot(x * kc, x * kc, ":", color="0.5", label="command")
            others = ", ".join(f"{si(n)[0]} at {held[k] * si(n)[1]:.3g}" for k, n in enumerate(commands) if k != i)
            word, axis = _VELOCITY_LABELS.get(velocities[j], (velocities[j], velocities[j]))
            ax.set(
                xlabel=f"commanded {si_name}" + (f"\n({others})" if others else ""),  # a line of its own: 3 fit
                ylabel=axis,
                title=f"{title}: {word} against {si_name}",
            )
            ax.legend(fontsize=7)
            ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def figure_range_function(ml: Any, model: Any, score: JsonObject, path: Path, title: str, truth: str = "Vicon") -> Path:
    """Readings against the ground truth's distance (Vicon's on MRCLAM), with the learned and From-Truth
    range functions. With bearing terms the readings are shown with the learned terms taken out,
    ``reading - d g(b)``, so that they scatter about f(d)."""
    d = ml.data
    ok, sensor_poses, lm = _truth_at_sensor(ml, score)
    dist = landmark_distance(sensor_poses, lm)
    chan = model.sensor.channels[0]
    reading = d.obs_readings[ok, 0] - dist * chan.bearing_gain(d.obs_bearing_rad[ok])
    f = chan.function
    f_ft = Polynomial1D.from_dict(score["range"]["from_truth_function"])
    x = np.linspace(dist.min(), dist.max(), 200)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    what = "sightings, learned bearing terms removed" if chan.bearing_terms else "sightings"
    name, k = si(chan.name)
    label = f"{what} ({truth}, at the fitted sensor pose)"
    ax.scatter(dist * MM, reading * k, s=3, alpha=0.25, color="0.4", label=label)
    ax.plot(x * MM, f(x) * k, lw=2, label="learned f (EM)")
    ax.plot(x * MM, f_ft(x) * k, "--", lw=2, label="From-Truth f")
    ax.set(xlabel="true distance (m)", ylabel=f"reading {name}", title=f"{title}: range function")
    ax.set_ylim(0, np.percentile(reading * k, 99.5) * 1.1)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def binned_rms(x: np.ndarray, y: np.ndarray, n_bins: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """The median of ``x`` and the RMS of ``y`` in each of ``n_bins`` quantile bins of ``x`` that holds
    any point. Tied values share a bin, so a log whose windows mostly have the same turn rate (a robot
    that stood still for half of it) gives fewer bins, never an empty one."""
    edges = np.quantile(x, np.linspace(0, 1, n_bins + 1))
    which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, n_bins - 1)
    filled = [k for k in range(n_bins) if np.any(which == k)]
    mid = np.array([np.median(x[which == k]) for k in filled])
    rms = np.array([np.sqrt(np.mean(y[which == k] ** 2)) for k in filled])
    return mid, rms


def figure_heading_noise(ml: Any, model: Any, score: JsonObject, path: Path, title: str, truth: str = "Vicon") -> Path:
    """The truth's heading drift over each 1-s window against the window's turn rate, its RMS in bins,
    the truth's ``a + b |turn|`` fit, and the drift the learned Sigma_m allows over the same window."""
    from sensact.evaluate.landmark_truth import from_truth_windows, heading_drift

    d = ml.data
    window = round(score["window_s"] / d.dt_s)
    _, D_true, features = from_truth_windows(d, *ml.truth_poses(), model.action, window)
    beta = np.asarray(score["action"]["from_truth_coefficients"])
    turn, drift = heading_drift(features(round(score["action"]["from_truth_delay_s"] / d.dt_s)) @ beta, D_true, d.dt_s)
    a, b = score["truth_noise"]["heading_drift_variance_fit"]
    a_m, b_m = score["truth_noise"]["learned_heading_variance_per_step"]
    x = np.linspace(0.0, np.percentile(turn, 99), 100)
    mid, rms = binned_rms(turn, drift)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ax.scatter(turn, np.abs(drift), s=3, alpha=0.2, color="0.5", label=f"|heading drift| per window ({truth})")
    ax.plot(mid, rms, "o", color="k", label="its RMS in tenths of the windows")
    ax.plot(x, np.sqrt(np.maximum(a + b * x, 0.0)), "--", lw=2, label=f"{truth}: variance a + b |turn|")
    kind = "turning" if model.turn_var is not None else "shared"
    ax.plot(x, np.sqrt(window * (a_m + b_m * x)), lw=2, label=f"learned Sigma_m ({kind})")
    ax.set(
        xlabel="window's mean turn rate (rad/s)",
        ylabel=f"heading drift over {score['window_s']:.2g} s (rad)",
        title=f"{title}: heading noise",
    )
    ax.set_xlim(0, x[-1])
    if max(rms) > 0:
        ax.set_ylim(0, 3 * max(rms))
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def bearing_residuals(ml: Any, score: JsonObject, posteriors: Any = None) -> tuple[np.ndarray, np.ndarray | None]:
    """The bearing residuals about the ground truth's pose moved to the fitted sensor pose, at the
    sightings with valid truth (the ones the bar's sigma is the trimmed RMS of), and, given EM's
    posteriors, about its smoothed path at the sightings whose bearing the E-step used (else None)."""
    from sensact.core.angles import wrap_angle
    from sensact.core.pose_models import landmark_bearing

    d, post = ml.data, posteriors
    ok, sensor_poses, lm = _truth_at_sensor(ml, score)
    truth = wrap_angle(d.obs_bearing_rad[ok] - landmark_bearing(sensor_poses, lm))
    if post is None:
        return truth, None
    used = post.obs_used & (post.weights[:, -1] > 0)
    lm_used = d.landmarks_xy[d.obs_landmark[used]]
    em = wrap_angle(d.obs_bearing_rad[used] - landmark_bearing(post.mean_gamma[d.obs_step[used]], lm_used))
    return truth, em


def figure_bearing_noise(
    ml: Any,
    model: Any,
    score: JsonObject,
    path: Path,
    title: str,
    posteriors: Any = None,
    truth: str = "Vicon",
) -> Path:
    """The bearing sigma bar as a picture: the residuals about the ground truth's pose (as the bar scores
    them) and about EM's smoothed path (what EM learns from), with the learned noise density, the truth's
    trimmed sigma (the bar's) and the camera's own noise (the sd of a sighting about its frame's
    mean; left out when no frame has two sightings). EM's histogram narrower than the learned density
    means the M-step's posterior variance term carries the sigma; narrower than the camera's own, the
    smoother has fitted its path to the bearings. Without posteriors (a model scored after the fact)
    EM's histogram is left out."""
    from scipy import stats

    res_truth, em = bearing_residuals(ml, score, posteriors)
    b, sensor = score["bearing"], model.sensor
    s_true, s_learned = b["sigma_truth_rad"], b["sigma_learned_rad"]
    own = score["truth_noise"]["bearing_within_frame_sd_rad"]
    passed = score.get("bars", {}).get("bearing_sigma")
    verdict = "" if passed is None else (", bar passed" if passed else ", bar failed")
    x = np.linspace(-4 * s_true, 4 * s_true, 400)
    bins = np.linspace(x[0], x[-1], 61)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.hist(res_truth, bins, density=True, color="0.75", label=f"about {truth}'s pose ({res_truth.size} sightings)")
    if em is not None:
        ax.hist(
            em,
            bins,
            density=True,
            histtype="step",
            lw=1.5,
            color="tab:blue",
            label=f"about EM's smoothed path ({em.size})",
        )
    if sensor.bearing_robust == "student_t":
        nu = sensor.bearing_robust_param
        learned, kind = stats.t.pdf(x, nu, scale=s_learned), f"Student-t, nu {nu:g}, scale"
    else:
        learned, kind = stats.norm.pdf(x, scale=s_learned), "Gaussian, sd"
    ax.plot(x, learned, lw=2, color="tab:blue", label=f"learned: {kind} {s_learned:.4f} rad")
    bar = f"{truth}'s trimmed RMS {s_true:.4f} (the bar's)"
    ax.plot(x, stats.norm.pdf(x, scale=s_true), "--", lw=2, color="k", label=bar)
    if own is not None and np.isfinite(own):  # needs frames with several sightings (null in JSON otherwise)
        ax.plot(
            x,
            stats.norm.pdf(x, scale=own),
            ":",
            lw=2,
            color="tab:red",
            label=f"camera's own sd {own:.4f} (about its frame)",
        )
    ax.set(
        xlabel="bearing residual (rad)",
        ylabel="density",
        title=f"{title}: bearing noise, learned / {truth} {b['sigma_ratio']:.2f}{verdict}",
    )
    ax.set_xlim(x[0], x[-1])
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def figure_loglik(results: JsonObject, path: Path) -> Path:
    """log P(O | C, lambda) against the iteration, one line per run; a dot where the held stage ends
    (from there the likelihood is the robust one, with Sigma_m and the bearing terms learned) and a
    triangle at each later ridge or delay search (learn/em/searches/ridge.py, delay.py), whose move shows
    as the next step up."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, res in results.items():
        ll = res.loglik_history
        (line,) = ax.plot(np.arange(ll.size), ll - ll.max(), lw=1, label=name)
        if 0 <= res.freed_at < ll.size:
            ax.plot(res.freed_at, ll[res.freed_at] - ll.max(), "o", ms=4, color=line.get_color())
        searched = {r.iteration for r in (res.ridge or []) + (res.delay_search or [])}
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


def write_robot(
    ml: Any,
    model: Any,
    score: JsonObject,
    stem: Path,
    name: str,
    posteriors: Any = None,
    truth: str = "Vicon",
) -> list[Path]:
    """One robot's figures against its ground truth, which the legends call ``truth``:
    ``<stem>_actions.png``, ``_range``, ``_heading_noise`` and, for a sensor that reads bearings, ``_bearing``."""

    def at(kind: str) -> Path:
        return stem.with_name(f"{stem.name}_{kind}.png")

    paths = [
        figure_action_curves(ml, model, score, at("actions"), name, truth),
        figure_range_function(ml, model, score, at("range"), name, truth),
        figure_heading_noise(ml, model, score, at("heading_noise"), name, truth),
    ]
    if score["bearing"] is not None:
        paths.append(figure_bearing_noise(ml, model, score, at("bearing"), name, posteriors, truth))
    return paths


def write_all(art: JsonObject, res: JsonObject, out: Path) -> list[Path]:
    paths = []
    runs = {}
    for key, (ml, r) in art.get("mrclam", {}).items():
        score = res["mrclam"][key]["score"]
        stem, name = out / f"real_mrclam_{key.replace('/', '_')}", key.replace("/", " ").replace("robot", "robot ")
        paths += write_robot(ml, r.model, score, stem, name, r.posteriors)
        runs[f"MRCLAM {name}"] = r
    more = art.get("turtlebot_more_logs", {})
    turtlebots = []  # (stem, run, summary): the training1.csv first
    if "turtlebot" in art:
        turtlebots.append((Path(res["turtlebot"]["file"]).stem, art["turtlebot"], res["turtlebot"]))
    turtlebots += [(stem, run, res["turtlebot_more_logs"][stem]) for stem, run in more.items()]
    for stem, run, summary in turtlebots:
        title = f"Turtlebot {Path(summary['file']).name}, EM in 1-D"
        paths.append(figure_turtlebot_em(run, summary["score"], out / f"real_turtlebot_{stem}.png", title))
        # named by its log when others are drawn beside it
        runs["Turtlebot" + (f" {stem}" if more else "")] = run.result
    for dataset, fleet in res.get("fleet", {}).items():
        from sensact.report.figures_fleet import figure_fleet

        paths.append(
            figure_fleet(fleet, out / f"real_fleet_{dataset}.png", f"{dataset}: each robot's model on every log")
        )
    if runs:
        paths.append(figure_loglik(runs, out / "real_loglik.png"))
    return paths
